// The change-layer denoiser: it lowers the error of a noisy shadow, keeps
// edges the guides show, leaves converged and untouched pixels alone, is
// judged by the dual-buffer test, and in a render session lowers the error
// of a composite against a converged reference without touching the photo
// elsewhere.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "propcam/render/denoise.h"
#include "propcam/render/props.h"
#include "propcam/render/render_session.h"
#include "propcam/render/synthetic_room.h"

namespace propcam::render {
namespace {

constexpr int kW = 64, kH = 48;

// A floor seen from above: normal +Y, depth 2 m, albedo 0.5, no prop.
DenoiseGuides flat_guides() {
  return {cv::Mat(kH, kW, CV_32FC3, cv::Scalar::all(0.5)), cv::Mat(kH, kW, CV_32FC3, cv::Scalar(0, 1, 0)),
          cv::Mat(kH, kW, CV_32F, cv::Scalar(2.0)), cv::Mat(kH, kW, CV_8U, cv::Scalar(0))};
}

// A soft round shadow: the change is -0.2 at its centre, fading out.
cv::Mat soft_shadow() {
  cv::Mat m(kH, kW, CV_32FC3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double r2 = (std::pow(x - kW / 2.0, 2) + std::pow(y - kH / 2.0, 2)) / (12.0 * 12.0);
      m.at<cv::Vec3f>(y, x) = cv::Vec3f::all(static_cast<float>(-0.2 * std::exp(-r2)));
    }
  return m;
}

cv::Mat with_noise(const cv::Mat& truth, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.f, static_cast<float>(sigma));
  cv::Mat out = truth.clone();
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) out.at<cv::Vec3f>(y, x) += cv::Vec3f::all(n(rng));
  return out;
}

double rmse(const cv::Mat& a, const cv::Mat& b) { return cv::norm(a, b, cv::NORM_L2) / std::sqrt(a.total() * 3.0); }

const cv::Mat kAllTouched(kH, kW, CV_8U, cv::Scalar(255));
const cv::Mat kNoCoverage(kH, kW, CV_32F, cv::Scalar(0));

TEST(Denoise, LowersTheErrorOfANoisyShadow) {
  const cv::Mat truth = soft_shadow();
  constexpr double kSigma = 0.05;
  const ChangeBuffer noisy{with_noise(truth, kSigma, 1), cv::Mat(kH, kW, CV_32F, cv::Scalar(kSigma * kSigma))};
  const cv::Mat filtered = denoise_change(noisy, kAllTouched, kNoCoverage, flat_guides());
  EXPECT_TRUE(cv::checkRange(filtered));
  EXPECT_LT(rmse(filtered, truth), 0.3 * rmse(noisy.change, truth));
}

TEST(Denoise, KeepsEdgesTheGuidesShow) {
  // Left half a floor, right half a wall: different light on each.
  DenoiseGuides g = flat_guides();
  cv::Mat truth(kH, kW, CV_32FC3, cv::Scalar::all(-0.05));
  g.normal(cv::Rect(kW / 2, 0, kW / 2, kH)).setTo(cv::Scalar(1, 0, 0));
  truth(cv::Rect(kW / 2, 0, kW / 2, kH)).setTo(cv::Scalar::all(-0.25));
  constexpr double kSigma = 0.03;
  const ChangeBuffer noisy{with_noise(truth, kSigma, 2), cv::Mat(kH, kW, CV_32F, cv::Scalar(kSigma * kSigma))};
  const cv::Mat filtered = denoise_change(noisy, kAllTouched, kNoCoverage, g);
  // The columns either side of the edge keep their own level.
  EXPECT_NEAR(cv::mean(filtered.col(kW / 2 - 1))[0], -0.05, 0.01);
  EXPECT_NEAR(cv::mean(filtered.col(kW / 2))[0], -0.25, 0.01);
}

