// Real photographs: OpenCV's sample façade and home (Debian's opencv-doc) and
// views cut from the CC0 HDR panoramas of Debian's blender-data, whose camera
// is known exactly. scripts/setup.sh installs both packages.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "common/compositor.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/infer.h"
#include "propcam/inference/sky.h"
#include "worlds/real_views.h"
#include "shadow_check.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;

const std::string kOpenCvData = "/usr/share/doc/opencv-doc/examples/data/";
// A shadow must darken the floor beside the prop by at least this much.
constexpr double kMaxShadowRatio = 0.95;
// A visible shadow: darkened pixels beside the prop, at least this share of
// the prop's own area, and this many times more than brightened ones.
constexpr double kMinShadowArea = 0.1;
constexpr double kMinDarkerOverBrighter = 3.0;
constexpr double kMaxFocalError = 0.10;
constexpr double kMaxUpErrorDeg = 3.0;

bool have(const std::string& path) { return fs::exists(path); }

// The indoor/outdoor decision the pipeline makes: lines, camera, then sky.
bool classified_indoor(const cv::Mat& photo) {
  inference::StageReport lines_report, class_report;
  const auto lines = inference::detect_lines(photo, {}, lines_report);
  const inference::CameraEstimate cam = inference::estimate_camera(lines, photo.cols, photo.rows);
  render::PinholeCamera camera;
  camera.width = photo.cols;
  camera.height = photo.rows;
  camera.fx = cam.fx;
  camera.fy = cam.fy;
  camera.cx = cam.cx;
  camera.cy = cam.cy;
  camera.R_world_from_cam = cam.R_world_from_cam;
  camera.center_world = {0, 1.5, 0};
  return inference::classify_indoor(photo, camera, class_report);
}

double up_error_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  // World up in camera coordinates is the second row of R_world_from_cam.
  const double c = std::clamp(a.row(1).normalized().dot(b.row(1).normalized()), -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

TEST(RealPhotos, SkyTellsStreetsFromRooms) {
  if (!have(kOpenCvData + "building.jpg") || !have(panorama_path("interior")))
    GTEST_SKIP() << "install opencv-doc and blender-data (scripts/setup.sh does)";
  EXPECT_FALSE(classified_indoor(capture::load_photo_linear(kOpenCvData + "building.jpg"))) << "building.jpg";
  EXPECT_FALSE(classified_indoor(capture::load_photo_linear(kOpenCvData + "home.jpg"))) << "home.jpg";
  for (double yaw = 0; yaw < 360; yaw += 60)
    EXPECT_TRUE(classified_indoor(shoot_panorama_view(panorama_path("interior"), render::view_spec(yaw, 5, 60, 480, 360)).photo_linear))
        << "hotel room, yaw " << yaw;
  for (const char* name : {"sunrise", "sunset"})
    for (double yaw : {120.0, 240.0})
      EXPECT_FALSE(classified_indoor(shoot_panorama_view(panorama_path(name), render::view_spec(yaw, 0, 60, 480, 360)).photo_linear))
          << name << ", yaw " << yaw;
  for (uint32_t seed : {1u, 2u, 3u}) {
    render::SyntheticRoomSpec spec;
    spec.width = 240;
    spec.height = 180;
    spec.seed = seed;
    render::RenderSettings settings;
    settings.samples_per_pixel = 4;
    EXPECT_TRUE(classified_indoor(shoot_synthetic_room(spec, settings).photo_linear)) << "synthetic room " << seed;
  }
}

TEST(RealPhotos, StreetCompositeCastsASunShadowOnTheGround) {
  const std::string photo_path = kOpenCvData + "building.jpg";
  if (!have(photo_path)) GTEST_SKIP() << "install opencv-doc (scripts/setup.sh does)";
  const cv::Mat photo = capture::load_photo_linear(photo_path);
  const inference::SceneModel scene = inference::infer_scene(photo);
  EXPECT_FALSE(scene.indoor);
  bool sun = false;
  for (const auto& l : scene.lights)
    sun = sun || (l.type == inference::LightSource::Type::Area &&
                  inference::distant_light_direction(l, scene.camera().center_world).has_value());
  EXPECT_TRUE(sun) << "outdoors, a directional source explains the sunlit façade";
  render::RenderSettings s;
  s.samples_per_pixel = 8;
  const CompositeResult r = composite_prop(photo, scene, load_prop("cube"), {300, 560, 1.0, 20}, s);
  const testing::ShadowPixels shadow = testing::shadow_pixels(photo, r.composite_linear, r.render.coverage);
  EXPECT_GT(shadow.darker, kMinShadowArea * shadow.prop) << "prop pixels " << shadow.prop;
  EXPECT_GT(shadow.darker, kMinDarkerOverBrighter * shadow.brighter) << "darker " << shadow.darker;
}

TEST(RealPhotos, RoomCompositeCastsAShadowOnTheFloor) {
  if (!have(panorama_path("interior"))) GTEST_SKIP() << "install blender-data (scripts/setup.sh does)";
  // A hotel room seen from the bed: door, floor, luggage rack.
  const RealView room = shoot_panorama_view(panorama_path("interior"), render::view_spec(135, -20, 65, 480, 360));
  const inference::SceneModel scene = inference::infer_scene(room.photo_linear);
  EXPECT_TRUE(scene.indoor);
  EXPECT_NEAR(scene.fx / room.camera.fx, 1.0, kMaxFocalError);
  EXPECT_LT(up_error_deg(scene.R_world_from_cam, room.camera.R_world_from_cam), kMaxUpErrorDeg);
  render::RenderSettings s;
  s.samples_per_pixel = 16;
  const CompositeResult r = composite_prop(room.photo_linear, scene, load_prop("cube"), {300, 315, 0.4, 20}, s);
  EXPECT_LT(testing::shadow_ratio(room.photo_linear, r.composite_linear, r.render.coverage), kMaxShadowRatio);
  const testing::ShadowPixels shadow = testing::shadow_pixels(room.photo_linear, r.composite_linear, r.render.coverage);
  EXPECT_GT(shadow.darker, kMinShadowArea * shadow.prop) << "prop pixels " << shadow.prop;
  EXPECT_GT(shadow.darker, kMinDarkerOverBrighter * shadow.brighter) << "darker " << shadow.darker;
}

// The hotel room is warm (wooden floor, tungsten-toned walls): its fitted
// lights may carry that cast or none, never the opposite (they came out pale
// blue, and so did a white plinth placed in it).
TEST(RealPhotos, AWarmRoomsLightsAreNotBlue) {
  if (!have(panorama_path("interior"))) GTEST_SKIP() << "install blender-data (scripts/setup.sh does)";
  const RealView room = shoot_panorama_view(panorama_path("interior"), render::view_spec(135, -20, 65, 640, 480));
  const cv::Scalar photo_mean = cv::mean(room.photo_linear);
  ASSERT_GT(photo_mean[0], photo_mean[2]) << "the view is warm";
  const inference::SceneModel scene = inference::infer_scene(room.photo_linear);
  Eigen::Vector3d light = Eigen::Vector3d::Zero();
  for (const auto& l : scene.lights)
    if (l.type != inference::LightSource::Type::Ibl) light += l.intensity;
  ASSERT_GT(light.sum(), 0.0);
  EXPECT_GE(light[0], 0.99 * light[2]) << "lights " << light.transpose();
  EXPECT_GE(light[1], 0.99 * light[2]) << "lights " << light.transpose();
}

}  // namespace
}  // namespace propcam::firmware
