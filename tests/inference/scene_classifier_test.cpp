// The scene classifier (SVM on the appearance descriptor): the committed
// model is the one its references train, it survives a save and load, it
// classifies real views of panoramas it never saw, and the combined stage
// says it decided.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "propcam/capture/image_file.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/inference/scene_class_knn.h"
#include "propcam/inference/scene_classifier.h"
#include "propcam/render/panorama.h"
#include "files_in_dir.h"
#include "scene_class_fixtures.h"

namespace propcam::inference {
namespace {

using testing::blender_panorama;
using testing::kBlenderPanoramaDir;
// Scores of the committed model and of a fresh training agree to this
// (the model file stores support vectors as text).
constexpr double kScoreTolerance = 1e-4;

const SceneReferenceSet& references() { return testing::committed_references(); }

const SceneClassifier& committed() {
  static const SceneClassifier c = SceneClassifier::load(default_scene_classifier_path());
  return c;
}

TEST(SceneClassifier, CommittedModelIsTheOneItsReferencesTrain) {
  const SceneClassifier fresh = SceneClassifier::train(references());
  int right = 0, checked = 0;
  for (size_t i = 0; i < references().size(); i += 37, ++checked) {
    const SceneReference& r = references().at(i);
    const double score = committed().indoor_score(r.descriptor);
    EXPECT_NEAR(score, fresh.indoor_score(r.descriptor), kScoreTolerance) << "reference " << i;
    right += (score >= 0) == r.indoor;
  }
  // Trained on them: nearly all of its own references right.
  EXPECT_GE(right, checked * 9 / 10) << right << " of " << checked;
}

TEST(SceneClassifier, SaveLoadKeepsTheScoresAndLeavesNoTemporaryFile) {
  const std::string dir = ::testing::TempDir() + "/scene_classifier_roundtrip";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  committed().save(dir + "/model.yml.gz");
  const SceneClassifier again = SceneClassifier::load(dir + "/model.yml.gz");
  for (size_t i = 0; i < references().size(); i += 101)
    EXPECT_EQ(again.indoor_score(references().at(i).descriptor), committed().indoor_score(references().at(i).descriptor));
  expect_only_files(dir, {"model.yml.gz"});
}

// A real view, classified by a model trained without any view of its
// panorama (leave-one-panorama-out).
TEST(SceneClassifier, HeldOutRealViewsAreClassifiedRight) {
  if (!std::filesystem::exists(std::string(kBlenderPanoramaDir) + "/interior.exr"))
    GTEST_SKIP() << "install blender-data (scripts/setup.sh does)";
  for (const auto& [name, indoor] : {std::pair{"interior", true}, std::pair{"sunset", false}}) {
    const auto views = panorama_views(blender_panorama(name), 1, {5.0}, 60.0, 320, 240);
    ASSERT_EQ(views.size(), 1u);
    const int group = references().find_group(name);
    ASSERT_GE(group, 0);
    const SceneClassifier held_out = SceneClassifier::train(references(), group);
    const double score = held_out.indoor_score(appearance_descriptor(views[0].photo_linear));
    EXPECT_EQ(score >= 0, indoor) << name << ": score " << score;
  }
}

TEST(SceneClassifier, CombinedStageSaysTheClassifierDecided) {
  render::ViewSpec spec;
  spec.width = 160;
  spec.height = 120;
  // Texture everywhere: nothing the sky rule could take for sky.
  cv::Mat textured(120, 160, CV_32FC3);
  cv::RNG rng(11);
  rng.fill(textured, cv::RNG::UNIFORM, 0.f, 1.f);
  StageReport report;
  const bool indoor = classify_indoor_combined(textured, render::view_camera(spec), references(), report, nullptr, {}, &committed());
  ASSERT_TRUE(report.details.contains("method"));
  EXPECT_EQ(report.details["method"], "svm") << "a textured frame shows no sky";
  ASSERT_TRUE(report.details.contains("svm_indoor_score"));
  EXPECT_EQ(report.details["svm_indoor_score"].get<double>() >= 0, indoor);
  EXPECT_TRUE(report.details.contains("knn_indoor_share")) << "k-NN is reported beside it";
}

// Where the sky rule sees sky, a confident indoor score still overrules it
// (a lit wall or ceiling taken for sky); a real outdoor view's score stays
// under the default threshold, so the sky decides it.
TEST(SceneClassifier, AConfidentIndoorScoreOverrulesTheSkyAndARealSkyStaysOutdoor) {
  if (!std::filesystem::exists(std::string(kBlenderPanoramaDir) + "/sunset.exr"))
    GTEST_SKIP() << "install blender-data (scripts/setup.sh does)";
  const auto views = panorama_views(blender_panorama("sunset"), 1, {5.0}, 60.0, 320, 240);
  ASSERT_EQ(views.size(), 1u);
  // panorama_views' first view: yaw 0, the pitch asked for.
  const render::PinholeCamera camera = render::view_camera(render::view_spec(0.0, 5.0, 60.0, 320, 240));
  StageReport by_default;
  EXPECT_FALSE(classify_indoor_combined(views[0].photo_linear, camera, references(), by_default, nullptr, {}, &committed()));
  ASSERT_EQ(by_default.details["method"], "sky") << by_default.details.dump();
  const double score = by_default.details["svm_indoor_score"].get<double>();
  EXPECT_LT(score, CombinedSceneClassOptions{}.confident_indoor_score);

  CombinedSceneClassOptions trusting;
  trusting.confident_indoor_score = score - 0.01;
  StageReport overruled;
  EXPECT_TRUE(classify_indoor_combined(views[0].photo_linear, camera, references(), overruled, nullptr, trusting, &committed()));
  EXPECT_EQ(overruled.details["method"], "svm_over_sky");
  EXPECT_NE(overruled.why.find("SVM: indoor"), std::string::npos) << overruled.why;

  // A sky over as much of the frame as the cap stays sky, however confident.
  trusting.confident_indoor_max_sky = by_default.details["sky_fraction"].get<double>();
  StageReport capped;
  EXPECT_FALSE(classify_indoor_combined(views[0].photo_linear, camera, references(), capped, nullptr, trusting, &committed()));
  EXPECT_EQ(capped.details["method"], "sky");
}

}  // namespace
}  // namespace propcam::inference
