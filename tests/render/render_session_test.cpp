#include <gtest/gtest.h>

#include <atomic>

#include "propcam/render/props.h"
#include "propcam/render/render_session.h"
#include "propcam/render/synthetic_room.h"

namespace propcam::render {
namespace {

// A synthetic room with a small cube on its free floor spot, and a "photo"
// (any image works: differential rendering only adds the prop's change).
class RenderSessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SyntheticRoomSpec spec;
    spec.width = 96;
    spec.height = 72;
    spec.seed = 4;
    room_ = make_synthetic_room(spec);
    scene_.add_mesh(room_.room, Layer::Background);
    Mesh cube = make_prop("cube");
    const float s = 0.3f / cube.bounds().sizes().y();
    Eigen::Affine3f xf = Eigen::Translation3f(room_.free_floor_point) * Eigen::Scaling(s) *
                         Eigen::Translation3f(-cube.bounds().center().x(), -cube.bounds().min().y(),
                                              -cube.bounds().center().z());
    cube.transform(xf);
    prop_bounds_ = cube.bounds();
    scene_.add_mesh(std::move(cube), Layer::Prop);
    scene_.commit();
    photo_ = cv::Mat(spec.height, spec.width, CV_32FC3, cv::Scalar(0.3, 0.3, 0.3));
    settings_.render.tile_size = 16;
    settings_.render.max_bounces = 2;
    settings_.max_samples_per_pixel = 8;
  }

  SyntheticRoom room_;
  Scene scene_;
  Eigen::AlignedBox3f prop_bounds_;
  cv::Mat photo_;
  SessionSettings settings_;
};

bool identical(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

// Doubling to 16 samples, then half as many again each pass, the last pass
// cut to the limit.
TEST_F(RenderSessionTest, PassesOfGrowingSamplesEqualOneRenderOfTheSameSamples) {
  settings_.cull_tiles = false;
  settings_.max_samples_per_pixel = 40;
  RenderSession session(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_);
  std::vector<int> samples;
  while (!session.finished()) samples.push_back(session.run_pass().max_samples);
  EXPECT_EQ(samples, (std::vector<int>{1, 2, 4, 8, 16, 24, 36, 40}));
  RenderSettings one = settings_.render;
  one.samples_per_pixel = 40;
  const DifferentialRender direct = render_differential(scene_, room_.camera, room_.lights, one);
  EXPECT_TRUE(identical(session.differential().change, direct.change));
  EXPECT_TRUE(identical(session.differential().coverage, direct.coverage));
}

TEST_F(RenderSessionTest, CancelAndResumeGiveTheSameImage) {
  RenderSession reference(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_);
  while (!reference.finished()) reference.run_pass();

  RenderSession session(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_);
  session.run_pass();
  std::atomic<bool> cancel{true};
  const PassReport cancelled = session.run_pass(&cancel);
  EXPECT_TRUE(cancelled.cancelled);
  EXPECT_EQ(cancelled.tiles_traced, 0);
  while (!session.finished()) EXPECT_FALSE(session.run_pass().cancelled);
  EXPECT_TRUE(identical(session.composite(), reference.composite()));
}

TEST_F(RenderSessionTest, CulledTilesKeepThePhotoAndTheRestMatchesSimulatingEverything) {
  RenderSession culled(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_);
  while (!culled.finished()) culled.run_pass();
  settings_.cull_tiles = false;
  RenderSession full(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_);
  while (!full.finished()) full.run_pass();
  int n_culled = 0;
  const cv::Mat a = culled.composite(), b = full.composite();
  for (const auto& t : culled.tiles()) {
    if (t.affected) {
      EXPECT_TRUE(identical(a(t.rect), b(t.rect))) << "traced tiles are rendered exactly as without culling";
    } else {
      ++n_culled;
      EXPECT_TRUE(identical(a(t.rect), photo_(t.rect)));
      EXPECT_EQ(t.samples, 0);
    }
  }
  EXPECT_GT(n_culled, 0) << "a 30 cm cube cannot reach every corner of a room";
  // Every pixel that sees the prop lies in a traced tile.
  const cv::Mat seen = full.differential().coverage > 0;
  EXPECT_EQ(cv::countNonZero(seen & (culled.reach().affected == 0)), 0);
}

TEST_F(RenderSessionTest, TheErrorEstimateFallsAsSamplesGrow) {
  settings_.max_samples_per_pixel = 32;
  RenderSession session(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_);
  session.run_pass();
  const double early = session.run_pass().max_relative_error;  // 2 spp (1 spp has no variance)
  while (!session.finished()) session.run_pass();
  double late = 0;
  for (const auto& t : session.tiles())
    if (t.affected) late = std::max(late, t.relative_error);
  EXPECT_LT(late, early);
  EXPECT_TRUE(std::isfinite(late));
}

TEST_F(RenderSessionTest, ATargetErrorStopsTilesEarly) {
  settings_.max_samples_per_pixel = 64;
  settings_.target_relative_error = 0.05;
  RenderSession session(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_);
  while (!session.finished()) session.run_pass();
  int early = 0;
  for (const auto& t : session.tiles())
    if (t.affected && t.samples < 64) {
      ++early;
      EXPECT_LE(t.relative_error, 0.05);
      EXPECT_GE(t.samples, settings_.min_samples_to_converge);
    }
  EXPECT_GT(early, 0) << "tiles far from the prop converge before the limit";
}

TEST_F(RenderSessionTest, APropOutOfSightAndReachLeavesThePhotoUntouched) {
  const Eigen::AlignedBox3f far_away(Eigen::Vector3f(500, 500, 500), Eigen::Vector3f(500.3f, 500.3f, 500.3f));
  RenderSession session(scene_, room_.camera, room_.lights, photo_, far_away, settings_);
  EXPECT_TRUE(session.finished()) << "nothing to trace";
  const PassReport r = session.run_pass();
  EXPECT_EQ(r.tiles_traced, 0);
  EXPECT_TRUE(identical(session.composite(), photo_));
}

TEST_F(RenderSessionTest, BadInputsAreClearErrors) {
  EXPECT_THROW(RenderSession(scene_, room_.camera, room_.lights, cv::Mat(3, 3, CV_32FC3), prop_bounds_, settings_),
               std::invalid_argument);
  settings_.max_samples_per_pixel = 0;
  EXPECT_THROW(RenderSession(scene_, room_.camera, room_.lights, photo_, prop_bounds_, settings_), std::invalid_argument);
}

TEST(RenderSessionHardCases, OnePixelImage) {
  Scene scene;
  Mesh cube = make_prop("cube");
  const Eigen::AlignedBox3f bounds = cube.bounds();
  scene.add_mesh(std::move(cube), Layer::Prop);
  scene.commit();
  PinholeCamera cam;
  cam.width = cam.height = 1;
  cam.fx = cam.fy = 1;
  cam.center_world = {0, 0.2, 3};
  cam.R_world_from_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  LightRig lights;
  lights.environment = std::make_shared<EnvironmentLight>(cv::Mat(8, 16, CV_32FC3, cv::Scalar::all(1.0)));
  SessionSettings s;
  s.max_samples_per_pixel = 4;
  const cv::Mat photo(1, 1, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  RenderSession session(scene, cam, lights, photo, bounds, s);
  while (!session.finished()) session.run_pass();
  EXPECT_TRUE(cv::checkRange(session.composite()));
  EXPECT_EQ(session.tiles().size(), 1u);
}

}  // namespace
}  // namespace propcam::render
