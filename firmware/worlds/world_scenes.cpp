#include "worlds/world_scenes.h"

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "common/compositor.h"
#include "propcam/capture/image_file.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A pixel of an emission-only render above this (summed RGB) sees an emitter.
constexpr float kEmissionFloor = 1e-4f;

// A camera's file: 8-bit sRGB. Returns the display values over 255 and
// sets `linear` to what load_photo_linear would read from that file.
cv::Mat quantise_like_a_camera(const cv::Mat& linear_render, cv::Mat* linear) {
  const cv::Mat srgb8 = capture::linear_to_srgb8(linear_render);
  if (linear) *linear = capture::srgb8_to_linear(srgb8);
  cv::Mat display;
  srgb8.convertTo(display, CV_32FC3, 1.0 / 255.0);
  return display;
}

// The room with the prop placed by the same rule `propcam composite` uses,
// committed, and the placed prop.
struct InsertionScene {
  render::Scene scene;
  render::PlacedProp placed;
};

void build_insertion_scene(InsertionScene& out, const render::SyntheticRoom& room, const render::Mesh& prop,
                           const render::PropPlacement& placement) {
  render::Scene support;
  support.add_mesh(room.room, render::Layer::Background);
  support.commit();
  out.placed = render::place_prop(prop, room.camera, support, placement);
  out.scene.add_mesh(room.room, render::Layer::Background);
  render::Mesh mesh = prop;
  mesh.transform(out.placed.world_from_prop);
  out.scene.add_mesh(std::move(mesh), render::Layer::Prop);
  out.scene.commit();
}

WorldScene own_scene(const std::string& name, const std::string& kind, const SyntheticShot& shot,
                     const render::Mesh& prop, const OwnWorldOptions& o, const render::RenderSettings& settings) {
  WorldScene w;
  w.world = "own";
  w.name = name;
  w.kind = kind;
  w.photo_display = quantise_like_a_camera(shot.photo_linear, &w.photo_linear);
  w.truth = shot.truth;
  w.true_camera = shot.room.camera;
  w.prop = o.prop;
  const Eigen::Vector2d at = free_floor_pixel(shot.room);
  w.placement = render::PropPlacement{at.x(), at.y(), o.height_m > 0 ? o.height_m : natural_height(o.prop, prop), o.yaw_deg};
  InsertionScene inserted;
  build_insertion_scene(inserted, shot.room, prop, w.placement);
  // The photo's settings, so both draw the same random streams: pixels whose
  // paths never meet the prop come out identical.
  w.insertion_display = quantise_like_a_camera(render::render_image(inserted.scene, shot.room.camera, shot.room.lights, settings), nullptr);
  w.prop_mask = render::render_primary_buffers(inserted.scene, shot.room.camera, true).prop_coverage;
  render::Scene empty;
  empty.add_mesh(shot.room.room, render::Layer::Background);
  empty.commit();
  // Emitters: the room's panels are emissive surfaces (their rig lights sit
  // just in front); with no lights and no bounce only those show.
  render::RenderSettings emission_only = settings;
  emission_only.samples_per_pixel = 1;
  emission_only.max_bounces = 0;
  cv::Mat emission;
  cv::transform(render::render_image(empty, shot.room.camera, render::LightRig{}, emission_only), emission,
                cv::Matx13f(1.f, 1.f, 1.f));
  w.emitters = emission > kEmissionFloor;
  const Eigen::Vector3f base = inserted.placed.base_world + Eigen::Vector3f::UnitY() * static_cast<float>(kProbeLiftM);
  w.true_light = probe_light_moments(empty, shot.room.lights, base, o.probe_face_px, o.probe_spp, settings.seed);
  return w;
}

json read_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  try {
    json j;
    in >> j;
    return j;
  } catch (const json::exception& e) {
    throw std::runtime_error("cannot parse " + path.string() + ": " + e.what());
  }
}

// photo.png or photo.jpg (the world keeps one of them).
fs::path image_with_stem(const fs::path& folder, const std::string& stem) {
  for (const char* ext : {".png", ".jpg", ".jpeg"})
    if (fs::exists(folder / (stem + ext))) return folder / (stem + ext);
  throw std::runtime_error("no " + stem + ".png or " + stem + ".jpg in " + folder.string());
}

cv::Mat read_display(const fs::path& path) {
  cv::Mat m = capture::read_image_float(path.string());
  if (m.channels() == 4) cv::cvtColor(m, m, cv::COLOR_RGBA2RGB);
  if (m.channels() == 1) cv::cvtColor(m, m, cv::COLOR_GRAY2RGB);
  if (m.type() != CV_32FC3) throw std::runtime_error(path.string() + " is not an RGB image");
  return m;
}

cv::Mat read_mask(const fs::path& path, const cv::Size& size) {
  if (!fs::exists(path)) return {};
  cv::Mat m = capture::read_image_float(path.string());
  if (m.channels() > 1) cv::extractChannel(m, m, 0);
  if (m.size() != size) throw std::runtime_error(path.string() + " differs in size from the photo");
  return m > 0.5f;
}

}  // namespace

