#include <gtest/gtest.h>

#include <limits>

#include "propcam/render/depth_of_field.h"

namespace propcam::render {
namespace {

DepthOfField lens(double focus, double aperture) {
  DepthOfField d;
  d.focus_distance_m = focus;
  d.aperture_m = aperture;
  return d;
}

TEST(DepthOfField, CircleOfConfusionFollowsTheThinLens) {
  const DepthOfField d = lens(2.0, 0.01);
  EXPECT_EQ(circle_of_confusion_px(2.0, 500, d), 0.0);
  EXPECT_NEAR(circle_of_confusion_px(1.0, 500, d), 500 * 0.01 * 0.5, 1e-12);
  EXPECT_NEAR(circle_of_confusion_px(std::numeric_limits<double>::infinity(), 500, d), 500 * 0.01 * 0.5, 1e-12);
  EXPECT_LE(circle_of_confusion_px(0.01, 500, d), d.max_blur_px) << "clamped";
  EXPECT_EQ(circle_of_confusion_px(1.0, 500, lens(2.0, 0.0)), 0.0) << "a pinhole has no blur";
}

TEST(DepthOfField, AConstantImageStaysConstantAndThePinholeChangesNothing) {
  const cv::Mat img(40, 50, CV_32FC3, cv::Scalar(0.2, 0.4, 0.6));
  cv::Mat depth(40, 50, CV_32F);
  cv::randu(depth, 0.5, 10.0);
  const cv::Mat out = apply_depth_of_field(img, depth, 400, lens(2.0, 0.02));
  EXPECT_LT(cv::norm(out, img, cv::NORM_INF), 1e-5);
  cv::Mat noise(40, 50, CV_32FC3);
  cv::randu(noise, 0.0, 1.0);
  EXPECT_EQ(cv::norm(apply_depth_of_field(noise, depth, 400, lens(2.0, 0.0)), noise, cv::NORM_INF), 0.0);
}

TEST(DepthOfField, TheFocusPlaneStaysSharpAndTheBackgroundBlurs) {
  // Left half: a checkerboard at the focus distance; right half: one far away.
  cv::Mat img(32, 64, CV_32FC3), depth(32, 64, CV_32F);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 64; ++x) {
      const float v = ((x / 2 + y / 2) % 2) ? 1.f : 0.f;
      img.at<cv::Vec3f>(y, x) = {v, v, v};
      depth.at<float>(y, x) = x < 32 ? 2.f : 50.f;
    }
  const cv::Mat out = apply_depth_of_field(img, depth, 400, lens(2.0, 0.02));
  // Sharp foreground: unchanged, even at its edge next to the blurred background.
  EXPECT_EQ(cv::norm(out.colRange(0, 32), img.colRange(0, 32), cv::NORM_INF), 0.0);
  // Blurred background: the checkerboard averages toward grey.
  cv::Scalar mean, stddev;
  cv::meanStdDev(out(cv::Rect(40, 8, 16, 16)), mean, stddev);
  EXPECT_NEAR(mean[0], 0.5, 0.1);
  EXPECT_LT(stddev[0], 0.15);
}

TEST(DepthOfField, HardCasesStayFinite) {
  cv::Mat img(5, 7, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  cv::Mat depth(5, 7, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  depth.at<float>(2, 2) = -1.f;
  depth.at<float>(1, 1) = 0.f;
  EXPECT_TRUE(cv::checkRange(apply_depth_of_field(img, depth, 100, lens(1.0, 0.05))));
  const cv::Mat one(1, 1, CV_32FC3, cv::Scalar(1, 2, 3));
  EXPECT_TRUE(cv::checkRange(apply_depth_of_field(one, cv::Mat(1, 1, CV_32F, cv::Scalar(3.f)), 1, lens(1.0, 0.5))));
  EXPECT_THROW(apply_depth_of_field(img, cv::Mat(4, 4, CV_32F), 100, lens(1.0, 0.05)), std::invalid_argument);
  EXPECT_THROW(apply_depth_of_field(img, depth, 100, lens(1.0, -1.0)), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::render
