#include "common/compositor.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include "propcam/inference/scene_world.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/mesh_io.h"
#include "propcam/render/props.h"
#include "propcam/render/scene.h"

namespace propcam::firmware {

// Samples per pixel of the low-resolution empty-scene layers used to relight the photo.
constexpr int kSceneLayerSamples = 8;

render::Mesh load_prop(const std::string& name_or_file, const MaterialOverride& override_material) {
  render::Mesh mesh;
  const bool is_file = name_or_file.find('/') != std::string::npos || name_or_file.find('.') != std::string::npos;
  if (is_file) {
    if (!std::filesystem::exists(name_or_file)) throw std::invalid_argument("no mesh file '" + name_or_file + "'");
    mesh = render::load_mesh_file(name_or_file);
  } else {
    mesh = render::make_prop(name_or_file);
  }
  for (auto& m : mesh.materials) {
    if (override_material.type) m.type = render::material_type_from_string(*override_material.type);
    if (override_material.albedo) {
      m.albedo = override_material.albedo->cwiseMax(0.f).cwiseMin(1.f);
      m.texture.reset();
    }
  }
  return mesh;
}

double natural_height(const std::string& name_or_file, const render::Mesh& mesh) {
  for (const auto& preset : render::prop_presets())
    if (preset.name == name_or_file) return preset.natural_height_m;
  return mesh.bounds().sizes().y();
}

render::PlacedProp place_near_level_support(const render::Mesh& prop, const render::PinholeCamera& camera,
                                            const render::Scene& world, const render::PropPlacement& placement,
                                            render::PropPlacement* used) {
  if (used) *used = placement;
  try {
    return render::place_prop(prop, camera, world, placement);
  } catch (const render::TiltedSupportError&) {
    // Rings of growing radius, so the nearest level pixel wins.
    for (int r = 1; r <= kMaxSupportNudgePx; ++r)
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
          if (std::max(std::abs(dx), std::abs(dy)) != r) continue;
          render::PropPlacement nudged = placement;
          nudged.pixel_u += dx, nudged.pixel_v += dy;
          try {
            const render::PlacedProp placed = render::place_prop(prop, camera, world, nudged);
            if (used) *used = nudged;
            return placed;
          } catch (const std::invalid_argument&) {
          }
        }
    throw;
  }
}

CompositeWorld build_composite_world(const inference::SceneModel& scene, const render::Mesh& prop,
                                     const render::PropPlacement& placement) {
  const auto start = std::chrono::steady_clock::now();
  CompositeWorld w;
  w.camera = scene.camera();
  w.scene = std::make_unique<render::Scene>();
  render::Scene& world = *w.scene;
  // The paper's insertion constraint: the prop's base stands on a flat patch.
  w.depth = scene.depth.clone();
  if (!scene.normals.empty() && scene.normals.size() == scene.depth.size()) {
    cv::Mat normals = scene.normals.clone();
    const Eigen::Vector3f size = prop.bounds().sizes();
    const double scale = placement.height_m > 0 && size.y() > 0 ? placement.height_m / size.y() : 1.0;
    const double footprint_radius_m = 0.5 * scale * std::max(size.x(), size.z());
    w.flattening = inference::flatten_insertion_region(w.depth, normals, w.camera, scene.planes, placement.pixel_u,
                                                       placement.pixel_v, footprint_radius_m);
  }
  // The world the lighting's basis renders saw (the facades it continued out
  // of the frame, the box it closed the room with), at the photo's size.
  inference::add_scene_world(world, w.depth, scene.albedo, w.camera, scene.hidden_facades, scene.enclosure);

  // The prop is an instance: the background's BVH is built once, placement
  // looks at the background alone, and then the prop is moved into place.
  w.prop_index = world.add_prop(prop, Eigen::Affine3f::Identity());
  world.commit();
  w.placed = place_near_level_support(prop, w.camera, world, placement, &w.placement);
  world.set_prop_transform(w.prop_index, w.placed.world_from_prop);
  w.prop_bounds = world.world_bounds(w.prop_index);
  w.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  w.lights = scene.light_rig();
  // A lamp prop lights the room: its light shines only in the with-prop world.
  for (const render::SphereLight& lamp : render::prop_lights(prop, w.placed.world_from_prop))
    w.lights.sphere_lights.push_back(lamp);
  return w;
}

