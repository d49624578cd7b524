// The work behind the appliance's screens, on a synthetic room with exact
// ground truth: spots on the floor, the prop's footprint, a progressive
// render to convergence, throughput predictions and relighting.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "appliance/appliance_shot.h"
#include "propcam/capture/image_file.h"
#include "propcam/render/props.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {
namespace fs = std::filesystem;

SyntheticShot synthetic_room(int width, int height, std::uint64_t seed, int samples_per_pixel) {
  render::SyntheticRoomSpec spec;
  spec.width = width;
  spec.height = height;
  spec.seed = seed;
  render::RenderSettings settings;
  settings.samples_per_pixel = samples_per_pixel;
  return shoot_synthetic_room(spec, settings);
}

class ApplianceShotTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const SyntheticShot shot = synthetic_room(160, 120, 4, 16);
    auto a = std::make_shared<Analysis>();
    a->photo_linear = shot.photo_linear;
    a->scene = shot.truth;
    a->scene_photo = capture::srgb_linear_to_response_linear(shot.photo_linear, a->scene.gamma);
    a->photo_rgb8 = capture::linear_to_srgb8(shot.photo_linear);
    analysis_ = new std::shared_ptr<const Analysis>(a);
  }
  static void TearDownTestSuite() { delete analysis_; }
  static const Analysis& analysis() { return **analysis_; }

  static PropEntry preset(const std::string& name) {
    PropEntry e;
    e.name = e.source = name;
    for (const auto& p : render::prop_presets())
      if (p.name == name) e.natural_height_m = p.natural_height_m;
    return e;
  }
  static std::shared_ptr<const Analysis>* analysis_;
};
std::shared_ptr<const Analysis>* ApplianceShotTest::analysis_ = nullptr;

TEST_F(ApplianceShotTest, SpotsLieOnUpwardSurfacesInTheImage) {
  const auto spots = find_spots(analysis().scene, 12);
  ASSERT_GE(spots.size(), 3u) << "the room's floor is in view";
  EXPECT_LE(spots.size(), 12u);
  for (const Spot& s : spots) {
    ASSERT_GE(s.pixel.x, 0);
    ASSERT_LT(s.pixel.x, analysis().scene.width);
    ASSERT_GE(s.pixel.y, 0);
    ASSERT_LT(s.pixel.y, analysis().scene.height);
    const cv::Vec3f n = analysis().scene.normals.at<cv::Vec3f>(static_cast<int>(s.pixel.y), static_cast<int>(s.pixel.x));
    EXPECT_GT(n[1], 0.85f) << "spot at " << s.pixel;
    EXPECT_GT(s.distance_m, 0.3);
    EXPECT_LT(s.distance_m, 20.0);
  }
  EXPECT_EQ(find_spots(analysis().scene, 12).size(), spots.size());
}

TEST_F(ApplianceShotTest, NoSurfaceGivesNoSpots) {
  inference::SceneModel walls = analysis().scene;
  walls.normals = cv::Mat(walls.height, walls.width, CV_32FC3, cv::Scalar(0, 0, 1));  // everything faces the camera
  EXPECT_TRUE(find_spots(walls, 12).empty());
  inference::SceneModel empty;
  EXPECT_TRUE(find_spots(empty, 12).empty());
}

TEST_F(ApplianceShotTest, FootprintSurroundsTheSpot) {
  const auto spots = find_spots(analysis().scene, 12);
  ASSERT_FALSE(spots.empty());
  const render::Mesh chair = load_prop("chair");
  const auto outline = footprint_outline(analysis().scene, spots.front(), chair, 0.9);
  ASSERT_EQ(outline.size(), 4u);
  std::vector<cv::Point2f> poly;
  for (const auto& p : outline) poly.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  EXPECT_GE(cv::pointPolygonTest(poly, cv::Point2f(spots.front().pixel), false), 0) << "the base is inside its footprint";
  // A bigger prop has a bigger footprint.
  const auto big = footprint_outline(analysis().scene, spots.front(), chair, 1.8);
  std::vector<cv::Point2f> big_poly;
  for (const auto& p : big) big_poly.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  EXPECT_GT(cv::contourArea(big_poly), 2.5 * cv::contourArea(poly));
}

