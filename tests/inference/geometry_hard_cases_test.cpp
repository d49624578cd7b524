// The geometry stage's hard cases (issue 4): each gives finite, deterministic
// depth, normals and camera, or a clear error.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "line_scenes.h"
#include "propcam/inference/infer.h"
#include "propcam/render/depth_mesh.h"
#include "room_truth.h"

namespace propcam::inference {
namespace {

using testing::axis_lines;
using testing::make_camera;
using testing::manhattan_lines;
using testing::rolled;

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// A plain mid-grey photo: the lines given decide the camera.
cv::Mat grey(int w = 640, int h = 480) { return cv::Mat(h, w, CV_32FC3, cv::Scalar::all(0.18)); }

GeometryEstimate run(const cv::Mat& photo, std::optional<std::vector<LineSegment>> lines) {
  InferenceOptions o;
  o.given_lines = std::move(lines);
  return infer_geometry(photo, o);
}

void expect_finite_and_deterministic(const cv::Mat& photo, const std::optional<std::vector<LineSegment>>& lines) {
  const GeometryEstimate a = run(photo, lines), b = run(photo, lines);
  ASSERT_EQ(a.depth.size(), photo.size());
  EXPECT_TRUE(cv::checkRange(a.depth));
  EXPECT_TRUE(cv::checkRange(a.normals));
  double lo = 0;
  cv::minMaxLoc(a.depth, &lo);
  EXPECT_GT(lo, 0.0);
  EXPECT_TRUE(std::isfinite(a.camera.fx) && a.camera.fx > 0);
  EXPECT_TRUE(a.camera.R_world_from_cam.allFinite());
  EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0.0) << "not deterministic";
  EXPECT_EQ(a.camera.fx, b.camera.fx);
  EXPECT_FALSE(a.planes.empty());
  for (const auto& r : a.reports) {
    if (r.stage == "depth") {
      EXPECT_TRUE(r.details.contains("converged"));
    }
  }
}

double up_error_deg(const Eigen::Matrix3d& est, const Eigen::Matrix3d& truth) {
  const Eigen::Vector3d a = est.transpose() * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d b = truth.transpose() * Eigen::Vector3d::UnitY();
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * kRadToDeg;
}

TEST(GeometryHardCases, NoLines) { expect_finite_and_deterministic(grey(), std::vector<LineSegment>{}); }

TEST(GeometryHardCases, AllLinesParallel) {
  expect_finite_and_deterministic(grey(), axis_lines(make_camera(540, 20, 5), 1, 40, 0.5, 3));
}

TEST(GeometryHardCases, TwoVanishingPointsOnly) {
  const auto cam = make_camera(540, 30, -8);
  std::vector<LineSegment> lines = axis_lines(cam, 0, 30, 0.5, 4);
  const auto more = axis_lines(cam, 1, 30, 0.5, 5);
  lines.insert(lines.end(), more.begin(), more.end());
  expect_finite_and_deterministic(grey(), lines);
  EXPECT_LT(up_error_deg(run(grey(), lines).camera.R_world_from_cam, cam.R_world_from_cam), 2.0);
}

TEST(GeometryHardCases, VanishingPointAtInfinity) {
  // A frontal, level view: verticals and one horizontal family are parallel in the image.
  const auto cam = make_camera(540, 0, 0);
  expect_finite_and_deterministic(grey(), manhattan_lines(cam, 30, 0.5, 6));
}

TEST(GeometryHardCases, NearlyCollinearVanishingPoints) {
  // Yaw 3, pitch 1: one horizontal point near the centre, the others far
  // out: the focal length is ill-conditioned and must fall back, finite.
  const auto cam = make_camera(540, 3, 1);
  const auto lines = manhattan_lines(cam, 30, 0.5, 7);
  expect_finite_and_deterministic(grey(), lines);
  const GeometryEstimate g = run(grey(), lines);
  EXPECT_GT(g.camera.fx, 0.4 * 0.85 * 640);
  EXPECT_LT(g.camera.fx, 2.5 * 0.85 * 640);
}

TEST(GeometryHardCases, TiltedHorizonRollTenDegrees) {
  const auto cam = rolled(make_camera(540, 35, -10), 10);
  const auto lines = manhattan_lines(cam, 40, 0.5, 8);
  expect_finite_and_deterministic(grey(), lines);
  EXPECT_LT(up_error_deg(run(grey(), lines).camera.R_world_from_cam, cam.R_world_from_cam), 2.0);
}

TEST(GeometryHardCases, VeryWideAndVeryNarrowFieldOfView) {
  for (double hfov_deg : {110.0, 20.0}) {
    const double f = 320.0 / std::tan(0.5 * hfov_deg / kRadToDeg);
    const auto cam = make_camera(f, 30, -5);
    expect_finite_and_deterministic(grey(), manhattan_lines(cam, 40, 0.5, 9));
  }
}

TEST(GeometryHardCases, TexturedFloorWithHundredsOfSpuriousLines) {
  // A rendered room (tiled floor) plus 400 short random segments.
  const RoomTruth t = room_truth(4, 320, 240);
  StageReport r;
  // The room's albedo under flat light is enough for LSD to see its edges.
  cv::Mat albedo;
  {
    render::Scene scene;
    scene.add_mesh(t.room.room, render::Layer::Background);
    scene.commit();
    albedo = render::render_primary_buffers(scene, t.room.camera, false).albedo;
  }
  std::vector<LineSegment> lines = detect_lines(albedo, {}, r);
  std::mt19937_64 rng(10);
  std::uniform_real_distribution<double> x(0, 319), y(120, 239), a(0, 3.14159), len(6, 25);
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector2d p(x(rng), y(rng));
    const double ang = a(rng), l = len(rng);
    lines.push_back({p, p + l * Eigen::Vector2d(std::cos(ang), std::sin(ang))});
  }
  expect_finite_and_deterministic(albedo, lines);
  EXPECT_LT(up_error_deg(run(albedo, lines).camera.R_world_from_cam, t.room.camera.R_world_from_cam), 3.0);
}

