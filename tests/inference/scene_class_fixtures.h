// What the scene-class tests share: the committed references and the RGB of
// one of blender-data's panoramas.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/capture/image_file.h"
#include "propcam/inference/scene_class_knn.h"

namespace propcam::inference::testing {

inline constexpr const char* kBlenderPanoramaDir = "/usr/share/blender/datafiles/studiolights/world";

inline const SceneReferenceSet& committed_references() {
  static const SceneReferenceSet refs = SceneReferenceSet::load(default_scene_reference_path());
  return refs;
}

inline cv::Mat blender_panorama(const std::string& name) {
  std::vector<cv::Mat> ch;
  cv::split(capture::read_image_float(std::string(kBlenderPanoramaDir) + "/" + name + ".exr"), ch);
  cv::Mat rgb;
  cv::merge(std::vector<cv::Mat>{ch[0], ch[1], ch[2]}, rgb);
  return rgb;
}

}  // namespace propcam::inference::testing
