// Compositing at the edges: a prop out of reach, hidden behind nearer
// geometry, sunk into the floor, larger than the room, at the horizon, behind
// the camera. Every case gives finite, deterministic output; the only
// exceptions are the std::invalid_argument the placement API documents.
// These tests carry the ctest label hard_case (tests/CMakeLists.txt).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <opencv2/imgproc.hpp>

#include "common/compositor.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/props.h"
#include "propcam/render/render_session.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;
constexpr int kPhotoSpp = 1;  // the photo is only the background: its noise does not matter here
constexpr int kSpp = 4;            // samples per pixel of every composite here
constexpr uint64_t kSeed = 0x5eed;
constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr float kNoLimit = std::numeric_limits<float>::infinity();

bool identical(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

struct SessionResult {
  cv::Mat composite;  // CV_32FC3
  cv::Mat coverage;   // CV_32F
  std::vector<render::TileStatus> tiles;
};

// A RenderSession run to its sample limit, as composite_prop runs it.
SessionResult run_session(const render::Scene& scene, const render::PinholeCamera& camera,
                          const render::LightRig& lights, const cv::Mat& photo, const Eigen::AlignedBox3f& prop_bounds,
                          bool cull = true, int max_bounces = 4, uint64_t seed = kSeed) {
  render::SessionSettings s;
  s.render.seed = seed;
  s.render.max_bounces = max_bounces;
  s.max_samples_per_pixel = kSpp;
  s.cull_tiles = cull;
  render::RenderSession session(scene, camera, lights, photo, prop_bounds, s);
  while (!session.finished()) session.run_pass();
  const render::DifferentialRender d = session.differential();
  return {session.composite(), d.coverage, session.tiles()};
}

// The photo's depth mesh (ground truth) as background and `prop` (already in
// world coordinates) as the prop.
std::unique_ptr<render::Scene> depth_world(const inference::SceneModel& model, render::Mesh prop) {
  auto scene = std::make_unique<render::Scene>();
  scene->add_mesh(render::mesh_from_depth(model.depth, model.albedo, model.camera()), render::Layer::Background);
  scene->add_mesh(std::move(prop), render::Layer::Prop);
  scene->commit();
  return scene;
}

// A preset scaled to `height`, its base centre at `base` (world).
render::Mesh prop_at(const std::string& name, float height, const Eigen::Vector3f& base) {
  render::Mesh mesh = render::make_prop(name);
  const Eigen::AlignedBox3f box = mesh.bounds();
  const float scale = height / box.sizes().y();
  mesh.transform(Eigen::Translation3f(base) * Eigen::Scaling(scale) *
                 Eigen::Translation3f(-box.center().x(), -box.min().y(), -box.center().z()));
  return mesh;
}

render::Mesh floor_quad(float half_width, float z_near, float z_far) {
  render::Mesh m;
  m.positions = {{-half_width, 0, z_near}, {half_width, 0, z_near}, {half_width, 0, z_far}, {-half_width, 0, z_far}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};  // counter-clockwise seen from above
  m.material_ids = {0, 0};
  render::Material grey;
  grey.name = "floor";
  grey.albedo = {0.5f, 0.5f, 0.5f};
  m.materials = {grey};
  return m;
}

// At (0, height, 0), looking toward -z, pitched down by `pitch_deg`.
render::PinholeCamera camera_toward_minus_z(double height, double pitch_deg, double horizontal_fov_deg = 60.0) {
  render::PinholeCamera cam;
  cam.width = kWidth;
  cam.height = kHeight;
  cam.fx = cam.fy = 0.5 * kWidth / std::tan(0.5 * horizontal_fov_deg * kDegToRad);
  cam.cx = (kWidth - 1) / 2.0;
  cam.cy = (kHeight - 1) / 2.0;
  const double p = pitch_deg * kDegToRad;
  cam.R_world_from_cam.col(0) = Eigen::Vector3d::UnitX();
  cam.R_world_from_cam.col(1) = Eigen::Vector3d(0, -std::cos(p), std::sin(p));   // image down
  cam.R_world_from_cam.col(2) = Eigen::Vector3d(0, -std::sin(p), -std::cos(p));  // forward
  cam.center_world = {0, height, 0};
  return cam;
}

// One ceiling-like panel shining down.
render::LightRig panel_light(const Eigen::Vector3f& corner, float size, float radiance) {
  render::LightRig rig;
  render::AreaLight a;
  a.corner = corner;
  a.edge_u = Eigen::Vector3f::UnitX() * size;
  a.edge_v = Eigen::Vector3f::UnitZ() * size;  // edge_u x edge_v points down
  a.radiance = Eigen::Vector3f::Constant(radiance);
  rig.area_lights.push_back(a);
  return rig;
}

class CompositeHardCases : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    render::SyntheticRoomSpec spec;
    spec.width = kWidth;
    spec.height = kHeight;
    spec.seed = 4;
    render::RenderSettings settings;
    settings.samples_per_pixel = kPhotoSpp;
    shot_ = new SyntheticShot(shoot_synthetic_room(spec, settings));
  }
  static void TearDownTestSuite() { delete shot_; }
  static SyntheticShot* shot_;
};
SyntheticShot* CompositeHardCases::shot_ = nullptr;

