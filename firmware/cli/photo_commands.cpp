#include "cli/photo_commands.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "cli/cli_checks.h"
#include "common/compositor.h"
#include "common/progress.h"
#include "common/working_size.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/physical_ranges.h"
#include "propcam/render/depth_of_field.h"
#include "propcam/render/relight.h"

namespace propcam::firmware {

void LensPrior::apply(inference::CameraOptions& o, const std::string& photo_path) const {
  if (fixed && !(focal_px > 0)) throw std::invalid_argument("--fixed-focal needs --focal PX");
  o.prior_focal_px = focal_px;
  o.fixed_focal = fixed;
  o.prior_source = focal_px > 0 ? "calibration (--focal)" : "";
  if (focal_px > 0 || photo_path.empty()) return;
  const capture::ExifLens exif = capture::read_exif_focal(photo_path);
  if (exif.focal_px > 0) {
    o.prior_focal_px = exif.focal_px;
    o.prior_source = exif.source;
  }
}

// "R2" or "R2,R4", as `propcam calibrate-vignetting` prints them.
render::Vignetting LensPrior::fall_off() const {
  const std::string& text = vignetting;
  if (text.empty()) return {};
  render::Vignetting v;
  const auto comma = text.find(',');
  std::size_t used = 0;
  try {
    v.r2 = std::stod(text.substr(0, comma), &used);
    if (used != text.substr(0, comma).size()) throw std::invalid_argument("");
    if (comma != std::string::npos) {
      const std::string r4 = text.substr(comma + 1);
      v.r4 = std::stod(r4, &used);
      if (used != r4.size()) throw std::invalid_argument("");
    }
  } catch (const std::exception&) {
    throw std::invalid_argument("--vignetting: expected R2 or R2,R4 (numbers), not \"" + text + "\"");
  }
  if (const std::string problem = render::vignetting_problem(v); !problem.empty())
    throw std::invalid_argument("--vignetting " + text + ": " + problem);
  return v;
}

namespace {

using nlohmann::json;

// Width of the empty-scene light layers that relight the photo (light is smooth).
constexpr int kSceneLayerWidth = 160;

Eigen::Vector3f parse_rgb(const std::string& text) {
  std::istringstream in(text);
  float r, g, b;
  char c1 = 0, c2 = 0;
  if (!(in >> r >> c1 >> g >> c2 >> b) || c1 != ',' || c2 != ',')
    throw std::invalid_argument("--albedo expects R,G,B (linear, 0..1), got '" + text + "'");
  for (const float c : {r, g, b}) inference::require_in_range(c, inference::kAlbedoRange, "an --albedo component");
  return {r, g, b};
}

json reports_json(const inference::SceneModel& scene) {
  json out = json::array();
  for (const auto& r : scene.reports) out.push_back(inference::to_json(r));
  return out;
}

void print_reports(const inference::SceneModel& scene) {
  for (const auto& r : scene.reports)
    if (!Progress::all_silenced() || !r.usable)  // -q: unusable stages only
      std::fprintf(stderr, "  %-18s %-6s %7.3fs  %s\n", r.stage.c_str(), r.usable ? "ok" : "UNUSABLE", r.seconds,
                   r.why.c_str());
}

// `photo` may be the file reduced to the working size: `pixel_scale` (its
// width over the file's) carries the lens prior, given in the file's pixels, to it.
inference::SceneModel infer_with_progress(const cv::Mat& photo, const std::string& source, double camera_height,
                                          const LensPrior& lens, Progress& progress, double pixel_scale = 1.0) {
  inference::InferenceOptions options;
  options.camera_height_m = camera_height;
  lens.apply(options.camera, source);
  options.camera.prior_focal_px *= pixel_scale;
  options.on_stage = [&](const std::string& s) { progress.stage("infer: " + s); };
  inference::SceneModel scene = inference::infer_scene(render::devignette(photo, lens.fall_off()), options);
  scene.source_photo = source;
  return scene;
}

// A photo larger than the working size (`--working-size`, a pixel budget
// given as WxH) is inferred and rendered reduced to it (working_size.h); the
// working size must fit `--memory-budget` (job_budget.h).
static_assert(firmware::kMinWorkingSide == inference::kMinPhotoSide, "a working size inference can take");
firmware::JobBudget job_budget_of(const std::string& working_size, long memory_mb, double render_seconds = 0) {
  firmware::JobBudget budget;
  budget.working_pixels = firmware::parse_working_size(working_size, "--working-size");
  budget.memory_mb = memory_mb;
  budget.render_seconds = render_seconds;
  const std::string problem = firmware::memory_budget_problem(budget);
  if (!problem.empty()) throw std::invalid_argument("--working-size " + working_size + ": " + problem + " (--memory-budget)");
  return budget;
}

constexpr inference::PhysicalRange kTimeBudgetRange{0.01, firmware::kMaxRenderSeconds, "s"};

void add_memory_budget_option(CLI::App& command, long& memory_mb) {
  command.add_option("--memory-budget", memory_mb, "Megabytes a job may use at its peak; the working size must fit them")
      ->capture_default_str()
      ->check(CLI::Range(firmware::kMinMemoryBudgetMb, firmware::kMaxMemoryBudgetMb));
}

// The photo at its working size, with the progress lines a user sees.
firmware::WorkingPhoto load_photo_for_work(const std::string& path, long budget, Progress& progress,
                                           cv::Size forced = {}) {
  progress.stage("loading " + path);
  firmware::WorkingPhoto photo = firmware::load_working_photo(path, budget, forced);
  if (photo.reduced())
    progress.stage("working at " + std::to_string(photo.working.cols) + "x" + std::to_string(photo.working.rows) +
                   " (the photo is " + std::to_string(photo.full_size.width) + "x" +
                   std::to_string(photo.full_size.height) + ")");
  return photo;
}

json size_json(const cv::Mat& m) { return json::array({m.cols, m.rows}); }

// "0=2,3=0.5" -> scales per light index (others 1).
render::LightScales parse_light_scales(const std::string& text, int count) {
  render::LightScales scales(static_cast<size_t>(std::max(count, 0)), 1.f);
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    int index = -1;
    float scale = 1.f;
    char eq = 0;
    std::istringstream one(item);
    if (!(one >> index >> eq >> scale) || eq != '=' || index < 0 || index >= count ||
        !inference::kLightScaleRange.contains(scale))
      throw std::invalid_argument("--light-scale expects I=S pairs with 0 <= I < " + std::to_string(count) + " and S " +
                                  inference::kLightScaleRange.describe() + ", got '" + item + "'");
    scales[index] = scale;
  }
  return scales;
}

// What the renderer decided to trace and to skip, and why.
json render_plan_json(const CompositeResult& r) {
  int culled = 0;
  long culled_pixels = 0, pixels = 0;
  for (const auto& t : r.tiles) {
    pixels += t.rect.area();
    if (!t.affected) {
      ++culled;
      culled_pixels += t.rect.area();
    }
  }
  json shadows = json::array(), significant = json::array(), light_index = json::array();
  for (size_t i = 0; i < r.reach.pixels_in_shadow.size(); ++i) {
    light_index.push_back(i < r.plan.source_index.size() ? r.plan.source_index[i] : static_cast<int>(i));
    shadows.push_back(r.reach.pixels_in_shadow[i]);
    significant.push_back(static_cast<bool>(r.reach.light_significant[i]));
  }
  json decisions = json::array();
  for (const auto& d : r.plan.decisions) decisions.push_back({{"effect", d.effect}, {"simulated", d.simulated}, {"why", d.why}});
  return {{"transport", decisions},
          {"tiles", r.tiles.size()},
          {"tiles_culled", culled},
          {"culled_pixel_share", pixels ? static_cast<double>(culled_pixels) / pixels : 0.0},
          {"passes", r.passes.size()},
          {"reach", {{"pixels_seeing_prop", r.reach.pixels_seen},
                     {"pixels_near_prop", r.reach.pixels_near},
                     {"pixels_in_shadow_per_area_light", shadows},
                     {"area_light_significant", significant},
                     {"area_light_index", light_index},
                     {"seconds", r.reach.seconds}}}};
}

void add_vignetting_option(CLI::App& cmd, LensPrior& lens) {
  cmd.add_option("--vignetting", lens.vignetting,
                 "The lens's calibrated fall-off R2[,R4] (`propcam calibrate-vignetting`; write --vignetting=R2,R4): "
                 "divided out of the photo the scene is inferred from, and given to the prop");
}

json camera_match_json(const render::CameraMatchReport& r) {
  json steps = json::array();
  for (const auto& step : r.steps) steps.push_back({{"effect", step.effect}, {"applied", step.applied}, {"why", step.why}});
  return {{"steps", steps}, {"blur_sigma_px", r.blur_sigma_px}, {"vignette_gain", r.vignette_gain},
          {"noise_added_8bit", r.noise_added_8bit},
          {"prop_noise_8bit", r.prop_noise_8bit}, {"seconds", r.seconds}};
}

void print_render_plan(const json& plan) {
  for (const auto& d : plan["transport"])
    std::fprintf(stderr, "plan: %-20s %-9s %s\n", d["effect"].get<std::string>().c_str(),
                 d["simulated"].get<bool>() ? "simulate" : "skip", d["why"].get<std::string>().c_str());
  std::fprintf(stderr, "plan: %d of %d tiles traced; %d culled (%.0f%% of the pixels: the prop cannot reach them)\n",
               plan["tiles"].get<int>() - plan["tiles_culled"].get<int>(), plan["tiles"].get<int>(),
               plan["tiles_culled"].get<int>(), 100.0 * plan["culled_pixel_share"].get<double>());
  const json& reach = plan["reach"];
  std::fprintf(stderr, "  reach (%.3fs, tested every 2nd pixel): %d see the prop, %d near enough for its occlusion/bounce light\n",
               reach["seconds"].get<double>(), reach["pixels_seeing_prop"].get<int>(), reach["pixels_near_prop"].get<int>());
  for (size_t i = 0; i < reach["pixels_in_shadow_per_area_light"].size(); ++i)
    std::fprintf(stderr, "  light %d (area): %s, %d in its shadow cone\n", reach["area_light_index"][i].get<int>(),
                 reach["area_light_significant"][i].get<bool>() ? "casts shadows" : "too weak at the prop: no shadow traced",
                 reach["pixels_in_shadow_per_area_light"][i].get<int>());
}

}  // namespace

