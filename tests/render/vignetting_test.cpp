// The lens's vignetting: fitted on flat fields we make with a known fall-off,
// and given to the prop so that it is darkened as the photo around it was.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <cmath>
#include <random>
#include <vector>

#include "propcam/capture/image_file.h"
#include "propcam/render/photo_imaging.h"
#include "propcam/render/vignetting.h"

namespace propcam::render {
namespace {

constexpr int kW = 640, kH = 480;
// A lens that passes 60% of the centre's light in the corners.
const Vignetting kLens{-0.55, 0.04};

// `value` (linear) under the lens and a light with its own gradient
// (`gradient` per half-frame to the right), through an 8-bit sRGB file with
// `noise_levels` of sensor noise.
cv::Mat flat_field(const Vignetting& lens, double value, double gradient, double noise_levels, uint32_t seed) {
  cv::Mat linear(kH, kW, CV_32FC3);
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c) {
      const double light = value * (1.0 + gradient * (c + 0.5 - 0.5 * kW) / (0.5 * kW));
      const float v = static_cast<float>(light * lens.at_pixel(c, r, {kW, kH}));
      linear.at<cv::Vec3f>(r, c) = {v, 0.95f * v, 0.9f * v};
    }
  cv::Mat srgb8 = capture::linear_to_srgb8(linear);
  if (noise_levels > 0) {
    cv::Mat noise(srgb8.size(), CV_32FC3), display;
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, noise_levels);
    srgb8.convertTo(display, CV_32FC3);
    display += noise;
    display.convertTo(srgb8, CV_8UC3);
  }
  return capture::srgb8_to_linear(srgb8);
}

TEST(Vignetting, AKnownFallOffIsFittedThroughTheLightsGradientAndNoise) {
  const VignettingFit fit = fit_vignetting({flat_field(kLens, 0.5, 0.1, 2.0, 1)});
  for (const double r : {0.25, 0.5, 0.75, 1.0})
    EXPECT_NEAR(fit.vignetting.at_radius(r), kLens.at_radius(r), 0.01) << "radius " << r;
  EXPECT_LT(fit.residual_rms, 0.01);
  EXPECT_NEAR(fit.gradient, 0.1 * std::hypot(kW, kH) / kW, 0.02) << "the light's own gradient is taken out";
  EXPECT_GT(fit.pixels, 1000);
  // Several frames are averaged; a lens without fall-off reads as none.
  const VignettingFit none =
      fit_vignetting({flat_field(Vignetting{}, 0.4, 0.0, 3.0, 2), flat_field(Vignetting{}, 0.4, 0.0, 3.0, 3)});
  EXPECT_NEAR(none.vignetting.at_radius(1.0), 1.0, 0.01);
}

