#include "propcam/render/panorama.h"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>
#include <algorithm>

#include "propcam/render/lights.h"

namespace propcam::render {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr double kMinFovDeg = 1.0, kMaxFovDeg = 170.0;

cv::Vec3f clean(const cv::Vec3f& c) {
  cv::Vec3f out;
  for (int k = 0; k < 3; ++k) out[k] = std::isfinite(c[k]) && c[k] > 0.f ? c[k] : 0.f;
  return out;
}

// Bilinear lookup that wraps in longitude and clamps in latitude.
cv::Vec3f sample_latlong(const cv::Mat& image, float u, float v) {
  const float x = u * image.cols - 0.5f, y = std::clamp(v * image.rows - 0.5f, 0.f, image.rows - 1.f);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float fx = x - x0, fy = y - y0;
  auto at = [&](int xi, int yi) {
    xi = ((xi % image.cols) + image.cols) % image.cols;
    yi = std::clamp(yi, 0, image.rows - 1);
    return clean(image.at<cv::Vec3f>(yi, xi));
  };
  return (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) + fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1));
}

}  // namespace

PinholeCamera view_camera(const ViewSpec& spec) {
  if (spec.width < 1 || spec.height < 1) throw std::invalid_argument("view size must be at least 1x1");
  if (!(spec.horizontal_fov_deg >= kMinFovDeg && spec.horizontal_fov_deg <= kMaxFovDeg))
    throw std::invalid_argument("horizontal field of view must lie in [1, 170] degrees");
  PinholeCamera cam;
  cam.width = spec.width;
  cam.height = spec.height;
  cam.fx = cam.fy = 0.5 * spec.width / std::tan(0.5 * spec.horizontal_fov_deg * kDegToRad);
  cam.cx = 0.5 * spec.width - 0.5;
  cam.cy = 0.5 * spec.height - 0.5;
  // Level camera looking along -Z: x right = +X, y down = -Y, z forward = -Z.
  Eigen::Matrix3d level;
  level.col(0) = Eigen::Vector3d::UnitX();
  level.col(1) = -Eigen::Vector3d::UnitY();
  level.col(2) = -Eigen::Vector3d::UnitZ();
  const Eigen::Matrix3d yaw = Eigen::AngleAxisd(spec.yaw_deg * kDegToRad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  // Pitch about the camera's x axis (up is -y), roll about its z axis.
  const Eigen::Matrix3d pitch = Eigen::AngleAxisd(spec.pitch_deg * kDegToRad, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d roll = Eigen::AngleAxisd(spec.roll_deg * kDegToRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  cam.R_world_from_cam = yaw * level * pitch * roll;
  cam.center_world = Eigen::Vector3d(0, spec.camera_height_m, 0);
  return cam;
}

cv::Mat rectilinear_view(const cv::Mat& latlong, const PinholeCamera& camera) {
  if (latlong.empty() || latlong.type() != CV_32FC3) throw std::invalid_argument("panorama must be a non-empty CV_32FC3 image");
  cv::Mat out(camera.height, camera.width, CV_32FC3);
  constexpr int kSub = 2;
  out.forEach<cv::Vec3f>([&](cv::Vec3f& pixel, const int* pos) {
    cv::Vec3f sum(0, 0, 0);
    for (int sy = 0; sy < kSub; ++sy)
      for (int sx = 0; sx < kSub; ++sx) {
        const double u = pos[1] - 0.5 + (sx + 0.5) / kSub, v = pos[0] - 0.5 + (sy + 0.5) / kSub;
        const Eigen::Vector3f d = camera.ray_direction(u, v).cast<float>();
        const Eigen::Vector2f uv = EnvironmentLight::direction_to_uv(d);
        sum += sample_latlong(latlong, uv.x(), uv.y());
      }
    pixel = sum * (1.f / (kSub * kSub));
  });
  return out;
}

}  // namespace propcam::render

namespace propcam::render {

double auto_expose(cv::Mat& linear, double percentile, double target) {
  constexpr double kMinLuminance = 1e-9;  // below this the image is black: leave it
  std::vector<float> lum;
  lum.reserve(linear.total());
  for (auto it = linear.begin<cv::Vec3f>(); it != linear.end<cv::Vec3f>(); ++it)
    lum.push_back(0.2126f * (*it)[0] + 0.7152f * (*it)[1] + 0.0722f * (*it)[2]);
  if (lum.empty()) return 1.0;
  const size_t k = std::min(lum.size() - 1, static_cast<size_t>(std::clamp(percentile, 0.0, 1.0) * (lum.size() - 1)));
  std::nth_element(lum.begin(), lum.begin() + k, lum.end());
  const double level = lum[k];
  if (!(level > kMinLuminance)) return 1.0;
  const double scale = target / level;
  linear *= scale;
  return scale;
}

}  // namespace propcam::render