TEST_F(ApplianceShotTest, ThePreviewShowsThePropWhereItWouldStand) {
  const auto spots = find_spots(analysis().scene, 12);
  ASSERT_GE(spots.size(), 2u);
  PlacementPreview preview(*analysis_, preset("cube"), spots[0]);
  for (const Spot& spot : {spots[0], spots[1]}) {
    const cv::Mat image = preview.render(spot);
    ASSERT_EQ(image.size(), analysis().photo_rgb8.size());
    ASSERT_EQ(image.type(), CV_8UC3);
    // Everything it drew lies around the spot, above the base (it stands on the floor).
    cv::Mat any = cv::Mat::zeros(image.size(), CV_8U);
    for (int y = 0; y < image.rows; ++y)
      for (int x = 0; x < image.cols; ++x)
        if (image.at<cv::Vec3b>(y, x) != analysis().photo_rgb8.at<cv::Vec3b>(y, x)) any.at<std::uint8_t>(y, x) = 255;
    ASSERT_GT(cv::countNonZero(any), 10) << "the cube is drawn";
    const cv::Rect box = cv::boundingRect(any);
    EXPECT_TRUE(box.contains(cv::Point(static_cast<int>(spot.pixel.x), box.y + box.height / 2)))
        << "drawn at " << box << " for a spot at " << spot.pixel;
    // Nothing below its footprint (the front edge of the base is the lowest thing seen).
    double lowest = spot.pixel.y;
    for (const auto& p : footprint_outline(analysis().scene, spot, load_prop("cube"), preset("cube").natural_height_m))
      lowest = std::max(lowest, p.y);
    EXPECT_LE(box.y + box.height, lowest + 2) << "nothing below the base";
  }
}

TEST_F(ApplianceShotTest, TiersCostMoreForLessError) {
  const TierSpec draft = tier_spec(appliance::Tier::Draft), good = tier_spec(appliance::Tier::Good),
                 final = tier_spec(appliance::Tier::Final);
  EXPECT_LT(draft.max_samples_per_pixel, good.max_samples_per_pixel);
  EXPECT_LT(good.max_samples_per_pixel, final.max_samples_per_pixel);
  EXPECT_GT(draft.target_relative_error, good.target_relative_error);
  EXPECT_GT(good.target_relative_error, final.target_relative_error);
}

