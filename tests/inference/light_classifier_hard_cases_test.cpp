// Hard cases of the light classifier: finite, deterministic output or a clear error.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "propcam/inference/light_classifier.h"

namespace propcam::inference {
namespace {

namespace fs = std::filesystem;

void expect_finite_and_deterministic(const cv::Mat& photo) {
  const LightClassifier model = LightClassifier::load(default_light_classifier_path());
  const SuperpixelFeatures f = superpixel_features(photo);
  EXPECT_TRUE(cv::checkRange(f.features));
  const cv::Mat a = model.source_mask(photo, {});
  const cv::Mat b = model.source_mask(photo, {});
  ASSERT_EQ(a.size(), photo.size());
  EXPECT_EQ(cv::countNonZero(a != b), 0);
}

TEST(LightClassifierHardCases, BlackFrame) { expect_finite_and_deterministic(cv::Mat::zeros(120, 160, CV_32FC3)); }

TEST(LightClassifierHardCases, SaturatedFrame) {
  expect_finite_and_deterministic(cv::Mat(120, 160, CV_32FC3, cv::Scalar(40, 40, 40)));
}

TEST(LightClassifierHardCases, TinyFrameAndNonFinitePixels) {
  cv::Mat tiny(16, 16, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  tiny.at<cv::Vec3f>(3, 3) = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -1.f};
  expect_finite_and_deterministic(tiny);
  EXPECT_THROW(superpixel_features(cv::Mat::zeros(4, 4, CV_32FC3)), std::invalid_argument);
}

TEST(LightClassifierHardCases, MissingOrCorruptModelIsAClearError) {
  EXPECT_THROW(LightClassifier::load("/nonexistent/model.yml.gz"), std::runtime_error);
  const std::string junk = (fs::path(::testing::TempDir()) / "propcam_junk_model.yml").string();
  std::ofstream(junk) << "%YAML:1.0\nnot_a_forest: 3\n";
  EXPECT_THROW(LightClassifier::load(junk), std::runtime_error);
  cv::Mat features(4, light_feature_count(), CV_32F, cv::Scalar(0));
  EXPECT_THROW(LightClassifier::train(features, cv::Mat::zeros(4, 1, CV_32S)), std::invalid_argument);
  EXPECT_THROW(LightClassifier::train(features, cv::Mat::zeros(3, 1, CV_32S)), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::inference
