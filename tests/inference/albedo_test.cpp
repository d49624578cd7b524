#include <gtest/gtest.h>

#include <cmath>

#include "propcam/inference/albedo.h"
#include "propcam/inference/poisson.h"

namespace propcam::inference {
namespace {

TEST(Poisson, IntegratesExactGradientsBackToTheField) {
  for (const cv::Size size : {cv::Size(33, 21), cv::Size(40, 30), cv::Size(1, 1), cv::Size(2, 1)}) {
    cv::Mat u(size, CV_64F);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) u.at<double>(y, x) = std::sin(0.3 * x) + 0.05 * y * y - 0.2 * x * y / 10;
    cv::Mat gx(size, CV_64F, cv::Scalar(0)), gy(size, CV_64F, cv::Scalar(0));
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) {
        if (x + 1 < size.width) gx.at<double>(y, x) = u.at<double>(y, x + 1) - u.at<double>(y, x);
        if (y + 1 < size.height) gy.at<double>(y, x) = u.at<double>(y + 1, x) - u.at<double>(y, x);
      }
    const cv::Mat back = integrate_gradients(gx, gy);
    const cv::Mat expected = u - cv::mean(u)[0];
    EXPECT_LT(cv::norm(back, expected, cv::NORM_INF), 1e-8) << size;
  }
  EXPECT_THROW(integrate_gradients(cv::Mat(), cv::Mat()), std::invalid_argument);
}

// Two large paints (a dark blue wall beside a light red one) under smooth
// light: Retinex gives the paints back; dividing by blurred luminance leaves
// a halo where the blur mixes the two sides.
TEST(Albedo, RetinexSeparatesPaintFromSmoothLight) {
  cv::Mat truth(96, 128, CV_32FC3), photo(96, 128, CV_32FC3);
  for (int y = 0; y < 96; ++y)
    for (int x = 0; x < 128; ++x) {
      const bool a = x >= 64;
      const cv::Vec3f albedo = a ? cv::Vec3f(0.8f, 0.5f, 0.4f) : cv::Vec3f(0.1f, 0.15f, 0.3f);
      const float light = 0.3f + 0.5f * std::exp(-((x - 90) * (x - 90) + (y - 20) * (y - 20)) / 4000.f);
      truth.at<cv::Vec3f>(y, x) = albedo;
      photo.at<cv::Vec3f>(y, x) = albedo * light;
    }
  StageReport report;
  AlbedoOptions retinex_options;
  retinex_options.method = AlbedoOptions::Method::Retinex;
  const cv::Mat retinex = estimate_albedo(photo, retinex_options, report);
  AlbedoOptions baseline;
  baseline.method = AlbedoOptions::Method::BlurredShading;
  const cv::Mat blurred = estimate_albedo(photo, baseline, report);
  EXPECT_LT(local_mse(retinex, truth), 0.01);
  // Over the whole image (one scale for all): the blur leaves the light's
  // large-scale falloff and halos at paint edges in the albedo; Retinex does not.
  auto global_error = [&](const cv::Mat& est) {
    const double alpha = est.dot(truth) / est.dot(est);
    return cv::norm(est * alpha, truth) / cv::norm(truth);
  };
  EXPECT_LT(global_error(retinex), 0.1);  // the light's step across the paint edge is taken as paint
  EXPECT_LT(global_error(retinex), 0.5 * global_error(blurred));
  EXPECT_EQ(report.stage, "albedo");
}

TEST(Albedo, HardCasesStayFiniteAndBounded) {
  StageReport report;
  for (const auto method : {AlbedoOptions::Method::Retinex, AlbedoOptions::Method::BlurredShading})
  for (const bool grey_world : {false, true}) {
  AlbedoOptions options;
  options.method = method;
  options.grey_world = grey_world;
  for (const cv::Mat& photo : {cv::Mat(cv::Size(16, 12), CV_32FC3, cv::Scalar(0, 0, 0)),
                               cv::Mat(cv::Size(16, 12), CV_32FC3, cv::Scalar(1, 1, 1)),
                               cv::Mat(cv::Size(1, 1), CV_32FC3, cv::Scalar(0.3, 0.2, 0.1)),
                               cv::Mat(cv::Size(3, 2), CV_32FC3, cv::Scalar(-1, 5, 0))}) {
    const cv::Mat a = estimate_albedo(photo, options, report);
    EXPECT_TRUE(cv::checkRange(a, true, nullptr, 0.0, 0.951)) << photo.size();
  }
  cv::Mat nan_photo(8, 8, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  nan_photo.at<cv::Vec3f>(3, 3) = {std::nanf(""), 1.f, 1.f};
  EXPECT_TRUE(cv::checkRange(estimate_albedo(nan_photo, options, report)));
  EXPECT_THROW(estimate_albedo(cv::Mat(), options, report), std::invalid_argument);
  }
}

// A grey-and-white room under a 3000 K lamp's orange: with grey world the
// albedo's mean is grey (the cast is left to the lights); without it, orange.
// A photo with no blue at all gets the largest gain, and stays finite.
TEST(Albedo, GreyWorldLeavesTheCastToTheLights) {
  const cv::Vec3f lamp(1.0f, 0.6f, 0.3f);
  cv::Mat photo(48, 64, CV_32FC3);
  for (int y = 0; y < photo.rows; ++y)
    for (int x = 0; x < photo.cols; ++x) {
      const float paint = x < 32 ? 0.8f : 0.3f;
      const float light = 0.4f + 0.3f * static_cast<float>(y) / photo.rows;
      photo.at<cv::Vec3f>(y, x) = lamp * (paint * light);
    }
  for (const auto method : {AlbedoOptions::Method::Retinex, AlbedoOptions::Method::BlurredShading}) {
    AlbedoOptions options;
    options.method = method;
    StageReport report;
    const cv::Scalar cast = cv::mean(estimate_albedo(photo, options, report));
    EXPECT_GT(cast[0], 2.0 * cast[2]);
    options.grey_world = true;
    const cv::Scalar grey = cv::mean(estimate_albedo(photo, options, report));
    EXPECT_NEAR(grey[0], grey[1], 0.01 * grey[1]);
    EXPECT_NEAR(grey[2], grey[1], 0.01 * grey[1]);
    ASSERT_TRUE(report.details.contains("grey_world_gains"));
    EXPECT_GT(report.details["grey_world_gains"][2].get<double>(), 1.0);
  }
  cv::Mat no_blue = photo.clone();
  no_blue.forEach<cv::Vec3f>([](cv::Vec3f& p, const int*) { p[2] = 0.f; });
  AlbedoOptions options;
  options.grey_world = true;
  StageReport report;
  const cv::Mat a = estimate_albedo(no_blue, options, report);
  EXPECT_TRUE(cv::checkRange(a, true, nullptr, 0.0, 0.951));
  EXPECT_DOUBLE_EQ(report.details["grey_world_gains"][2].get<double>(), kMaxGreyWorldGain);
}

TEST(Albedo, LocalMseIsZeroForAScaledTruthAndOneForZero) {
  cv::Mat truth(40, 40, CV_32FC3);
  cv::randu(truth, 0.1, 0.9);
  EXPECT_NEAR(local_mse(truth * 0.5, truth), 0.0, 1e-12);
  EXPECT_NEAR(local_mse(cv::Mat::zeros(40, 40, CV_32FC3), truth), 1.0, 1e-12);
}

}  // namespace
}  // namespace propcam::inference