TEST(Denoise, ConvergedAndUntouchedPixelsKeepTheirValues) {
  const cv::Mat truth = soft_shadow();
  // Converged: zero variance everywhere, so every neighbour differs by infinitely many deviations.
  const ChangeBuffer exact{truth, cv::Mat(kH, kW, CV_32F, cv::Scalar(0))};
  const cv::Mat same = denoise_change(exact, kAllTouched, kNoCoverage, flat_guides());
  EXPECT_LT(cv::norm(same, truth, cv::NORM_INF), 1e-6);
  // Untouched pixels (the left half) are returned bit for bit.
  cv::Mat touched = kAllTouched.clone();
  touched(cv::Rect(0, 0, kW / 2, kH)).setTo(0);
  const ChangeBuffer noisy{with_noise(truth, 0.05, 3), cv::Mat(kH, kW, CV_32F, cv::Scalar(0.0025))};
  const cv::Mat half = denoise_change(noisy, touched, kNoCoverage, flat_guides());
  EXPECT_EQ(cv::norm(half(cv::Rect(0, 0, kW / 2, kH)), noisy.change(cv::Rect(0, 0, kW / 2, kH)), cv::NORM_INF), 0.0);
  // Silhouette pixels (partial prop coverage) are kept as well.
  cv::Mat coverage = kNoCoverage.clone();
  coverage.at<float>(10, 40) = 0.5f;
  const cv::Mat kept = denoise_change(noisy, kAllTouched, coverage, flat_guides());
  EXPECT_EQ(kept.at<cv::Vec3f>(10, 40), noisy.change.at<cv::Vec3f>(10, 40));
}

TEST(Denoise, TheDualBufferTestSaysWhereTheFilterHelps) {
  const cv::Mat truth = soft_shadow();
  constexpr double kSigma = 0.05;
  const cv::Mat variance(kH, kW, CV_32F, cv::Scalar(kSigma * kSigma));
  const cv::Mat a = with_noise(truth, kSigma, 4), b = with_noise(truth, kSigma, 5);
  const cv::Mat a_filtered = denoise_change({a, variance}, kAllTouched, kNoCoverage, flat_guides());
  const std::vector<cv::Rect> tiles = {cv::Rect(0, 0, kW / 2, kH), cv::Rect(kW / 2, 0, kW / 2, kH)};
  EXPECT_EQ(filter_helps_per_tile(a, a_filtered, b, kAllTouched, tiles), (std::vector<bool>{true, true}));
  // A fine checkerboard of light with almost no noise, whose variance is
  // overstated: the filter blurs real detail, and the test catches it.
  cv::Mat checker(kH, kW, CV_32FC3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) checker.at<cv::Vec3f>(y, x) = cv::Vec3f::all((x + y) % 2 ? -0.3f : 0.f);
  const cv::Mat ca = with_noise(checker, 0.001, 6), cb = with_noise(checker, 0.001, 7);
  const cv::Mat overstated(kH, kW, CV_32F, cv::Scalar(1.0));
  const cv::Mat ca_filtered = denoise_change({ca, overstated}, kAllTouched, kNoCoverage, flat_guides());
  EXPECT_EQ(filter_helps_per_tile(ca, ca_filtered, cb, kAllTouched, tiles), (std::vector<bool>{false, false}));
}

TEST(DenoiseHardCases, DegenerateGuidesAndInputsStayFiniteOrFailClearly) {
  const cv::Mat truth = soft_shadow();
  DenoiseGuides g = flat_guides();
  g.albedo.setTo(cv::Scalar::all(0));  // black surfaces: nothing divided out
  g.depth.setTo(0);                    // nothing hit
  g.normal.setTo(cv::Scalar::all(0));
  cv::Mat variance(kH, kW, CV_32F, cv::Scalar(0.01));
  variance.at<float>(3, 3) = std::numeric_limits<float>::quiet_NaN();
  variance.at<float>(4, 4) = std::numeric_limits<float>::infinity();
  const cv::Mat out = denoise_change({with_noise(truth, 0.1, 8), variance}, kAllTouched, kNoCoverage, g);
  EXPECT_TRUE(cv::checkRange(out));
  // Nothing touched, no levels, a single pixel.
  const ChangeBuffer noisy{with_noise(truth, 0.1, 9), variance};
  EXPECT_EQ(cv::norm(denoise_change(noisy, cv::Mat(kH, kW, CV_8U, cv::Scalar(0)), kNoCoverage, g), noisy.change,
                     cv::NORM_INF),
            0.0);
  DenoiseOptions none;
  none.levels = 0;
  EXPECT_EQ(cv::norm(denoise_change(noisy, kAllTouched, kNoCoverage, flat_guides(), none), noisy.change, cv::NORM_INF),
            0.0);
  const DenoiseGuides one{cv::Mat(1, 1, CV_32FC3, cv::Scalar::all(0.5)), cv::Mat(1, 1, CV_32FC3, cv::Scalar(0, 1, 0)),
                          cv::Mat(1, 1, CV_32F, cv::Scalar(1)), cv::Mat(1, 1, CV_8U, cv::Scalar(0))};
  const cv::Mat pixel = denoise_change({cv::Mat(1, 1, CV_32FC3, cv::Scalar::all(-0.1)), cv::Mat(1, 1, CV_32F, cv::Scalar(1))},
                                       cv::Mat(1, 1, CV_8U, cv::Scalar(255)), cv::Mat(1, 1, CV_32F, cv::Scalar(0)), one);
  EXPECT_NEAR(pixel.at<cv::Vec3f>(0, 0)[0], -0.1f, 1e-6f);
  // Wrong sizes and types, bad options.
  EXPECT_THROW(denoise_change({truth, cv::Mat(3, 3, CV_32F)}, kAllTouched, kNoCoverage, g), std::invalid_argument);
  EXPECT_THROW(denoise_change({truth, variance}, kAllTouched, kNoCoverage, one), std::invalid_argument);
  DenoiseOptions bad;
  bad.luminance_sigma = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(denoise_change({truth, variance}, kAllTouched, kNoCoverage, flat_guides(), bad), std::invalid_argument);
  bad = {};
  bad.levels = 99;
  EXPECT_THROW(denoise_change({truth, variance}, kAllTouched, kNoCoverage, flat_guides(), bad), std::invalid_argument);
}