void add_infer_options(CLI::App& cmd, InferArgs& a) {
  cmd.add_option("photo", a.photo, "Photo (PNG, JPEG, EXR, ...)");
  cmd.add_option("-o,--output", a.out, "Scene folder to write");
  cmd.add_option("--lines", a.lines_csv, "Run the camera stage on x1,y1,x2,y2 segments from a CSV file");
  cmd.add_option("--size", a.size, "Image size WxH for --lines");
  cmd.add_option("--camera-height", a.camera_height, "Camera height above the floor in metres")
      ->check(within(inference::kCameraHeightRange));
  cmd.add_option("--focal", a.lens.focal_px,
                 "Calibrated focal length in pixels at the photo's size (a prior for the camera stage)")
      ->check(within(inference::kFocalPxRange));
  cmd.add_flag("--fixed-focal", a.lens.fixed, "Use --focal as the focal length (estimate the rotation only)");
  add_vignetting_option(cmd, a.lens);
  cmd.add_option("--working-size", a.working_size,
                 "A larger photo is inferred reduced to this many pixels (WxH), its aspect kept")
      ->capture_default_str();
  add_memory_budget_option(cmd, a.memory_mb);
  cmd.add_flag("--json", a.json_out, "Machine-readable output on stdout");
}

int run_infer_command(const InferArgs& a) {
  Progress progress(a.json_out);
  if (!a.lines_csv.empty()) {
    // Camera stage on given segments (no photo needed).
    int w = 0, h = 0;
    if (!parse_pair(a.size, w, h, 'x') || w <= 0 || h <= 0)
      throw std::invalid_argument("--lines needs --size WxH (e.g. 640x480)");
    const auto lines = inference::read_lines_csv(a.lines_csv);
    inference::CameraOptions camera_options;
    a.lens.apply(camera_options);
    const auto cam = inference::estimate_camera(lines, w, h, camera_options);
    json out = {{"K", {{"fx", cam.fx}, {"fy", cam.fy}, {"cx", cam.cx}, {"cy", cam.cy}}},
                {"R_world_from_cam", json::array()},
                {"report", inference::to_json(cam.report)}};
    for (int r = 0; r < 3; ++r)
      out["R_world_from_cam"].push_back({cam.R_world_from_cam(r, 0), cam.R_world_from_cam(r, 1), cam.R_world_from_cam(r, 2)});
    std::cout << out.dump(2) << std::endl;
    return 0;
  }
  if (a.photo.empty()) throw std::invalid_argument("infer needs a PHOTO (or --lines FILE --size WxH)");
  if (a.out.empty()) throw std::invalid_argument("infer needs -o SCENE_DIR");
  const firmware::WorkingPhoto photo =
      load_photo_for_work(a.photo, job_budget_of(a.working_size, a.memory_mb).working_pixels, progress);
  inference::SceneModel scene =
      infer_with_progress(photo.working, a.photo, a.camera_height, a.lens, progress, photo.scale());
  inference::save_scene(scene, a.out);
  if (a.json_out) {
    std::cout << json{{"scene", a.out},
                      {"photo_size", {photo.full_size.width, photo.full_size.height}},
                      {"working_size", size_json(photo.working)},
                      {"reports", reports_json(scene)}}
                     .dump(2)
              << std::endl;
  } else {
    print_reports(scene);
    progress.stage("wrote " + a.out + "/scene.json");
  }
  return 0;
}