TEST_F(CompositeHardCases, EmptyInsertionLeavesThePhotoBitIdentical) {
  const inference::SceneModel& truth = shot_->truth;
  const render::PinholeCamera camera = truth.camera();
  const render::LightRig lights = truth.light_rig();
  // 1 km behind the camera, on the floor.
  Eigen::Vector3d back = -(camera.R_world_from_cam * Eigen::Vector3d::UnitZ());
  back.y() = 0;
  const Eigen::Vector3f base = (camera.center_world + 1000.0 * back.normalized()).cast<float>() -
                               Eigen::Vector3f::UnitY() * static_cast<float>(camera.center_world.y());
  render::Mesh prop = prop_at("chair", 0.9f, base);
  const Eigen::AlignedBox3f bounds = prop.bounds();
  const auto scene = depth_world(truth, std::move(prop));

  const SessionResult culled = run_session(*scene, camera, lights, shot_->photo_linear, bounds);
  for (const auto& t : culled.tiles) EXPECT_FALSE(t.affected) << "no tile is within the prop's reach";
  EXPECT_TRUE(identical(culled.composite, shot_->photo_linear));
  // Tracing every tile anyway: no sample touches the prop, so every change is exactly 0.
  const SessionResult traced = run_session(*scene, camera, lights, shot_->photo_linear, bounds, false);
  EXPECT_TRUE(identical(traced.composite, shot_->photo_linear));
  EXPECT_EQ(cv::countNonZero(traced.coverage), 0);
}

