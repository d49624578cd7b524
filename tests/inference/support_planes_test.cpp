#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "propcam/inference/support_planes.h"
#include "propcam/render/depth_mesh.h"
#include "room_truth.h"

namespace propcam::inference {
namespace {

TEST(SupportPlanes, FindsTheFloorWithItsExtentsInSyntheticRooms) {
  for (uint64_t seed : {1, 2, 4}) {
    const RoomTruth t = room_truth(seed, 200, 150);
    StageReport report;
    const auto planes = find_support_planes(t.depth, t.normals, t.room.camera, {}, report);
    ASSERT_FALSE(planes.empty());
    EXPECT_EQ(planes[0].name, "floor");
    EXPECT_NEAR(-planes[0].offset, 0.0, 0.02) << seed;
    EXPECT_GT(planes[0].pixels, 0);
    const Eigen::Vector3f f = t.room.free_floor_point;
    EXPECT_GE(f.x(), planes[0].extent_min.x() - 0.1);
    EXPECT_LE(f.x(), planes[0].extent_max.x() + 0.1);
    EXPECT_GE(f.z(), planes[0].extent_min.z() - 0.1);
    EXPECT_LE(f.z(), planes[0].extent_max.z() + 0.1);
    for (size_t i = 1; i < planes.size(); ++i) {
      EXPECT_GE(-planes[i].offset, 0.2);
      EXPECT_LT(-planes[i].offset, t.room.camera.center_world.y());
    }
    EXPECT_EQ(report.stage, "support_planes");
  }
}

TEST(SupportPlanes, InsertionFlattensNoisyDepthOntoTheFloorOnly) {
  const RoomTruth t = room_truth(2, 200, 150);
  Eigen::Vector2d px;
  ASSERT_TRUE(t.room.camera.project(t.room.free_floor_point.cast<double>(), px));
  cv::Mat depth = t.depth.clone(), normals = t.normals.clone();
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.f, 0.02f);
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) depth.at<float>(y, x) *= 1.f + noise(rng);
  std::vector<SupportPlane> planes = {{"floor", Eigen::Vector3d::UnitY(), 0.0}};
  const InsertionFlattening f = flatten_insertion_region(depth, normals, t.room.camera, planes, px.x(), px.y(), 0.3);
  ASSERT_TRUE(f.applied) << f.why;
  EXPECT_NEAR(f.plane_height_m, 0.0, 1e-9);
  EXPECT_GT(f.pixels_changed, 20);
  // The base and its neighbours are exactly on the floor now.
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx) {
      const int x = static_cast<int>(std::lround(px.x())) + dx, y = static_cast<int>(std::lround(px.y())) + dy;
      EXPECT_NEAR(depth.at<float>(y, x), t.depth.at<float>(y, x), 1e-3 * t.depth.at<float>(y, x));
      EXPECT_FLOAT_EQ(normals.at<cv::Vec3f>(y, x)[1], 1.f);
    }
}

}  // namespace
}  // namespace propcam::inference
