// The photo's blur and noise, estimated on photos we degrade ourselves with
// a known blur and noise, and matched on what the prop adds.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "propcam/capture/image_file.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/depth_of_field.h"
#include "propcam/render/photo_imaging.h"

namespace propcam::render {
namespace {

constexpr int kW = 320, kH = 240, kSuper = 8;

// A scene of flat-shaded shapes over a gentle gradient, linear light, each
// pixel the average over its area (a box pixel, as our renderer's).
cv::Mat shapes_photo(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  cv::Mat big(kH * kSuper, kW * kSuper, CV_32FC3);
  for (int y = 0; y < big.rows; ++y)
    for (int x = 0; x < big.cols; ++x) {
      const float v = 0.15f + 0.2f * static_cast<float>(x) / static_cast<float>(big.cols);
      big.at<cv::Vec3f>(y, x) = {v, v * 0.9f, v * 0.8f};
    }
  for (int i = 0; i < 14; ++i) {
    const cv::Scalar colour(0.03 + 0.8 * u(rng), 0.03 + 0.8 * u(rng), 0.03 + 0.8 * u(rng));
    const cv::Point centre(static_cast<int>(u(rng) * big.cols), static_cast<int>(u(rng) * big.rows));
    const int radius = static_cast<int>((12 + 40 * u(rng)) * kSuper);
    if (i % 2) {
      cv::circle(big, centre, radius, colour, cv::FILLED, cv::LINE_8);
    } else {
      const cv::RotatedRect box(centre, cv::Size2f(static_cast<float>(radius * 2), static_cast<float>(radius)),
                                static_cast<float>(180 * u(rng)));
      cv::Point2f corners[4];
      box.points(corners);
      std::vector<cv::Point> poly(corners, corners + 4);
      cv::fillConvexPoly(big, poly, colour, cv::LINE_8);
    }
  }
  cv::Mat photo;
  cv::resize(big, photo, {kW, kH}, 0, 0, cv::INTER_AREA);
  return photo;
}

cv::Mat blurred(const cv::Mat& linear, double sigma) {
  if (sigma <= 0) return linear.clone();
  cv::Mat out;
  const int k = 2 * static_cast<int>(std::ceil(3 * sigma)) + 1;
  cv::GaussianBlur(linear, out, {k, k}, sigma, sigma, cv::BORDER_REFLECT);
  return out;
}

cv::Mat to_display(const cv::Mat& linear) {
  cv::Mat d(linear.size(), CV_32FC3);
  for (int r = 0; r < d.rows; ++r)
    for (int c = 0; c < d.cols; ++c)
      for (int k = 0; k < 3; ++k)
        d.at<cv::Vec3f>(r, c)[k] = capture::linear_to_srgb(std::clamp(linear.at<cv::Vec3f>(r, c)[k], 0.f, 1.f));
  return d;
}

cv::Mat to_linear(const cv::Mat& display) {
  cv::Mat l(display.size(), CV_32FC3);
  for (int r = 0; r < l.rows; ++r)
    for (int c = 0; c < l.cols; ++c)
      for (int k = 0; k < 3; ++k) l.at<cv::Vec3f>(r, c)[k] = capture::srgb_to_linear(display.at<cv::Vec3f>(r, c)[k]);
  return l;
}

// Display-domain noise of sigma^2 = a * value + b (the value before noise),
// then the 8-bit file's rounding.
cv::Mat noisy_8bit(const cv::Mat& display, double a, double b, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, 1);
  cv::Mat out = display.clone();
  for (int r = 0; r < out.rows; ++r)
    for (int c = 0; c < out.cols; ++c)
      for (int k = 0; k < 3; ++k) {
        float& v = out.at<cv::Vec3f>(r, c)[k];
        const float sigma = static_cast<float>(std::sqrt(a * v + b));
        v = std::round(255.f * std::clamp(v + sigma * n(rng), 0.f, 1.f)) / 255.f;
      }
  return out;
}

TEST(PhotoImaging, TheNoiseOfAFlatNoisyImageIsItsSigma) {
  // Also the check of the lower envelope's bias constant (4000+ blocks).
  cv::Mat flat(512, 512, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  cv::Mat noise(flat.size(), CV_32FC3);
  cv::RNG(21).fill(noise, cv::RNG::NORMAL, 0.0, 0.02);  // its own stream: cv::randn's depends on the tests before
  int blocks = 0;
  const NoiseLevelFunction nlf = estimate_noise_level(flat + noise, {}, &blocks);
  EXPECT_GT(blocks, 3000);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(nlf.at(ch, 0.5f), 0.02, 0.02 * 0.04) << "channel " << ch;
}

TEST(PhotoImaging, TheNoiseOfASmallRegionIsItsSigma) {
  cv::Mat flat(64, 64, CV_32FC3, cv::Scalar(0.4, 0.5, 0.6)), noise(64, 64, CV_32FC3);
  cv::RNG(22).fill(noise, cv::RNG::NORMAL, 0.0, 0.01);
  cv::Mat region = cv::Mat::zeros(64, 64, CV_8U);
  region(cv::Rect(16, 16, 32, 32)).setTo(255);
  int pixels = 0;
  const std::array<float, 3> sigma = region_noise_sigma(flat + noise, region, &pixels);
  EXPECT_EQ(pixels, 1024);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(sigma[ch], 0.01, 0.002) << "channel " << ch;
  region.setTo(0);
  region(cv::Rect(0, 0, 4, 4)).setTo(255);
  EXPECT_EQ(region_noise_sigma(flat + noise, region)[1], 0.0f) << "too small to tell";
}

TEST(PhotoImaging, NoiseOfADegradedPhotoIsFoundWithinTwentyPercent) {
  for (const double sigma_levels : {2.0, 5.0, 10.0}) {
    const double b = std::pow(sigma_levels / 255.0, 2);
    const cv::Mat photo = noisy_8bit(to_display(shapes_photo(3)), 0.0, b, 11);
    int blocks = 0;
    const NoiseLevelFunction nlf = estimate_noise_level(photo, {}, &blocks);
    EXPECT_GT(blocks, 100);
    EXPECT_NEAR(nlf.median_8bit(), sigma_levels, 0.2 * sigma_levels) << sigma_levels << " levels";
  }
}

TEST(PhotoImaging, SignalDependentNoiseIsFollowedAcrossIntensities) {
  // sigma^2 = a * v: 3.2 levels at v = 0.2, 6.4 at v = 0.8.
  const double a = std::pow(6.4 / 255.0, 2) / 0.8;
  const cv::Mat photo = noisy_8bit(to_display(shapes_photo(4)), a, 0.0, 12);
  const NoiseLevelFunction nlf = estimate_noise_level(photo, {});
  for (const float v : {0.5f, 0.7f}) {
    const double truth = 255.0 * std::sqrt(a * v);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(255.0 * nlf.at(ch, v), truth, 0.2 * truth) << "value " << v;
  }
}

TEST(PhotoImaging, BlurOfADegradedPhotoIsFoundWithinTwentyPercent) {
  for (const double sigma : {0.8, 1.5, 2.5}) {
    const cv::Mat photo = to_linear(noisy_8bit(to_display(blurred(shapes_photo(5), sigma)), 0.0, std::pow(1.0 / 255, 2), 13));
    int edges = 0;
    const double estimate = estimate_edge_blur(photo, {}, &edges);
    EXPECT_GT(edges, 30);
    EXPECT_NEAR(estimate, sigma, 0.2 * sigma) << "sigma " << sigma;
  }
}

// Noise reads as sharpness at edges (read directly, 2.5 px came out 1.7 px
// under 2 levels of noise and 1.1 px under 4, over three such photos); a
// noisy photo's edges are found on its smoothed luminance and read summed
// along each edge.
// Through 4 levels a 2.5 px blur still reads 1.45 px (docs/camera_match.md).
TEST(PhotoImaging, BlurIsFoundWithinTwentyPercentThroughNoise) {
  const std::vector<std::pair<double, double>> cases = {{0.8, 2}, {1.5, 2}, {2.5, 2}, {0.8, 4}, {1.5, 4}};
  for (const auto& [sigma, levels] : cases) {
    const cv::Mat photo =
        to_linear(noisy_8bit(to_display(blurred(shapes_photo(7), sigma)), 0.0, std::pow(levels / 255.0, 2), 15));
    const PhotoImaging imaging = estimate_photo_imaging(photo);
    ASSERT_TRUE(imaging.blur_measured && imaging.noise_measured) << sigma << " px, " << levels << " levels";
    EXPECT_TRUE(imaging.blur_read_through_noise);
    EXPECT_NEAR(imaging.noise.median_8bit(), levels, 0.2 * levels);
    EXPECT_NEAR(imaging.blur_sigma_px, sigma, 0.2 * sigma) << sigma << " px, " << levels << " levels";
  }
}

TEST(PhotoImaging, AClean8BitPhotoIsReadDirectly) {
  const PhotoImaging imaging =
      estimate_photo_imaging(to_linear(noisy_8bit(to_display(blurred(shapes_photo(7), 1.5)), 0, 0, 16)));
  EXPECT_FALSE(imaging.blur_read_through_noise);
  EXPECT_NEAR(imaging.blur_sigma_px, 1.5, 0.3);
}

TEST(PhotoImaging, ASharpPhotoIsAsSharpAsOurRender) {
  const cv::Mat photo = to_linear(noisy_8bit(to_display(shapes_photo(6)), 0.0, 0.0, 14));
  int edges = 0;
  EXPECT_LT(estimate_edge_blur(photo, {}, &edges), kMinMatchedBlurPx);
  EXPECT_GT(edges, 30);
}

TEST(PhotoImaging, BlurChangeLeavesWhatTheChangeCannotReachBitIdentical) {
  const cv::Mat photo = shapes_photo(7);
  cv::Mat composite = photo.clone();
  cv::rectangle(composite, cv::Rect(100, 80, 40, 60), cv::Scalar(0.9, 0.9, 0.9), cv::FILLED);
  cv::Mat coverage = cv::Mat::zeros(photo.size(), CV_32F);
  coverage(cv::Rect(100, 80, 40, 60)).setTo(1.0f);
  const cv::Mat out = blur_change(photo, composite, coverage, 1.5);
  const int reach = 2 * static_cast<int>(std::ceil(3 * 1.5)) / 2 + 1;
  cv::Mat far = cv::Mat::ones(photo.size(), CV_8U);
  far(cv::Rect(100 - reach, 80 - reach, 40 + 2 * reach, 60 + 2 * reach)).setTo(0);
  cv::Mat diff;
  cv::absdiff(out, photo, diff);
  EXPECT_EQ(cv::norm(diff, cv::NORM_INF, far), 0.0);
  // The rectangle's edge is softened: its inside keeps its value (the
  // photo under it does not show through), its border is in between.
  EXPECT_NEAR(out.at<cv::Vec3f>(110, 120)[0], 0.9f, 1e-4);
  const float border = out.at<cv::Vec3f>(110, 100)[0], outside = photo.at<cv::Vec3f>(110, 99)[0];
  EXPECT_GT(border, std::min(outside, 0.9f) + 0.02f) << outside;
  EXPECT_LT(border, std::max(outside, 0.9f) - 0.02f) << outside;
  EXPECT_EQ(cv::norm(blur_change(photo, photo, cv::Mat::zeros(photo.size(), CV_32F), 2.0), photo, cv::NORM_INF), 0.0)
      << "no change, no blur";
}

// A photo blurred by sigma with a sharp, box-pixel prop (a disc) pasted in:
// the composite's prop edges match the photo's after the camera match.
TEST(PhotoImaging, APropPastedIntoABlurredPhotoGetsThePhotosEdgeWidth) {
  const double sigma = 1.5;
  const cv::Mat photo = to_linear(noisy_8bit(to_display(blurred(shapes_photo(8), sigma)), 0.0, 0.0, 15));
  cv::Mat big = cv::Mat::zeros(kH * kSuper, kW * kSuper, CV_32F);
  cv::circle(big, {160 * kSuper, 120 * kSuper}, 45 * kSuper, 1.0, cv::FILLED);
  cv::Mat coverage;
  cv::resize(big, coverage, {kW, kH}, 0, 0, cv::INTER_AREA);
  cv::Mat composite = photo.clone();
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c) {
      const float m = coverage.at<float>(r, c);
      composite.at<cv::Vec3f>(r, c) = (1 - m) * photo.at<cv::Vec3f>(r, c) + m * cv::Vec3f(0.85f, 0.8f, 0.7f);
    }
  const PhotoImaging imaging = estimate_photo_imaging(photo);
  ASSERT_TRUE(imaging.blur_measured);
  EXPECT_NEAR(imaging.blur_sigma_px, sigma, 0.2 * sigma);
  CameraMatchReport report;
  const cv::Mat matched = match_camera(photo, composite, coverage, imaging, {}, 1.0, &report);
  ASSERT_EQ(report.steps.size(), 3u);
  EXPECT_TRUE(report.steps[0].applied) << report.steps[0].why;
  EXPECT_FALSE(report.steps[1].applied) << "no calibrated vignetting: " << report.steps[1].why;
  EXPECT_FALSE(report.steps[2].applied) << "a clean photo gets no noise: " << report.steps[2].why;
  // The disc's silhouette: a ring around its radius.
  cv::Mat ring = cv::Mat::zeros(kH, kW, CV_8U);
  cv::circle(ring, {160, 120}, 45, 255, 5);
  int edges = 0;
  const double before = estimate_edge_blur(composite, ring, &edges);
  const double after = estimate_edge_blur(matched, ring, &edges);
  EXPECT_LT(before, kMinMatchedBlurPx) << "the pasted prop is sharp";
  EXPECT_GT(edges, 30);
  EXPECT_NEAR(after, sigma, 0.2 * sigma);
}

// A ground plane receding from 1.1 m (bottom row) to 10 m (top row) with
// flat shapes standing on it, each at the depth of its lowest row, and the
// depth that goes with it: a photo whose defocus grows away from a focus.
constexpr int kDofW = 480, kDofH = 360, kDofSuper = 4;
constexpr double kDofFx = 450.0;

double ramp_depth(double row_fraction) { return 1.0 / (0.1 + 0.9 * row_fraction); }

cv::Mat shapes_on_a_ground(uint32_t seed, cv::Mat& depth) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  cv::Mat big(kDofH * kDofSuper, kDofW * kDofSuper, CV_32FC3), big_depth(big.size(), CV_32F);
  for (int y = 0; y < big.rows; ++y)
    for (int x = 0; x < big.cols; ++x) {
      const float v = 0.15f + 0.2f * static_cast<float>(x) / static_cast<float>(big.cols);
      big.at<cv::Vec3f>(y, x) = {v, v * 0.9f, v * 0.8f};
      big_depth.at<float>(y, x) = static_cast<float>(ramp_depth(static_cast<double>(y) / big.rows));
    }
  for (int i = 0; i < 60; ++i) {
    const cv::Scalar colour(0.03 + 0.8 * u(rng), 0.03 + 0.8 * u(rng), 0.03 + 0.8 * u(rng));
    const cv::Point centre(static_cast<int>(u(rng) * big.cols), static_cast<int>(u(rng) * big.rows));
    const int radius = static_cast<int>((6 + 20 * u(rng)) * kDofSuper);
    const int bottom = std::min(big.rows - 1, centre.y + radius);
    cv::Mat shape = cv::Mat::zeros(big.size(), CV_8U);
    if (i % 2) {
      cv::circle(shape, centre, radius, 255, cv::FILLED);
    } else {
      const cv::RotatedRect box(centre, cv::Size2f(static_cast<float>(radius * 2), static_cast<float>(radius)),
                                static_cast<float>(180 * u(rng)));
      cv::Point2f corners[4];
      box.points(corners);
      cv::fillConvexPoly(shape, std::vector<cv::Point>(corners, corners + 4), 255);
    }
    big.setTo(colour, shape);
    big_depth.setTo(ramp_depth(static_cast<double>(bottom) / big.rows), shape);
  }
  cv::Mat photo;
  cv::resize(big, photo, {kDofW, kDofH}, 0, 0, cv::INTER_AREA);
  cv::resize(big_depth, depth, {kDofW, kDofH}, 0, 0, cv::INTER_NEAREST);
  return photo;
}