// A floor, a 1.2 x 0.5 x 0.2 m box in front, and a 0.45 m cube behind it whose
// top shows above the box. The cube lies entirely on the far side of every
// face of the box the camera sees, so with one bounce no path from those faces
// can reach it: the box's pixels stay bit-identical.
TEST(CompositeHardCasesBuilt, PropBehindNearerGeometryIsHiddenByIt) {
  const render::PinholeCamera camera = camera_toward_minus_z(1.0, 12.0);
  render::Mesh occluder = render::make_prop("cube");  // 0.2 m, base on y = 0
  occluder.transform(Eigen::Translation3f(0.f, 0.f, -2.1f) * Eigen::Scaling(6.f, 2.5f, 1.f));
  const float occluder_top = occluder.bounds().max().y();
  render::Mesh prop = prop_at("cube", 0.45f, {0.f, 0.001f, -3.5f});
  ASSERT_LT(prop.bounds().max().y(), occluder_top);
  ASSERT_LT(prop.bounds().max().z(), occluder.bounds().min().z());
  ASSERT_LT(prop.bounds().max().x(), occluder.bounds().max().x());
  const Eigen::AlignedBox3f bounds = prop.bounds();
  const render::LightRig lights = panel_light({-1.f, 3.f, -1.5f}, 2.f, 8.f);

  render::Scene background;
  background.add_mesh(floor_quad(20.f, 10.f, -40.f), render::Layer::Background);
  const int occluder_index = background.add_mesh(occluder, render::Layer::Background);
  background.commit();
  render::RenderSettings photo_settings;
  photo_settings.samples_per_pixel = kPhotoSpp;
  const cv::Mat photo = render::render_image(background, camera, lights, photo_settings);

  render::Scene world;
  world.add_mesh(floor_quad(20.f, 10.f, -40.f), render::Layer::Background);
  world.add_mesh(occluder, render::Layer::Background);
  world.add_mesh(prop, render::Layer::Prop);
  world.commit();
  render::Scene unoccluded;
  unoccluded.add_mesh(floor_quad(20.f, 10.f, -40.f), render::Layer::Background);
  unoccluded.add_mesh(std::move(prop), render::Layer::Prop);
  unoccluded.commit();

  // Pixels whose centre sees the box (eroded: jittered samples of edge pixels
  // may pass beside it), and pixels where the cube would be seen without it.
  cv::Mat box(kHeight, kWidth, CV_8U, cv::Scalar(0));
  const Eigen::Vector3f origin = camera.center_world.cast<float>();
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      render::RayHit hit;
      if (world.intersect(origin, camera.ray_direction(x, y).cast<float>(), kNoLimit, true, hit) &&
          hit.mesh == occluder_index)
        box.at<uint8_t>(y, x) = 255;
    }
  cv::erode(box, box, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
  const cv::Mat would_see = render::render_primary_buffers(unoccluded, camera, true).prop_coverage;
  ASSERT_GT(cv::countNonZero(box & would_see), 20) << "the box hides part of the cube";

  const SessionResult r = run_session(world, camera, lights, photo, bounds, true, 1);
  cv::Mat covered = r.coverage > 0;
  EXPECT_EQ(cv::countNonZero(covered & box), 0) << "the cube shows through the box";
  EXPECT_GT(cv::countNonZero(r.coverage > 0.5f), 20) << "the cube's top is seen above the box";
  cv::Mat same = cv::Mat::zeros(kHeight, kWidth, CV_8U);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
      same.at<uint8_t>(y, x) = r.composite.at<cv::Vec3f>(y, x) == photo.at<cv::Vec3f>(y, x) ? 255 : 0;
  EXPECT_EQ(cv::countNonZero(box & ~same), 0) << "the box's pixels are unchanged";
  EXPECT_TRUE(cv::checkRange(r.composite));
}

TEST_F(CompositeHardCases, PropSunkHalfwayIntoTheFloor) {
  const inference::SceneModel& truth = shot_->truth;
  const Eigen::Vector2d at = free_floor_pixel(shot_->room);
  const render::Mesh chair = load_prop("chair");
  constexpr double kHeightM = 0.9;
  const CompositeWorld placed = build_composite_world(truth, chair, {at.x(), at.y(), kHeightM, 0.0});
  render::Mesh sunk = chair;
  sunk.transform(Eigen::Translation3f(0.f, -0.5f * static_cast<float>(kHeightM), 0.f) * placed.placed.world_from_prop);
  ASSERT_LT(sunk.bounds().min().y(), -0.4f);
  const Eigen::AlignedBox3f bounds = sunk.bounds();
  const auto scene = depth_world(truth, std::move(sunk));
  SessionResult a, b;
  ASSERT_NO_THROW(a = run_session(*scene, placed.camera, placed.lights, shot_->photo_linear, bounds));
  ASSERT_NO_THROW(b = run_session(*scene, placed.camera, placed.lights, shot_->photo_linear, bounds));
  EXPECT_TRUE(cv::checkRange(a.composite));
  EXPECT_GT(cv::countNonZero(a.coverage > 0.5f), 10) << "the upper half stands out of the floor";
  EXPECT_TRUE(identical(a.composite, b.composite));
}