CompositeResult composite_prop(const cv::Mat& photo_linear, const inference::SceneModel& scene,
                               const render::Mesh& prop, const render::PropPlacement& placement,
                               const render::RenderSettings& settings, const CompositeOptions& options) {
  if (photo_linear.cols != scene.width || photo_linear.rows != scene.height)
    throw std::invalid_argument("the scene model was inferred from a photo of another size (" +
                                std::to_string(scene.width) + "x" + std::to_string(scene.height) + ")");
  const CompositeWorld w = build_composite_world(scene, prop, placement);
  const render::Scene& world = *w.scene;
  const render::PinholeCamera& camera = w.camera;
  const render::LightRig& lights = w.lights;
  CompositeResult result;
  result.placed = w.placed;
  result.scene_build_seconds = w.build_seconds;
  result.flattening = w.flattening;
  result.plan = render::plan_transport(world, lights, settings, options.plan);
  render::SessionSettings session_settings;
  session_settings.render = result.plan.settings;
  session_settings.render.light_layers = options.light_layers || settings.light_layers;
  session_settings.max_samples_per_pixel = settings.samples_per_pixel;
  // Tile culling bounds where the prop's shadows and bounce light fall; a
  // prop's own light reaches much further, so then every tile is rendered.
  bool prop_emits = false;
  for (const render::SphereLight& l : lights.sphere_lights) prop_emits = prop_emits || l.prop_only;
  session_settings.cull_tiles = options.cull_tiles && !prop_emits;
  session_settings.target_relative_error = options.target_relative_error;
  session_settings.denoise = options.denoise;
  render::RenderSession session(world, camera, result.plan.lights, photo_linear, w.prop_bounds, session_settings);
  while (!session.finished()) {
    if (!result.passes.empty() && options.time_budget_seconds > 0 &&
        result.passes.back().total_seconds + session.predicted_next_pass_seconds() > options.time_budget_seconds) {
      result.stopped_by_time_budget = true;
      break;
    }
    result.passes.push_back(session.run_pass());
    if (settings.progress) settings.progress(static_cast<double>(result.passes.back().max_samples) / settings.samples_per_pixel);
    if (options.on_pass) options.on_pass(session, result.passes.back());
  }
  result.samples_per_pixel = result.passes.empty() ? 0 : result.passes.back().max_samples;
  result.render = options.denoise ? session.denoised(&result.denoise) : session.differential();
  result.composite_linear = render::composite_differential(photo_linear, result.render);
  if (options.match_camera) {
    render::CameraMatchOptions match = options.camera_match;
    if (!(match.prop_depth_m > 0)) match.prop_depth_m = camera.world_to_camera(w.placed.base_world.cast<double>()).z();
    result.composite_linear = render::match_camera(photo_linear, result.composite_linear, result.render.coverage,
                                                   scene.imaging, match, scene.gamma, &result.camera_match);
  }
  if (options.full_size.width > photo_linear.cols)
    result.full_size_coverage = full_size_prop_coverage(world, camera, result.render.coverage, options.full_size,
                                                        result.camera_match.blur_sigma_px);
  result.tiles = session.tiles();
  result.reach = session.reach();
  if (session_settings.render.light_layers)
    result.layers = render::layers_in_original_order(result.plan, session.light_layers());
  if (options.scene_layers_width > 0) {
    render::RenderSettings low = settings;
    low.samples_per_pixel = std::min(settings.samples_per_pixel, kSceneLayerSamples);
    result.scene_layers = render::render_scene_light_layers(world, camera, lights, options.scene_layers_width, low);
  }
  // Depth of the composite: the scene's, with the prop's where it is seen.
  result.depth = w.depth.clone();
  const render::PrimaryBuffers primary = render::render_primary_buffers(world, camera, true);
  primary.depth.copyTo(result.depth, primary.prop_coverage);
  return result;
}

}  // namespace propcam::firmware