// A 30 mm pupil focused at 2 m: circles of confusion from 0.3 px near the
// focus to 4-5 px at the ends of the ground.
cv::Mat defocused(const cv::Mat& photo, const cv::Mat& depth) {
  DepthOfField dof;
  dof.aperture_m = 0.03;
  dof.focus_distance_m = 2.0;
  return apply_depth_of_field(photo, depth, kDofFx, dof);
}

// A sharp, box-pixel prop (a bright bar) pasted at a row of the ground, and
// the photo's edges at the prop's depth, away from it: after the camera
// match with the prop's depth, the prop's edges are as wide as the photo's
// there (within 20%), near and far from the focus.
TEST(PhotoImaging, APropInADefocusedPhotoGetsItsOwnDepthsBlur) {
  cv::Mat depth;
  const cv::Mat photo = defocused(shapes_on_a_ground(5, depth), depth);
  const PhotoImaging imaging = estimate_photo_imaging(photo, depth);
  ASSERT_TRUE(imaging.defocus.found) << imaging.defocus.bands.size() << " bands";
  EXPECT_NEAR(imaging.defocus.focus_dioptres, 0.5, 0.15) << "focused at 2 m";
  for (const int row : {30, 320}) {
    const double prop_depth = ramp_depth((row + 0.5) / kDofH);
    const cv::Rect bar(kDofW / 2 - 40, row - 10, 80, 20);
    cv::Mat coverage = cv::Mat::zeros(photo.size(), CV_32F);
    coverage(bar).setTo(1.0f);
    cv::Mat composite = photo.clone();
    composite(bar).setTo(cv::Scalar(0.9, 0.85, 0.8));
    CameraMatchOptions options;
    options.prop_depth_m = prop_depth;
    CameraMatchReport report;
    const cv::Mat matched = match_camera(photo, composite, coverage, imaging, options, 1.0, &report);
    ASSERT_TRUE(report.steps.at(0).applied) << report.steps[0].why;
    EXPECT_NE(report.steps[0].why.find("prop's depth"), std::string::npos) << report.steps[0].why;
    cv::Mat outline = cv::Mat::zeros(photo.size(), CV_8U);
    cv::rectangle(outline, bar, 255, 5);
    // The photo's edges at the prop's depth (within 0.06 dioptres), away from the bar.
    cv::Mat same_depth = cv::Mat::zeros(photo.size(), CV_8U);
    for (int r = 0; r < kDofH; ++r)
      for (int c = 0; c < kDofW; ++c)
        if (std::abs(1.0 / depth.at<float>(r, c) - 1.0 / prop_depth) < 0.06) same_depth.at<uint8_t>(r, c) = 255;
    cv::Mat grown_bar = cv::Mat::zeros(photo.size(), CV_8U);
    cv::rectangle(grown_bar, bar, 255, 15);
    grown_bar(bar).setTo(255);
    same_depth.setTo(0, grown_bar);
    int prop_edges = 0, photo_edges = 0;
    const double prop_blur = estimate_edge_blur(matched, outline, &prop_edges, 20);
    const double photo_blur = estimate_edge_blur(photo, same_depth, &photo_edges, 20);
    ASSERT_GT(prop_edges, 0);
    ASSERT_GT(photo_edges, 0);
    EXPECT_NEAR(prop_blur, photo_blur, 0.2 * photo_blur) << "at " << prop_depth << " m (row " << row << ")";
    EXPECT_NEAR(report.blur_sigma_px, imaging.blur_sigma_at(prop_depth), 1e-12);
  }
}