void add_composite_options(CLI::App& cmd, CompositeArgs& a) {
  cmd.add_option("photo", a.photo, "Photo")->required()->check(CLI::ExistingFile);
  cmd.add_option("--scene", a.scene_dir, "Scene folder from `propcam infer` (inferred if absent)");
  cmd.add_option("--prop", a.prop, "Preset name (see `propcam props`) or mesh file (OBJ)")->required();
  cmd.add_option("--at", a.at, "Pixel U,V of the support point under the prop")->required();
  cmd.add_option("--height", a.height, "Prop height in metres (default: its natural size)")
      ->check(within(inference::kPropHeightRange));
  cmd.add_option("--yaw", a.yaw, "Turn about the up axis, degrees counter-clockwise from above")
      ->check(within(inference::kYawDegRange));
  cmd.add_option("--spp", a.spp, "Samples per pixel")->check(CLI::Range(1, kMaxCliSpp));
  cmd.add_option("--bounces", a.bounces, "Light bounces as Blender Cycles counts them (0: direct light only)")
      ->check(CLI::Range(0, kMaxCliBounces));
  cmd.add_option("--seed", a.seed, "Random seed (same seed, same image)");
  cmd.add_option("--material", a.material,
                 "Override the prop's material: diffuse|plastic|glossy|metal|dielectric|glass")
      ->check(CLI::IsMember({"diffuse", "plastic", "glossy", "metal", "dielectric", "glass"}));
  cmd.add_option("--albedo", a.albedo, "Override the prop's albedo: R,G,B linear in 0..1");
  cmd.add_option("--camera-height", a.camera_height, "Camera height in metres when inferring")
      ->check(within(inference::kCameraHeightRange));
  cmd.add_option("--focal", a.lens.focal_px, "Calibrated focal length in pixels when inferring (a prior)")
      ->check(within(inference::kFocalPxRange));
  cmd.add_flag("--fixed-focal", a.lens.fixed, "Use --focal as the focal length when inferring");
  cmd.add_option("--working-size", a.working_size,
                 "A larger photo is inferred and rendered reduced to this many pixels (WxH) and the "
                 "composite delivered at the photo's size")
      ->capture_default_str();
  add_memory_budget_option(cmd, a.memory_mb);
  cmd.add_option("--time-budget", a.time_budget,
                 "Seconds the render may take: no pass starts that would end after them (the samples "
                 "reached are reported)")
      ->capture_default_str()
      ->check(within(kTimeBudgetRange));
  cmd.add_option("--save-scene", a.save_scene, "Also write the inferred scene folder here");
  cmd.add_option("-o,--output", a.out, "Composite image to write (PNG, JPEG or EXR)")->required();
  cmd.add_flag("--json", a.json_out, "Machine-readable summary on stdout");
  cmd.add_flag("--explain", a.explain, "Print what the renderer traced and skipped, and why");
  cmd.add_option("--light-scale", a.light_scale,
                 "Relight after rendering: I=S,... scales light I (scene.json order; the last index is "
                 "emissive surfaces) on the prop and its shadows");
  cmd.add_flag("--relight-scene", a.relight_scene, "With --light-scale: relight the whole photo too");
  cmd.add_option("--aperture", a.aperture, "Depth of field: lens aperture diameter in metres (0: none)")
      ->check(within(inference::kApertureRange));
  cmd.add_option("--focus", a.focus, "Depth of field: focus distance in metres (default: the prop)")
      ->check(within(inference::kFocusDistanceRange));
  cmd.add_flag("--no-cull", a.no_cull, "Simulate everything: every tile, light and path (to measure what the plan saves)");
  cmd.add_flag("--no-denoise", a.no_denoise, "Keep the raw Monte Carlo change (no edge-aware filter of the prop's change)");
  cmd.add_flag("--no-camera-match", a.no_camera_match,
               "Leave the prop as rendered (the photo's blur and noise not matched)");
  add_vignetting_option(cmd, a.lens);
}

