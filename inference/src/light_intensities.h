// The lighting stage's last step (estimate_lighting, lighting.cpp): basis
// renders of the empty scene, one light at a time, then the fit of the
// lights' intensities, colours and the camera response. It lives apart from
// lighting.cpp only to keep each file readable.
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/inference/lighting.h"

namespace propcam::inference {

using LightingClock = std::chrono::steady_clock;

inline double seconds_since(LightingClock::time_point start) {
  return std::chrono::duration<double>(LightingClock::now() - start).count();
}

// What the fit takes from estimate_lighting's arguments and earlier steps.
struct LightFitInputs {
  const cv::Mat& photo_linear;
  const cv::Mat& depth;
  const cv::Mat& albedo;
  const render::PinholeCamera& camera;
  const std::vector<SupportPlane>& planes;
  bool indoor;
  const LightingOptions& options;
  const GeometryCues& cues;
  bool sky_calibrated;  // the sky was seen: the environment's weight is measured
  bool search_sun;      // outdoors the sun is searched for from the shadows
  const std::vector<Eigen::Vector3d>& ranked_sun_directions;  // the search's first guesses
  size_t visible_sources;  // out.lights' first entries, seen in the photo
};

// out.lights (visible sources, unseen ones, the environment last) and
// colours (one per light) come in; the fitted intensities, response
// (out.gamma), albedo scale and the stage's report go out. Lights the fit
// switched off are pruned; a searched sun may join them.
void fit_light_intensities(const LightFitInputs& in, std::vector<Eigen::Vector3d>& colours, LightingEstimate& out);

}  // namespace propcam::inference
