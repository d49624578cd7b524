// Hard cases of the sun patch (sun_patch.h): floors painted analytically,
// seen by a camera looking down at them, so the answer is known exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "propcam/inference/sun_patch.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/scene.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;

struct Floor {
  render::PinholeCamera camera;
  cv::Mat photo, depth;
};

// A camera 1.5 m over the floor, looking along -Z and 40 degrees down; the
// floor's brightness at (x, z) is `paint` (sky, where the ray misses it,
// at luminance 1).
Floor painted_floor(const std::function<double(double, double)>& paint) {
  Floor f;
  f.camera = render::pinhole_with_fov(160, 120, 60);
  f.camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, -40 * kPi / 180, 0);
  f.camera.center_world = {0, 1.5, 0};
  f.photo = cv::Mat(120, 160, CV_32FC3);
  f.depth = cv::Mat(120, 160, CV_32F);
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x) {
      const Vector3d ray = f.camera.R_world_from_cam * Vector3d((x - f.camera.cx) / f.camera.fx, (y - f.camera.cy) / f.camera.fy, 1);
      if (ray.y() >= -1e-3) {
        f.depth.at<float>(y, x) = static_cast<float>(render::kSkyDepthM);
        f.photo.at<cv::Vec3f>(y, x) = {1, 1, 1};
        continue;
      }
      const double t = 1.5 / -ray.y();
      const Vector3d p = f.camera.center_world + t * ray;
      f.depth.at<float>(y, x) = static_cast<float>(t);  // the ray's z in the camera is 1
      const float v = static_cast<float>(paint(p.x(), p.z()));
      f.photo.at<cv::Vec3f>(y, x) = {v, v, v};
    }
  return f;
}

RoomHeights on_floor() {
  RoomHeights h;
  h.floor_y = 0.0;
  return h;
}

// The parallelogram a window 1.2 m wide in a wall along z casts, its sun
// line sheared 25 degrees from the wall's normal (x): x in [-0.75, 0.7],
// z in [-3, -1.1], all in the frame.
constexpr double kShear = 25 * kPi / 180;
bool in_patch(double x, double z) {
  const double beta = (0.7 - x) / std::cos(kShear);  // along the sun line
  const double alpha = z + 3.0 - beta * std::sin(kShear);  // along the wall
  return beta >= 0.0 && beta <= 1.6 && alpha >= 0.0 && alpha <= 1.2;
}

TEST(SunPatchHardCases, ASharpParallelogramGivesItsShearedSunLine) {
  const Floor f = painted_floor([](double x, double z) { return in_patch(x, z) ? 0.8 : 0.1; });
  const SunPatch p = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  ASSERT_TRUE(p.found) << p.why << " " << p.details.dump();
  EXPECT_EQ(p.details["wall_axis"], "z");
  // The sun line is 25 degrees off the wall's normal (x); either way along it.
  const double line_deg = std::atan2(std::abs(p.sun_direction.z()), std::abs(p.sun_direction.x())) * 180 / kPi;
  EXPECT_NEAR(line_deg, 25.0, 3.0) << p.details.dump();
  EXPECT_NEAR(p.brightness_ratio, 8.0, 1.0);
  EXPECT_TRUE(p.sun_direction.allFinite());
}

TEST(SunPatchHardCases, AnEvenFloorHasNone) {
  const Floor f = painted_floor([](double, double) { return 0.2; });
  const SunPatch p = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  EXPECT_FALSE(p.found);
  EXPECT_EQ(p.why, "no bright patch on the floor");
}

TEST(SunPatchHardCases, ACheckedFloorIsAPatternNotAPatch) {
  const Floor f = painted_floor([](double x, double z) {
    const bool odd = (static_cast<int>(std::floor(x / 0.5)) + static_cast<int>(std::floor(z / 0.5))) % 2 != 0;
    return odd ? 0.6 : 0.1;
  });
  const SunPatch p = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  EXPECT_FALSE(p.found);
  EXPECT_NE(p.why.find("pattern"), std::string::npos) << p.why;
}

TEST(SunPatchHardCases, ALampsPoolOfLightFades) {
  const Floor f = painted_floor([](double x, double z) {
    const double r2 = x * x + (z + 2.5) * (z + 2.5);
    return 0.05 + 1.5 * std::exp(-r2 / (2 * 0.6 * 0.6));  // 30x the floor at its centre
  });
  const SunPatch p = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  EXPECT_FALSE(p.found);
  EXPECT_NE(p.why.find("fades"), std::string::npos) << p.why;
}