// One blur everywhere: no defocus, and every depth takes the photo's blur.
TEST(PhotoImaging, APhotoBlurredAlikeAtEveryDepthShowsNoDefocus) {
  cv::Mat depth;
  const cv::Mat photo = blurred(shapes_on_a_ground(6, depth), 1.2);
  const PhotoImaging imaging = estimate_photo_imaging(photo, depth);
  EXPECT_GE(static_cast<int>(imaging.defocus.bands.size()), kMinDefocusBands) << "the bands were read";
  EXPECT_FALSE(imaging.defocus.found);
  for (const double z : {1.2, 2.0, 8.0}) EXPECT_EQ(imaging.blur_sigma_at(z), imaging.blur_sigma_px);
}

// Depth that gives nothing to band: none, all sky, non-finite, another
// size, another type.
TEST(PhotoImaging, DepthWithoutSurfacesLooksForNoDefocus) {
  cv::Mat depth;
  const cv::Mat photo = defocused(shapes_on_a_ground(7, depth), depth);
  EXPECT_TRUE(estimate_photo_imaging(photo).defocus.bands.empty()) << "no depth, no bands";
  for (const float z : {kSkyDepthM, 0.0f, -1.0f, std::numeric_limits<float>::quiet_NaN(),
                        std::numeric_limits<float>::infinity()}) {
    const PhotoImaging imaging = estimate_photo_imaging(photo, cv::Mat(photo.size(), CV_32F, cv::Scalar(z)));
    EXPECT_FALSE(imaging.defocus.found) << z;
    EXPECT_TRUE(imaging.defocus.bands.empty()) << z;
    EXPECT_TRUE(std::isfinite(imaging.blur_sigma_at(z))) << z;
  }
  cv::Mat half;
  cv::resize(depth, half, {kDofW / 2, kDofH / 2}, 0, 0, cv::INTER_NEAREST);
  EXPECT_TRUE(estimate_photo_imaging(photo, half).defocus.found) << "a depth map of another size is resized";
  EXPECT_THROW(estimate_photo_imaging(photo, cv::Mat(photo.size(), CV_64F, cv::Scalar(2.0))), std::invalid_argument);
}

