// Hard cases of the scene classifier: degenerate photos give a finite,
// deterministic score; bad models, descriptors and training sets are clear
// errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "propcam/inference/scene_class_knn.h"
#include "propcam/inference/scene_classifier.h"

namespace propcam::inference {
namespace {

const SceneClassifier& committed() {
  static const SceneClassifier c = SceneClassifier::load(default_scene_classifier_path());
  return c;
}

void expect_finite_and_deterministic(const cv::Mat& photo) {
  const std::vector<float> d = appearance_descriptor(photo);
  const double a = committed().indoor_score(d);
  EXPECT_TRUE(std::isfinite(a));
  EXPECT_EQ(a, committed().indoor_score(d));
}

TEST(SceneClassifierHardCases, BlackPhoto) { expect_finite_and_deterministic(cv::Mat(120, 160, CV_32FC3, cv::Scalar(0, 0, 0))); }

TEST(SceneClassifierHardCases, SaturatedPhoto) {
  expect_finite_and_deterministic(cv::Mat(120, 160, CV_32FC3, cv::Scalar(50, 50, 50)));
}

TEST(SceneClassifierHardCases, TinyNoisyPhoto) {
  cv::Mat photo(16, 16, CV_32FC3);
  cv::randu(photo, 0.f, 1.f);
  expect_finite_and_deterministic(photo);
}

TEST(SceneClassifierHardCases, WrongOrNonFiniteDescriptorIsAClearError) {
  EXPECT_THROW(committed().indoor_score(std::vector<float>(3, 0.f)), std::invalid_argument);
  std::vector<float> d(kAppearanceDescriptorLength, 0.f);
  d[5] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(committed().indoor_score(d), std::invalid_argument);
}

TEST(SceneClassifierHardCases, MissingOrBrokenModelNamesTheFile) {
  const std::string dir = ::testing::TempDir() + "/scene_classifier_bad";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  try {
    SceneClassifier::load(dir + "/absent.yml.gz");
    FAIL() << "a missing model loaded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("absent.yml.gz"), std::string::npos) << e.what();
  }
  std::ofstream(dir + "/broken.yml") << "%YAML:1.0\n---\nversion: 1\nmean: [1, 2]\n";
  EXPECT_THROW(SceneClassifier::load(dir + "/broken.yml"), std::runtime_error);
  std::ofstream(dir + "/garbage.yml") << "\x01\x02 not yaml at all {{{";
  EXPECT_THROW(SceneClassifier::load(dir + "/garbage.yml"), std::runtime_error);
}

TEST(SceneClassifierHardCases, OneClassOrNothingToTrainOnIsAClearError) {
  SceneReferenceSet refs;
  refs.add({std::vector<float>(kAppearanceDescriptorLength, 0.1f), true, kRenderedGroup});
  refs.add({std::vector<float>(kAppearanceDescriptorLength, 0.2f), true, kRenderedGroup});
  EXPECT_THROW(SceneClassifier::train(refs), std::invalid_argument);
  EXPECT_THROW(SceneClassifier::train(SceneReferenceSet{}), std::invalid_argument);
  SceneClassifierOptions bad;
  bad.c = 0;
  refs.add({std::vector<float>(kAppearanceDescriptorLength, 0.3f), false, kRenderedGroup});
  EXPECT_THROW(SceneClassifier::train(refs, -2, bad), std::invalid_argument);
}

TEST(SceneClassifierHardCases, IdenticalDescriptorsOfBothClassesTrainToAFiniteScore) {
  // Nothing tells the classes apart: the model must still be finite.
  SceneReferenceSet refs;
  const std::vector<float> same(kAppearanceDescriptorLength, 0.25f);
  refs.add({same, true, kRenderedGroup});
  refs.add({same, false, kRenderedGroup});
  const SceneClassifier c = SceneClassifier::train(refs);
  EXPECT_TRUE(std::isfinite(c.indoor_score(same)));
}

}  // namespace
}  // namespace propcam::inference
