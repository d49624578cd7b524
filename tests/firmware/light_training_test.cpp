// The light classifier's training set: the panoramas' views and the Blender
// world's tune photos, subsampled the same way wherever it is rebuilt (the
// committed model, the panorama world's leave-one-out models, bench lights'
// folds).
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "tools/light_training.h"

namespace propcam::firmware {
namespace {

inference::LabelledFeatures rows(const std::vector<int>& labels, float first_value) {
  inference::LabelledFeatures f;
  f.features = cv::Mat(static_cast<int>(labels.size()), 2, CV_32F);
  for (int r = 0; r < f.features.rows; ++r) f.features.at<float>(r, 0) = first_value + static_cast<float>(r);
  f.labels = cv::Mat(labels, true).reshape(1, static_cast<int>(labels.size()));
  return f;
}

TEST(LightTraining, EverySourceAndEveryNthOtherWithTheCountRunningAcrossGroups) {
  const inference::LabelledFeatures a = rows({0, 1, 0, 0}, 0), b = rows({0, 0, 1, 0, 0}, 100);
  const inference::LabelledFeatures set = light_training_set({&a, &b}, 3);
  // Negatives counted 0..6 over both groups: the 0th (a0) and 3rd (b0) and 6th (b4) kept.
  std::vector<float> kept;
  for (int r = 0; r < set.features.rows; ++r) kept.push_back(set.features.at<float>(r, 0));
  EXPECT_EQ(kept, (std::vector<float>{0, 1, 100, 102, 104}));
  EXPECT_EQ(cv::countNonZero(set.labels), 2);
  ASSERT_EQ(set.labels.rows, set.features.rows);
}

TEST(LightTraining, EmptyGroupsGiveAnEmptySet) {
  const inference::LabelledFeatures set = light_training_set({}, 8);
  EXPECT_EQ(set.features.rows, 0);
  EXPECT_EQ(set.labels.rows, 0);
}

TEST(LightTraining, ABlenderScenesFoldIsItsSeedModuloTheFolds) {
  EXPECT_EQ(blender_light_fold("scene_1", 4), 1);
  EXPECT_EQ(blender_light_fold("scene_44", 4), 0);
  EXPECT_EQ(blender_light_fold("scene_65", 4), 1);
  EXPECT_EQ(blender_light_fold("scene_7", 1), 0);
  // A folder without a seed still lands in a fold, the same one every time.
  const int f = blender_light_fold("living_room", 4);
  EXPECT_GE(f, 0);
  EXPECT_LT(f, 4);
  EXPECT_EQ(blender_light_fold("living_room", 4), f);
}

}  // namespace
}  // namespace propcam::firmware
