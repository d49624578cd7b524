#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "common/compositor.h"
#include "shadow_check.h"
#include "propcam/inference/infer.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

double rmse(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  cv::Mat d = a - b;
  d = d.mul(d);
  const cv::Scalar m = cv::mean(d, mask);
  return std::sqrt((m[0] + m[1] + m[2]) / 3.0);
}

// One synthetic room for all tests: a photo with exact ground truth.
class CompositeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    render::SyntheticRoomSpec spec;
    spec.width = 320;
    spec.height = 240;
    spec.seed = 4;
    render::RenderSettings settings;
    settings.samples_per_pixel = 32;
    shot_ = new SyntheticShot(shoot_synthetic_room(spec, settings));
  }
  static void TearDownTestSuite() { delete shot_; }

  static render::PropPlacement at_free_floor(double height) {
    const Eigen::Vector2d px = free_floor_pixel(shot_->room);
    return {px.x(), px.y(), height, 20.0};
  }
  static CompositeResult composite(const inference::SceneModel& scene, const std::string& prop, double height,
                                   int spp = 16) {
    render::RenderSettings s;
    s.samples_per_pixel = spp;
    return composite_prop(shot_->photo_linear, scene, load_prop(prop), at_free_floor(height), s);
  }
  // A white diffuse cube composited into `photo` as inferred: the mean of
  // its fully covered pixels.
  static cv::Scalar white_cube_on(const cv::Mat& photo) {
    const inference::SceneModel scene = inference::infer_scene(photo);
    MaterialOverride white;
    white.type = "diffuse";
    white.albedo = Eigen::Vector3f(0.8f, 0.8f, 0.8f);
    render::RenderSettings s;
    s.samples_per_pixel = 16;
    const CompositeResult r = composite_prop(photo, scene, load_prop("cube", white), at_free_floor(0.4), s);
    const cv::Mat on_prop = r.render.coverage > 0.99f;
    EXPECT_GT(cv::countNonZero(on_prop), 50);
    return cv::mean(r.composite_linear, on_prop);
  }
  static SyntheticShot* shot_;
};
SyntheticShot* CompositeTest::shot_ = nullptr;

TEST_F(CompositeTest, PixelsFarFromThePropAreUnchanged) {
  const CompositeResult r = composite(shot_->truth, "cube", 0.4);
  // The top quarter of the frame (walls, ceiling) is far from a floor prop.
  const cv::Rect top(0, 0, shot_->photo_linear.cols, shot_->photo_linear.rows / 4);
  cv::Mat diff;
  cv::absdiff(r.composite_linear(top), shot_->photo_linear(top), diff);
  cv::Mat grey;
  cv::transform(diff, grey, cv::Matx13f(1.f, 1.f, 1.f));
  EXPECT_LT(cv::mean(grey)[0], 3e-3);
  const double unchanged = static_cast<double>(cv::countNonZero(grey == 0)) / grey.total();
  EXPECT_GT(unchanged, 0.9) << "shared samples should leave untouched pixels bit-identical";
  EXPECT_GT(cv::countNonZero(r.render.coverage > 0.5), 50) << "the prop is in view";
}

TEST_F(CompositeTest, ThePropsShadowDarkensTheFloorBesideIt) {
  const CompositeResult r = composite(shot_->truth, "cube", 0.4, 32);
  ASSERT_GT(cv::countNonZero(r.render.coverage > 0), 0);
  EXPECT_LT(testing::shadow_ratio(shot_->photo_linear, r.composite_linear, r.render.coverage), 0.95);
}

TEST_F(CompositeTest, CompositeFromInferredSceneApproachesTheFullInsertion) {
  const inference::SceneModel inferred = inference::infer_scene(shot_->photo_linear);
  render::RenderSettings s;
  s.samples_per_pixel = 32;
  // A diffuse prop: its look depends on the inferred light, not on a mirror
  // image of the unseen room.
  const render::Mesh prop = load_prop("chair");
  const render::PropPlacement placement = at_free_floor(0.9);
  const cv::Mat insertion = render_full_insertion(shot_->room, prop, placement, s);
  const CompositeResult r = composite_prop(shot_->photo_linear, inferred, prop, placement, s);
  // Where the prop and its effects are: its silhouette in the true insertion, grown.
  cv::Mat diff;
  cv::absdiff(insertion, shot_->photo_linear, diff);
  cv::Mat region;
  cv::transform(diff, region, cv::Matx13f(1.f, 1.f, 1.f));
  region = region > 0.02;
  cv::dilate(region, region, cv::getStructuringElement(cv::MORPH_ELLIPSE, {15, 15}));
  ASSERT_GT(cv::countNonZero(region), 100);
  const double composite_error = rmse(r.composite_linear, insertion, region);
  const double photo_error = rmse(shot_->photo_linear, insertion, region);
  EXPECT_LT(composite_error, 0.7 * photo_error) << "composite " << composite_error << " photo " << photo_error;
}

