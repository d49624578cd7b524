// The k-NN scene classifier's committed reference set (renders + real
// panorama views) and its use on real views held out by panorama.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "propcam/capture/image_file.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/inference/scene_class_knn.h"
#include "propcam/render/panorama.h"
#include "files_in_dir.h"
#include "scene_class_fixtures.h"

namespace propcam::inference {
namespace {

using testing::blender_panorama;
using testing::kBlenderPanoramaDir;
// What scripts/build_scene_refs.sh commits: the depth database's 160 rooms
// and 120 streets, views of the 26 panoramas (25 groups: pmndrs' sunrise is
// blender-data's), and photos of the Blender world's tune split.
constexpr size_t kRendered = 280;
constexpr size_t kPanoramaGroups = 25;

const SceneReferenceSet& references() { return testing::committed_references(); }

TEST(SceneClassKnn, CommittedReferencesLoadWithRendersRealViewsAndTheBlenderWorldsTuneSplitOnly) {
  const SceneReferenceSet& refs = references();
  size_t panorama_groups = 0, blender_groups = 0;
  for (const std::string& g : refs.groups()) {
    if (g.rfind("blender/scene_", 0) != 0) {
      ++panorama_groups;
      continue;
    }
    ++blender_groups;
    const int seed = std::stoi(g.substr(14));
    EXPECT_NE(seed % 3, 0) << g << " belongs to the held split, which is never learnt from";
  }
  EXPECT_EQ(panorama_groups, kPanoramaGroups);
  EXPECT_GT(blender_groups, 0u);
  size_t rendered = 0, real_indoor = 0, real_outdoor = 0;
  for (size_t i = 0; i < refs.size(); ++i) {
    const SceneReference& r = refs.at(i);
    EXPECT_EQ(r.descriptor.size(), static_cast<size_t>(kAppearanceDescriptorLength));
    if (r.group == kRenderedGroup)
      ++rendered;
    else
      ++(r.indoor ? real_indoor : real_outdoor);
  }
  EXPECT_EQ(rendered, kRendered);
  EXPECT_GT(real_indoor, 0u);
  EXPECT_GT(real_outdoor, 0u);
  for (const char* g : {"interior", "sunset", "sunrise", "pmndrs_lobby", "pmndrs_venice"}) EXPECT_GE(refs.find_group(g), 0) << g;
  EXPECT_LT(refs.find_group("pmndrs_sunrise"), 0) << "one photograph, one group: blender-data's sunrise";
}

TEST(SceneClassKnn, SaveLoadRoundTripIsByteIdentical) {
  const std::string dir = ::testing::TempDir() + "/scene_refs_roundtrip";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  references().save(dir + "/a.bin");
  SceneReferenceSet::load(dir + "/a.bin").save(dir + "/b.bin");
  std::ifstream a(dir + "/a.bin", std::ios::binary), b(dir + "/b.bin", std::ios::binary);
  const std::string sa((std::istreambuf_iterator<char>(a)), {}), sb((std::istreambuf_iterator<char>(b)), {});
  EXPECT_FALSE(sa.empty());
  EXPECT_EQ(sa, sb);
  expect_only_files(dir, {"a.bin", "b.bin"});
}

TEST(SceneClassKnn, ClassificationIsDeterministic) {
  cv::Mat photo(120, 160, CV_32FC3);
  cv::RNG rng(7);
  rng.fill(photo, cv::RNG::UNIFORM, 0.f, 1.f);
  const KnnSceneClass a = classify_indoor_knn(photo, references());
  const KnnSceneClass b = classify_indoor_knn(photo, references());
  EXPECT_EQ(a.indoor, b.indoor);
  EXPECT_EQ(a.indoor_share, b.indoor_share);
  EXPECT_EQ(a.real_neighbours, b.real_neighbours);
  EXPECT_EQ(a.k, 7);
}

TEST(SceneClassKnn, ExcludedGroupIsNeverANeighbour) {
  // A reference set of one rendered indoor and one real outdoor example:
  // leaving the real one's group out leaves only the render to vote.
  SceneReferenceSet refs;
  const int g = refs.group("pano");
  refs.add({references().at(0).descriptor, true, kRenderedGroup});
  refs.add({references().at(0).descriptor, false, g});
  const KnnSceneClass all = classify_indoor_knn(references().at(0).descriptor, refs, {7});
  const KnnSceneClass held_out = classify_indoor_knn(references().at(0).descriptor, refs, {7, g});
  EXPECT_EQ(all.k, 2);
  EXPECT_EQ(held_out.k, 1);
  EXPECT_EQ(held_out.real_neighbours, 0);
  EXPECT_TRUE(held_out.indoor);
  EXPECT_THROW(classify_indoor_knn(references().at(0).descriptor, SceneReferenceSet{}, {7}), std::invalid_argument);
}

// A real view, classified against references that hold no view of its
// panorama (leave-one-panorama-out, as `propcam bench scene-class` measures).
TEST(SceneClassKnn, HeldOutRealViewsAreClassifiedRight) {
  if (!std::filesystem::exists(std::string(kBlenderPanoramaDir) + "/interior.exr"))
    GTEST_SKIP() << "install blender-data (scripts/setup.sh does)";
  for (const auto& [name, indoor] : {std::pair{"interior", true}, std::pair{"sunset", false}}) {
    const auto views = panorama_views(blender_panorama(name), 1, {5.0}, 60.0, 320, 240);
    ASSERT_EQ(views.size(), 1u);
    const int group = references().find_group(name);
    ASSERT_GE(group, 0);
    const KnnSceneClass c = classify_indoor_knn(views[0].photo_linear, references(), {7, group});
    EXPECT_EQ(c.indoor, indoor) << name << ": indoor share " << c.indoor_share;
  }
}

TEST(SceneClassKnn, CombinedReportSaysWhichMethodDecided) {
  render::ViewSpec spec;
  spec.width = 160;
  spec.height = 120;
  StageReport report;
  const cv::Mat grey(120, 160, CV_32FC3, cv::Scalar(0.3, 0.3, 0.3));
  const bool indoor = classify_indoor_combined(grey, render::view_camera(spec), references(), report);
  EXPECT_EQ(report.stage, "scene_class");
  ASSERT_TRUE(report.details.contains("method"));
  const std::string method = report.details["method"];
  EXPECT_TRUE(method == "sky" || method == "knn") << method;
  if (method == "knn") {
    EXPECT_TRUE(report.details.contains("knn_indoor_share"));
  }
  StageReport again;
  EXPECT_EQ(classify_indoor_combined(grey, render::view_camera(spec), references(), again), indoor);
}

}  // namespace
}  // namespace propcam::inference
