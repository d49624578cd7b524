// Emissive triangles as lights: the light BVH's probabilities, and renders
// of scenes lit only by emissive meshes against the same light as a rig light.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <cstdio>
#include <random>

#include "emissive_lights.h"
#include "light_stand_ins.h"
#include "propcam/render/props.h"
#include "propcam/render/synthetic_room.h"
#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"

namespace propcam::render {
namespace {

using detail::EmissiveLights;
using Eigen::Vector3f;

Material emissive(float radiance) {
  Material m;
  m.type = Material::Type::Emissive;
  m.emission = Vector3f::Constant(radiance);
  return m;
}

// A horizontal quad at height y, its winding facing -Y when `down`.
Mesh quad(float half, float y, const Material& material, bool down) {
  Mesh m;
  m.positions = {{-half, y, -half}, {half, y, -half}, {half, y, half}, {-half, y, half}};
  m.triangles = down ? std::vector<Eigen::Vector3i>{{0, 1, 2}, {0, 2, 3}} : std::vector<Eigen::Vector3i>{{0, 2, 1}, {0, 3, 2}};
  m.material_ids = {0, 0};
  m.materials.push_back(material);
  return m;
}

// A flat-shaded UV sphere of `rings` x `segments` quads.
Mesh globe(const Vector3f& centre, float radius, const Material& material, int rings, int segments) {
  Mesh m;
  const float pi = std::numbers::pi_v<float>;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const float theta = pi * i / rings, phi = 2.f * pi * j / segments;
      m.positions.push_back(centre + radius * Vector3f(std::sin(theta) * std::cos(phi), std::cos(theta),
                                                       std::sin(theta) * std::sin(phi)));
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * segments + j, b = i * segments + (j + 1) % segments, c = a + segments, d = b + segments;
      for (const Eigen::Vector3i& t : {Eigen::Vector3i(a, b, d), Eigen::Vector3i(a, d, c)}) {
        if ((m.positions[t[1]] - m.positions[t[0]]).cross(m.positions[t[2]] - m.positions[t[0]]).norm() < 1e-12f) continue;
        m.triangles.push_back(t);
        m.material_ids.push_back(0);
      }
    }
  m.materials.push_back(material);
  return m;
}

// A scene of many emissive triangles of different powers: two globes and a panel.
std::unique_ptr<Scene> lamps_scene() {
  auto scene = std::make_unique<Scene>();
  scene->add_mesh(quad(20.f, 0.f, Material{}, false), Layer::Background);
  scene->add_mesh(globe({-1.f, 1.f, 0.5f}, 0.1f, emissive(20.f), 8, 16), Layer::Background);
  scene->add_mesh(globe({1.5f, 0.5f, -1.f}, 0.05f, emissive(100.f), 6, 12), Layer::Background);
  scene->add_mesh(quad(0.5f, 2.5f, emissive(5.f), true), Layer::Background);
  scene->commit();
  return scene;
}

TEST(EmissiveLights, FindsEveryEmissiveTriangleOnce) {
  const auto scene = lamps_scene();
  const EmissiveLights& lights = scene->emissive_lights();
  const int expected = static_cast<int>(scene->mesh(1).triangles.size() + scene->mesh(2).triangles.size()) + 2;
  ASSERT_EQ(lights.size(), expected);
  for (int i = 0; i < lights.size(); ++i) {
    const auto& t = lights.triangle(i);
    EXPECT_EQ(lights.index_of(t.mesh, t.triangle), i);
  }
  EXPECT_EQ(lights.index_of(0, 0), -1);  // the floor
  EXPECT_EQ(lights.index_of(99, 0), -1);
}

// For any receiving point the pick probabilities of all triangles sum to 1,
// every triangle that could light the point has a non-zero probability, and
// pick() reports the probability pmf() gives.
TEST(EmissiveLights, PickProbabilitiesAreConsistent) {
  const auto scene = lamps_scene();
  const EmissiveLights& lights = scene->emissive_lights();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  for (int trial = 0; trial < 50; ++trial) {
    const Vector3f p(6.f * unit(rng) - 3.f, 0.01f + 2.4f * unit(rng), 6.f * unit(rng) - 3.f);
    const Vector3f n = trial % 2 ? Vector3f(Vector3f::UnitY()) : Vector3f(Vector3f::Zero());
    double sum = 0.0;
    for (int i = 0; i < lights.size(); ++i) {
      const float pmf = lights.pmf(p, n, i);
      ASSERT_TRUE(std::isfinite(pmf));
      sum += pmf;
      const auto& t = lights.triangle(i);
      // Any triangle with a corner above the floor point can light it.
      const bool reachable = (t.a - p).dot(n) > 0.f || (t.b - p).dot(n) > 0.f || (t.c - p).dot(n) > 0.f || n.isZero();
      if (reachable) {
        EXPECT_GT(pmf, 0.f) << "triangle " << i << " trial " << trial;
      }
    }
    EXPECT_NEAR(sum, 1.0, 1e-4);
    for (int k = 0; k < 64; ++k) {
      const EmissiveLights::Pick pick = lights.pick(p, n, unit(rng));
      ASSERT_GE(pick.index, 0);
      EXPECT_FLOAT_EQ(pick.pmf, lights.pmf(p, n, pick.index));
    }
  }
}

// The density sample() reports is the one pdf() gives for the same direction,
// by solid angle close by and by area far away.
TEST(EmissiveLights, SampleDensityMatchesPdf) {
  const auto scene = lamps_scene();
  const EmissiveLights& lights = scene->emissive_lights();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  for (const Vector3f& from : {Vector3f(0.f, 0.2f, 0.f), Vector3f(-1.f, 0.85f, 0.5f), Vector3f(300.f, 50.f, 0.f)})
    for (int i = 0; i < lights.size(); i += 7) {
      const LightSample s = lights.sample(i, from, unit(rng), unit(rng));
      if (!(s.pdf > 0.f)) continue;
      EXPECT_NEAR(lights.pdf(i, from, s.direction, s.distance), s.pdf, 1e-3f * s.pdf);
      EXPECT_TRUE(s.radiance.isApprox(lights.triangle(i).emission));
    }
}

TEST(EmissiveLights, MovingAPropMovesItsEmissiveTriangles) {
  Scene scene;
  scene.add_mesh(quad(5.f, 0.f, Material{}, false), Layer::Background);
  const int lamp = scene.add_prop(globe(Vector3f::Zero(), 0.1f, emissive(10.f), 4, 8), Eigen::Affine3f::Identity());
  scene.commit();
  ASSERT_FALSE(scene.emissive_lights().empty());
  EXPECT_TRUE(scene.emissive_lights().triangle(0).prop);
  const float x_before = scene.emissive_lights().triangle(0).a.x();
  scene.set_prop_transform(lamp, Eigen::Affine3f(Eigen::Translation3f(2.f, 1.f, 0.f)));
  EXPECT_NEAR(scene.emissive_lights().triangle(0).a.x(), x_before + 2.f, 1e-5f);
}

// A panel of emissive triangles lights a floor as an area light of the same
// radiance does, and with comparable noise: it is sampled as a light, not
// only found by BSDF sampling.
TEST(EmissiveLights, PanelLightsLikeAnAreaLightWithComparableNoise) {
  constexpr float kRadiance = 4.f, kHalf = 0.5f, kHeight = 1.5f;
  Scene panel_scene;
  panel_scene.add_mesh(quad(1000.f, 0.f, Material{}, false), Layer::Background);
  panel_scene.add_mesh(quad(kHalf, kHeight, emissive(kRadiance), true), Layer::Background);
  panel_scene.commit();
  Scene floor_scene;
  floor_scene.add_mesh(quad(1000.f, 0.f, Material{}, false), Layer::Background);
  floor_scene.commit();
  LightRig area;
  AreaLight light;
  light.corner = {-kHalf, kHeight, -kHalf};
  light.edge_u = {2 * kHalf, 0.f, 0.f};
  light.edge_v = {0.f, 0.f, 2 * kHalf};  // facing down
  light.radiance = Vector3f::Constant(kRadiance);
  area.area_lights.push_back(light);

  PinholeCamera cam;
  cam.width = cam.height = 24;
  cam.fx = cam.fy = 12;  // a wide view of the floor under the panel, the panel itself out of view
  cam.cx = cam.cy = 11.5;
  cam.R_world_from_cam << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  cam.center_world = {0.f, 1.f, 0.f};
  RenderSettings settings;
  settings.max_bounces = 1;
  settings.samples_per_pixel = 1024;
  const cv::Mat reference = render_background_image(floor_scene, cam, area, settings);
  settings.samples_per_pixel = 4;
  settings.seed = 99;
  const cv::Mat area_few = render_background_image(floor_scene, cam, area, settings);
  const cv::Mat panel_few = render_background_image(panel_scene, cam, LightRig{}, settings);
  settings.samples_per_pixel = 256;
  const cv::Mat panel_many = render_background_image(panel_scene, cam, LightRig{}, settings);
  const double mean = cv::mean(reference)[0];
  EXPECT_NEAR(cv::mean(panel_many)[0], mean, 0.02 * mean);
  const double area_error = cv::norm(area_few, reference, cv::NORM_L2);
  const double panel_error = cv::norm(panel_few, reference, cv::NORM_L2);
  // Two triangles, each picked by what it gives, against one rectangle sampled by solid angle.
  EXPECT_LT(panel_error, 2.0 * area_error) << "area " << area_error << " panel " << panel_error;
  std::printf("area %g panel %g\n", area_error, panel_error);
}

// Degenerate emitters: slivers, a huge triangle, points in a triangle's
// plane; the image stays finite and deterministic.
TEST(EmissiveLights, DegenerateEmittersRenderFinite) {
  Scene scene;
  scene.add_mesh(quad(10.f, 0.f, Material{}, false), Layer::Background);
  Mesh sliver;
  sliver.positions = {{0.f, 1.f, 0.f}, {1.f, 1.f, 0.f}, {0.5f, 1.f, 1e-7f}, {-1e4f, 3.f, -1e4f}, {1e4f, 3.f, -1e4f},
                      {0.f, 3.f, 1e4f}, {0.f, 0.f, 0.f}, {0.f, 0.f, 0.f}, {1.f, 0.f, 0.f}};
  sliver.triangles = {{0, 1, 2}, {3, 4, 5}, {6, 7, 8}};
  sliver.material_ids = {0, 0, 0};
  sliver.materials.push_back(emissive(1e3f));
  scene.add_mesh(sliver, Layer::Background);
  scene.commit();
  EXPECT_EQ(scene.emissive_lights().size(), 2);  // the zero-area one is no light
  PinholeCamera cam;
  cam.width = cam.height = 16;
  cam.fx = cam.fy = 8;
  cam.cx = cam.cy = 7.5;
  cam.R_world_from_cam << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  cam.center_world = {0.2f, 1.f, 0.f};  // in the sliver's plane
  RenderSettings settings;
  settings.samples_per_pixel = 8;
  settings.max_bounces = 3;
  const cv::Mat a = render_image(scene, cam, LightRig{}, settings);
  const cv::Mat b = render_image(scene, cam, LightRig{}, settings);
  EXPECT_TRUE(cv::checkRange(a));
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
}

// A closed emitter 3 cm above a floor: the shadow rays toward its near side
// must end before its surface although the floor's ray origins are lifted by
// more than the shadow ray's shortening (a bench room's tube by its wall came
// out 22% too dark). The floor's radiance equals what cosine-weighted rays
// from the floor find.
TEST(EmissiveLights, EmitterCloseToASurfaceLightsItFully) {
  Scene scene;
  scene.add_mesh(quad(5.f, 0.f, Material{}, false), Layer::Background);
  scene.add_mesh(globe({0.f, 0.05f, 0.f}, 0.02f, emissive(50.f), 12, 24), Layer::Background);
  scene.commit();
  const Vector3f p(0.05f, 0.f, 0.f), up = Vector3f::UnitY();
  // Irradiance by cosine-weighted rays (no light sampling involved).
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  constexpr int kRays = 200000;
  double irradiance = 0.0;
  for (int k = 0; k < kRays; ++k) {
    const float r = std::sqrt(unit(rng)), phi = 2.f * std::numbers::pi_v<float> * unit(rng);
    const Vector3f d(r * std::cos(phi), std::sqrt(std::max(0.f, 1.f - r * r)), r * std::sin(phi));
    RayHit hit;
    if (!scene.intersect(p + 1e-4f * up, d, 1e30f, false, hit)) continue;
    const SurfacePoint sp = scene.surface(hit, p, d);
    if (sp.material->type == Material::Type::Emissive) irradiance += std::numbers::pi * sp.material->emission.x();
  }
  irradiance /= kRays;
  const double expected = Material{}.albedo.x() / std::numbers::pi * irradiance;
  // A narrow camera looking at p from above and to the side, the globe out of view.
  PinholeCamera cam;
  cam.width = cam.height = 4;
  cam.fx = cam.fy = 4000;
  cam.cx = cam.cy = 1.5;
  cam.center_world = Eigen::Vector3d(0.55, 1.0, 0.0);
  const Eigen::Vector3d forward = (p.cast<double>() - cam.center_world).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  cam.R_world_from_cam.col(0) = right;
  cam.R_world_from_cam.col(1) = forward.cross(right);
  cam.R_world_from_cam.col(2) = forward;
  RenderSettings settings;
  settings.max_bounces = 1;  // direct light
  settings.samples_per_pixel = 256;
  settings.max_sample_luminance = 0.f;
  const double rendered = cv::mean(render_image(scene, cam, LightRig{}, settings))[0];
  EXPECT_NEAR(rendered, expected, 0.03 * expected) << "irradiance " << irradiance;
}

// The rig's lights that stand for emissive surfaces: the synthetic room's
// panels (area lights 3 mm below them) and the lamp prop's globe (its
// prop_lights sphere); a panel whose light is elsewhere is sampled itself.
TEST(EmissiveLights, RigLightsStandForPanelsAndALampsGlobe) {
  for (uint64_t seed : {1u, 2u, 3u}) {
    SyntheticRoomSpec spec;
    spec.seed = seed;
    const SyntheticRoom room = make_synthetic_room(spec);
    Scene scene;
    scene.add_mesh(room.room, Layer::Background);
    scene.commit();
    ASSERT_FALSE(scene.emissive_lights().empty());
    EXPECT_TRUE(detail::rig_stands_for_every_emitter(room.lights, scene.emissive_lights())) << "seed " << seed;
    LightRig moved = room.lights;
    moved.area_lights[0].corner.y() -= 0.1f;  // 10 cm below its panel
    EXPECT_FALSE(detail::rig_stands_for_every_emitter(moved, scene.emissive_lights())) << "seed " << seed;
    EXPECT_FALSE(detail::rig_stands_for_every_emitter(LightRig{}, scene.emissive_lights()));
  }
  const Eigen::Affine3f at(Eigen::Translation3f(0.5f, 0.f, -2.f));
  Scene scene;
  scene.add_mesh(quad(5.f, 0.f, Material{}, false), Layer::Background);
  scene.add_prop(make_prop("lamp"), at);
  scene.commit();
  LightRig rig;
  for (const SphereLight& l : prop_lights(make_prop("lamp"), at)) rig.sphere_lights.push_back(l);
  EXPECT_TRUE(detail::rig_stands_for_every_emitter(rig, scene.emissive_lights()));
  rig.sphere_lights[0].radius *= 0.9f;
  EXPECT_FALSE(detail::rig_stands_for_every_emitter(rig, scene.emissive_lights()));
}

}  // namespace
}  // namespace propcam::render