TEST_F(ApplianceShotTest, ThroughputIsMeasuredAndKept) {
  const fs::path dir = fs::temp_directory_path() / ("propcam_throughput_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const fs::path file = dir / "throughput.json";
  {
    ThroughputModel model(file);
    EXPECT_FALSE(model.measured());
    EXPECT_DOUBLE_EQ(model.pixel_samples_per_second(), ThroughputModel::kDefaultPixelSamplesPerSecond);
    model.record(1e6, 2.0);
    EXPECT_TRUE(model.measured());
    EXPECT_DOUBLE_EQ(model.pixel_samples_per_second(), 5e5);
    EXPECT_DOUBLE_EQ(model.predict_seconds(1000, 100), 0.2);
    model.record(1e6, 0.01);  // too short to count
    EXPECT_DOUBLE_EQ(model.pixel_samples_per_second(), 5e5);
  }
  ThroughputModel reloaded(file);
  EXPECT_TRUE(reloaded.measured());
  EXPECT_DOUBLE_EQ(reloaded.pixel_samples_per_second(), 5e5);
  fs::remove_all(dir);
}

TEST_F(ApplianceShotTest, RenderConvergesAndRelightsWithoutRerendering) {
  const auto spots = find_spots(analysis().scene, 12);
  ASSERT_FALSE(spots.empty());
  CompositeRender render(*analysis_, preset("cube"), spots.front(), tier_spec(appliance::Tier::Draft), 2);
  std::atomic<bool> cancel{false};
  int passes = 0;
  double last_fraction = -1;
  while (!render.finished() && passes < 20) {
    render.run_pass(&cancel);
    ++passes;
    const auto s = render.snapshot(false);
    EXPECT_GE(s->converged_fraction, last_fraction) << "convergence never goes back";
    last_fraction = s->converged_fraction;
  }
  ASSERT_TRUE(render.finished());
  const auto done = render.snapshot(true);
  EXPECT_DOUBLE_EQ(done->converged_fraction, 1.0);
  EXPECT_TRUE(done->finished);
  EXPECT_GT(done->skipped_tiles, 0) << "a small cube cannot reach every tile";
  EXPECT_FALSE(done->layers.change.empty());
  EXPECT_EQ(done->depth.size(), analysis().photo_linear.size());
  EXPECT_GT(render.pixel_samples(), 0);
  // The composite differs from the photo where the cube stands.
  const cv::Point base(static_cast<int>(spots.front().pixel.x), static_cast<int>(spots.front().pixel.y));
  const cv::Rect near_base = cv::Rect(base.x - 4, base.y - 10, 8, 10) & cv::Rect(0, 0, 160, 120);
  cv::Mat diff;
  cv::absdiff(done->composite(near_base), analysis().scene_photo(near_base), diff);
  EXPECT_GT(cv::mean(diff)[0] + cv::mean(diff)[1] + cv::mean(diff)[2], 0.01);

  // No adjustment: the composite as rendered, back in the photo's sRGB-linear space.
  const cv::Mat plain = adjusted_composite(analysis(), *done, Adjustment{});
  const cv::Mat expected = capture::response_linear_to_srgb_linear(done->composite, analysis().scene.gamma);
  cv::absdiff(plain, expected, diff);
  double max_diff = 0;
  cv::minMaxLoc(diff.reshape(1), nullptr, &max_diff);
  EXPECT_LT(max_diff, 1e-3);
  // The board's calibrated vignetting scales what the cube adds (its own
  // pixels, its shadow) by the lens's gain there, and nothing else.
  Analysis vignetted = analysis();
  vignetted.vignetting = render::Vignetting{-0.8, 0.0};
  const cv::Mat dimmed = capture::srgb_linear_to_response_linear(adjusted_composite(vignetted, *done, Adjustment{}),
                                                                 analysis().scene.gamma);
  const cv::Mat as_rendered = capture::srgb_linear_to_response_linear(plain, analysis().scene.gamma);
  const cv::Mat& photo = analysis().scene_photo;
  double worst = 0;
  int changed = 0;
  for (int r = 0; r < dimmed.rows; ++r)
    for (int c = 0; c < dimmed.cols; ++c) {
      const float uncovered = 1.0f - done->layers.coverage.at<float>(r, c);
      const float gain = static_cast<float>(vignetted.vignetting.at_pixel(c, r, dimmed.size()));
      const cv::Vec3f photo_share = uncovered * photo.at<cv::Vec3f>(r, c);
      const cv::Vec3f expected = photo_share + gain * (as_rendered.at<cv::Vec3f>(r, c) - photo_share);
      worst = std::max(worst, cv::norm(dimmed.at<cv::Vec3f>(r, c) - expected, cv::NORM_INF));
      changed += cv::norm(dimmed.at<cv::Vec3f>(r, c) - as_rendered.at<cv::Vec3f>(r, c), cv::NORM_INF) > 1e-3;
    }
  EXPECT_LT(worst, 1e-4);
  EXPECT_GT(changed, 10);
  // One stop more scene light doubles the response-linear photo far from the cube.
  Adjustment brighter;
  brighter.scene_ev = 1.0;
  const cv::Mat lit = capture::srgb_linear_to_response_linear(adjusted_composite(analysis(), *done, brighter),
                                                              analysis().scene.gamma);
  const cv::Rect corner(0, 0, 16, 12);
  const double ratio = cv::mean(lit(corner))[1] / cv::mean(analysis().scene_photo(corner))[1];
  EXPECT_NEAR(ratio, 2.0, 0.05);
  // Depth of field blurs: the far corner loses detail with a wide aperture focused on the cube.
  Adjustment blurred;
  blurred.aperture_m = 0.04;
  blurred.focus_m = done->prop_distance_m;
  const cv::Mat soft = adjusted_composite(analysis(), *done, blurred);
  for (const cv::Mat& m : {soft, plain}) ASSERT_TRUE(cv::checkRange(m));
  EXPECT_FALSE(cv::norm(soft, plain, cv::NORM_INF) == 0.0);
}

TEST_F(ApplianceShotTest, ARenderOutOfTimeEndsAfterItsFirstPass) {
  const auto spots = find_spots(analysis().scene, 12);
  ASSERT_FALSE(spots.empty());
  CompositeRender render(*analysis_, preset("cube"), spots.front(), tier_spec(appliance::Tier::Final), 2, 1e-9);
  EXPECT_FALSE(render.finished()) << "the first pass always runs";
  std::atomic<bool> cancel{false};
  EXPECT_TRUE(render.run_pass(&cancel));
  EXPECT_TRUE(render.finished());
  EXPECT_FALSE(render.run_pass(&cancel));
  const auto done = render.snapshot(true);
  EXPECT_TRUE(done->finished);
  EXPECT_TRUE(done->stopped_by_time_budget);
  EXPECT_EQ(done->samples_per_pixel, 1);
  EXPECT_LT(done->converged_fraction, 1.0);
}

// The still at twice the working size: the render runs at the working size
// and the export carries it up, the far corner the still's own.
TEST_F(ApplianceShotTest, AStillLargerThanTheWorkingSizeIsExportedAtItsOwnSize) {
  auto reduced = std::make_shared<Analysis>(analysis());
  cv::resize(analysis().photo_linear, reduced->full_photo_linear, {320, 240}, 0, 0, cv::INTER_CUBIC);
  reduced->full_photo_linear = cv::max(reduced->full_photo_linear, 0.f);
  const auto spots = find_spots(reduced->scene, 12);
  ASSERT_FALSE(spots.empty());
  CompositeRender render(reduced, preset("cube"), spots.front(), tier_spec(appliance::Tier::Draft), 2);
  std::atomic<bool> cancel{false};
  for (int passes = 0; !render.finished() && passes < 20; ++passes) render.run_pass(&cancel);
  const auto done = render.snapshot(true);
  // The cube's silhouette traced at the still's size: whole inside, shared on its edges.
  ASSERT_FALSE(done->full_size_coverage.empty());
  EXPECT_EQ(done->full_size_coverage.region & cv::Rect(0, 0, 320, 240), done->full_size_coverage.region);
  double most = 0;
  cv::minMaxLoc(done->full_size_coverage.coverage, nullptr, &most);
  EXPECT_EQ(most, 1.0);
  const cv::Mat& sharp = done->full_size_coverage.coverage;
  EXPECT_GT(cv::countNonZero((sharp > 0.f) & (sharp < 1.f)), 0);
  const cv::Mat exported = exported_composite(*reduced, *done, Adjustment{});
  ASSERT_EQ(exported.size(), cv::Size(320, 240));
  ASSERT_TRUE(cv::checkRange(exported));
  const cv::Rect corner(0, 0, 24, 16);
  // As exported (8-bit): the screen's composite goes through the camera
  // response and back, which moves floats by 1e-7.
  EXPECT_EQ(cv::norm(capture::linear_to_srgb8(exported(corner)),
                     capture::linear_to_srgb8(reduced->full_photo_linear(corner)), cv::NORM_INF),
            0.0);
  const cv::Point base(static_cast<int>(2 * spots.front().pixel.x), static_cast<int>(2 * spots.front().pixel.y));
  const cv::Rect near_base = cv::Rect(base.x - 8, base.y - 20, 16, 20) & cv::Rect(0, 0, 320, 240);
  EXPECT_GT(cv::norm(exported(near_base), reduced->full_photo_linear(near_base), cv::NORM_L1) / near_base.area(), 0.01)
      << "the cube stands in the full-size export";
  EXPECT_EQ(adjusted_composite(*reduced, *done, Adjustment{}).size(), cv::Size(160, 120)) << "the screen's is working size";
}

TEST(AnalyseStill, AStillLargerThanTheWorkingSizeIsInferredReduced) {
  const SyntheticShot shot = synthetic_room(320, 240, 5, 4);
  const Analysis a = analyse_still(shot.photo_linear, capture::linear_to_srgb8(shot.photo_linear), 1.5, 160 * 120,
                                   [](const std::string&) {});
  EXPECT_EQ(a.photo_linear.size(), cv::Size(160, 120));
  EXPECT_EQ(a.photo_rgb8.size(), cv::Size(160, 120));
  EXPECT_EQ(a.scene_photo.size(), cv::Size(160, 120));
  EXPECT_EQ(a.full_photo_linear.size(), cv::Size(320, 240));
  EXPECT_EQ(a.scene.width, 160);
  EXPECT_EQ(a.scene.height, 120);
}

// The board's calibrated lens: the scene is inferred from the still with the
// lens's fall-off divided out, and the still itself is what is composited.
TEST(AnalyseStill, ACalibratedLensIsDividedOutOfWhatIsInferred) {
  const SyntheticShot shot = synthetic_room(160, 120, 5, 4);
  const render::Vignetting lens{-0.6, 0.0};
  const cv::Mat still = render::vignette_image(shot.photo_linear, lens);
  const auto quiet = [](const std::string&) {};
  const cv::Mat rgb8 = capture::linear_to_srgb8(still);
  const Analysis known = analyse_still(still, rgb8, 1.5, 160 * 120, quiet, lens);
  const Analysis lens_free = analyse_still(render::devignette(still, lens), rgb8, 1.5, 160 * 120, quiet);
  EXPECT_EQ(cv::norm(known.photo_linear, still, cv::NORM_INF), 0.0) << "the still as taken is composited";
  EXPECT_EQ(known.vignetting.r2, lens.r2);
  EXPECT_EQ(cv::norm(known.scene.albedo, lens_free.scene.albedo, cv::NORM_INF), 0.0);
  EXPECT_EQ(known.scene.lights.size(), lens_free.scene.lights.size());
}

TEST_F(ApplianceShotTest, SliderStepsMapToUnitsAndBack) {
  std::array<int, appliance::kRelightParamCount> steps{};
  steps[static_cast<size_t>(appliance::RelightParam::SceneLight)] = 4;
  steps[static_cast<size_t>(appliance::RelightParam::Focus)] = 4;
  steps[static_cast<size_t>(appliance::RelightParam::Aperture)] = -3;
  const Adjustment a = adjustment_from_steps(steps, 2.0);
  EXPECT_DOUBLE_EQ(a.scene_ev, 1.0);
  EXPECT_DOUBLE_EQ(a.prop_ev, 0.0);
  EXPECT_DOUBLE_EQ(a.focus_m, 4.0) << "four steps double the focus distance";
  EXPECT_DOUBLE_EQ(a.aperture_m, 0.0) << "below zero the lens stays a pinhole";
  EXPECT_EQ(describe_step(appliance::RelightParam::SceneLight, 4, 2.0), "+1.00 EV");
  EXPECT_EQ(describe_step(appliance::RelightParam::Aperture, 0, 2.0), "pinhole");
  EXPECT_EQ(describe_step(appliance::RelightParam::Aperture, 2, 2.0), "8 mm");
  // A nonsense prop distance falls back to a finite focus.
  EXPECT_TRUE(std::isfinite(adjustment_from_steps(steps, std::nan("")).focus_m));
}

}  // namespace
}  // namespace propcam::firmware