// The stated tolerances of the first-cut camera and geometry stages on a
// synthetic Manhattan room (measured: 0.5% focal, 0.1 deg, 7% depth).
TEST_F(CompositeTest, InferredCameraAndDepthMatchGroundTruth) {
  const inference::SceneModel est = inference::infer_scene(shot_->photo_linear);
  const inference::SceneModel& truth = shot_->truth;
  EXPECT_NEAR(est.fx / truth.fx, 1.0, 0.03);
  const Eigen::Vector3d up_est = est.R_world_from_cam.transpose() * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d up_true = truth.R_world_from_cam.transpose() * Eigen::Vector3d::UnitY();
  EXPECT_LT(std::acos(std::clamp(up_est.dot(up_true), -1.0, 1.0)) * 180.0 / M_PI, 1.0);
  cv::Mat rel;
  cv::absdiff(est.depth, truth.depth, rel);
  rel /= truth.depth;
  EXPECT_LT(cv::mean(rel)[0], 0.2);
}

// The photo made grey: whatever the inference finds in it, a white prop
// must come out white (no tint from fitted lights or albedo).
TEST_F(CompositeTest, ANeutralPropInANeutralPhotoStaysNeutral) {
  cv::Mat grey_photo;
  cv::transform(shot_->photo_linear, grey_photo, cv::Matx33f(0.2126f, 0.7152f, 0.0722f, 0.2126f, 0.7152f, 0.0722f,
                                                              0.2126f, 0.7152f, 0.0722f));
  const cv::Scalar mean = white_cube_on(grey_photo);
  const double grey = (mean[0] + mean[1] + mean[2]) / 3.0;
  ASSERT_GT(grey, 0.0);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c] / grey, 1.0, 0.02) << "channel " << c;
}

// The same photo with a warm cast (a tungsten room, as a camera kept it):
// the white prop may take the cast or stay white, never the opposite tint.
TEST_F(CompositeTest, AWhitePropInAWarmPhotoIsNeverBluerThanWhite) {
  cv::Mat warm;
  cv::transform(shot_->photo_linear, warm, cv::Matx33f(0.2126f, 0.7152f, 0.0722f, 0.2126f * 0.8f, 0.7152f * 0.8f,
                                                        0.0722f * 0.8f, 0.2126f * 0.55f, 0.7152f * 0.55f, 0.0722f * 0.55f));
  const cv::Scalar mean = white_cube_on(warm);
  EXPECT_GE(mean[0], 0.99 * mean[1]) << "red below green: bluer than white";
  EXPECT_GE(mean[1], 0.99 * mean[2]) << "green below blue: bluer than white";
}

