#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "propcam/inference/depth_transfer.h"

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

}  // namespace
}  // namespace propcam::inference