// A spot on one steep triangle of the depth mesh amid level floor (a spike
// of depth noise) stands on the nearest level pixel; a wall stays refused.
TEST_F(CompositeHardCases, ASpotOnASpikeOfDepthNoiseStandsBesideIt) {
  inference::SceneModel spiky = shot_->truth;
  spiky.depth = shot_->truth.depth.clone();
  const render::PinholeCamera camera = spiky.camera();
  const Eigen::Vector2d at = free_floor_pixel(shot_->room);
  // A vertex of the step-2 depth mesh, pulled 7% toward the camera.
  const int u = 2 * static_cast<int>(std::lround(at.x() / 2)), v = 2 * static_cast<int>(std::lround(at.y() / 2));
  spiky.depth.at<float>(v, u) *= 0.93f;
  render::Scene world;
  world.add_mesh(render::mesh_from_depth(spiky.depth, spiky.albedo, camera), render::Layer::Background);
  world.commit();
  const render::Mesh cube = load_prop("cube");
  const render::PropPlacement asked{static_cast<double>(u), static_cast<double>(v), 0.3, 0.0};
  EXPECT_THROW(render::place_prop(cube, camera, world, asked), render::TiltedSupportError);
  render::PropPlacement used;
  const render::PlacedProp placed = place_near_level_support(cube, camera, world, asked, &used);
  const double moved = std::max(std::abs(used.pixel_u - asked.pixel_u), std::abs(used.pixel_v - asked.pixel_v));
  EXPECT_GT(moved, 0.0);
  EXPECT_LE(moved, kMaxSupportNudgePx);
  EXPECT_GT(placed.support_normal.y(), std::cos(render::kMaxSupportTiltDeg * kDegToRad));
  EXPECT_TRUE(placed.world_from_prop.matrix().allFinite());
  // The same again: the search is deterministic.
  render::PropPlacement again;
  place_near_level_support(cube, camera, world, asked, &again);
  EXPECT_EQ(again.pixel_u, used.pixel_u);
  EXPECT_EQ(again.pixel_v, used.pixel_v);

  // A wall pixel whose whole neighbourhood is wall: still refused.
  const int margin = kMaxSupportNudgePx + 3;
  std::optional<cv::Point> wall;
  for (int y = margin; y < kHeight - margin && !wall; ++y)
    for (int x = margin; x < kWidth - margin && !wall; ++x) {
      bool all_wall = true;
      for (int dy = -margin; dy <= margin && all_wall; ++dy)
        for (int dx = -margin; dx <= margin && all_wall; ++dx)
          all_wall = std::abs(spiky.normals.at<cv::Vec3f>(y + dy, x + dx)[1]) < 0.1f;
      if (all_wall) wall = cv::Point(x, y);
    }
  ASSERT_TRUE(wall.has_value()) << "the room shows a wall";
  const render::PropPlacement on_wall{static_cast<double>(wall->x), static_cast<double>(wall->y), 0.3, 0.0};
  EXPECT_THROW(place_near_level_support(cube, camera, world, on_wall), render::TiltedSupportError);
}

// The camera ends up inside the cube, and under the chair's seat.
TEST_F(CompositeHardCases, PropFiftyMetresTallSwallowsTheRoom) {
  const Eigen::Vector2d at = free_floor_pixel(shot_->room);
  render::RenderSettings s;
  s.samples_per_pixel = kSpp;
  s.seed = kSeed;
  for (const char* name : {"cube", "chair"}) {
    const render::Mesh prop = load_prop(name);
    const render::PropPlacement placement{at.x(), at.y(), 50.0, 0.0};
    CompositeResult a, b;
    ASSERT_NO_THROW(a = composite_prop(shot_->photo_linear, shot_->truth, prop, placement, s)) << name;
    ASSERT_NO_THROW(b = composite_prop(shot_->photo_linear, shot_->truth, prop, placement, s)) << name;
    EXPECT_TRUE(cv::checkRange(a.composite_linear)) << name;
    EXPECT_TRUE(cv::checkRange(a.depth)) << name;
    // Its faces lie beyond the room's walls or above the camera (a 50 m chair
    // stands over it): seen through gaps of the depth mesh at most.
    EXPECT_TRUE(cv::checkRange(a.render.coverage, true, nullptr, 0.0, 1.0 + 1e-6)) << name;
    EXPECT_TRUE(identical(a.composite_linear, b.composite_linear)) << name;
  }
}