namespace {

MaterialOverride material_from_args(const CompositeArgs& a) {
  MaterialOverride material;
  if (!a.material.empty()) material.type = a.material;
  if (!a.albedo.empty()) material.albedo = parse_rgb(a.albedo);
  return material;
}

// The scene folder's model and the photo at the size it was inferred at.
void load_scene_folder(const CompositeArgs& a, const firmware::JobBudget& budget, Progress& progress,
                       inference::SceneModel& scene, firmware::WorkingPhoto& loaded) {
  scene = inference::load_scene(a.scene_dir);
  firmware::JobBudget at_scene_size = budget;
  at_scene_size.working_pixels = static_cast<long>(scene.width) * scene.height;
  if (const std::string problem = firmware::memory_budget_problem(at_scene_size); !problem.empty())
    throw std::invalid_argument("the scene folder '" + a.scene_dir + "' is " + std::to_string(scene.width) + "x" +
                                std::to_string(scene.height) + ": " + problem + " (--memory-budget)");
  if (scene.depth.empty())
    throw std::invalid_argument("the scene folder '" + a.scene_dir + "' has no depth.exr: make it again with " +
                                "`propcam infer PHOTO -o " + a.scene_dir + "`");
  // The photo is worked at the size the scene was inferred at.
  loaded = load_photo_for_work(a.photo, 0, progress, {scene.width, scene.height});
  if (!firmware::same_view_reduced(loaded.full_size, loaded.working.size()))
    throw std::invalid_argument("the scene folder '" + a.scene_dir + "' was inferred from a " +
                                std::to_string(scene.width) + "x" + std::to_string(scene.height) +
                                " photo; this photo is " + std::to_string(loaded.full_size.width) + "x" +
                                std::to_string(loaded.full_size.height));
}

// The scene model (read, or inferred on the way) and the photo at its working size.
void scene_and_photo(const CompositeArgs& a, const firmware::JobBudget& budget, Progress& progress,
                     inference::SceneModel& scene, firmware::WorkingPhoto& loaded) {
  if (!a.scene_dir.empty()) {
    load_scene_folder(a, budget, progress, scene, loaded);
    return;
  }
  loaded = load_photo_for_work(a.photo, budget.working_pixels, progress);
  scene = infer_with_progress(loaded.working, a.photo, a.camera_height, a.lens, progress, loaded.scale());
  if (!a.json_out) print_reports(scene);
  if (!a.save_scene.empty()) inference::save_scene(scene, a.save_scene);
}

CompositeOptions composite_options(const CompositeArgs& a, const firmware::JobBudget& budget,
                                   const firmware::WorkingPhoto& loaded) {
  CompositeOptions options;
  options.cull_tiles = !a.no_cull;
  options.plan.allow_skips = !a.no_cull;
  options.denoise = !a.no_denoise;
  options.match_camera = !a.no_camera_match;
  options.camera_match.seed = a.seed;
  options.camera_match.vignetting = a.lens.fall_off();
  options.camera_match.vignetting_source = "--vignetting";
  options.light_layers = !a.light_scale.empty();
  options.time_budget_seconds = budget.render_seconds;
  // The prop's edges at the photo's own size, unless depth of field blurs them anyway.
  if (loaded.reduced() && a.aperture <= 0) options.full_size = loaded.full_size;
  options.scene_layers_width = a.relight_scene && !a.light_scale.empty() ? kSceneLayerWidth : 0;
  return options;
}

// --light-scale, then --aperture: the rendered composite relit and given
// depth of field. Returns the depth of field's JSON (null without).
json finish_composite(const CompositeArgs& a, const cv::Mat& scene_photo, const inference::SceneModel& scene,
                      const CompositeResult& result, const CompositeOptions& options, cv::Mat& image) {
  const double prop_depth_m = scene.camera().world_to_camera(result.placed.base_world.cast<double>()).z();
  if (!a.light_scale.empty()) {
    const render::LightScales scales = parse_light_scales(a.light_scale, static_cast<int>(result.layers.change.size()));
    image = a.relight_scene ? render::relight_scene(scene_photo, result.layers, result.scene_layers, scales)
                            : render::relight_prop(scene_photo, result.layers, scales);
    if (options.match_camera) {
      render::CameraMatchOptions match = options.camera_match;
      if (!(match.prop_depth_m > 0)) match.prop_depth_m = prop_depth_m;
      image = render::match_camera(scene_photo, image, result.render.coverage, scene.imaging, match, scene.gamma);
    }
  }
  if (!(a.aperture > 0)) return nullptr;
  render::DepthOfField dof;
  dof.aperture_m = a.aperture;
  // Focus on the prop unless told otherwise.
  dof.focus_distance_m = a.focus > 0 ? a.focus : prop_depth_m;
  image = render::apply_depth_of_field(image, result.depth, scene.fx, dof);
  return {{"aperture_m", dof.aperture_m}, {"focus_m", dof.focus_distance_m}};
}

void write_composite(const CompositeArgs& a, const firmware::WorkingPhoto& loaded, const cv::Mat& scene_photo,
                     const cv::Mat& image, const CompositeResult& result, double gamma, Progress& progress) {
  if (!loaded.reduced()) {
    capture::write_image(a.out, capture::response_linear_to_srgb_linear(image, gamma));
    return;
  }
  // The composite at the photo's own size: the working composite's change
  // carried up onto the full photo, in the same response-linear space.
  const cv::Size output_size = loaded.full_size;
  progress.stage("composite at " + std::to_string(output_size.width) + "x" + std::to_string(output_size.height));
  firmware::FullSizeDelivery delivery(scene_photo, image, result.render.coverage, output_size);
  delivery.use_sharp_coverage(result.full_size_coverage);
  firmware::write_full_size_composite(loaded, a.out, delivery, gamma);
}

double share_untouched_by_prop(const render::RenderStats& st) {
  return st.camera_samples ? static_cast<double>(st.paths_prop_untouched) / st.camera_samples : 0.0;
}

json composite_summary(const CompositeArgs& a, const firmware::WorkingPhoto& loaded, const CompositeResult& result,
                       const render::PropPlacement& placement, const firmware::JobBudget& budget, const json& plan,
                       const json& dof_json, double total_seconds) {
  const auto& st = result.render.stats;
  return {{"output", a.out},
          {"output_size", {loaded.full_size.width, loaded.full_size.height}},
          {"working_size", size_json(loaded.working)},
          {"prop", a.prop},
          {"base_world", {result.placed.base_world.x(), result.placed.base_world.y(), result.placed.base_world.z()}},
          {"height_m", placement.height_m},
          {"render_seconds", st.seconds},
          {"scene_build_seconds", result.scene_build_seconds},
          {"samples_per_pixel", result.samples_per_pixel},
          {"time_budget", {{"seconds", budget.render_seconds}, {"stopped_render", result.stopped_by_time_budget}}},
          {"rays", st.rays},
          {"samples_untouched_by_prop", share_untouched_by_prop(st)},
          {"denoise", {{"on", !a.no_denoise},
                       {"tiles_judged", result.denoise.tiles_judged},
                       {"tiles_filtered", result.denoise.tiles_filtered},
                       {"seconds", result.denoise.seconds}}},
          {"plan", plan},
          {"camera_match", camera_match_json(result.camera_match)},
          {"insertion_constraint", {{"applied", result.flattening.applied},
                                    {"plane_height_m", result.flattening.plane_height_m},
                                    {"pixels", result.flattening.pixels_changed},
                                    {"why", result.flattening.why}}},
          {"depth_of_field", dof_json},
          {"full_size_edges", {{"pixels", result.full_size_coverage.region.area()},
                               {"rays_per_pixel", result.full_size_coverage.rays_per_side *
                                                      result.full_size_coverage.rays_per_side},
                               {"seconds", result.full_size_coverage.seconds}}},
          {"total_seconds", total_seconds}};
}

void print_composite_report(const CompositeArgs& a, const CompositeResult& result, const firmware::JobBudget& budget,
                            const json& plan) {
  const auto& st = result.render.stats;
  if (!Progress::all_silenced()) {
    std::fprintf(stderr, "render %.2fs, %.1f Mrays, %.0f%% of traced samples untouched by the prop (no second path)\n",
                 st.seconds, st.rays / 1e6, 100.0 * share_untouched_by_prop(st));
    if (result.stopped_by_time_budget)
      std::fprintf(stderr, "render stopped at %d of %d spp: the next pass would have ended after the time budget "
                   "of %g s (--time-budget)\n", result.samples_per_pixel, a.spp, budget.render_seconds);
  }
  if (a.explain) {
    print_render_plan(plan);
    if (result.camera_match.steps.empty()) std::fprintf(stderr, "camera: match off (--no-camera-match)\n");
    for (const auto& step : result.camera_match.steps)
      std::fprintf(stderr, "camera: %-20s %-9s %s\n", step.effect.c_str(), step.applied ? "match" : "skip", step.why.c_str());
  }
}

}  // namespace

