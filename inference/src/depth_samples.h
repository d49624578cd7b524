// A depth map's surface pixels as world points, sampled on a grid: what the
// support planes and the hidden facades both histogram.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference::depth_samples {

// A pixel beyond this share of the sky's depth (or not finite and positive) is sky.
inline bool is_surface(float depth) { return std::isfinite(depth) && depth > 0 && depth < 0.5 * render::kSkyDepthM; }

inline Eigen::Vector3d world_point(const render::PinholeCamera& c, double x, double y, double depth) {
  return c.center_world + c.R_world_from_cam * Eigen::Vector3d((x - c.cx) / c.fx * depth, (y - c.cy) / c.fy * depth, depth);
}

// Where a world point falls in the photo, its depth along the camera's z,
// and the depth the photo sees at that pixel. None when the point is not
// farther than `min_view_depth` in front of the camera or falls outside
// the frame.
struct SeenAt {
  cv::Point pixel;
  double point_depth = 0.0;
  float seen_depth = 0.0f;
};
inline std::optional<SeenAt> seen_at(const render::PinholeCamera& c, const cv::Mat& depth, const Eigen::Vector3d& p,
                                     double min_view_depth) {
  const Eigen::Vector3d pc = c.world_to_camera(p);
  if (!(pc.z() > min_view_depth)) return std::nullopt;
  const double u = c.fx * pc.x() / pc.z() + c.cx, v = c.fy * pc.y() / pc.z() + c.cy;
  if (!(u >= 0 && v >= 0 && u < depth.cols && v < depth.rows)) return std::nullopt;
  const cv::Point px(static_cast<int>(u), static_cast<int>(v));
  return SeenAt{px, pc.z(), depth.at<float>(px)};
}

// The p-th quantile (0..1, nearest rank) of a non-empty list.
inline double percentile(std::vector<double> v, double p) {
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(p * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// Peaks of the histogram of `values` over [lo, hi) in bins of `bin`, smoothed
// over `thickness` (a plane's), strongest first: each found peak clears
// `suppress_halves` half-thicknesses around it before the next is sought.
// At most `max_peaks` rounds; a round whose peak holds fewer than
// `min_count` smoothed values ends the search. Values outside the range
// count in the end bins.
inline std::vector<double> histogram_peaks(const std::vector<double>& values, double lo, double hi, double bin,
                                           double thickness, double min_count, int max_peaks, int suppress_halves) {
  const int bins = static_cast<int>(std::ceil((hi - lo) / bin));
  std::vector<double> hist(bins, 0.0);
  for (double v : values) hist[std::clamp(static_cast<int>((v - lo) / bin), 0, bins - 1)] += 1;
  const int half = std::max(1, static_cast<int>(std::lround(0.5 * thickness / bin)));
  std::vector<double> smooth(bins, 0.0);
  for (int b = 0; b < bins; ++b)
    for (int k = -half; k <= half; ++k)
      if (b + k >= 0 && b + k < bins) smooth[b] += hist[b + k];
  std::vector<double> peaks;
  for (int round = 0; round < max_peaks; ++round) {
    const int best = static_cast<int>(std::max_element(smooth.begin(), smooth.end()) - smooth.begin());
    if (smooth[best] < min_count) break;
    for (int b = std::max(0, best - suppress_halves * half); b <= std::min(bins - 1, best + suppress_halves * half); ++b)
      smooth[b] = 0;
    peaks.push_back(lo + (best + 0.5) * bin);
  }
  return peaks;
}

// Calls visit(x, y, depth) for each surface pixel of a grid `step` pixels
// apart; returns how many grid pixels there were (surface or not).
template <class Visit>
int for_each_surface_sample(const cv::Mat& depth, int step, Visit&& visit) {
  int sampled = 0;
  for (int y = step / 2; y < depth.rows; y += step)
    for (int x = step / 2; x < depth.cols; x += step) {
      ++sampled;
      const float d = depth.at<float>(y, x);
      if (is_surface(d)) visit(x, y, d);
    }
  return sampled;
}

}  // namespace propcam::inference::depth_samples
