// Real photographs with a known camera: rectilinear views cut from the CC0
// HDR panoramas of Debian's blender-data, exposed and quantised as a camera
// would (auto exposure, clipping, 8-bit sRGB). Fixtures and benchmarks use
// them to measure inference on real scenes, not only on our own renders.
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "propcam/render/camera.h"
#include "propcam/render/panorama.h"

namespace propcam::firmware {

// Where Debian's blender-data installs its panoramas (city, courtyard, forest,
// interior, night, studio, sunrise, sunset).
inline constexpr const char* kBlenderWorldDir = "/usr/share/blender/datafiles/studiolights/world";

std::string panorama_path(const std::string& name);  // kBlenderWorldDir/name.exr

struct RealView {
  cv::Mat photo_linear;          // CV_32FC3, clipped to [0,1] and quantised to 8 bits
  render::PinholeCamera camera;  // the exact camera
};

// Throws std::runtime_error when the panorama cannot be read.
RealView shoot_panorama_view(const std::string& panorama_file, const render::ViewSpec& spec);

}  // namespace propcam::firmware
