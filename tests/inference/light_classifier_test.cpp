#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>

#include "propcam/capture/image_file.h"
#include "propcam/inference/light_classifier.h"

namespace propcam::inference {
namespace {

namespace fs = std::filesystem;

// A dim room-like photo with one blown-out panel near the top.
cv::Mat photo_with_panel() {
  cv::Mat photo(240, 320, CV_32FC3, cv::Scalar(0.12, 0.1, 0.08));
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) photo.at<cv::Vec3f>(y, x) *= 0.6f + 0.8f * y / 240.f;  // darker up
  photo(cv::Rect(120, 20, 80, 30)).setTo(cv::Scalar(8, 8, 8));
  return photo;
}

TEST(LightClassifier, FeaturesHaveOneRowPerSuperpixelAndAreFinite) {
  const SuperpixelFeatures f = superpixel_features(photo_with_panel());
  EXPECT_GT(f.count, 100);
  EXPECT_EQ(f.features.rows, f.count);
  EXPECT_EQ(f.features.cols, light_feature_count());
  EXPECT_TRUE(cv::checkRange(f.features));
  double lo, hi;
  cv::minMaxLoc(f.labels, &lo, &hi);
  EXPECT_GE(lo, 0);
  EXPECT_LT(hi, f.count);
}

TEST(LightClassifier, TheCommittedModelFindsABlownOutPanelAndNotTheWalls) {
  const LightClassifier model = LightClassifier::load(default_light_classifier_path());
  const cv::Mat photo = photo_with_panel();
  const cv::Mat mask = model.source_mask(photo, {}) & threshold_source_mask(photo);
  const cv::Rect panel(120, 20, 80, 30);
  EXPECT_GT(cv::countNonZero(mask(panel)), panel.area() / 3);
  EXPECT_EQ(cv::countNonZero(mask) - cv::countNonZero(mask(panel)), 0);
}

TEST(LightClassifier, TrainsDeterministicallyAndRoundTripsThroughAFile) {
  // Two small panoramas' views: a sun in a sky, and a dim room with a lamp.
  cv::Mat sky(64, 128, CV_32FC3, cv::Scalar(0.3, 0.4, 0.6));
  sky(cv::Rect(32, 36, 64, 28)).setTo(cv::Scalar(0.1, 0.1, 0.08));  // ground
  cv::circle(sky, {60, 20}, 2, cv::Scalar(500, 480, 450), -1);
  const auto views = panorama_views(sky, 4, {0.0, 30.0}, 70.0, 160, 120);
  ASSERT_EQ(views.size(), 8u);
  const LabelledFeatures data = labelled_features(views);
  ASSERT_GT(cv::countNonZero(data.labels), 0);
  const LightClassifier a = LightClassifier::train(data.features, data.labels, 10, 6);
  const LightClassifier b = LightClassifier::train(data.features, data.labels, 10, 6);
  EXPECT_EQ(a.scores(data.features), b.scores(data.features));
  const std::string path = (fs::path(::testing::TempDir()) / "propcam_light_classifier.yml.gz").string();
  a.save(path);
  EXPECT_EQ(LightClassifier::load(path).scores(data.features), a.scores(data.features));
}

}  // namespace
}  // namespace propcam::inference
