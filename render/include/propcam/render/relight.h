// Relighting after rendering, as in the paper: the differential render keeps
// the prop's change split by light, so a light's intensity can be changed
// with no re-render — for the prop alone ("change only the prop's light") or
// for the whole photo ("change the scene light"), the photo then relit by the
// ratio of per-light renders of the empty scene.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"

namespace propcam::render {

struct LightLayers {
  cv::Mat coverage;             // CV_32F, M
  std::vector<cv::Mat> change;  // CV_32FC3 per light (rig order, then emissive surfaces): mean per-sample change
};

// Scale per layer (missing entries are 1). Negative or non-finite scales are errors.
using LightScales = std::vector<float>;

// The composite with each light's part of the prop's change scaled; the photo
// itself is unchanged. With all scales 1 this is the ordinary composite.
cv::Mat relight_prop(const cv::Mat& photo_linear, const LightLayers& layers, const LightScales& scales);

// Per-light renders of the empty scene (the background world), at a reduced
// width: what the photo's own light is made of, for relighting the photo.
struct SceneLightLayers {
  std::vector<cv::Mat> empty_scene;  // CV_32FC3 per rig light, low resolution
};
SceneLightLayers render_scene_light_layers(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                           int width, const RenderSettings& settings);

// The whole photo relit: photo x (sum s_i N_i / sum N_i), plus the scaled change.
cv::Mat relight_scene(const cv::Mat& photo_linear, const LightLayers& layers, const SceneLightLayers& scene_layers,
                      const LightScales& scales);

}  // namespace propcam::render
