// A depth map's surface pixels as world points, sampled on a grid: what the
// support planes and the hidden facades both histogram.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference::depth_samples {

// A pixel beyond this share of the sky's depth (or not finite and positive) is sky.
inline bool is_surface(float depth) { return std::isfinite(depth) && depth > 0 && depth < 0.5 * render::kSkyDepthM; }

inline Eigen::Vector3d world_point(const render::PinholeCamera& c, double x, double y, double depth) {
  return c.center_world + c.R_world_from_cam * Eigen::Vector3d((x - c.cx) / c.fx * depth, (y - c.cy) / c.fy * depth, depth);
}

// The p-th quantile (0..1, nearest rank) of a non-empty list.
inline double percentile(std::vector<double> v, double p) {
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(p * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
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
