// The appliance's main job: a photo and a scene model in, a prop placed and
// composited by differential rendering out.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "propcam/inference/scene_model.h"
#include "propcam/render/mesh.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/photo_imaging.h"
#include "propcam/inference/support_planes.h"
#include "propcam/render/placement.h"
#include "propcam/render/render_session.h"
#include "propcam/render/transport_plan.h"
#include "common/working_size.h"

namespace propcam::firmware {

struct MaterialOverride {
  std::optional<std::string> type;             // diffuse|plastic|glossy|metal|dielectric|glass
  std::optional<Eigen::Vector3f> albedo;
};

// A preset name or a mesh file path; applies the override to every material.
render::Mesh load_prop(const std::string& name_or_file, const MaterialOverride& override_material = {});
// Natural height of a preset, or of a loaded mesh's bounding box.
double natural_height(const std::string& name_or_file, const render::Mesh& mesh);

// The world a composite is rendered in: the photo's depth mesh as background
// and the placed prop, committed; with the camera and lights of the scene model.
// Keep it in place while a RenderSession refers to its members.
struct CompositeWorld {
  std::unique_ptr<render::Scene> scene;
  render::PinholeCamera camera;
  render::LightRig lights;
  render::PlacedProp placed;
  int prop_index = -1;  // the prop's instance in `scene` (set_prop_transform moves it)
  Eigen::AlignedBox3f prop_bounds;
  double build_seconds = 0.0;  // depth mesh, placement and acceleration structures
  cv::Mat depth;               // the scene's depth with the insertion constraint applied
  inference::InsertionFlattening flattening;
  // Where the prop stands: the asked pixel, or the nearest one within
  // kMaxSupportNudgePx when the asked one fell on a steep triangle.
  render::PropPlacement placement;
};

// A spot offered from the smoothed normals can fall on one steep triangle of
// the depth mesh (depth noise, a kerb's edge) amid level ground: the prop then
// stands on the nearest level pixel this close. A wall stays refused.
constexpr int kMaxSupportNudgePx = 3;

// place_prop, but on a tilted surface it tries the pixels within
// kMaxSupportNudgePx, nearest first; `used` gets the pixel the prop stands on.
// Throws as place_prop does when none of them is level.
render::PlacedProp place_near_level_support(const render::Mesh& prop, const render::PinholeCamera& camera,
                                            const render::Scene& world, const render::PropPlacement& placement,
                                            render::PropPlacement* used = nullptr);

// Throws std::invalid_argument as place_prop does (pixel outside, no support,
// a surface tilted at and around the pixel).
CompositeWorld build_composite_world(const inference::SceneModel& scene, const render::Mesh& prop,
                                     const render::PropPlacement& placement);

struct CompositeOptions {
  bool cull_tiles = true;               // skip tiles the prop cannot affect
  render::PlanOptions plan;             // which transport to skip (plan.allow_skips = false: simulate everything)
  double target_relative_error = 0.0;   // stop tiles early at this error (0: run to --spp)
  // > 0: no pass starts that would end after this many seconds of rendering
  // (predicted from the last pass's time per sample); the first always runs.
  double time_budget_seconds = 0.0;
  bool light_layers = false;            // keep the change split by light (relighting)
  int scene_layers_width = 0;           // > 0: also per-light renders of the empty scene this wide
  // Filter the prop's change where the half buffers say it lowers the error
  // (render/denoise.h); per-light layers stay unfiltered.
  bool denoise = true;
  // Give the prop the photo's blur and noise where the scene's imaging
  // estimate says the photo has them (render/photo_imaging.h).
  bool match_camera = true;
  render::CameraMatchOptions camera_match;
  // Larger than the photo: also the prop's coverage at this size, for
  // delivering the composite there with sharp edges (working_size.h).
  cv::Size full_size;
  // Called after each progressive pass with the session (snapshot, tiles, errors).
  std::function<void(const render::RenderSession&, const render::PassReport&)> on_pass;
};

struct CompositeResult {
  cv::Mat composite_linear;  // CV_32FC3
  render::DifferentialRender render;     // denoised where it helped, with options.denoise
  render::DenoiseReport denoise;
  render::CameraMatchReport camera_match;  // with options.match_camera
  render::PlacedProp placed;
  double scene_build_seconds = 0.0;
  std::vector<render::PassReport> passes;
  int samples_per_pixel = 0;            // reached (below the settings' when the time budget stopped the render)
  bool stopped_by_time_budget = false;
  std::vector<render::TileStatus> tiles;
  render::PropReach reach;
  render::TransportPlan plan;
  render::LightLayers layers;              // with options.light_layers
  render::SceneLightLayers scene_layers;   // with options.scene_layers_width > 0
  inference::InsertionFlattening flattening;  // the insertion constraint around the prop's base
  cv::Mat depth;  // CV_32F metres along camera z of what each pixel sees, the prop included (for depth of field)
  SharpCoverage full_size_coverage;  // with options.full_size
};

CompositeResult composite_prop(const cv::Mat& photo_linear, const inference::SceneModel& scene,
                               const render::Mesh& prop, const render::PropPlacement& placement,
                               const render::RenderSettings& settings, const CompositeOptions& options = {});

}  // namespace propcam::firmware
