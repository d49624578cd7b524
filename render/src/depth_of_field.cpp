#include "propcam/render/depth_of_field.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace propcam::render {
namespace {

// Below this diameter a circle of confusion is a point: the pixel stays sharp.
constexpr double kSharpCocPx = 1.0;
// A neighbour nearer than the pixel by this factor of depth is foreground.
constexpr float kForegroundDepthRatio = 0.98f;
constexpr double kMinFocusDistanceM = 1e-3;

}  // namespace

double circle_of_confusion_px(double depth_m, double fx_px, const DepthOfField& dof) {
  if (!(dof.aperture_m > 0) || !(fx_px > 0)) return 0.0;
  const double focus = std::max(dof.focus_distance_m, kMinFocusDistanceM);
  const double inverse_depth = depth_m > 0 && std::isfinite(depth_m) ? 1.0 / depth_m : 0.0;
  const double coc = fx_px * dof.aperture_m * std::abs(inverse_depth - 1.0 / focus);
  return std::min(coc, std::max(0.0, dof.max_blur_px));
}

cv::Mat apply_depth_of_field(const cv::Mat& linear, const cv::Mat& depth, double fx_px, const DepthOfField& dof) {
  if (linear.type() != CV_32FC3 || depth.type() != CV_32F || linear.size() != depth.size())
    throw std::invalid_argument("depth of field: need a CV_32FC3 image and a CV_32F depth map of one size");
  if (!std::isfinite(dof.focus_distance_m) || !std::isfinite(dof.aperture_m) || dof.aperture_m < 0)
    throw std::invalid_argument("depth of field: focus distance and aperture must be finite, aperture >= 0");
  if (!(dof.aperture_m > 0)) return linear.clone();
  const int w = linear.cols, h = linear.rows;
  cv::Mat radius(h, w, CV_32F);
  float max_radius = 0.f;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double coc = circle_of_confusion_px(depth.at<float>(y, x), fx_px, dof);
      const float r = coc < kSharpCocPx ? 0.f : static_cast<float>(0.5 * coc);
      radius.at<float>(y, x) = r;
      max_radius = std::max(max_radius, r);
    }
  auto z_of = [&](int x, int y) {
    const float z = depth.at<float>(y, x);
    return z > 0 && std::isfinite(z) ? z : std::numeric_limits<float>::infinity();
  };
  const int reach = static_cast<int>(std::ceil(max_radius));
  cv::Mat out(h, w, CV_32FC3);
  // Scatter as gather: neighbour j lands on pixel i when i lies inside j's
  // circle, with weight 1/area (energy preserving). A neighbour behind the
  // pixel only counts within the pixel's own circle, so a sharp foreground
  // edge is not overlaid by the blurred background behind it.
  out.forEach<cv::Vec3f>([&](cv::Vec3f& result, const int* pos) {
    const int y = pos[0], x = pos[1];
    const float zi = z_of(x, y), ri = radius.at<float>(y, x);
    cv::Vec3f sum(0, 0, 0);
    float weight = 0.f;
    for (int dy = -reach; dy <= reach; ++dy) {
      const int yj = y + dy;
      if (yj < 0 || yj >= h) continue;
      for (int dx = -reach; dx <= reach; ++dx) {
        const int xj = x + dx;
        if (xj < 0 || xj >= w) continue;
        const float rj = radius.at<float>(yj, xj);
        const float d2 = static_cast<float>(dx * dx + dy * dy);
        const bool foreground = z_of(xj, yj) < zi * kForegroundDepthRatio;
        // Its own spread reaches i; background neighbours also need i's spread.
        const float r = foreground ? rj : std::min(rj, ri);
        if (d2 > (r + 0.5f) * (r + 0.5f)) continue;
        const float wj = 1.f / (1.f + r * r);
        sum += wj * linear.at<cv::Vec3f>(yj, xj);
        weight += wj;
      }
    }
    result = weight > 0 ? sum / weight : linear.at<cv::Vec3f>(y, x);
  });
  return out;
}

}  // namespace propcam::render