TEST(PhotoImaging, APropPastedIntoANoisyPhotoGetsItsNoise) {
  const double sigma_levels = 5.0;
  const cv::Mat photo =
      to_linear(noisy_8bit(to_display(shapes_photo(9)), 0.0, std::pow(sigma_levels / 255.0, 2), 16));
  cv::Mat coverage = cv::Mat::zeros(kH, kW, CV_32F);
  coverage(cv::Rect(120, 80, 80, 80)).setTo(1.0f);
  cv::Mat composite = photo.clone();
  composite(cv::Rect(120, 80, 80, 80)).setTo(cv::Scalar(0.3, 0.3, 0.3));
  const PhotoImaging imaging = estimate_photo_imaging(photo);
  ASSERT_TRUE(imaging.noise_measured);
  CameraMatchReport report;
  const cv::Mat matched = match_camera(photo, composite, coverage, imaging, {}, 1.0, &report);
  ASSERT_EQ(report.steps.at(2).effect, "noise");
  EXPECT_TRUE(report.steps[2].applied) << report.steps[2].why;
  // The prop's pixels now carry the photo's noise; every other pixel is untouched.
  cv::Mat display = to_display(matched), quantised;
  display.convertTo(quantised, CV_8UC3, 255.0);
  quantised.convertTo(display, CV_32FC3, 1.0 / 255.0);
  cv::Mat inside = cv::Mat::zeros(kH, kW, CV_8U);
  inside(cv::Rect(122, 82, 76, 76)).setTo(255);
  const NoiseLevelFunction on_prop = estimate_noise_level(display, inside);
  EXPECT_NEAR(on_prop.median_8bit(), sigma_levels, 0.2 * sigma_levels);
  cv::Mat outside = ~(coverage > 0);
  EXPECT_EQ(cv::norm(matched, photo, cv::NORM_INF, outside), 0.0);
  // Deterministic.
  EXPECT_EQ(cv::norm(match_camera(photo, composite, coverage, imaging, {}, 1.0), matched, cv::NORM_INF), 0.0);
}

