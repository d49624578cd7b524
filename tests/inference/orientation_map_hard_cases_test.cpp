#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "propcam/inference/orientation_map.h"

namespace propcam::inference {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A level camera at 1.5 m looking along -Z, turned by yaw (degrees) about the vertical.
render::PinholeCamera level_camera(int w, int h, double f, double yaw_deg = 0) {
  render::PinholeCamera cam;
  cam.width = w;
  cam.height = h;
  cam.fx = cam.fy = f;
  cam.cx = 0.5 * w - 0.5;
  cam.cy = 0.5 * h - 0.5;
  const double yaw = yaw_deg * std::numbers::pi / 180.0;
  const Eigen::Vector3d forward(-std::sin(yaw), 0, -std::cos(yaw));
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitY()).normalized();
  cam.R_world_from_cam.col(0) = right;
  cam.R_world_from_cam.col(1) = forward.cross(right);
  cam.R_world_from_cam.col(2) = forward;
  cam.center_world = {0, 1.5, 0};
  return cam;
}

struct Labelled {
  std::vector<LineSegment> lines;
  std::vector<int> labels;
};

void add(const render::PinholeCamera& cam, const Eigen::Vector3d& p, const Eigen::Vector3d& q, int axis, Labelled& l) {
  Eigen::Vector2d a, b;
  ASSERT_TRUE(cam.project(p, a) && cam.project(q, b));
  l.lines.push_back({a, b});
  l.labels.push_back(axis);
}

// A floor grid (X and Z lines) and a back wall grid (X and Y lines) at z = -6.
Labelled room_lines(const render::PinholeCamera& cam) {
  Labelled l;
  for (double x = -2; x <= 2; x += 1) add(cam, {x, 0, -2}, {x, 0, -6}, 2, l);
  for (double z = -2.5; z >= -6; z -= 1) add(cam, {-2, 0, z}, {2, 0, z}, 0, l);
  for (double x = -2; x <= 2; x += 1) add(cam, {x, 0, -6}, {x, 2.5, -6}, 1, l);
  for (double y = 0.5; y <= 2.5; y += 1) add(cam, {-2, y, -6}, {2, y, -6}, 0, l);
  return l;
}

int count(const cv::Mat& labels, SurfaceOrientation o) {
  return cv::countNonZero(labels == static_cast<uint8_t>(o));
}

void expect_valid(const OrientationMap& m, int w, int h) {
  ASSERT_EQ(m.labels.type(), CV_8U);
  EXPECT_EQ(m.labels.cols, w);
  EXPECT_EQ(m.labels.rows, h);
  double lo = 0, hi = 0;
  cv::minMaxLoc(m.labels, &lo, &hi);
  EXPECT_LE(hi, 3.0);
  EXPECT_EQ(m.report.stage, "orientation_map");
  EXPECT_TRUE(std::isfinite(m.report.details["coverage"].get<double>()));
  EXPECT_TRUE(std::isfinite(m.report.seconds));
}

void expect_all_unknown(const OrientationMap& m) {
  EXPECT_EQ(cv::countNonZero(m.labels), 0);
  EXPECT_FALSE(m.report.usable);
  EXPECT_EQ(m.report.details["coverage"].get<double>(), 0.0);
}

TEST(OrientationMapHardCases, NoLines) {
  const OrientationMap m = estimate_orientation_map({}, {}, level_camera(640, 480, 500));
  expect_valid(m, 160, 120);
  expect_all_unknown(m);
}

TEST(OrientationMapHardCases, OnlyOutliers) {
  const render::PinholeCamera cam = level_camera(640, 480, 500, 30);
  Labelled l = room_lines(cam);
  std::fill(l.labels.begin(), l.labels.end(), -1);
  const OrientationMap m = estimate_orientation_map(l.lines, l.labels, cam);
  expect_valid(m, 160, 120);
  expect_all_unknown(m);
  EXPECT_EQ(m.report.details["lines_used"].get<int>(), 0);
}

TEST(OrientationMapHardCases, LabelsOutOfRangeAreIgnored) {
  const render::PinholeCamera cam = level_camera(640, 480, 500, 30);
  Labelled l = room_lines(cam);
  std::fill(l.labels.begin(), l.labels.end(), 7);
  l.labels[0] = -5;
  expect_all_unknown(estimate_orientation_map(l.lines, l.labels, cam));
}

TEST(OrientationMapHardCases, AllLinesParallel) {
  // One class only (the horizontal_only / vertical_only cameras): no pair of
  // classes, so nothing is labelled.
  const render::PinholeCamera cam = level_camera(640, 480, 500, 30);
  for (int axis = 0; axis < 3; ++axis) {
    Labelled l;
    for (int n = 0; n < 12; ++n) {
      Eigen::Vector3d p(-2 + 0.3 * n, 0.2 * n, -4 - 0.2 * n), q = p;
      q[axis] += 1.0;
      add(cam, p, q, axis, l);
    }
    const OrientationMap m = estimate_orientation_map(l.lines, l.labels, cam);
    expect_valid(m, 160, 120);
    expect_all_unknown(m);
  }
}

