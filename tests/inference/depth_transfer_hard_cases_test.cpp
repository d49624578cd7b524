#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "propcam/inference/depth_transfer.h"
#include "files_in_dir.h"

namespace propcam::inference {
namespace {

render::PinholeCamera camera(double pitch_deg, double roll_deg) {
  render::PinholeCamera c;
  c.width = 64;
  c.height = 48;
  c.fx = c.fy = 54;
  c.cx = 31.5;
  c.cy = 23.5;
  const Eigen::Matrix3d level = (Eigen::Matrix3d() << 1, 0, 0, 0, -1, 0, 0, 0, -1).finished();
  c.R_world_from_cam = level * Eigen::AngleAxisd(pitch_deg * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                       Eigen::AngleAxisd(roll_deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  c.center_world = {0, 1.5, 0};
  return c;
}

DepthDatabase one_example_db(bool indoor) {
  DepthDatabase db;
  DepthExample e;
  e.descriptor = appearance_descriptor(cv::Mat(48, 64, CV_32FC3, cv::Scalar(0.2, 0.3, 0.4)));
  e.depth = cv::Mat(12, 16, CV_32F, cv::Scalar(2.f));
  e.indoor = indoor;
  db.add(e);
  return db;
}

TEST(DepthTransferHardCases, DescriptorOfBlackSaturatedAndTinyImages) {
  for (const cv::Mat& m : {cv::Mat(48, 64, CV_32FC3, cv::Scalar::all(0)), cv::Mat(48, 64, CV_32FC3, cv::Scalar::all(50)),
                           cv::Mat(16, 16, CV_32FC3, cv::Scalar::all(0.5)), cv::Mat(1, 1, CV_32FC3, cv::Scalar::all(0.5))}) {
    const auto d = appearance_descriptor(m);
    ASSERT_EQ(d.size(), static_cast<size_t>(kAppearanceDescriptorLength));
    for (float v : d) EXPECT_TRUE(std::isfinite(v));
  }
  EXPECT_THROW(appearance_descriptor(cv::Mat()), std::invalid_argument);
}

TEST(DepthTransferHardCases, EmptyDatabaseOrNoExampleOfTheClassIsAClearError) {
  const cv::Mat photo(48, 64, CV_32FC3, cv::Scalar::all(0.3));
  EXPECT_THROW(transfer_depth(photo, camera(0, 0), 1.5, true, DepthDatabase{}, {16, 12}), std::invalid_argument);
  EXPECT_THROW(transfer_depth(photo, camera(0, 0), 1.5, false, one_example_db(true), {16, 12}), std::invalid_argument);
  EXPECT_THROW(transfer_depth(photo, camera(0, 0), 1.5, true, one_example_db(true), {0, 12}), std::invalid_argument);
}

TEST(DepthTransferHardCases, KLargerThanTheDatabaseTinyOutputAndExtremeCameras) {
  const cv::Mat photo(48, 64, CV_32FC3, cv::Scalar::all(0.3));
  const DepthDatabase db = one_example_db(true);
  DepthTransferOptions o;
  o.k = 50;
  for (auto [pitch, roll] : {std::pair{0.0, 0.0}, std::pair{89.9, 0.0}, std::pair{-90.0, 0.0}, std::pair{30.0, 170.0}}) {
    for (cv::Size s : {cv::Size(1, 1), cv::Size(16, 12)}) {
      const TransferredDepth t = transfer_depth(photo, camera(pitch, roll), 1.5, true, db, s, o);
      ASSERT_EQ(t.candidates.size(), 1u);
      EXPECT_TRUE(cv::checkRange(t.median, true, nullptr, 1e-6, 1e5)) << pitch << " " << roll;
      EXPECT_EQ(t.median.size(), s);
    }
  }
}

TEST(DepthTransferHardCases, LoadRejectsMissingTruncatedAndForeignFiles) {
  const std::string dir = ::testing::TempDir() + "/depth_db_bad";
  std::filesystem::create_directories(dir);
  EXPECT_THROW(DepthDatabase::load(dir + "/missing.bin"), std::runtime_error);
  {
    std::ofstream(dir + "/foreign.bin") << "not a database at all";
  }
  EXPECT_THROW(DepthDatabase::load(dir + "/foreign.bin"), std::runtime_error);
  one_example_db(true).save(dir + "/good.bin");
  std::ifstream in(dir + "/good.bin", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  for (size_t cut : {size_t{10}, bytes.size() / 2, bytes.size() - 1}) {
    std::ofstream(dir + "/cut.bin", std::ios::binary) << bytes.substr(0, cut);
    EXPECT_THROW(DepthDatabase::load(dir + "/cut.bin"), std::runtime_error) << cut;
  }
  std::string wrong_version = bytes;
  wrong_version[8] = 9;
  std::ofstream(dir + "/version.bin", std::ios::binary) << wrong_version;
  EXPECT_THROW(DepthDatabase::load(dir + "/version.bin"), std::runtime_error);
  EXPECT_NO_THROW(DepthDatabase::load(dir + "/good.bin"));
}

// Bytes that are the right length but wrong inside: each is refused with a
// runtime_error that names the file, never read as a database.
TEST(DepthTransferHardCases, LoadRejectsCorruptContents) {
  const std::string dir = ::testing::TempDir() + "/depth_db_corrupt";
  std::filesystem::create_directories(dir);
  one_example_db(true).save(dir + "/good.bin");
  std::ifstream in(dir + "/good.bin", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  // Layout: magic[8], version, count, descriptor length, width, height (uint32 each), then records
  // starting with the focal length (double).
  const auto patched = [&](size_t offset, const std::string& with) {
    std::string b = bytes;
    b.replace(offset, with.size(), with);
    return b;
  };
  const auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), sizeof v); };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::string nan_bytes(reinterpret_cast<const char*>(&nan), sizeof nan);
  const float nanf = std::numeric_limits<float>::quiet_NaN();
  const std::string nanf_bytes(reinterpret_cast<const char*>(&nanf), sizeof nanf);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"magic", patched(0, "PCDEPTX")},
      {"huge count", patched(12, u32(0xFFFFFFFFu))},
      {"descriptor length", patched(16, u32(7))},
      {"huge width", patched(20, u32(1u << 30))},
      {"zero height", patched(24, u32(0))},
      {"count too small (trailing bytes)", patched(12, u32(0))},
      {"NaN focal length", patched(28, nan_bytes)},
      {"NaN descriptor", patched(28 + 4 * sizeof(double) + 1, nanf_bytes)},
  };
  for (const auto& [what, b] : cases) {
    const std::string path = dir + "/corrupt.bin";
    std::ofstream(path, std::ios::binary | std::ios::trunc) << b;
    try {
      DepthDatabase::load(path);
      ADD_FAILURE() << what << ": loaded";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << what << ": " << e.what();
    }
  }
}

TEST(DepthTransferHardCases, SaveIsAtomicAndLeavesNoTemporaryFile) {
  const std::string dir = ::testing::TempDir() + "/depth_db_atomic";
  std::filesystem::remove_all(dir);
  one_example_db(true).save(dir + "/sub/db.bin");  // creates the folder
  one_example_db(false).save(dir + "/sub/db.bin");  // replaces the file
  expect_only_files(dir + "/sub", {"db.bin"});
  const DepthDatabase back = DepthDatabase::load(dir + "/sub/db.bin");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_FALSE(back.at(0).indoor);
}

}  // namespace
}  // namespace propcam::inference
