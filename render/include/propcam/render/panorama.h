// Rectilinear views of equirectangular panoramas: real photographs with a
// known camera, cut from the HDR panoramas the project installs from Debian
// (blender-data). Used as real-photo fixtures and, later, for IBL matching.
#pragma once

#include <opencv2/core.hpp>

#include "propcam/render/camera.h"

namespace propcam::render {

struct ViewSpec {
  int width = 640;
  int height = 480;
  double horizontal_fov_deg = 60.0;
  double yaw_deg = 0.0;    // turn about world Y, counter-clockwise seen from above; 0 looks along -Z
  double pitch_deg = 0.0;  // positive looks up
  double roll_deg = 0.0;   // about the view axis
  double camera_height_m = 1.5;
};

inline ViewSpec view_spec(double yaw_deg, double pitch_deg, double horizontal_fov_deg, int width, int height) {
  ViewSpec spec;
  spec.width = width;
  spec.height = height;
  spec.horizontal_fov_deg = horizontal_fov_deg;
  spec.yaw_deg = yaw_deg;
  spec.pitch_deg = pitch_deg;
  return spec;
}

// Camera (OpenCV axes, world Y up, centre `camera_height_m` above the origin) for a view.
PinholeCamera view_camera(const ViewSpec& spec);

// Samples the latlong (CV_32FC3, same convention as EnvironmentLight: the
// centre column is -Z, columns increase toward +X, the seam is +Z, row 0 is
// +Y) through `camera`, 2x2
// supersampled with bilinear lookups. Negative and non-finite texels become 0.
cv::Mat rectilinear_view(const cv::Mat& latlong, const PinholeCamera& camera);

}  // namespace propcam::render

namespace propcam::render {

// A camera's auto exposure: scales linear radiance so that the given
// luminance percentile lands at `target` (brighter texels then clip in an
// 8-bit file, as in a real photo). Returns the scale applied; 1 for a black image.
double auto_expose(cv::Mat& linear, double percentile = 0.97, double target = 0.9);

}  // namespace propcam::render