// A photo blurred by a known sigma: its blur is read, and the prop's
// silhouette comes out as soft as the photo's edges (the camera match),
// within 20%.
TEST_F(CompositeTest, APropInABlurredPhotoIsAsSoftAsThePhoto) {
  constexpr double kSigma = 1.5;
  cv::Mat blurred;
  cv::GaussianBlur(shot_->photo_linear, blurred, {11, 11}, kSigma, kSigma, cv::BORDER_REFLECT);
  // The true room, with the imaging the inference estimates from the photo.
  inference::SceneModel scene = shot_->truth;
  scene.imaging = render::estimate_photo_imaging(blurred);
  ASSERT_TRUE(scene.imaging.blur_measured);
  // The room's own edges are not all steps (penumbrae, shading): the
  // estimate is the blur added to what the unblurred photo reads.
  const double own = render::estimate_photo_imaging(shot_->photo_linear).blur_sigma_px;
  const double expected = std::hypot(kSigma, own);
  EXPECT_NEAR(scene.imaging.blur_sigma_px, expected, 0.2 * expected) << "unblurred photo " << own;
  render::RenderSettings s;
  s.samples_per_pixel = 32;
  const render::Mesh prop = load_prop("cube");
  const CompositeResult matched = composite_prop(blurred, scene, prop, at_free_floor(0.5), s);
  CompositeOptions raw_options;
  raw_options.match_camera = false;
  const CompositeResult raw = composite_prop(blurred, scene, prop, at_free_floor(0.5), s, raw_options);
  ASSERT_EQ(matched.camera_match.steps.size(), 3u);
  EXPECT_TRUE(matched.camera_match.steps[0].applied) << matched.camera_match.steps[0].why;
  // The prop's silhouette: a band around where its coverage crosses a half.
  const cv::Mat inside = raw.render.coverage > 0.5f;
  cv::Mat grown, shrunk;
  cv::dilate(inside, grown, cv::Mat(), {-1, -1}, 2);
  cv::erode(inside, shrunk, cv::Mat(), {-1, -1}, 2);
  const cv::Mat band = grown & ~shrunk;
  int edges_raw = 0, edges_matched = 0;
  const double sigma_raw = render::estimate_edge_blur(raw.composite_linear, band, &edges_raw);
  const double sigma_matched = render::estimate_edge_blur(matched.composite_linear, band, &edges_matched);
  ASSERT_GT(edges_matched, 0);
  EXPECT_LT(sigma_raw, kSigma * 0.6) << "rendered edges are sharp (" << edges_raw << " edge pixels)";
  EXPECT_NEAR(sigma_matched, scene.imaging.blur_sigma_px, 0.2 * scene.imaging.blur_sigma_px)
      << edges_matched << " edge pixels";
}

TEST_F(CompositeTest, SameSeedSameComposite) {
  const CompositeResult a = composite(shot_->truth, "mug", 0.3, 2);
  const CompositeResult b = composite(shot_->truth, "mug", 0.3, 2);
  EXPECT_EQ(cv::norm(a.composite_linear, b.composite_linear, cv::NORM_INF), 0.0);
}

TEST_F(CompositeTest, ATimeBudgetStopsTheRenderBetweenPassesAndSaysSo) {
  render::RenderSettings s;
  s.samples_per_pixel = 64;
  CompositeOptions within_budget;
  within_budget.time_budget_seconds = 1e-9;  // spent by the first pass, which always runs
  const CompositeResult stopped =
      composite_prop(shot_->photo_linear, shot_->truth, load_prop("cube"), at_free_floor(0.3), s, within_budget);
  EXPECT_TRUE(stopped.stopped_by_time_budget);
  ASSERT_EQ(stopped.passes.size(), 1u);
  EXPECT_EQ(stopped.samples_per_pixel, 1);
  EXPECT_TRUE(cv::checkRange(stopped.composite_linear));

  s.samples_per_pixel = 4;
  const CompositeResult unbounded = composite_prop(shot_->photo_linear, shot_->truth, load_prop("cube"),
                                                   at_free_floor(0.3), s);
  EXPECT_FALSE(unbounded.stopped_by_time_budget);
  EXPECT_EQ(unbounded.samples_per_pixel, 4);
}

TEST_F(CompositeTest, PlacementOutsideThePhotoOrOnAWallIsAClearError) {
  render::RenderSettings s;
  s.samples_per_pixel = 1;
  const render::Mesh prop = load_prop("cube");
  EXPECT_THROW(composite_prop(shot_->photo_linear, shot_->truth, prop, {-50, 10, 0.2, 0}, s), std::invalid_argument);
  // The top rows of the frame see a wall.
  try {
    composite_prop(shot_->photo_linear, shot_->truth, prop, {160, 5, 0.2, 0}, s);
    FAIL() << "placing on a wall must fail";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tilted"), std::string::npos) << e.what();
  }
}

TEST_F(CompositeTest, PropAtTheHorizonStaysFinite) {
  // A level camera's horizon row: the support point is very far away.
  inference::SceneModel scene = inference::infer_scene(shot_->photo_linear);
  const double horizon_row = scene.cy - scene.fy * scene.R_world_from_cam(1, 2) / scene.R_world_from_cam(1, 1);
  render::RenderSettings s;
  s.samples_per_pixel = 1;
  const double row = std::clamp(horizon_row + 1.0, 0.0, scene.height - 1.0);
  try {
    const CompositeResult r = composite_prop(shot_->photo_linear, scene, load_prop("cube"), {160, row, 0.2, 0}, s);
    EXPECT_TRUE(cv::checkRange(r.composite_linear));
  } catch (const std::invalid_argument&) {
    SUCCEED() << "a clear refusal is also acceptable";
  }
}

}  // namespace
}  // namespace propcam::firmware
