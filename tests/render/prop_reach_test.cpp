#include <gtest/gtest.h>

#include "propcam/render/path_tracer.h"
#include "propcam/render/prop_reach.h"
#include <opencv2/imgproc.hpp>

#include "propcam/render/props.h"

namespace propcam::render {
namespace {

// A wide grey floor seen from above at an angle, a 0.3 m cube on it.
struct FloorScene {
  Scene scene;
  PinholeCamera camera;
  Eigen::AlignedBox3f cube_bounds;
  FloorScene() {
    Mesh floor;
    floor.positions = {{-30, 0, -30}, {30, 0, -30}, {30, 0, 30}, {-30, 0, 30}};
    floor.triangles = {{0, 2, 1}, {0, 3, 2}};
    floor.material_ids = {0, 0};
    floor.materials.resize(1);
    floor.materials[0].albedo = {0.5f, 0.5f, 0.5f};
    scene.add_mesh(floor, Layer::Background);
    Mesh cube = make_prop("cube");
    const float s = 0.3f / cube.bounds().sizes().maxCoeff();
    const Eigen::Affine3f xf = Eigen::Scaling(s) * Eigen::Translation3f(-cube.bounds().center().x(),
                                                                       -cube.bounds().min().y(),
                                                                       -cube.bounds().center().z());
    const int id = scene.add_prop(cube, xf);
    scene.commit();
    cube_bounds = scene.world_bounds(id);
    camera.width = 64;
    camera.height = 48;
    camera.fx = camera.fy = 40;
    camera.cx = 31.5;
    camera.cy = 23.5;
    // 3 m up, 3 m back along +Z, looking down 45 degrees toward the origin.
    const Eigen::Vector3d forward = Eigen::Vector3d(0, -1, -1).normalized();
    const Eigen::Vector3d right = Eigen::Vector3d::UnitX();
    const Eigen::Vector3d down = forward.cross(right);
    camera.R_world_from_cam.col(0) = right;
    camera.R_world_from_cam.col(1) = down;
    camera.R_world_from_cam.col(2) = forward;
    camera.center_world = {0, 3, 3};
  }
};

// Every pixel the prop visibly changes lies in its reach.
void expect_reach_covers_the_change(const FloorScene& f, const LightRig& lights, const char* what) {
  const PropReach reach = estimate_prop_reach(f.scene, f.camera, lights, f.cube_bounds);
  RenderSettings s;
  s.samples_per_pixel = 32;
  s.max_bounces = 1;
  const DifferentialRender r = render_differential(f.scene, f.camera, lights, s);
  // "Visibly": a change above 2% of the floor's brightness without the prop.
  const cv::Mat empty = render_background_image(f.scene, f.camera, lights, s);
  int changed = 0, missed = 0;
  for (int y = 0; y < r.change.rows; ++y)
    for (int x = 0; x < r.change.cols; ++x) {
      const float base = empty.at<cv::Vec3f>(y, x)[1];
      if (std::abs(r.change.at<cv::Vec3f>(y, x)[1]) > 0.02f * base + 1e-6f || r.coverage.at<float>(y, x) > 0) {
        ++changed;
        if (!reach.affected.at<uint8_t>(y, x)) ++missed;
      }
    }
  EXPECT_GT(changed, 10) << what;
  EXPECT_LE(missed, changed / 100) << what << ": " << missed << " of " << changed << " changed pixels outside the reach";
  EXPECT_LT(cv::countNonZero(reach.affected), reach.affected.total()) << what << ": something is culled";
}

TEST(PropReach, CoversTheLongShadowOfALowSun) {
  FloorScene f;
  LightRig lights;
  SunLight sun;
  sun.direction = Eigen::Vector3f(1, 0.25f, 0.3f).normalized();  // 14 degrees up
  sun.irradiance = Eigen::Vector3f::Constant(3.f);
  lights.suns.push_back(sun);
  expect_reach_covers_the_change(f, lights, "low sun");
}

TEST(PropReach, CoversTheShadowOfASunInsideTheEnvironment) {
  FloorScene f;
  cv::Mat env(64, 128, CV_32FC3, cv::Scalar::all(0.05));
  const Eigen::Vector2f uv = EnvironmentLight::direction_to_uv(Eigen::Vector3f(-1, 0.35f, 0.2f).normalized());
  cv::circle(env, {static_cast<int>(uv.x() * 128), static_cast<int>(uv.y() * 64)}, 1, cv::Scalar::all(5000.0), cv::FILLED);
  LightRig lights;
  lights.environment = std::make_shared<EnvironmentLight>(env);
  expect_reach_covers_the_change(f, lights, "environment sun");
  EXPECT_TRUE(estimate_prop_reach(f.scene, f.camera, lights, f.cube_bounds).environment_has_sun);
}

TEST(PropReach, CoversTheShadowOfAnAreaLight) {
  FloorScene f;
  LightRig lights;
  AreaLight l;
  l.corner = {-1.6f, 1.0f, -0.2f};
  l.edge_u = {0, 0, 0.4f};
  l.edge_v = {0, 0.4f, 0};
  if (l.normal().x() < 0) std::swap(l.edge_u, l.edge_v);  // face +X, toward the cube
  l.radiance = Eigen::Vector3f::Constant(40.f);
  lights.area_lights.push_back(l);
  expect_reach_covers_the_change(f, lights, "area light");
}

// One centred ray per pixel is the primary buffers' prop coverage; more rays
// give the edge pixels their share and leave the inside whole.
TEST(PropCoverage, StratifiedRaysGiveEdgePixelsTheirShare) {
  const FloorScene f;
  const cv::Rect all(0, 0, f.camera.width, f.camera.height);
  const cv::Mat centred = render_prop_coverage(f.scene, f.camera, all, 1, 2);
  cv::Mat primary;
  render_primary_buffers(f.scene, f.camera, true).prop_coverage.convertTo(primary, CV_32F, 1.0 / 255.0);
  EXPECT_EQ(cv::norm(centred, primary, cv::NORM_INF), 0.0);
  ASSERT_GT(cv::countNonZero(centred), 4);

  const cv::Mat shares = render_prop_coverage(f.scene, f.camera, all, 4, 2);
  const cv::Mat partial = (shares > 0.f) & (shares < 1.f);
  EXPECT_GT(cv::countNonZero(partial), 0) << "the cube's edges cross pixels";
  cv::Mat inside;
  cv::erode(shares >= 1.f, inside, cv::Mat());
  const cv::Mat inside_centred = centred > 0.f;
  EXPECT_EQ(cv::countNonZero(inside & ~inside_centred), 0) << "wholly covered pixels are covered at their centre";
  // The total area agrees with the centred count to within the edge pixels.
  EXPECT_NEAR(cv::sum(shares)[0], cv::sum(centred)[0], cv::countNonZero(partial));

  // A region is that part of the whole; one outside the image is empty.
  const cv::Rect part(20, 10, 24, 30);
  const cv::Mat region = render_prop_coverage(f.scene, f.camera, part, 4, 1);
  EXPECT_EQ(cv::norm(region, shares(part), cv::NORM_INF), 0.0);
  EXPECT_TRUE(render_prop_coverage(f.scene, f.camera, {100, 100, 5, 5}, 4).empty());
  EXPECT_THROW(render_prop_coverage(f.scene, f.camera, all, 0), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::render