// Hard cases: what is not a flat field, or cannot be read, is a clear error.
TEST(Vignetting, WhatIsNotAReadableFlatFieldIsAClearError) {
  const auto message = [](const std::vector<cv::Mat>& frames) {
    try {
      fit_vignetting(frames);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // A scene: a bright window beside a dark wall.
  cv::Mat scene = flat_field(kLens, 0.3, 0.0, 1.0, 4);
  scene(cv::Rect(60, 40, 200, 260)) *= 3.0;
  EXPECT_NE(message({scene}).find("not a flat field"), std::string::npos) << message({scene});
  EXPECT_NE(message({cv::Mat(kH, kW, CV_32FC3, cv::Scalar::all(0.0))}).find("black nor clipped"), std::string::npos);
  EXPECT_NE(message({cv::Mat(kH, kW, CV_32FC3, cv::Scalar::all(1.0))}).find("black nor clipped"), std::string::npos);
  EXPECT_NE(message({cv::Mat(kH, kW, CV_32FC3, cv::Scalar::all(0.015))}).find("too dark"), std::string::npos);
  EXPECT_NE(message({cv::Mat(20, 20, CV_32FC3, cv::Scalar::all(0.5))}).find("smaller"), std::string::npos);
  cv::Mat nan_frame(kH, kW, CV_32FC3, cv::Scalar::all(0.5));
  nan_frame.at<cv::Vec3f>(3, 3)[1] = std::nanf("");
  EXPECT_NE(message({nan_frame}).find("non-finite"), std::string::npos);
  EXPECT_NE(message({cv::Mat(kH, kW, CV_32FC3, cv::Scalar::all(0.5)), cv::Mat(kW, kH, CV_32FC3, cv::Scalar::all(0.5))})
                .find("differ in size"),
            std::string::npos);
  EXPECT_NE(message({cv::Mat(kH, kW, CV_8UC3, cv::Scalar::all(128))}).find("CV_32FC3"), std::string::npos);
  EXPECT_NE(message({}).find("no flat-field"), std::string::npos);
}

TEST(Vignetting, NoLensGainsOutsideTheirBounds) {
  EXPECT_EQ(vignetting_problem(kLens), "");
  EXPECT_EQ(vignetting_problem(Vignetting{}), "");
  EXPECT_NE(vignetting_problem(Vignetting{std::nan(""), 0}), "");
  EXPECT_NE(vignetting_problem(Vignetting{0, INFINITY}), "");
  EXPECT_NE(vignetting_problem(Vignetting{-4.0, 0}), "") << "gain exp(-4) = 0.018 in the corners";
  EXPECT_NE(vignetting_problem(Vignetting{1.0, 0}), "") << "gain 2.7 in the corners";
  EXPECT_NE(vignetting_problem(Vignetting{0, -6.0}), "");
  EXPECT_DOUBLE_EQ(kLens.at_radius(0.0), 1.0);
  EXPECT_DOUBLE_EQ(kLens.at_radius(3.0), kLens.at_radius(1.0)) << "clamped to the frame";
  EXPECT_DOUBLE_EQ(kLens.at_pixel(-0.5 + 0.5 * kW, -0.5 + 0.5 * kH, {kW, kH}), 1.0);
  EXPECT_DOUBLE_EQ(kLens.at_pixel(-0.5, -0.5, {kW, kH}), kLens.at_radius(1.0));
}

// Known truth: a grey card in a photo through the lens, and a prop of the
// same grey with its shadow rendered from the lens-free scene. Matched, the
// prop is the photo and the shadow halves the photo's pixels, as the lens
// would have given them.
TEST(Vignetting, APropInAVignettedPhotoIsDarkenedAsThePhotoWas) {
  const cv::Mat photo = capture::srgb8_to_linear(capture::linear_to_srgb8(
      cv::Mat(kH, kW, CV_32FC3, cv::Scalar::all(0.4))));  // an 8-bit file's grey, the prop's value
  const cv::Mat vignetted = vignette_image(photo, kLens);
  EXPECT_LT(cv::norm(devignette(vignetted, kLens), photo, cv::NORM_INF), 1e-6);
  // The prop: a corner square (a soft edge on its left) of the grey, unvignetted.
  const cv::Rect corner(kW - 120, kH - 100, 120, 100);
  cv::Mat coverage = cv::Mat::zeros(kH, kW, CV_32F);
  coverage(corner).setTo(1.0f);
  coverage(cv::Rect(corner.x, corner.y, 1, corner.height)).setTo(0.5f);
  cv::Mat composite = vignetted.clone();
  for (int r = corner.y; r < corner.y + corner.height; ++r)
    for (int c = corner.x; c < corner.x + corner.width; ++c) {
      const float m = coverage.at<float>(r, c);
      composite.at<cv::Vec3f>(r, c) = m * photo.at<cv::Vec3f>(r, c) + (1 - m) * vignetted.at<cv::Vec3f>(r, c);
    }
  // Its shadow beside it, from the lens-free scene (the grey halved): the
  // change, half the lens-free grey, taken from the photo's pixels as
  // composite_differential does.
  const cv::Rect shadow(corner.x - 40, corner.y, 40, corner.height);
  composite(shadow) -= 0.5 * photo(shadow);
  cv::Mat truth = vignetted.clone();
  truth(shadow) *= 0.5;
  const PhotoImaging imaging = estimate_photo_imaging(vignetted);  // a clean, edgeless photo: no blur, no noise
  CameraMatchOptions options;
  options.vignetting = kLens;
  options.vignetting_source = "test lens";
  CameraMatchReport report;
  const cv::Mat matched = match_camera(vignetted, composite, coverage, imaging, options, 1.0, &report);
  ASSERT_EQ(report.steps.size(), 3u);
  ASSERT_EQ(report.steps[1].effect, "vignette");
  EXPECT_TRUE(report.steps[1].applied) << report.steps[1].why;
  EXPECT_NE(report.steps[1].why.find("test lens"), std::string::npos) << report.steps[1].why;
  EXPECT_NEAR(report.vignette_gain, kLens.at_pixel(corner.x + 59.5, corner.y + 49.5, {kW, kH}), 1e-6);
  EXPECT_LT(cv::norm(matched, truth, cv::NORM_INF), 1e-5) << "the prop and its shadow darkened as the photo was";
  EXPECT_GT(cv::norm(composite(corner), truth(corner), cv::NORM_INF), 0.1) << "unmatched, the prop stands out";
  EXPECT_GT(cv::norm(composite(shadow), truth(shadow), cv::NORM_INF), 0.02) << "and its shadow is too deep";
  cv::Mat untouched = coverage == 0;
  untouched(shadow).setTo(0);
  EXPECT_EQ(cv::norm(matched, composite, cv::NORM_INF, untouched), 0.0) << "the rest is untouched";
  EXPECT_GT(cv::norm(composite, photo, cv::NORM_INF), 0.0) << "the caller's composite is left as it was";

  // Unknown, or a lens no calibration gives: not applied, and said why.
  for (const Vignetting& lens : {Vignetting{}, Vignetting{-9.0, 0.0}}) {
    options.vignetting = lens;
    const cv::Mat same = match_camera(vignetted, composite, coverage, imaging, options, 1.0, &report);
    EXPECT_FALSE(report.steps[1].applied);
    EXPECT_EQ(cv::norm(same, composite, cv::NORM_INF), 0.0) << report.steps[1].why;
  }
  EXPECT_NE(report.steps[1].why.find("unusable"), std::string::npos) << report.steps[1].why;
}

}  // namespace
}  // namespace propcam::render
