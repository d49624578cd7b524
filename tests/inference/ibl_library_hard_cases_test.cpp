#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "propcam/inference/ibl_library.h"

namespace propcam::inference {
namespace {

TEST(IblLibraryHardCases, NegativeAndNonFiniteTexelsAreClamped) {
  cv::Mat pano(32, 64, CV_32FC3, cv::Scalar(1, 1, 1));
  pano.at<cv::Vec3f>(3, 4) = cv::Vec3f(-5.f, std::numeric_limits<float>::quiet_NaN(),
                                        std::numeric_limits<float>::infinity());
  const cv::Mat clean = sanitize_latlong(pano);
  EXPECT_EQ(clean.at<cv::Vec3f>(3, 4), cv::Vec3f(0, 0, 0));
  EXPECT_EQ(clean.at<cv::Vec3f>(0, 0), cv::Vec3f(1, 1, 1));
  // A NaN texel must not become a light or poison the others.
  const auto lights = find_light_regions(pano, SceneKind::Indoor);
  EXPECT_TRUE(lights.empty());
}

TEST(IblLibraryHardCases, BlackAndUniformPanoramasHaveNoLights) {
  EXPECT_TRUE(find_light_regions(cv::Mat(32, 64, CV_32FC3, cv::Scalar(0, 0, 0)), SceneKind::Outdoor).empty());
  EXPECT_TRUE(find_light_regions(cv::Mat(32, 64, CV_32FC3, cv::Scalar(2, 2, 2)), SceneKind::Outdoor).empty());
}

TEST(IblLibraryHardCases, LightAcrossTheSeamIsOneRegion) {
  cv::Mat pano(32, 64, CV_32FC3, cv::Scalar(0.1, 0.1, 0.1));
  for (int y = 10; y < 13; ++y)
    for (int x : {0, 1, 62, 63}) pano.at<cv::Vec3f>(y, x) = cv::Vec3f(100, 100, 100);
  const auto lights = find_light_regions(pano, SceneKind::Indoor);
  ASSERT_EQ(lights.size(), 1u);
  EXPECT_GT(lights[0].power_share, 0.5);
}

TEST(IblLibraryHardCases, RejectsWrongImageTypes) {
  EXPECT_THROW(sanitize_latlong(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(sanitize_latlong(cv::Mat(4, 8, CV_8UC3)), std::invalid_argument);
  EXPECT_THROW(procedural_sky(30, 0, 3, 2), std::invalid_argument);
}

class CorruptLibrary : public ::testing::Test {
 protected:
  void SetUp() override {
    // One folder per test: ctest runs this suite's tests in parallel.
    dir_ = std::string(PROPCAM_BINARY_DIR) + "/test_ibl_library_corrupt/" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::filesystem::remove_all(dir_);
    IblLibraryOptions options;
    options.width = 32;
    options.blender_dir = "/nonexistent";
    options.procedural_skies = 1;
    options.procedural_rooms = 0;
    save_ibl_library(build_ibl_library(options), dir_);
  }
  void write_json(const std::string& text) { std::ofstream(dir_ + "/library.json") << text; }
  void expect_error_mentions(const std::string& needle) {
    try {
      load_ibl_library(dir_);
      FAIL() << "corrupt library accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  }
  std::string dir_;
};

TEST_F(CorruptLibrary, ValidLibraryLoads) { EXPECT_EQ(load_ibl_library(dir_).entries.size(), 1u); }

TEST_F(CorruptLibrary, TruncatedJsonIsRejected) {
  write_json("{\"format\": \"propcam-ibl-library\", \"entr");
  expect_error_mentions("not valid JSON");
}

TEST_F(CorruptLibrary, MissingFieldIsRejected) {
  write_json(R"({"format":"propcam-ibl-library","version":1,"entries":[{"name":"sky_0"}]})");
  expect_error_mentions("sky_0");
}

TEST_F(CorruptLibrary, BadAnnotationIsRejected) {
  write_json(R"({"format":"propcam-ibl-library","version":1,"entries":[{"name":"sky_0","source":"x",
    "kind":"outdoor","file":"sky_0.exr","width":32,"height":16,
    "lights":[{"direction":[0,2,0],"solid_angle_sr":0.1,"power_share":0.5,"distance":"infinite"}]}]})");
  expect_error_mentions("out of range");
}

TEST_F(CorruptLibrary, UnknownKindAndMissingImageAreRejected) {
  write_json(R"({"format":"propcam-ibl-library","version":1,"entries":[{"name":"sky_0","source":"x",
    "kind":"cave","file":"sky_0.exr","width":32,"height":16,"lights":[]}]})");
  expect_error_mentions("unknown kind");
  write_json(R"({"format":"propcam-ibl-library","version":1,"entries":[{"name":"sky_0","source":"x",
    "kind":"outdoor","file":"gone.exr","width":32,"height":16,"lights":[]}]})");
  expect_error_mentions("missing panorama");
}

TEST_F(CorruptLibrary, MissingFolderIsRejected) {
  std::filesystem::remove_all(dir_);
  expect_error_mentions("cannot open");
}

}  // namespace
}  // namespace propcam::inference
