#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "propcam/inference/scene_class_knn.h"

namespace propcam::inference {
namespace {

const DepthDatabase& database() {
  static const DepthDatabase db = DepthDatabase::load(default_depth_database_path());
  return db;
}

const SceneReferenceSet& references() {
  static const SceneReferenceSet refs = SceneReferenceSet::load(default_scene_reference_path());
  return refs;
}

void expect_finite_and_deterministic(const cv::Mat& photo) {
  for (int exclude : {-2, 0}) {  // all references, and one panorama left out
    const KnnSceneClass a = classify_indoor_knn(photo, references(), {7, exclude});
    const KnnSceneClass b = classify_indoor_knn(photo, references(), {7, exclude});
    EXPECT_EQ(a.k, 7);
    EXPECT_TRUE(std::isfinite(a.indoor_share));
    EXPECT_GE(a.indoor_share, 0.0);
    EXPECT_LE(a.indoor_share, 1.0);
    EXPECT_EQ(a.indoor, b.indoor);
    EXPECT_EQ(a.indoor_share, b.indoor_share);
  }
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

// A small set saved and read back, and its bytes damaged in every part.
SceneReferenceSet small_set() {
  SceneReferenceSet set;
  const int g = set.group("pano");
  set.add({references().at(0).descriptor, true, kRenderedGroup});
  set.add({references().at(1).descriptor, false, g});
  return set;
}

TEST(SceneClassKnnHardCases, ReferenceLoadRejectsCorruptFilesNamingThem) {
  const std::string dir = ::testing::TempDir() + "/scene_refs_corrupt";
  std::filesystem::create_directories(dir);
  small_set().save(dir + "/good.bin");
  EXPECT_EQ(SceneReferenceSet::load(dir + "/good.bin").size(), 2u);
  std::ifstream in(dir + "/good.bin", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  // Layout: magic[8], version @8, group count @12, name length @16, "pano" @20,
  // count @24, descriptor length @28, then records: class (u8), group (i32), floats.
  const auto patched = [&](size_t offset, const std::string& with) {
    std::string b = bytes;
    b.replace(offset, with.size(), with);
    return b;
  };
  const auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), sizeof v); };
  const float nanf = std::numeric_limits<float>::quiet_NaN();
  const std::string nanf_bytes(reinterpret_cast<const char*>(&nanf), sizeof nanf);
  const size_t second_record = 32 + 5 + 4 * kAppearanceDescriptorLength;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"magic", patched(0, "PCSCENX")},
      {"version", patched(8, u32(9))},
      {"huge group count", patched(12, u32(0xFFFFFFFFu))},
      {"zero-length group name", patched(16, u32(0))},
      {"huge count", patched(24, u32(0xFFFFFFFFu))},
      {"descriptor length", patched(28, u32(7))},
      {"count too small (trailing bytes)", patched(24, u32(1))},
      {"class byte", patched(32, std::string(1, '\x05'))},
      {"unknown group", patched(second_record + 1, u32(3))},
      {"NaN descriptor", patched(32 + 5, nanf_bytes)},
      {"truncated", bytes.substr(0, bytes.size() - 3)},
      {"truncated header", bytes.substr(0, 10)},
      {"empty", ""},
  };
  for (const auto& [what, b] : cases) {
    const std::string path = dir + "/corrupt.bin";
    std::ofstream(path, std::ios::binary | std::ios::trunc) << b;
    try {
      SceneReferenceSet::load(path);
      ADD_FAILURE() << what << ": loaded";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << what << ": " << e.what();
    }
  }
  EXPECT_THROW(SceneReferenceSet::load(dir + "/missing.bin"), std::runtime_error);
}

TEST(SceneClassKnnHardCases, AddRejectsBadReferences) {
  SceneReferenceSet set;
  EXPECT_THROW(set.add({std::vector<float>(7, 0.f), true, kRenderedGroup}), std::invalid_argument);
  std::vector<float> nan(kAppearanceDescriptorLength, 0.f);
  nan[3] = NAN;
  EXPECT_THROW(set.add({nan, true, kRenderedGroup}), std::invalid_argument);
  EXPECT_THROW(set.add({references().at(0).descriptor, true, 4}), std::invalid_argument);  // no such group
  EXPECT_EQ(set.size(), 0u);
}

TEST(SceneClassKnnHardCases, EveryReferenceLeftOutThrows) {
  SceneReferenceSet set;
  const int g = set.group("only");
  set.add({references().at(0).descriptor, true, g});
  EXPECT_THROW(classify_indoor_knn(references().at(0).descriptor, set, {7, g}), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::inference
