// Hard cases of the lamp read from lit walls (lit_wall_lamp.h): a box room
// painted analytically, so the answer is known exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "propcam/inference/lit_wall_lamp.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;

SupportPlane plane(const char* name, Vector3d normal, double offset) {
  SupportPlane p;
  p.name = name;
  p.normal = normal;
  p.offset = offset;
  return p;
}

// A room x in [-3, 3], y in [0, 2.8], z in [-6, 2]; normals face inward.
std::vector<SupportPlane> box_planes() {
  return {plane("floor", {0, 1, 0}, 0.0), plane("ceiling", {0, -1, 0}, 2.8), plane("wall_front", {0, 0, 1}, 6.0),
          plane("wall_back", {0, 0, -1}, 2.0), plane("wall_left", {1, 0, 0}, 3.0), plane("wall_right", {-1, 0, 0}, 3.0)};
}

struct Room {
  render::PinholeCamera camera;
  cv::Mat photo, depth;
};

// The box seen from (0, 1.5, 0) along -Z, 8 degrees down; each surface point
// p with normal n has luminance 0.5 * (ambient + power * max(0, n.(lamp - p)) / |lamp - p|^3).
Room painted_room(std::optional<Vector3d> lamp, double ambient = 0.05, double power = 1.0) {
  Room r;
  r.camera = render::pinhole_with_fov(160, 120, 60);
  r.camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, -8 * kPi / 180, 0);
  r.camera.center_world = {0, 1.5, 0};
  r.photo = cv::Mat(120, 160, CV_32FC3);
  r.depth = cv::Mat(120, 160, CV_32F);
  const auto planes = box_planes();
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x) {
      const Vector3d ray_cam((x - r.camera.cx) / r.camera.fx, (y - r.camera.cy) / r.camera.fy, 1);
      const Vector3d ray = r.camera.R_world_from_cam * ray_cam;
      double t_near = std::numeric_limits<double>::infinity();
      Vector3d normal = Vector3d::Zero();
      for (const auto& p : planes) {
        const double facing = p.normal.dot(ray);
        if (facing >= 0) continue;  // the inside faces the ray coming at it
        const double t = -(p.normal.dot(r.camera.center_world) + p.offset) / facing;
        if (t > 0 && t < t_near) t_near = t, normal = p.normal;
      }
      const Vector3d point = r.camera.center_world + t_near * ray;
      r.depth.at<float>(y, x) = static_cast<float>(t_near);  // ray_cam's z is 1
      double shade = ambient;
      if (lamp) {
        const Vector3d to_lamp = *lamp - point;
        shade += power * std::max(0.0, normal.dot(to_lamp)) / std::pow(to_lamp.norm(), 3);
      }
      const float v = static_cast<float>(0.5 * shade);
      r.photo.at<cv::Vec3f>(y, x) = {v, v, v};
    }
  return r;
}

cv::Mat even_albedo(const Room& r) { return cv::Mat(r.photo.size(), CV_32FC3, cv::Scalar::all(0.5)); }

void expect_finite(const LitWallLamp& lamp) {
  EXPECT_TRUE(lamp.position.allFinite());
  EXPECT_TRUE(std::isfinite(lamp.explained));
  EXPECT_TRUE(std::isfinite(lamp.lamp_share));
  if (!lamp.found) EXPECT_FALSE(lamp.why.empty());
}

// Exact cos/d^2 shading from a lamp out of view: found where it is.
TEST(LitWallLampHardCases, AnExactFalloffGivesTheLampsPlace) {
  const Vector3d truth(-2.2, 1.0, -1.0);
  const Room r = painted_room(truth);
  const LitWallLamp lamp = find_lit_wall_lamp(r.photo, r.depth, even_albedo(r), r.camera, box_planes());
  ASSERT_TRUE(lamp.found) << lamp.why << " " << lamp.details.dump();
  EXPECT_LT((lamp.position - truth).norm(), 0.25) << lamp.details.dump();
  EXPECT_GT(lamp.explained, 0.95);
}

TEST(LitWallLampHardCases, EvenlyLitWallsGiveNoLamp) {
  const Room r = painted_room(std::nullopt);
  const LitWallLamp lamp = find_lit_wall_lamp(r.photo, r.depth, even_albedo(r), r.camera, box_planes());
  EXPECT_FALSE(lamp.found);
  EXPECT_NE(lamp.why.find("evenly"), std::string::npos) << lamp.why;
  expect_finite(lamp);
}