TEST(OrientationMapHardCases, VanishingPointsAtInfinityFrontalWall) {
  // Frontal view of a wall grid over a floor grid: VP_X and VP_Y at infinity,
  // so those sweeps are translations. Inside the wall and the floor every
  // label is right. (Beside them the open edges of the grids sweep out into
  // empty space, labelled as the side walls a real room would have there.)
  const render::PinholeCamera cam = level_camera(640, 480, 500);
  const Labelled l = room_lines(cam);
  const OrientationMap m = estimate_orientation_map(l.lines, l.labels, cam);
  expect_valid(m, 160, 120);
  const render::PinholeCamera out = cam.resized(160, 120);
  int wall = 0, wall_right = 0, floor = 0, floor_right = 0;
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x) {
      const Eigen::Vector3d d = out.ray_direction(x, y), o = out.center_world;
      const uint8_t got = m.labels.at<uint8_t>(y, x);
      const Eigen::Vector3d on_wall = o + d * ((-6 - o.z()) / d.z());
      if (std::abs(on_wall.x()) < 2 && on_wall.y() > 0 && on_wall.y() < 2.5) {
        ++wall;
        wall_right += got == static_cast<uint8_t>(SurfaceOrientation::kNormalZ);
        EXPECT_TRUE(got == 0 || got == static_cast<uint8_t>(SurfaceOrientation::kNormalZ)) << x << "," << y;
      }
      if (d.y() >= 0) continue;
      const Eigen::Vector3d on_floor = o + d * (-o.y() / d.y());
      if (std::abs(on_floor.x()) < 2 && on_floor.z() > -6 && on_floor.z() < -2.5) {
        ++floor;
        floor_right += got == static_cast<uint8_t>(SurfaceOrientation::kNormalY);
        EXPECT_TRUE(got == 0 || got == static_cast<uint8_t>(SurfaceOrientation::kNormalY)) << x << "," << y;
      }
    }
  ASSERT_GT(wall, 0);
  ASSERT_GT(floor, 0);
  EXPECT_GT(wall_right, 0.8 * wall);
  EXPECT_GT(floor_right, 0.8 * floor);
}

TEST(OrientationMapHardCases, LookingStraightDown) {
  // VP_Y at the principal point, VP_X and VP_Z at infinity: a floor grid is level.
  render::PinholeCamera cam;
  cam.width = 320;
  cam.height = 240;
  cam.fx = cam.fy = 260;
  cam.cx = 159.5;
  cam.cy = 119.5;
  cam.R_world_from_cam.col(0) = Eigen::Vector3d::UnitX();
  cam.R_world_from_cam.col(1) = -Eigen::Vector3d::UnitZ();
  cam.R_world_from_cam.col(2) = -Eigen::Vector3d::UnitY();
  cam.center_world = {0, 2, 0};
  Labelled l;
  for (double x = -1; x <= 1; x += 0.5) add(cam, {x, 0, -1}, {x, 0, 1}, 2, l);
  for (double z = -1; z <= 1; z += 0.5) add(cam, {-1, 0, z}, {1, 0, z}, 0, l);
  const OrientationMap m = estimate_orientation_map(l.lines, l.labels, cam);
  expect_valid(m, 160, 120);
  EXPECT_GT(count(m.labels, SurfaceOrientation::kNormalY), 0.3 * m.labels.total());
  EXPECT_EQ(count(m.labels, SurfaceOrientation::kNormalX) + count(m.labels, SurfaceOrientation::kNormalZ), 0);
}

TEST(OrientationMapHardCases, NonFiniteAndAbsurdSegmentsAreIgnored) {
  const render::PinholeCamera cam = level_camera(640, 480, 500, 30);
  const Labelled clean = room_lines(cam);
  Labelled dirty = clean;
  const double inf = std::numeric_limits<double>::infinity();
  dirty.lines.push_back({{kNaN, 10}, {100, 100}});
  dirty.lines.push_back({{10, 10}, {inf, 100}});
  dirty.lines.push_back({{1e300, -1e300}, {1e301, 5}});
  dirty.lines.push_back({{50, 50}, {50, 50}});  // zero length
  for (int n = 0; n < 4; ++n) dirty.labels.push_back(n % 3);
  const OrientationMap a = estimate_orientation_map(clean.lines, clean.labels, cam);
  const OrientationMap b = estimate_orientation_map(dirty.lines, dirty.labels, cam);
  expect_valid(b, 160, 120);
  EXPECT_EQ(cv::norm(a.labels, b.labels, cv::NORM_INF), 0.0);
}

