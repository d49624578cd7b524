// The appliance's main job: a photo and a scene model in, a prop placed and
// composited by differential rendering out.
#pragma once

#include <optional>
#include <string>

#include "propcam/inference/scene_model.h"
#include "propcam/render/mesh.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/placement.h"

namespace propcam::firmware {

struct MaterialOverride {
  std::optional<std::string> type;             // diffuse|plastic|glossy|metal|dielectric|glass
  std::optional<Eigen::Vector3f> albedo;
};

// A preset name or a mesh file path; applies the override to every material.
render::Mesh load_prop(const std::string& name_or_file, const MaterialOverride& override_material = {});
// Natural height of a preset, or of a loaded mesh's bounding box.
double natural_height(const std::string& name_or_file, const render::Mesh& mesh);

struct CompositeResult {
  cv::Mat composite_linear;  // CV_32FC3
  render::DifferentialRender render;
  render::PlacedProp placed;
  double scene_build_seconds = 0.0;
};

CompositeResult composite_prop(const cv::Mat& photo_linear, const inference::SceneModel& scene,
                               const render::Mesh& prop, const render::PropPlacement& placement,
                               const render::RenderSettings& settings);

}  // namespace propcam::firmware