TEST(GeometryHardCases, TinyBlackAndSaturatedFrames) {
  expect_finite_and_deterministic(cv::Mat(16, 16, CV_32FC3, cv::Scalar::all(0.3)), std::nullopt);
  expect_finite_and_deterministic(cv::Mat(120, 160, CV_32FC3, cv::Scalar::all(0.0)), std::nullopt);
  expect_finite_and_deterministic(cv::Mat(120, 160, CV_32FC3, cv::Scalar::all(1.0)), std::nullopt);
  EXPECT_THROW(run(cv::Mat(8, 8, CV_32FC3, cv::Scalar::all(0.3)), std::nullopt), std::invalid_argument);
}

TEST(GeometryHardCases, LargeNonManhattanObject) {
  // A room's lines plus a big box turned 30 degrees about the vertical
  // (its horizontal edges point nowhere Manhattan): as many lines as the room.
  const auto cam = make_camera(540, 25, -8);
  std::vector<LineSegment> lines = manhattan_lines(cam, 25, 0.5, 11);
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(30.0 / kRadToDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d centre(0.5, 0.0, -4.0);
  for (int i = 0; i < 75; ++i) {
    const int axis = i % 2 == 0 ? 0 : 2;
    Eigen::Vector3d p(-1.0 + 0.1 * (i % 20), 0.05 * (i % 30), 0.0), q = p;
    q[axis] += 1.2;
    Eigen::Vector2d a, b;
    if (cam.project(centre + turn * p, a) && cam.project(centre + turn * q, b)) lines.push_back({a, b});
  }
  expect_finite_and_deterministic(grey(), lines);
  EXPECT_LT(up_error_deg(run(grey(), lines).camera.R_world_from_cam, cam.R_world_from_cam), 3.0);
}

}  // namespace
}  // namespace propcam::inference
