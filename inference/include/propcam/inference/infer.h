// Single-photo scene inference: camera, geometry, albedo, lights.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "propcam/inference/camera.h"
#include "propcam/inference/layout.h"
#include "propcam/inference/lighting.h"
#include "propcam/inference/scene_model.h"

namespace propcam::inference {

struct InferenceOptions {
  double camera_height_m = 1.5;  // the board's mount height; the paper's scale prior
  LineDetectionOptions lines;
  CameraOptions camera;
  LayoutOptions layout;
  AlbedoOptions albedo;
  LightingOptions lighting;
  // Segments given instead of detected (e.g. `--lines FILE.csv`).
  std::optional<std::vector<LineSegment>> given_lines;
  // Called with each stage's name before it starts.
  std::function<void(const std::string&)> on_stage;
};

// `photo_linear` is CV_32FC3 linear RGB. Throws std::invalid_argument for an
// empty or too small photo; otherwise always returns a finite model whose
// reports say which fallbacks applied.
SceneModel infer_scene(const cv::Mat& photo_linear, const InferenceOptions& options = {});

constexpr int kMinPhotoSide = 16;
// Linear radiance above this is clipped (HDR inputs, and infinities).
constexpr double kMaxPhotoRadiance = 1e4;

}  // namespace propcam::inference