TEST(PhotoImaging, ACleanSharpPhotoChangesNothing) {
  const cv::Mat photo = to_linear(noisy_8bit(to_display(shapes_photo(10)), 0.0, 0.0, 17));
  cv::Mat composite = photo.clone(), coverage = cv::Mat::zeros(kH, kW, CV_32F);
  composite(cv::Rect(100, 100, 30, 30)).setTo(cv::Scalar(0.5, 0.5, 0.5));
  coverage(cv::Rect(100, 100, 30, 30)).setTo(1.0f);
  const PhotoImaging imaging = estimate_photo_imaging(photo);
  CameraMatchReport report;
  const cv::Mat matched = match_camera(photo, composite, coverage, imaging, {}, 2.2, &report);
  EXPECT_EQ(cv::norm(matched, composite, cv::NORM_INF), 0.0);
  for (const auto& s : report.steps) EXPECT_FALSE(s.applied) << s.effect << ": " << s.why;
}

// Hard cases: tiny, constant, saturated and non-finite photos give finite
// "not measured" estimates, never a throw or NaN.
TEST(PhotoImaging, DegeneratePhotosAreNotMeasured) {
  cv::Mat nan_photo(40, 40, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  nan_photo.at<cv::Vec3f>(5, 5) = {std::nanf(""), INFINITY, -INFINITY};
  for (const cv::Mat& photo : {cv::Mat(1, 1, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5)),
                               cv::Mat(3, 200, CV_32FC3, cv::Scalar(0.2, 0.2, 0.2)),
                               cv::Mat(240, 320, CV_32FC3, cv::Scalar(0.0, 0.0, 0.0)),
                               cv::Mat(240, 320, CV_32FC3, cv::Scalar(1.0, 1.0, 1.0)), nan_photo}) {
    const PhotoImaging imaging = estimate_photo_imaging(photo);
    EXPECT_FALSE(imaging.blur_measured);
    EXPECT_TRUE(std::isfinite(imaging.blur_sigma_px));
    for (const auto& bin : imaging.noise.sigma)
      for (float s : bin) EXPECT_TRUE(std::isfinite(s));
    const cv::Mat out = match_camera(photo, photo, cv::Mat::ones(photo.size(), CV_32F), imaging, {}, 2.2);
    EXPECT_EQ(out.size(), photo.size());
  }
  EXPECT_THROW(estimate_photo_imaging(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(estimate_photo_imaging(cv::Mat(4, 4, CV_8UC3)), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::render
