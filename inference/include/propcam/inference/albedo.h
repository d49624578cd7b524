// Diffuse albedo by Color Retinex (Grosse et al. 2009, after Land and
// McCann): an image derivative belongs to reflectance when the chromaticity
// changes across it or when it is a large step in intensity; every other
// derivative is shading. The reflectance derivatives are integrated by a DCT
// Poisson solve (poisson.h), so it runs in milliseconds on the device.
#pragma once

#include <opencv2/core.hpp>
#include <optional>

#include "propcam/inference/scene_model.h"

namespace propcam::inference {

struct AlbedoOptions {
  // Retinex, or the first cut: the photo divided by its Gaussian-blurred
  // luminance (sigma 2% of the diagonal). Retinex indoors: on all three
  // worlds it lowers the rooms' composite error (docs/albedo.md). Outdoors
  // the worlds disagree (Blender's streets gain, our own lose a composite
  // that beat the photo, the panoramas' light direction moves 5 degrees
  // further off), and the blur normalises locally where the light fit
  // under-renders a region (the lawn of building.jpg): `outdoor_method`
  // keeps the blur there; empty means `method` everywhere.
  enum class Method { Retinex, BlurredShading };
  Method method = Method::Retinex;
  std::optional<Method> outdoor_method = Method::BlurredShading;
  double blur_sigma_fraction = 0.02;
  // Thresholds on per-pixel derivatives, chosen on the generator's rooms
  // (`propcam bench`, albedo LMSE): chromaticity change (|delta rgb/sum|) and
  // log-intensity step that mark a reflectance edge.
  double chromaticity_threshold = 0.02;
  double log_intensity_threshold = 0.35;
  double mean_albedo = 0.5;  // reflectance assigned to the image's average (albedo is known up to scale)
  // Grey world: the albedo's mean colour is made grey, so that the photo's
  // colour cast (a 3000 K lamp's orange) is left for the lights to carry and
  // reaches the prop. Off, the cast stays in the albedo and a white prop
  // renders white in an orange room. Each channel's gain is bounded by
  // kMaxGreyWorldGain. Off by default: it lowers the Blender world's
  // composite error (tune mean 0.095 -> 0.092), whose renders keep the
  // lamp's colour, but raises the panoramas' (diffuse si-RMSE 0.179 ->
  // 0.205), real captures already white-balanced (`propcam bench worlds
  // --sweeps grey_world`; docs/albedo.md).
  bool grey_world = false;
  int max_solve_width = 1024;  // wider photos are solved at this width and upsampled
};

constexpr double kMaxGreyWorldGain = 4.0;

// `photo_linear` CV_32FC3; returns CV_32FC3 albedo in [0, 0.95].
cv::Mat estimate_albedo(const cv::Mat& photo_linear, const AlbedoOptions& options, StageReport& report);

// Multiplies the albedo by `scale` in place, clamped to the same [0, 0.95]
// (the light fit may find the albedo's scale: LightingEstimate::albedo_scale).
void scale_albedo(cv::Mat& albedo, double scale);

// Grosse et al.'s local mean squared error: over 20-px windows (step 10),
// each estimate window scaled to fit the truth best, summed and normalised
// by the truth's energy. 0 is perfect; 1 is as bad as predicting zero.
double local_mse(const cv::Mat& estimate, const cv::Mat& truth, int window = 20);

}  // namespace propcam::inference