TEST(OrientationMapHardCases, SegmentThroughAVanishingPoint) {
  // Lines that pass exactly through another class's vanishing point (a
  // frontal view: horizontal lines through the centre row contain VP_Z's row).
  const render::PinholeCamera cam = level_camera(640, 480, 500);
  Labelled l;
  l.lines.push_back({{100, 239.5}, {300, 239.5}});  // an X line on the horizon, through VP_Z
  l.labels.push_back(0);
  l.lines.push_back({{319.5, 239.5}, {319.5, 400}});  // a Y line starting at VP_Z
  l.labels.push_back(1);
  l.lines.push_back({{319.5, 239.5}, {100, 400}});  // a Z line ending at VP_Z
  l.labels.push_back(2);
  expect_valid(estimate_orientation_map(l.lines, l.labels, cam), 160, 120);
}

TEST(OrientationMapHardCases, TinyCamera) {
  const render::PinholeCamera cam = level_camera(16, 16, 14, 20);
  Labelled l;
  l.lines = {{{1, 12}, {14, 13}}, {{3, 2}, {3, 14}}, {{8, 15}, {9, 9}}, {{2, 9}, {13, 8}}};
  l.labels = {0, 1, 2, 0};
  const OrientationMap m = estimate_orientation_map(l.lines, l.labels, cam);
  expect_valid(m, 160, 160);
  OrientationMapOptions o;
  o.width = 16;
  expect_valid(estimate_orientation_map(l.lines, l.labels, cam, o), 16, 16);
}

TEST(OrientationMapHardCases, OutputWidthOne) {
  const render::PinholeCamera cam = level_camera(640, 480, 500, 30);
  const Labelled l = room_lines(cam);
  OrientationMapOptions o;
  o.width = 1;
  const OrientationMap m = estimate_orientation_map(l.lines, l.labels, cam, o);
  expect_valid(m, 1, 1);  // round(1 * 480 / 640) = 1
  // A very wide panorama strip still gets one row.
  const OrientationMap strip = estimate_orientation_map(l.lines, l.labels, level_camera(4000, 100, 500), o);
  expect_valid(strip, 1, 1);
}

TEST(OrientationMapHardCases, SizeMismatchIsAClearError) {
  const render::PinholeCamera cam = level_camera(640, 480, 500);
  const Labelled l = room_lines(cam);
  std::vector<int> short_labels(l.labels.begin(), l.labels.end() - 1);
  EXPECT_THROW(estimate_orientation_map(l.lines, short_labels, cam), std::invalid_argument);
  EXPECT_THROW(estimate_orientation_map({}, {0}, cam), std::invalid_argument);
}

TEST(OrientationMapHardCases, BadCameraOrOptionsAreClearErrors) {
  const Labelled l = room_lines(level_camera(640, 480, 500));
  auto with = [](auto edit) {
    render::PinholeCamera c = level_camera(640, 480, 500);
    edit(c);
    return c;
  };
  EXPECT_THROW(estimate_orientation_map(l.lines, l.labels, with([](auto& c) { c.width = 0; })), std::invalid_argument);
  EXPECT_THROW(estimate_orientation_map(l.lines, l.labels, with([](auto& c) { c.fx = 0; })), std::invalid_argument);
  EXPECT_THROW(estimate_orientation_map(l.lines, l.labels, with([](auto& c) { c.cy = kNaN; })), std::invalid_argument);
  EXPECT_THROW(estimate_orientation_map(l.lines, l.labels, with([](auto& c) { c.R_world_from_cam(1, 2) = kNaN; })),
               std::invalid_argument);
  OrientationMapOptions o;
  o.width = 0;
  EXPECT_THROW(estimate_orientation_map(l.lines, l.labels, level_camera(640, 480, 500), o), std::invalid_argument);
  o = {};
  o.max_sweep_fraction = kNaN;
  EXPECT_THROW(estimate_orientation_map(l.lines, l.labels, level_camera(640, 480, 500), o), std::invalid_argument);
}

TEST(OrientationMapHardCases, RunTwiceGivesIdenticalLabels) {
  const render::PinholeCamera cam = level_camera(640, 480, 500, 35);
  Labelled l = room_lines(cam);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> px(0, 640), py(0, 480);
  for (int n = 0; n < 200; ++n) {  // clutter with random labels
    l.lines.push_back({{px(rng), py(rng)}, {px(rng), py(rng)}});
    l.labels.push_back(static_cast<int>(rng() % 4) - 1);
  }
  const OrientationMap a = estimate_orientation_map(l.lines, l.labels, cam);
  const OrientationMap b = estimate_orientation_map(l.lines, l.labels, cam);
  expect_valid(a, 160, 120);
  EXPECT_EQ(cv::norm(a.labels, b.labels, cv::NORM_INF), 0.0);
  EXPECT_EQ(a.report.details["coverage"], b.report.details["coverage"]);
}

}  // namespace
}  // namespace propcam::inference
