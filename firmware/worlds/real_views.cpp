#include "worlds/real_views.h"

#include "propcam/capture/image_file.h"

namespace propcam::firmware {

std::string panorama_path(const std::string& name) { return std::string(kBlenderWorldDir) + "/" + name + ".exr"; }

RealView shoot_panorama_view(const std::string& panorama_file, const render::ViewSpec& spec) {
  RealView view;
  view.camera = render::view_camera(spec);
  cv::Mat linear = render::rectilinear_view(capture::read_image_float(panorama_file), view.camera);
  render::auto_expose(linear);
  // What an 8-bit camera file keeps: clipped, sRGB-encoded, quantised.
  view.photo_linear = capture::srgb8_to_linear(capture::linear_to_srgb8(linear));
  return view;
}

}  // namespace propcam::firmware
