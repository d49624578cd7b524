#include <gtest/gtest.h>

#include <cmath>

#include "propcam/inference/support_planes.h"
#include "propcam/render/depth_mesh.h"
#include "room_truth.h"

namespace propcam::inference {
namespace {

TEST(SupportPlanesHardCases, OutsideSkyAndNonFiniteBasesChangeNothing) {
  const RoomTruth t = room_truth(1, 200, 150);
  cv::Mat depth = t.depth.clone(), normals = t.normals.clone();
  const std::vector<SupportPlane> planes;
  for (auto [u, v] : {std::pair{-5.0, 10.0}, std::pair{10.0, 1e9}, std::pair{std::nan(""), 3.0}}) {
    const InsertionFlattening f = flatten_insertion_region(depth, normals, t.room.camera, planes, u, v, 0.3);
    EXPECT_FALSE(f.applied);
    EXPECT_FALSE(f.why.empty());
  }
  depth.at<float>(5, 5) = static_cast<float>(render::kSkyDepthM);
  EXPECT_FALSE(flatten_insertion_region(depth, normals, t.room.camera, planes, 5, 5, 0.3).applied);
  EXPECT_EQ(cv::norm(depth.rowRange(10, depth.rows), t.depth.rowRange(10, depth.rows), cv::NORM_INF), 0.0);
  // A huge footprint and a NaN one stay bounded.
  EXPECT_NO_THROW(flatten_insertion_region(depth, normals, t.room.camera, planes, 100, 140, 1e9));
  EXPECT_NO_THROW(flatten_insertion_region(depth, normals, t.room.camera, planes, 100, 140, std::nan("")));
  EXPECT_TRUE(cv::checkRange(depth));
}

TEST(SupportPlanesHardCases, EmptyOrBlankMapsGiveTheDefaultFloor) {
  render::PinholeCamera c;
  c.width = 16;
  c.height = 16;
  c.fx = c.fy = 14;
  c.cx = c.cy = 7.5;
  c.center_world = Eigen::Vector3d(0, 1.5, 0);
  cv::Mat sky(16, 16, CV_32F, cv::Scalar(static_cast<float>(render::kSkyDepthM)));
  cv::Mat up(16, 16, CV_32FC3, cv::Scalar(0, 1, 0));
  StageReport r;
  const auto planes = find_support_planes(sky, up, c, {}, r);
  ASSERT_EQ(planes.size(), 1u);
  EXPECT_EQ(planes[0].name, "floor");
  EXPECT_EQ(planes[0].offset, 0.0);
  EXPECT_THROW(find_support_planes(cv::Mat(8, 8, CV_32F), up, c, {}, r), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::inference
