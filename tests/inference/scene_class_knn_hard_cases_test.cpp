#include <gtest/gtest.h>

#include <cmath>

#include "propcam/inference/scene_class_knn.h"

namespace propcam::inference {
namespace {

const DepthDatabase& database() {
  static const DepthDatabase db = DepthDatabase::load(default_depth_database_path());
  return db;
}

void expect_finite_and_deterministic(const cv::Mat& photo) {
  const KnnSceneClass a = classify_indoor_knn(photo, database());
  const KnnSceneClass b = classify_indoor_knn(photo, database());
  EXPECT_EQ(a.k, 7);
  EXPECT_TRUE(std::isfinite(a.indoor_share));
  EXPECT_GE(a.indoor_share, 0.0);
  EXPECT_LE(a.indoor_share, 1.0);
  EXPECT_EQ(a.indoor, b.indoor);
  EXPECT_EQ(a.indoor_share, b.indoor_share);
}

TEST(SceneClassKnnHardCases, BlackPhoto) { expect_finite_and_deterministic(cv::Mat(120, 160, CV_32FC3, cv::Scalar(0, 0, 0))); }

TEST(SceneClassKnnHardCases, TinyPhoto) {
  cv::Mat photo(16, 16, CV_32FC3);
  cv::randu(photo, 0.f, 1.f);
  expect_finite_and_deterministic(photo);
}

TEST(SceneClassKnnHardCases, SaturatedPhoto) {
  expect_finite_and_deterministic(cv::Mat(120, 160, CV_32FC3, cv::Scalar(50, 50, 50)));
}

TEST(SceneClassKnnHardCases, NonFinitePhotoIsFinite) {
  cv::Mat photo(64, 64, CV_32FC3, cv::Scalar(0.3, 0.3, 0.3));
  photo.at<cv::Vec3f>(5, 5) = cv::Vec3f(NAN, INFINITY, -1.f);
  expect_finite_and_deterministic(photo);
}

TEST(SceneClassKnnHardCases, BadInputsAreRejected) {
  EXPECT_THROW(classify_indoor_knn(cv::Mat(8, 8, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5)), DepthDatabase{}),
               std::invalid_argument);
  EXPECT_THROW(classify_indoor_knn(cv::Mat(8, 8, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5)), database(), 0),
               std::invalid_argument);
  EXPECT_THROW(classify_indoor_knn(cv::Mat(), database()), std::invalid_argument);
}

TEST(SceneClassKnnHardCases, TwoExampleDatabaseTieGoesIndoor) {
  // Fewer examples than k, evenly split: every example votes and the tie is decided.
  DepthDatabase db;
  for (bool indoor : {true, false}) {
    DepthExample e = database().at(0);
    e.indoor = indoor;
    db.add(e);
  }
  const KnnSceneClass c = classify_indoor_knn(cv::Mat(32, 32, CV_32FC3, cv::Scalar(0.2, 0.2, 0.2)), db, 7);
  EXPECT_EQ(c.k, 2);
  EXPECT_DOUBLE_EQ(c.indoor_share, 0.5);
  EXPECT_TRUE(c.indoor);  // a tie goes indoor
}

}  // namespace
}  // namespace propcam::inference
