// Sky detection: the cue that tells a street from a room, and the part of an
// outdoor photo that is light source rather than geometry.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

struct SkyOptions {
  int analysis_width = 160;            // the test runs on a copy this wide
  double max_log_gradient = 0.12;      // sky is smooth: |grad log L| per analysis pixel
  int texture_window = 7;              // analysis pixels
  double max_local_log_std = 0.07;     // spread of log L in that window
  double min_relative_brightness = 0.45;  // of the image's 99th-percentile luminance
  double max_red_over_blue = 1.12;     // sky is neutral or blue, never warm or green
  double max_green_over_blue = 1.15;
  double max_below_horizon = 0.03;     // ray slope: sky lies above the horizon
  double min_fraction_outdoor = 0.02;  // sky area (of the frame) that makes a photo outdoor
  // A clearly blue sky is rare indoors, so less of it is enough.
  double clear_sky_blue_over_red = 2.0;
  double min_clear_sky_fraction = 0.015;
  double clear_sky_brightness_factor = 0.3;  // blue pixels need only this share of the brightness
};

struct SkyEstimate {
  cv::Mat mask;                 // CV_8U at the photo's size, 255 on sky
  double fraction = 0.0;        // of the frame
  Eigen::Vector3d mean_colour = Eigen::Vector3d::Zero();  // linear RGB of the sky pixels
  bool blue = false;
  double blue_over_red = 0.0;
  double largest_region_fraction = 0.0;  // the biggest connected sky region
};

// Sky pixels: smooth, bright, neutral-to-blue regions above the horizon of
// `camera` that touch the top of the frame (or its sides above the horizon).
SkyEstimate detect_sky(const cv::Mat& photo_linear, const render::PinholeCamera& camera, const SkyOptions& options = {});

// Indoor unless enough sky is seen. Fills the "scene_class" stage report.
bool classify_indoor(const cv::Mat& photo_linear, const render::PinholeCamera& camera, StageReport& report,
                     SkyEstimate* sky = nullptr, const SkyOptions& options = {});

}  // namespace propcam::inference
