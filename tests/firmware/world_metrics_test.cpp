#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "worlds/world_metrics.h"

namespace propcam::firmware {
namespace {

cv::Mat ramp(int w, int h) {
  cv::Mat m(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      m.at<cv::Vec3f>(y, x) = cv::Vec3f(0.2f + 0.6f * x / w, 0.3f + 0.4f * y / h, 0.5f + 0.1f * std::sin(0.3f * x));
  return m;
}

TEST(WorldMetrics, SsimIsOneForTheSameImageAndFallsWithNoise) {
  const cv::Mat a = ramp(64, 48);
  EXPECT_NEAR(ssim_in_mask(a, a, {}), 1.0, 1e-9);
  cv::Mat noisy = a.clone();
  cv::RNG rng(3);
  cv::Mat noise(a.size(), CV_32FC3);
  rng.fill(noise, cv::RNG::NORMAL, 0, 0.1);
  noisy += noise;
  const double s = ssim_in_mask(a, noisy, {});
  EXPECT_LT(s, 0.8);
  EXPECT_GT(s, 0.0);
  EXPECT_TRUE(std::isnan(ssim_in_mask(a, a, cv::Mat::zeros(a.size(), CV_8U)))) << "an empty region has no score";
}

TEST(WorldMetrics, DepthAbsRelIgnoresScaleAndSeesShapeErrors) {
  cv::Mat truth(10, 10, CV_32F), est(10, 10, CV_32F);
  for (int i = 0; i < 100; ++i) truth.at<float>(i) = 1.0f + 0.05f * i;
  est = truth * 3.0;  // right shape, wrong scale
  EXPECT_NEAR(depth_abs_rel_median_scaled(est, truth, {}, 1e3), 0.0, 1e-6);
  est.at<float>(0) = 100.f;  // one pixel far off
  EXPECT_GT(depth_abs_rel_median_scaled(est, truth, {}, 1e3), 0.1);
  EXPECT_TRUE(std::isnan(depth_abs_rel_median_scaled(cv::Mat::zeros(10, 10, CV_32F), truth, {}, 1e3)));
}

TEST(WorldMetrics, LmseForgivesAScalePerWindowButNotWrongShading) {
  const cv::Mat truth = ramp(64, 48);
  EXPECT_NEAR(albedo_lmse(truth * 0.4, truth, {}, 8), 0.0, 1e-9) << "a global scale is free";
  cv::Mat shaded = truth.clone();
  for (int y = 0; y < shaded.rows; ++y)
    for (int x = 0; x < shaded.cols; ++x) shaded.at<cv::Vec3f>(y, x) *= (x % 16 < 8 ? 1.f : 0.2f);
  const double wrong = albedo_lmse(shaded, truth, {}, 8);
  EXPECT_GT(wrong, 0.01);
  EXPECT_LE(albedo_lmse(cv::Mat::zeros(truth.size(), CV_32FC3), truth, {}, 8), 1.0 + 1e-9) << "zero scores 1";
  EXPECT_TRUE(std::isnan(albedo_lmse(truth, cv::Mat::zeros(truth.size(), CV_32FC3), {}, 8)));
}

TEST(WorldMetrics, CameraErrorsSeparateFocalTiltAndHeight) {
  render::PinholeCamera truth = render::pinhole_with_fov(320, 240, 60);
  truth.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0.3, -0.2, 0.0);
  truth.center_world = {0, 1.5, 0};
  render::PinholeCamera est = truth;
  est.fx *= 1.1;
  est.R_world_from_cam = render::rotation_from_yaw_pitch_roll(1.2, -0.2 + 5 * std::numbers::pi / 180, 0.0);
  est.center_world = {0, 1.8, 0};
  const CameraErrors e = camera_errors(est, truth);
  EXPECT_NEAR(e.focal_rel, 0.1, 1e-9);
  EXPECT_NEAR(e.up_deg, 5.0, 1e-6) << "a turn about the vertical is no camera error";
  EXPECT_NEAR(e.pitch_deg, 5.0, 1e-6);
  EXPECT_NEAR(e.roll_deg, 0.0, 1e-6);
  EXPECT_NEAR(e.height_rel, 0.2, 1e-9);
}

TEST(WorldMetrics, EmittersAreCountedObjectByObject) {
  cv::Mat truth = cv::Mat::zeros(100, 100, CV_8U);
  cv::rectangle(truth, {10, 10, 10, 10}, 255, cv::FILLED);  // a lamp, 1% of the frame
  cv::rectangle(truth, {60, 10, 20, 5}, 255, cv::FILLED);   // a panel, 1%
  truth.at<uint8_t>(90, 90) = 255;                           // a speck: don't care
  cv::Mat est = cv::Mat::zeros(100, 100, CV_8U);
  cv::rectangle(est, {12, 12, 4, 4}, 255, cv::FILLED);   // the lamp's core: found
  cv::rectangle(est, {40, 60, 6, 6}, 255, cv::FILLED);   // a lit wall: wrong
  est.at<uint8_t>(90, 90) = 255;                          // the speck: neither
  const EmitterCounts c = count_emitters(truth, est);
  EXPECT_EQ(c.truth, 2);
  EXPECT_EQ(c.found, 1);
  EXPECT_EQ(c.detected, 2);
  EXPECT_EQ(c.right, 1);
  const EmitterCounts none = count_emitters(truth, {});
  EXPECT_EQ(none.found, 0);
  EXPECT_EQ(none.detected, 0);
}

TEST(WorldMetrics, AnglesOfZeroOrNonFiniteVectorsAreTheWorst) {
  EXPECT_NEAR(angle_between_deg({1, 0, 0}, {0, 1, 0}), 90.0, 1e-9);
  EXPECT_EQ(angle_between_deg({0, 0, 0}, {0, 1, 0}), 180.0);
  EXPECT_EQ(angle_between_deg({NAN, 0, 0}, {0, 1, 0}), 180.0);
}

}  // namespace
}  // namespace propcam::firmware
