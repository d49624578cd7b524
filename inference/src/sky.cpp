#include "propcam/inference/sky.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "luminance.h"

namespace propcam::inference {
namespace {

constexpr double kLogOffset = 1e-3;      // keeps log L finite on black pixels
constexpr float kClippedLinear = 0.98f;  // a channel this bright is clipped: sky by brightness
constexpr double kMinBlueExcess = 1.08;  // blue over red that marks a blue (clear) sky

}  // namespace

SkyEstimate detect_sky(const cv::Mat& photo_linear, const render::PinholeCamera& camera, const SkyOptions& options) {
  SkyEstimate out;
  out.mask = cv::Mat::zeros(photo_linear.size(), CV_8U);
  if (photo_linear.empty() || photo_linear.cols < 2 || photo_linear.rows < 2) return out;
  const int w = std::min(photo_linear.cols, std::max(8, options.analysis_width));
  const int h = std::max(2, static_cast<int>(std::lround(static_cast<double>(w) * photo_linear.rows / photo_linear.cols)));
  cv::Mat small;
  cv::resize(photo_linear, small, {w, h}, 0, 0, cv::INTER_AREA);
  const cv::Mat lum = luminance_image(small);
  cv::Mat log_lum;
  cv::log(lum + kLogOffset, log_lum);
  cv::GaussianBlur(log_lum, log_lum, {0, 0}, 0.8);
  cv::Mat gx, gy;
  cv::Sobel(log_lum, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(log_lum, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  // Local spread of log L over a window: sky is smooth at every scale, a
  // backlit curtain or a lit wall has folds and texture.
  cv::Mat mean, mean_sq;
  const cv::Size window(options.texture_window, options.texture_window);
  cv::blur(log_lum, mean, window, {-1, -1}, cv::BORDER_REFLECT);
  cv::blur(log_lum.mul(log_lum), mean_sq, window, {-1, -1}, cv::BORDER_REFLECT);
  std::vector<float> sorted(lum.begin<float>(), lum.end<float>());
  const size_t k99 = static_cast<size_t>(0.99 * (sorted.size() - 1));
  std::nth_element(sorted.begin(), sorted.begin() + k99, sorted.end());
  const double bright_level = options.min_relative_brightness * sorted[k99];

  const double sx = static_cast<double>(photo_linear.cols) / w, sy = static_cast<double>(photo_linear.rows) / h;
  cv::Mat candidate = cv::Mat::zeros(h, w, CV_8U);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const cv::Vec3f c = small.at<cv::Vec3f>(y, x);
      const float l = lum.at<float>(y, x);
      const bool clipped = std::max({c[0], c[1], c[2]}) >= kClippedLinear;
      // Clear blue sky can be darker than a sunlit wall; neutral sky cannot.
      const bool clear_blue = c[2] > options.clear_sky_blue_over_red * std::max(c[0], 1e-6f) && c[2] >= c[1];
      const double needed = clear_blue ? bright_level * options.clear_sky_brightness_factor : bright_level;
      if (!(l > 0.f) || (!clipped && l < needed)) continue;
      if (std::hypot(gx.at<float>(y, x), gy.at<float>(y, x)) > options.max_log_gradient) continue;
      const float m = mean.at<float>(y, x);
      if (std::sqrt(std::max(0.f, mean_sq.at<float>(y, x) - m * m)) > options.max_local_log_std) continue;
      const double blue = std::max<double>(c[2], 1e-6);
      if (c[0] / blue > options.max_red_over_blue || c[1] / blue > options.max_green_over_blue) continue;
      const Eigen::Vector3d ray = camera.ray_direction((x + 0.5) * sx - 0.5, (y + 0.5) * sy - 0.5);
      if (ray.y() < -options.max_below_horizon) continue;
      candidate.at<uint8_t>(y, x) = 255;
    }
  // Sky reaches the frame's edge: keep regions touching the top row, or a
  // side column above the horizon (a sky seen past a building's corner).
  cv::Mat labels;
  const int n = cv::connectedComponents(candidate, labels, 8, CV_32S);
  std::vector<uint8_t> touches(n, 0);
  std::vector<int> area(n, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) ++area[labels.at<int>(y, x)];
  for (int x = 0; x < w; ++x) touches[labels.at<int>(0, x)] = 1;
  for (int y = 0; y < h; ++y) {
    touches[labels.at<int>(y, 0)] = 1;
    touches[labels.at<int>(y, w - 1)] = 1;
  }
  touches[0] = 0;  // background label
  cv::Mat sky_small = cv::Mat::zeros(h, w, CV_8U);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (candidate.at<uint8_t>(y, x) && touches[labels.at<int>(y, x)]) {
        sky_small.at<uint8_t>(y, x) = 255;
        const cv::Vec3f c = small.at<cv::Vec3f>(y, x);
        sum += Eigen::Vector3d(c[0], c[1], c[2]);
        ++count;
      }
  for (int i = 1; i < n; ++i)
    if (touches[i]) out.largest_region_fraction = std::max(out.largest_region_fraction, area[i] / (static_cast<double>(w) * h));
  cv::resize(sky_small, out.mask, photo_linear.size(), 0, 0, cv::INTER_NEAREST);
  out.fraction = static_cast<double>(count) / (static_cast<double>(w) * h);
  if (count > 0) {
    out.mean_colour = sum / count;
    out.blue_over_red = out.mean_colour.z() / std::max(out.mean_colour.x(), 1e-6);
    out.blue = out.blue_over_red > kMinBlueExcess;
  }
  return out;
}

bool classify_indoor(const cv::Mat& photo_linear, const render::PinholeCamera& camera, StageReport& report,
                     SkyEstimate* sky_out, const SkyOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  SkyEstimate sky = detect_sky(photo_linear, camera, options);
  const bool outdoor = sky.fraction >= options.min_fraction_outdoor ||
                       (sky.blue_over_red >= options.clear_sky_blue_over_red && sky.fraction >= options.min_clear_sky_fraction);
  report.stage = "scene_class";
  report.usable = true;
  report.why = outdoor ? "sky seen: outdoor" : "no sky seen: indoor";
  report.details = {{"sky_fraction", sky.fraction},
                    {"sky_blue", sky.blue},
                    {"blue_over_red", sky.blue_over_red},
                    {"largest_region", sky.largest_region_fraction},
                    {"sky_colour", {sky.mean_colour.x(), sky.mean_colour.y(), sky.mean_colour.z()}}};
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (sky_out) *sky_out = std::move(sky);
  return !outdoor;
}

}  // namespace propcam::inference