std::vector<WorldScene> make_own_world(const OwnWorldOptions& o) {
  const render::Mesh prop = load_prop(o.prop);
  render::RenderSettings settings;
  settings.samples_per_pixel = o.spp;
  std::vector<WorldScene> out;
  render::SyntheticRoomSpec room_spec;
  room_spec.width = o.width;
  room_spec.height = o.height;
  for (int seed = 1; seed <= o.rooms; ++seed) {
    room_spec.seed = static_cast<uint64_t>(seed);
    out.push_back(own_scene("room " + std::to_string(seed), "room", shoot_synthetic_room(room_spec, settings), prop, o, settings));
  }
  render::SyntheticStreetSpec street_spec;
  street_spec.width = o.width;
  street_spec.height = o.height;
  for (int seed = 1; seed <= o.streets; ++seed) {
    street_spec.seed = static_cast<uint64_t>(seed);
    out.push_back(own_scene("street " + std::to_string(seed), "street", shoot_synthetic_street(street_spec, settings), prop,
                            o, settings));
  }
  return out;
}

WorldScene load_blender_scene(const std::string& folder_name) {
  const fs::path folder(folder_name);
  WorldScene w;
  w.world = "blender";
  w.name = folder.filename().string();
  const json meta = read_json(folder / "meta.json");
  w.split = meta.value("split", "");
  w.kind = meta.value("kind", "");
  w.exposure = meta.value("exposure_multiplier", 1.0);
  if (const auto rule = meta.find("spp_rule"); rule != meta.end() && rule->is_object() &&
                                               rule->contains("predicted_rmse_8bit") && (*rule)["predicted_rmse_8bit"].is_number())
    w.render_noise_8bit = (*rule)["predicted_rmse_8bit"].get<double>();
  const fs::path photo = image_with_stem(folder, "photo");
  w.photo_display = read_display(photo);
  w.photo_linear = capture::load_photo_linear(photo.string());
  w.truth = inference::load_scene((folder / "truth").string());
  // The truth folder's lights are in Blender's units (scripts/blender_units_check.sh);
  // a scene model's are the photo's linear values, which the exposure scaled.
  for (inference::LightSource& light : w.truth.lights) light.intensity *= w.exposure;
  if (w.truth.width != w.photo_display.cols || w.truth.height != w.photo_display.rows)
    throw std::runtime_error(folder.string() + ": the truth's image size differs from the photo's");
  w.true_camera = w.truth.camera();
  w.emitters = read_mask(folder / "emitters.png", w.photo_display.size());

  const json placement = read_json(folder / "placement.json");
  try {
    w.prop = placement.at("prop").get<std::string>();
    w.placement.pixel_u = placement.at("at").at(0);
    w.placement.pixel_v = placement.at("at").at(1);
    w.placement.height_m = placement.at("height");
    w.placement.yaw_deg = placement.value("yaw", 0.0);
  } catch (const json::exception& e) {
    throw std::runtime_error((folder / "placement.json").string() + ": " + e.what());
  }
  w.insertion_display = read_display(image_with_stem(folder, "insertion"));
  if (w.insertion_display.size() != w.photo_display.size())
    throw std::runtime_error(folder.string() + ": the insertion differs in size from the photo");
  w.prop_mask = read_mask(folder / "prop_mask.png", w.photo_display.size());
  if (fs::exists(folder / "probe.exr")) {
    cv::Mat probe = capture::read_image_float((folder / "probe.exr").string());
    if (probe.channels() == 4) cv::cvtColor(probe, probe, cv::COLOR_RGBA2RGB);
    if (probe.type() != CV_32FC3) throw std::runtime_error((folder / "probe.exr").string() + " is not an RGB image");
    w.true_light = latlong_light_moments(probe);
  }
  return w;
}

std::vector<WorldScene> load_blender_world(const std::string& dir, const std::string& split) {
  const fs::path root(dir);
  if (!fs::exists(root / "world.json"))
    throw std::runtime_error("no Blender world in '" + dir +
                             "' (world.json missing): make one with scripts/make_blender_world.sh --out " + dir +
                             " (docs/blender_world.md)");
  const json world = read_json(root / "world.json");
  std::vector<WorldScene> out;
  for (const json& s : world.value("scenes", json::array())) {
    const std::string name = s.value("name", "");
    if (name.empty() || name.find('/') != std::string::npos || name.find("..") != std::string::npos)
      throw std::runtime_error((root / "world.json").string() + ": a scene has a bad name '" + name + "'");
    if (!split.empty() && s.value("split", "") != split) continue;
    if (!fs::exists(root / name / "meta.json")) continue;  // not rendered (yet)
    out.push_back(load_blender_scene((root / name).string()));
  }
  return out;
}

}  // namespace propcam::firmware