TEST(SunPatchHardCases, NoFloorSeen) {
  Floor f = painted_floor([](double, double) { return 0.2; });
  f.depth.setTo(render::kSkyDepthM);
  EXPECT_EQ(find_sun_patch(f.photo, f.depth, f.camera, on_floor()).why, "too little floor seen");
  // The floor far below where the layout puts it.
  const Floor g = painted_floor([](double x, double z) { return in_patch(x, z) ? 0.8 : 0.1; });
  RoomHeights high;
  high.floor_y = 1.0;
  EXPECT_FALSE(find_sun_patch(g.photo, g.depth, g.camera, high).found);
}

TEST(SunPatchHardCases, BadInputsAreNotJudged) {
  const Floor f = painted_floor([](double x, double z) { return in_patch(x, z) ? 0.8 : 0.1; });
  EXPECT_FALSE(find_sun_patch(cv::Mat(), f.depth, f.camera, on_floor()).found);
  EXPECT_FALSE(find_sun_patch(f.photo, cv::Mat(), f.camera, on_floor()).found);
  cv::Mat small;
  cv::resize(f.depth, small, {80, 60});
  EXPECT_FALSE(find_sun_patch(f.photo, small, f.camera, on_floor()).found);
  // A black photo.
  EXPECT_FALSE(find_sun_patch(cv::Mat::zeros(f.photo.size(), CV_32FC3), f.depth, f.camera, on_floor()).found);
}

TEST(SunPatchHardCases, NonFiniteValuesStayOut) {
  Floor f = painted_floor([](double x, double z) { return in_patch(x, z) ? 0.8 : 0.1; });
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (int y = 0; y < f.photo.rows; y += 7)
    for (int x = 0; x < f.photo.cols; x += 5) {
      f.photo.at<cv::Vec3f>(y, x) = {nan, nan, nan};
      f.depth.at<float>(y + 3 < f.depth.rows ? y + 3 : y, x) = (x / 5) % 2 ? nan : inf;
    }
  const SunPatch p = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  EXPECT_TRUE(p.sun_direction.allFinite());
  EXPECT_TRUE(p.window.corner.allFinite() && p.window.edge_u.allFinite() && p.window.edge_v.allFinite());
  EXPECT_TRUE(std::isfinite(p.brightness_ratio));
  cv::Mat albedo(f.photo.size(), CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  EXPECT_TRUE(std::isfinite(take_sun_patch_out_of_albedo(albedo, p)));
  EXPECT_TRUE(cv::checkRange(albedo));
}

TEST(SunPatchHardCases, IsDeterministic) {
  const Floor f = painted_floor([](double x, double z) { return in_patch(x, z) ? 0.8 : 0.1; });
  const SunPatch a = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  const SunPatch b = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  ASSERT_EQ(a.found, b.found);
  EXPECT_EQ(a.sun_direction, b.sun_direction);
  EXPECT_EQ(a.window.corner, b.window.corner);
  EXPECT_EQ(a.details.dump(), b.details.dump());
}

// The albedo's correction changes nothing for a patch not found, and
// nothing of an albedo of another size.
TEST(SunPatchHardCases, AnAlbedoIsOnlyChangedWhereAPatchWasFound) {
  const Floor f = painted_floor([](double, double) { return 0.2; });
  const SunPatch none = find_sun_patch(f.photo, f.depth, f.camera, on_floor());
  cv::Mat albedo = f.photo.clone();
  EXPECT_EQ(take_sun_patch_out_of_albedo(albedo, none), 1.0);
  EXPECT_EQ(cv::norm(albedo, f.photo, cv::NORM_INF), 0.0);
  const Floor g = painted_floor([](double x, double z) { return in_patch(x, z) ? 0.8 : 0.1; });
  const SunPatch found = find_sun_patch(g.photo, g.depth, g.camera, on_floor());
  ASSERT_TRUE(found.found);
  cv::Mat other(60, 80, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  EXPECT_EQ(take_sun_patch_out_of_albedo(other, found), 1.0);
}

}  // namespace
}  // namespace propcam::inference
