#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>

#include "propcam/inference/camera.h"
#include "propcam/render/camera.h"

namespace propcam::inference {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

render::PinholeCamera make_camera(double f, double yaw_deg, double pitch_deg) {
  render::PinholeCamera cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = cam.fy = f;
  cam.cx = 319.5;
  cam.cy = 239.5;
  const double yaw = yaw_deg / kRadToDeg, pitch = pitch_deg / kRadToDeg;
  const Eigen::Vector3d forward(-std::sin(yaw) * std::cos(pitch), std::sin(pitch), -std::cos(yaw) * std::cos(pitch));
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitY()).normalized();
  cam.R_world_from_cam.col(0) = right;
  cam.R_world_from_cam.col(1) = forward.cross(right);
  cam.R_world_from_cam.col(2) = forward;
  cam.center_world = {0, 1.5, 0};
  return cam;
}

// Projects random axis-aligned 3D segments inside a 6x3x8 m room, with pixel noise.
std::vector<LineSegment> manhattan_lines(const render::PinholeCamera& cam, int per_axis, double noise_px,
                                         uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(-3, 3), y(0, 3), z(-8, -1.5), len(0.5, 1.5);
  std::normal_distribution<double> noise(0, noise_px);
  std::vector<LineSegment> lines;
  for (int axis = 0; axis < 3; ++axis)
    for (int i = 0; i < per_axis * 20 && static_cast<int>(lines.size()) < per_axis * (axis + 1); ++i) {
      const Eigen::Vector3d p(x(rng), y(rng), z(rng));
      Eigen::Vector3d q = p;
      q[axis] += len(rng);
      Eigen::Vector2d a, b;
      if (!cam.project(p, a) || !cam.project(q, b)) continue;
      auto inside = [&](const Eigen::Vector2d& v) { return v.x() >= 0 && v.y() >= 0 && v.x() < 640 && v.y() < 480; };
      if (!inside(a) || !inside(b) || (a - b).norm() < 20) continue;
      lines.push_back({a + Eigen::Vector2d(noise(rng), noise(rng)), b + Eigen::Vector2d(noise(rng), noise(rng))});
    }
  return lines;
}

double up_error_deg(const Eigen::Matrix3d& est, const Eigen::Matrix3d& truth) {
  const Eigen::Vector3d a = est.transpose() * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d b = truth.transpose() * Eigen::Vector3d::UnitY();
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * kRadToDeg;
}

void expect_finite(const CameraEstimate& e) {
  EXPECT_TRUE(std::isfinite(e.fx) && e.fx > 0);
  EXPECT_TRUE(e.R_world_from_cam.allFinite());
  EXPECT_NEAR(e.R_world_from_cam.determinant(), 1.0, 1e-9);
  EXPECT_NEAR((e.R_world_from_cam * e.R_world_from_cam.transpose() - Eigen::Matrix3d::Identity()).norm(), 0, 1e-9);
}

TEST(Camera, RecoversFocalAndUpFromThreeVanishingPoints) {
  for (const auto& [f, yaw, pitch] : {std::tuple{500.0, 30.0, -12.0}, {800.0, -20.0, -5.0}, {420.0, 40.0, 10.0}}) {
    const auto cam = make_camera(f, yaw, pitch);
    const auto lines = manhattan_lines(cam, 25, 0.5, 42);
    ASSERT_GE(lines.size(), 60u);
    const CameraEstimate est = estimate_camera(lines, 640, 480);
    expect_finite(est);
    EXPECT_EQ(est.which, CameraCase::ThreeVanishingPoints) << est.report.why;
    EXPECT_NEAR(est.fx / f, 1.0, 0.03) << "f=" << f;
    EXPECT_LT(up_error_deg(est.R_world_from_cam, cam.R_world_from_cam), 0.5) << "f=" << f;
  }
}