int run_composite_command(const CompositeArgs& a) {
  Progress progress(a.json_out);
  render::PropPlacement placement;
  if (!parse_pair(a.at, placement.pixel_u, placement.pixel_v, ','))
    throw std::invalid_argument("--at expects U,V in pixels, got '" + a.at + "'");
  if (a.spp <= 0 || a.spp > kMaxCliSpp) throw std::invalid_argument("--spp must be in 1.." + std::to_string(kMaxCliSpp));
  const int max_bounces = renderer_bounces(a.bounces);
  const MaterialOverride material = material_from_args(a);
  const firmware::JobBudget budget = job_budget_of(a.working_size, a.memory_mb, a.time_budget);
  a.lens.fall_off();  // a bad --vignetting is refused before the inference's seconds
  const render::Mesh prop = load_prop(a.prop, material);
  placement.height_m = a.height > 0 ? a.height : natural_height(a.prop, prop);
  placement.yaw_deg = a.yaw;

  inference::SceneModel scene;
  firmware::WorkingPhoto loaded;
  scene_and_photo(a, budget, progress, scene, loaded);
  const cv::Mat& photo = loaded.working;
  placement.pixel_u *= static_cast<double>(photo.cols) / loaded.full_size.width;
  placement.pixel_v *= static_cast<double>(photo.rows) / loaded.full_size.height;

  render::RenderSettings settings;
  settings.samples_per_pixel = a.spp;
  settings.max_bounces = max_bounces;
  settings.seed = a.seed;
  settings.progress = progress.fraction_printer("render");
  progress.stage("render: " + std::to_string(a.spp) + " spp, " + std::to_string(a.bounces) + " bounces");
  const CompositeOptions options = composite_options(a, budget, loaded);
  // Light is added in the photo's own linear space: its camera response
  // (fitted with the light intensities) undone, and redone at the end.
  const cv::Mat scene_photo = capture::srgb_linear_to_response_linear(photo, scene.gamma);
  const CompositeResult result = composite_prop(scene_photo, scene, prop, placement, settings, options);
  const json plan = render_plan_json(result);
  cv::Mat final_image = result.composite_linear;
  const json dof_json = finish_composite(a, scene_photo, scene, result, options, final_image);
  write_composite(a, loaded, scene_photo, final_image, result, scene.gamma, progress);

  if (a.json_out) {
    std::cout << composite_summary(a, loaded, result, placement, budget, plan, dof_json, progress.elapsed()).dump(2)
              << std::endl;
  } else {
    print_composite_report(a, result, budget, plan);
    progress.stage("wrote " + a.out);
  }
  return 0;
}

}  // namespace propcam::firmware
