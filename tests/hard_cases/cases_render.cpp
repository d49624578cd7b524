// render: a light at grazing angle, a prop at the horizon, zero samples per
// pixel, degenerate and non-finite meshes, environment maps with NaN / Inf /
// negative texels, broken cameras, corrupt mesh and scene files, a scene
// taken for a flat field.
#include <filesystem>
#include <limits>

#include "catalogue.h"
#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/mesh.h"
#include "propcam/render/mesh_io.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/placement.h"
#include "propcam/render/props.h"
#include "propcam/render/scene.h"
#include "propcam/render/scene_file.h"
#include "propcam/render/vignetting.h"

namespace propcam::render {
namespace {

using hard_cases::check;
using hard_cases::Digest;

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

Mesh with_one_material(Mesh m) {
  m.materials = {Material{}};
  m.material_ids.assign(m.triangles.size(), 0);
  return m;
}

// A floor at y = 0 from z = near to z = far (negative: in front of a camera looking down -z).
Mesh floor_quad(float half_width, float z_near, float z_far) {
  Mesh m;
  m.positions = {{-half_width, 0, z_near}, {half_width, 0, z_near}, {half_width, 0, z_far}, {-half_width, 0, z_far}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return with_one_material(m);
}

// 24x16, 1.5 m up, looking down -z and 15 degrees down.
PinholeCamera small_camera(int w = 24, int h = 16, double pitch = -0.26) {
  PinholeCamera c = pinhole_with_fov(w, h, 60);
  c.R_world_from_cam = rotation_from_yaw_pitch_roll(0, pitch, 0);
  c.center_world = {0, 1.5, 0};
  return c;
}

RenderSettings few_samples(int spp = 4) {
  RenderSettings s;
  s.samples_per_pixel = spp;
  s.max_bounces = 2;
  s.threads = 2;
  return s;
}

LightRig panel_above() {
  LightRig rig;
  AreaLight a;
  a.corner = {-0.5f, 3.f, -3.5f};
  a.edge_u = {1, 0, 0};  // edge_u x edge_v points down
  a.edge_v = {0, 0, 1};
  a.radiance = {5, 5, 5};
  rig.area_lights.push_back(a);
  return rig;
}

std::unique_ptr<Scene> floor_scene() {
  auto scene = std::make_unique<Scene>();
  scene->add_mesh(floor_quad(50, 10, -50), Layer::Background);
  scene->commit();
  return scene;
}

}  // namespace
}  // namespace propcam::render

namespace propcam::hard_cases {

void add_render_cases(std::vector<HardCase>& cases) {
  using namespace propcam::render;
  const std::string m = "render";
  cases.push_back({"LightAtGrazingAngle", m,
                   "a 4 m x 1 cm area light lying 1 mm above the floor, emitting along it; 24x16 at 4 spp",
                   "a finite, non-negative image", Expect::Result, {}, [](Digest& d) {
                     const auto scene = floor_scene();
                     LightRig rig;
                     AreaLight a;
                     a.corner = {-2.f, 0.001f, -6.f};
                     a.edge_u = {4, 0, 0};
                     a.edge_v = {0, 0.01f, 0};  // normal +z: toward the camera, grazing the floor
                     a.radiance = {100, 100, 100};
                     rig.area_lights.push_back(a);
                     const cv::Mat img = render_image(*scene, small_camera(), rig, few_samples());
                     double lo = 0;
                     cv::minMaxLoc(img.reshape(1), &lo);
                     check(lo >= 0, "radiance is non-negative");
                     d.mat(img);
                   }});
  cases.push_back({"SunAtTheHorizon", m, "a sun exactly in the floor's plane (direction (1, 0, 0)) over the floor",
                   "a finite image (the floor receives nothing from it)", Expect::Result, {}, [](Digest& d) {
                     const auto scene = floor_scene();
                     LightRig rig;
                     SunLight sun;
                     sun.direction = {1, 0, 0};
                     sun.irradiance = {3, 3, 3};
                     rig.suns.push_back(sun);
                     d.mat(render_image(*scene, small_camera(), rig, few_samples()));
                   }});
  cases.push_back({"ZeroSamplesPerPixel", m, "render_image with samples_per_pixel = 0",
                   "error naming samples_per_pixel", Expect::Error, {"samples_per_pixel"}, [](Digest&) {
                     const auto scene = floor_scene();
                     render_image(*scene, small_camera(), panel_above(), few_samples(0));
                   }});
  cases.push_back({"CameraWithNanFocalLength", m, "render_image through a camera whose fx is NaN",
                   "error naming the intrinsics", Expect::Error, {"intrinsics"}, [](Digest&) {
                     const auto scene = floor_scene();
                     PinholeCamera c = small_camera();
                     c.fx = std::numeric_limits<double>::quiet_NaN();
                     render_image(*scene, c, panel_above(), few_samples());
                   }});
  cases.push_back({"DegenerateTriangles", m,
                   "a mesh of zero-area triangles (collinear, repeated vertices) over the floor; 24x16 at 4 spp",
                   "a finite image", Expect::Result, {}, [](Digest& d) {
                     Scene scene;
                     scene.add_mesh(floor_quad(50, 10, -50), Layer::Background);
                     Mesh degenerate;
                     degenerate.positions = {{0, 0.5f, -3}, {0.5f, 0.5f, -3}, {1, 0.5f, -3}, {0, 1, -3}};
                     degenerate.triangles = {{0, 1, 2}, {3, 3, 3}, {0, 0, 1}};
                     degenerate.compute_vertex_normals();
                     scene.add_mesh(with_one_material(degenerate), Layer::Background);
                     scene.commit();
                     const cv::Mat img = render_image(scene, small_camera(), panel_above(), few_samples());
                     check(cv::sum(img)[1] > 0, "the floor is lit");
                     d.mat(img);
                   }});
  cases.push_back({"NonFiniteVertex", m, "a mesh with a NaN vertex added to a scene",
                   "error naming the non-finite vertex", Expect::Error, {"non-finite vertex"}, [](Digest&) {
                     Mesh bad = floor_quad(1, 0, -1);
                     bad.positions[2] = {kNan, 0, 0};
                     Scene scene;
                     scene.add_mesh(bad, Layer::Background);
                     scene.commit();
                   }});
  cases.push_back({"EnvironmentWithNonFiniteTexels", m,
                   "an environment light from a 32x16 map with NaN, +Inf and negative texels; 24x16 at 4 spp",
                   "a finite image (bad texels are dark)", Expect::Result, {}, [](Digest& d) {
                     cv::Mat map(16, 32, CV_32FC3, cv::Scalar::all(0.5));
                     map.at<cv::Vec3f>(2, 3) = {kNan, kNan, kNan};
                     map.at<cv::Vec3f>(4, 9) = {kInf, kInf, kInf};
                     map.row(12).setTo(cv::Scalar::all(-7));
                     LightRig rig;
                     rig.environment = std::make_shared<EnvironmentLight>(map);
                     const auto scene = floor_scene();
                     const cv::Mat img = render_image(*scene, small_camera(), rig, few_samples());
                     check(cv::sum(img)[1] > 0, "the sky lights the floor");
                     d.mat(img);
                   }});
  cases.push_back({"EnvironmentOfBytes", m, "an environment light from an 8-bit map", "error naming CV_32FC3",
                   Expect::Error, {"cv_32fc3"}, [](Digest&) {
                     EnvironmentLight env(cv::Mat(16, 32, CV_8UC3, cv::Scalar::all(128)));
                   }});
  cases.push_back({"PropAtTheHorizon", m,
                   "place_prop a cube half a pixel below the horizon of a level camera over an endless floor, then a differential render at 2 spp",
                   "the cube placed over 100 m away, a finite differential render", Expect::Result, {},
                   [](Digest& d) {
                     const PinholeCamera cam = small_camera(48, 32, 0.0);
                     Scene background;
                     background.add_mesh(floor_quad(1e4f, 10, -1e4f), Layer::Background);
                     background.commit();
                     Eigen::Vector2d horizon;
                     check(cam.project({0, 1.5, -1e9}, horizon), "the horizon is in view");
                     const Mesh cube = make_prop("cube");
                     const PlacedProp placed = place_prop(cube, cam, background, {horizon.x(), horizon.y() + 0.5, 0.5, 0});
                     check((placed.base_world - cam.center_world.cast<float>()).norm() > 100.f, "far away");
                     for (int i = 0; i < 3; ++i) d.number(placed.base_world[i]);
                     Scene world;
                     world.add_mesh(floor_quad(1e4f, 10, -1e4f), Layer::Background);
                     world.add_prop(cube, placed.world_from_prop);
                     world.commit();
                     const DifferentialRender r = render_differential(world, cam, panel_above(), few_samples(2));
                     d.mat(r.coverage);
                     d.mat(r.change);
                   }});
  cases.push_back({"PropAboveTheHorizon", m, "place_prop a cube half a pixel above the horizon (the sky)",
                   "error saying no surface is seen there", Expect::Error, {"no surface"}, [](Digest&) {
                     const PinholeCamera cam = small_camera(48, 32, 0.0);
                     Scene background;
                     background.add_mesh(floor_quad(1e4f, 10, -1e4f), Layer::Background);
                     background.commit();
                     Eigen::Vector2d horizon;
                     check(cam.project({0, 1.5, -1e9}, horizon), "the horizon is in view");
                     place_prop(make_prop("cube"), cam, background, {horizon.x(), horizon.y() - 0.5, 0.5, 0});
                   }});
  cases.push_back({"CorruptObj", m, "an OBJ file whose face names vertex 9 of 2", "error naming the file",
                   Expect::Error, {"broken.obj"}, [](Digest&) {
                     ScratchDir dir("CorruptObj");
                     write_text_file(dir / "broken.obj", "v 0 0 0\nv 1 0 0\nf 1 2 9\n");
                     load_mesh_file((dir / "broken.obj").string());
                   }});
  cases.push_back({"SceneFileTruncated", m, "a scene JSON file cut inside the camera object",
                   "error naming the file", Expect::Error, {"cut.json"}, [](Digest&) {
                     ScratchDir dir("SceneFileTruncated");
                     write_text_file(dir / "cut.json", "{\"camera\": {\"K\": {\"fx\": 20,");
                     load_scene_file((dir / "cut.json").string());
                   }});
  cases.push_back({"VignettingFromAScene", m,
                   "fit_vignetting on a 64x48 frame half dark, half bright (a scene, not a flat field)",
                   "error saying it is not a flat field", Expect::Error, {"not a flat field"}, [](Digest&) {
                     cv::Mat frame(48, 64, CV_32FC3, cv::Scalar::all(0.1));
                     frame.colRange(32, 64).setTo(cv::Scalar::all(0.6));
                     fit_vignetting({frame});
                   }});
}

}  // namespace propcam::hard_cases