TEST(Camera, SurvivesThirtyPercentOutlierLines) {
  const auto cam = make_camera(600, 25, -10);
  auto lines = manhattan_lines(cam, 25, 0.5, 7);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> px(0, 640), py(0, 480);
  const size_t outliers = lines.size() * 3 / 7;
  for (size_t i = 0; i < outliers; ++i) lines.push_back({{px(rng), py(rng)}, {px(rng), py(rng)}});
  const CameraEstimate est = estimate_camera(lines, 640, 480);
  expect_finite(est);
  EXPECT_NEAR(est.fx / 600.0, 1.0, 0.05);
  EXPECT_LT(up_error_deg(est.R_world_from_cam, cam.R_world_from_cam), 1.0);
}

TEST(Camera, FrontalViewFallsBackToTheFocalPrior) {
  // Yaw 0, pitch 0: the two horizontal vanishing points are at infinity; the
  // focal length is unobservable and the prior must be used.
  const auto cam = make_camera(600, 0, 0);
  const auto lines = manhattan_lines(cam, 25, 0.3, 9);
  CameraOptions options;
  options.prior_focal_px = 555;
  const CameraEstimate est = estimate_camera(lines, 640, 480, options);
  expect_finite(est);
  EXPECT_FALSE(est.focal_from_vanishing_points);
  EXPECT_DOUBLE_EQ(est.fx, 555);
  EXPECT_LT(up_error_deg(est.R_world_from_cam, cam.R_world_from_cam), 1.0);
}

// Hard cases: each must give a finite, deterministic camera and say which case applied.
TEST(CameraHardCases, NoLinesGivesALevelCameraWithThePriorFocal) {
  const CameraEstimate est = estimate_camera({}, 640, 480);
  expect_finite(est);
  EXPECT_EQ(est.which, CameraCase::NoVanishingPoints);
  EXPECT_EQ(est.report.why, "no_vanishing_points");
  EXPECT_NEAR(up_error_deg(est.R_world_from_cam, make_camera(500, 0, 0).R_world_from_cam), 0.0, 1e-9);
}

TEST(CameraHardCases, ParallelLinesOnly) {
  std::vector<LineSegment> lines;
  for (int i = 0; i < 30; ++i) lines.push_back({{10.0, 10.0 + 15 * i}, {600.0, 10.0 + 15 * i}});
  const CameraEstimate a = estimate_camera(lines, 640, 480);
  const CameraEstimate b = estimate_camera(lines, 640, 480);
  expect_finite(a);
  EXPECT_EQ(a.R_world_from_cam, b.R_world_from_cam);  // deterministic
  EXPECT_EQ(a.fx, b.fx);
}

TEST(CameraHardCases, DegenerateSegmentsAndConcurrentLines) {
  std::vector<LineSegment> lines;
  for (int i = 0; i < 20; ++i) lines.push_back({{100, 100}, {100, 100}});  // zero length
  for (int i = 0; i < 20; ++i) {
    const double a = i * 0.15;
    lines.push_back({{320, 240}, {320 + 200 * std::cos(a), 240 + 200 * std::sin(a)}});  // all through one point
  }
  lines.push_back({{1e9, -1e9}, {-1e9, 1e9}});  // absurd coordinates
  expect_finite(estimate_camera(lines, 640, 480));
  expect_finite(estimate_camera(lines, 1, 1));
}

TEST(CameraHardCases, RejectsAnEmptyImageSize) {
  EXPECT_THROW(estimate_camera({}, 0, 480), std::invalid_argument);
}

TEST(LinesCsv, ReadsRowsSkipsHeaderAndRejectsGarbage) {
  const std::string path = ::testing::TempDir() + "/lines.csv";
  std::ofstream(path) << "x1,y1,x2,y2\n1,2,3,4\n\n5,6,7,8\n";
  const auto lines = read_lines_csv(path);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[1].b, Eigen::Vector2d(7, 8));
  std::ofstream(path) << "1,2,3,4\nnot,a,line\n";
  EXPECT_THROW(read_lines_csv(path), std::runtime_error);
  EXPECT_THROW(read_lines_csv(path + ".missing"), std::runtime_error);
}

}  // namespace
}  // namespace propcam::inference