// A small cube on a synthetic room's floor: at 16 spp the denoised composite
// is closer to a 256-spp reference than the raw one, and pixels the prop
// never changed are the photo's, bit for bit.
TEST(DenoiseSession, LowersTheCompositesErrorAndLeavesThePhotoElsewhere) {
  SyntheticRoomSpec spec;
  spec.width = 96;
  spec.height = 72;
  spec.seed = 4;
  const SyntheticRoom room = make_synthetic_room(spec);
  Scene scene;
  scene.add_mesh(room.room, Layer::Background);
  Mesh cube = make_prop("cube");
  const float s = 0.4f / cube.bounds().sizes().y();
  cube.transform(Eigen::Affine3f(Eigen::Translation3f(room.free_floor_point) * Eigen::Scaling(s) *
                                 Eigen::Translation3f(-cube.bounds().center().x(), -cube.bounds().min().y(),
                                                      -cube.bounds().center().z())));
  const Eigen::AlignedBox3f bounds = cube.bounds();
  scene.add_mesh(std::move(cube), Layer::Prop);
  scene.commit();
  const cv::Mat photo(spec.height, spec.width, CV_32FC3, cv::Scalar(0.3, 0.3, 0.3));
  SessionSettings settings;
  settings.render.tile_size = 16;
  settings.render.max_bounces = 2;
  settings.render.seed = 99;
  settings.max_samples_per_pixel = 256;
  RenderSession reference(scene, room.camera, room.lights, photo, bounds, settings);
  while (!reference.finished()) reference.run_pass();
  const cv::Mat truth = reference.composite();
  settings.render.seed = 1;
  settings.max_samples_per_pixel = 16;
  settings.denoise = true;
  RenderSession session(scene, room.camera, room.lights, photo, bounds, settings);
  while (!session.finished()) session.run_pass();
  DenoiseReport report;
  const cv::Mat denoised = composite_differential(photo, session.denoised(&report));
  const cv::Mat raw = composite_differential(photo, session.differential());
  EXPECT_GT(report.tiles_filtered, 0);
  EXPECT_LE(report.tiles_filtered, report.tiles_judged);
  EXPECT_LT(rmse(denoised, truth), 0.8 * rmse(raw, truth));
  EXPECT_EQ(cv::norm(session.composite(), denoised, cv::NORM_INF), 0.0);  // settings.denoise: composite() is denoised
  // Where no sample of the session touched the prop, the photo is unchanged.
  const cv::Mat touched = session.touched();
  ASSERT_GT(cv::countNonZero(touched), 0);
  ASSERT_LT(cv::countNonZero(touched), static_cast<int>(touched.total()));
  for (int y = 0; y < photo.rows; ++y)
    for (int x = 0; x < photo.cols; ++x)
      if (!touched.at<uint8_t>(y, x)) ASSERT_EQ(denoised.at<cv::Vec3f>(y, x), photo.at<cv::Vec3f>(y, x)) << x << "," << y;
}

}  // namespace
}  // namespace propcam::render