// The lamp's pool is in the frame, with the lamp itself where the photo
// sees the wall behind it: no lamp is put where the photo would show one.
TEST(LitWallLampHardCases, NeverWhereThePhotoWouldShowIt) {
  const Room r = painted_room(Vector3d(0.0, 1.4, -4.5), 0.05, 0.3);
  const LitWallLamp lamp = find_lit_wall_lamp(r.photo, r.depth, even_albedo(r), r.camera, box_planes());
  expect_finite(lamp);
  if (lamp.found) {
    const Vector3d c = r.camera.world_to_camera(lamp.position);
    const double u = r.camera.fx * c.x() / c.z() + r.camera.cx, v = r.camera.fy * c.y() / c.z() + r.camera.cy;
    const bool in_frame = c.z() > 0.1 && u >= 0 && v >= 0 && u < r.photo.cols && v < r.photo.rows;
    if (in_frame) EXPECT_LE(r.depth.at<float>(static_cast<int>(v), static_cast<int>(u)), 1.1 * c.z());
  }
}

TEST(LitWallLampHardCases, NoWallsInTheLayout) {
  const Room r = painted_room(Vector3d(-2.2, 1.0, -1.0));
  const LitWallLamp lamp = find_lit_wall_lamp(r.photo, r.depth, even_albedo(r), r.camera, {box_planes()[0]});
  EXPECT_FALSE(lamp.found);
  expect_finite(lamp);
}

TEST(LitWallLampHardCases, ABlackPhotoOrAllSky) {
  Room r = painted_room(Vector3d(-2.2, 1.0, -1.0));
  const cv::Mat black = cv::Mat::zeros(r.photo.size(), CV_32FC3);
  LitWallLamp lamp = find_lit_wall_lamp(black, r.depth, even_albedo(r), r.camera, box_planes());
  EXPECT_FALSE(lamp.found);
  expect_finite(lamp);
  const cv::Mat sky(r.depth.size(), CV_32F, cv::Scalar(render::kSkyDepthM));
  lamp = find_lit_wall_lamp(r.photo, sky, even_albedo(r), r.camera, box_planes());
  EXPECT_FALSE(lamp.found);
  expect_finite(lamp);
}

TEST(LitWallLampHardCases, NonFiniteInputsStayFinite) {
  Room r = painted_room(Vector3d(-2.2, 1.0, -1.0));
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (int y = 0; y < r.photo.rows; y += 3)
    for (int x = 0; x < r.photo.cols; x += 5) {
      r.photo.at<cv::Vec3f>(y, x) = {nan, inf, -inf};
      r.depth.at<float>((y + 1) % r.photo.rows, x) = (x % 2) ? nan : -inf;
    }
  cv::Mat albedo = even_albedo(r);
  albedo.at<cv::Vec3f>(10, 10) = {nan, nan, nan};
  expect_finite(find_lit_wall_lamp(r.photo, r.depth, albedo, r.camera, box_planes()));
  std::vector<SupportPlane> planes = box_planes();
  planes[2].offset = std::numeric_limits<double>::quiet_NaN();
  planes[3].normal = Vector3d::Constant(std::numeric_limits<double>::infinity());
  expect_finite(find_lit_wall_lamp(r.photo, r.depth, albedo, r.camera, planes));
  render::PinholeCamera broken = r.camera;
  broken.fx = std::numeric_limits<double>::quiet_NaN();
  const LitWallLamp lamp = find_lit_wall_lamp(r.photo, r.depth, albedo, broken, box_planes());
  EXPECT_FALSE(lamp.found);
  expect_finite(lamp);
}

TEST(LitWallLampHardCases, MismatchedSizesAreRefused) {
  const Room r = painted_room(Vector3d(-2.2, 1.0, -1.0));
  cv::Mat small_depth;
  cv::resize(r.depth, small_depth, cv::Size(80, 60));
  LitWallLamp lamp = find_lit_wall_lamp(r.photo, small_depth, even_albedo(r), r.camera, box_planes());
  EXPECT_FALSE(lamp.found);
  EXPECT_NE(lamp.why.find("size"), std::string::npos);
  lamp = find_lit_wall_lamp(cv::Mat(), r.depth, cv::Mat(), r.camera, box_planes());
  EXPECT_FALSE(lamp.found);
  const cv::Mat grey(r.photo.size(), CV_8UC3, cv::Scalar::all(100));
  EXPECT_FALSE(find_lit_wall_lamp(grey, r.depth, cv::Mat(), r.camera, box_planes()).found);
}

TEST(LitWallLampHardCases, Deterministic) {
  const Room r = painted_room(Vector3d(-2.2, 1.0, -1.0));
  const LitWallLamp a = find_lit_wall_lamp(r.photo, r.depth, even_albedo(r), r.camera, box_planes());
  const LitWallLamp b = find_lit_wall_lamp(r.photo, r.depth, even_albedo(r), r.camera, box_planes());
  EXPECT_EQ(a.found, b.found);
  EXPECT_EQ(a.position, b.position);
  EXPECT_EQ(a.details, b.details);
}

}  // namespace
}  // namespace propcam::inference