// An endless floor (20 km): half a pixel below the horizon the support point is
// hundreds of metres away; half a pixel above it there is none.
TEST(CompositeHardCasesBuilt, PropAtTheHorizon) {
  constexpr double kCameraHeightM = 1.5;
  const render::PinholeCamera camera = camera_toward_minus_z(kCameraHeightM, 5.0);
  render::Scene background;
  background.add_mesh(floor_quad(1e4f, 10.f, -1e4f), render::Layer::Background);
  background.commit();
  Eigen::Vector2d horizon;
  ASSERT_TRUE(camera.project({0.0, kCameraHeightM, -1e9}, horizon));
  const render::Mesh cube = render::make_prop("cube");
  EXPECT_THROW(render::place_prop(cube, camera, background, {horizon.x(), horizon.y() - 0.5, 0.5, 0}),
               std::invalid_argument);
  render::PlacedProp placed;
  ASSERT_NO_THROW(placed = render::place_prop(cube, camera, background, {horizon.x(), horizon.y() + 0.5, 0.5, 0}));
  EXPECT_GT((placed.base_world - camera.center_world.cast<float>()).norm(), 100.f);

  render::Mesh prop = cube;
  prop.transform(placed.world_from_prop);
  const Eigen::AlignedBox3f bounds = prop.bounds();
  render::Scene world;
  world.add_mesh(floor_quad(1e4f, 10.f, -1e4f), render::Layer::Background);
  world.add_mesh(std::move(prop), render::Layer::Prop);
  world.commit();
  const render::LightRig lights = panel_light({-1.f, 3.f, -2.f}, 2.f, 8.f);
  const cv::Mat photo(kHeight, kWidth, CV_32FC3, cv::Scalar::all(0.2));
  SessionResult a, b;
  ASSERT_NO_THROW(a = run_session(world, camera, lights, photo, bounds));
  ASSERT_NO_THROW(b = run_session(world, camera, lights, photo, bounds));
  EXPECT_TRUE(cv::checkRange(a.composite));
  EXPECT_TRUE(cv::checkRange(a.coverage, true, nullptr, 0.0, 1.0 + 1e-6));
  EXPECT_TRUE(identical(a.composite, b.composite));
  EXPECT_TRUE(std::any_of(a.tiles.begin(), a.tiles.end(), [](const auto& t) { return t.affected; }))
      << "the tile around the prop is traced";
}

// No pixel can place a prop behind the camera; put it there by hand.
TEST_F(CompositeHardCases, PropBehindTheCamera) {
  const inference::SceneModel& truth = shot_->truth;
  const render::PinholeCamera camera = truth.camera();
  const render::LightRig lights = truth.light_rig();
  Eigen::Vector3d back = -(camera.R_world_from_cam * Eigen::Vector3d::UnitZ());
  back.y() = 0;
  const Eigen::Vector3d base = camera.center_world + back.normalized() - Eigen::Vector3d::UnitY() * camera.center_world.y();
  Eigen::Vector2d pixel;
  ASSERT_FALSE(camera.project(base, pixel)) << "behind the camera";
  render::Mesh prop = prop_at("chair", 0.9f, base.cast<float>());
  const Eigen::AlignedBox3f bounds = prop.bounds();
  const auto scene = depth_world(truth, std::move(prop));
  for (const bool cull : {true, false}) {
    SessionResult a, b;
    ASSERT_NO_THROW(a = run_session(*scene, camera, lights, shot_->photo_linear, bounds, cull));
    ASSERT_NO_THROW(b = run_session(*scene, camera, lights, shot_->photo_linear, bounds, cull));
    EXPECT_TRUE(cv::checkRange(a.composite)) << "cull " << cull;
    EXPECT_EQ(cv::countNonZero(a.coverage), 0) << "the camera cannot see behind itself";
    EXPECT_TRUE(identical(a.composite, b.composite)) << "cull " << cull;
  }
}

}  // namespace
}  // namespace propcam::firmware
