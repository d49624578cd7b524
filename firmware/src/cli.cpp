#include "cli.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "bench.h"
#include "bench_render.h"
#include "bench_camera.h"
#include "bench_geometry.h"
#include "bench_lighting.h"
#include "bench_worlds.h"
#include <spdlog/spdlog.h>

#include "capture_commands.h"
#include "cli_checks.h"
#include "export_commands.h"
#include "run_command.h"
#include "light_training.h"
#include "logging.h"
#include "bench_transfer.h"
#include "bench_scene_class.h"
#include "ibl_training.h"
#include "depth_database_builder.h"
#include "scene_reference_builder.h"
#include "working_size.h"
#include "compositor.h"
#include "progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/data_dir.h"
#include "propcam/inference/ibl_library.h"
#include "propcam/inference/infer.h"
#include "propcam/render/depth_of_field.h"
#include "propcam/render/panorama.h"
#include "propcam/render/relight.h"
#include "propcam/render/mesh_io.h"
#include "propcam/render/props.h"
#include "propcam/render/scene_file.h"
#include "propcam/ui_fb/console.h"
#include "synthetic_truth.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Width of the empty-scene light layers that relight the photo (light is smooth).
constexpr int kSceneLayerWidth = 160;

// Parses "A,B" or "AxB" into two numbers.
template <typename T>
bool parse_pair(const std::string& text, T& a, T& b, char separator) {
  std::istringstream in(text);
  char sep = 0;
  return static_cast<bool>(in >> a >> sep >> b) && sep == separator && in.peek() == EOF;
}

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

// A calibrated lens (the board's calibration): its focal length in pixels at
// the photo's resolution, a prior for the camera stage or, fixed, the focal length.
// The lens: a calibrated focal length given on the command line wins;
// otherwise the photo's EXIF focal length (if any) is the camera stage's
// prior (not fixed: the lines may still overrule it).
struct LensPrior {
  double focal_px = 0;  // 0: none
  bool fixed = false;
  void apply(inference::CameraOptions& o, const std::string& photo_path = {}) const {
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
};

// `photo` may be the file reduced to the working size: `pixel_scale` (its
// width over the file's) carries the lens prior, given in the file's pixels, to it.
inference::SceneModel infer_with_progress(const cv::Mat& photo, const std::string& source, double camera_height,
                                          const LensPrior& lens, Progress& progress, double pixel_scale = 1.0) {
  inference::InferenceOptions options;
  options.camera_height_m = camera_height;
  lens.apply(options.camera, source);
  options.camera.prior_focal_px *= pixel_scale;
  options.on_stage = [&](const std::string& s) { progress.stage("infer: " + s); };
  inference::SceneModel scene = inference::infer_scene(photo, options);
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

struct InferArgs {
  std::string photo, out, lines_csv, size, working_size = "1024x768";
  long memory_mb = firmware::kDefaultMemoryBudgetMb;
  double camera_height = 1.5;
  LensPrior lens;
  bool json_out = false;
};

int cmd_infer(const InferArgs& a) {
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

// `--bounces` counts as Blender Cycles' max_bounces does (0: direct light
// only); the renderer's max_bounces is one more (path_tracer.h).
constexpr int kDefaultCliBounces = 3;
constexpr int kMaxCliBounces = 63;
constexpr int kMaxCliSpp = 65536;
constexpr int kExitBadArguments = 2;
constexpr int kMaxCliThreads = 1024;
int renderer_bounces(int cli_bounces) {
  if (cli_bounces < 0 || cli_bounces > kMaxCliBounces)
    throw std::invalid_argument("--bounces must be in 0.." + std::to_string(kMaxCliBounces));
  return cli_bounces + 1;
}

struct CompositeArgs {
  std::string photo, scene_dir, prop, at, out, material, albedo, save_scene, working_size = "1024x768";
  long memory_mb = firmware::kDefaultMemoryBudgetMb;
  double time_budget = firmware::kDefaultRenderSeconds;
  double height = 0, yaw = 0, camera_height = 1.5;
  LensPrior lens;
  int spp = 16, bounces = kDefaultCliBounces;
  uint64_t seed = 0x5eed;
  bool json_out = false, explain = false, no_cull = false, no_denoise = false, no_camera_match = false;
  double aperture = 0, focus = 0;
  std::string light_scale;  // "I=S,I=S": relight after rendering
  bool relight_scene = false;
};

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

json camera_match_json(const render::CameraMatchReport& r) {
  json steps = json::array();
  for (const auto& step : r.steps) steps.push_back({{"effect", step.effect}, {"applied", step.applied}, {"why", step.why}});
  return {{"steps", steps}, {"blur_sigma_px", r.blur_sigma_px}, {"noise_added_8bit", r.noise_added_8bit},
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

int cmd_composite(const CompositeArgs& a) {
  Progress progress(a.json_out);
  render::PropPlacement placement;
  if (!parse_pair(a.at, placement.pixel_u, placement.pixel_v, ','))
    throw std::invalid_argument("--at expects U,V in pixels, got '" + a.at + "'");
  if (a.spp <= 0 || a.spp > kMaxCliSpp) throw std::invalid_argument("--spp must be in 1.." + std::to_string(kMaxCliSpp));
  const int max_bounces = renderer_bounces(a.bounces);
  MaterialOverride material;
  if (!a.material.empty()) material.type = a.material;
  if (!a.albedo.empty()) material.albedo = parse_rgb(a.albedo);
  const firmware::JobBudget budget = job_budget_of(a.working_size, a.memory_mb, a.time_budget);
  const render::Mesh prop = load_prop(a.prop, material);
  placement.height_m = a.height > 0 ? a.height : natural_height(a.prop, prop);
  placement.yaw_deg = a.yaw;

  inference::SceneModel scene;
  firmware::WorkingPhoto loaded;
  if (!a.scene_dir.empty()) {
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
  } else {
    loaded = load_photo_for_work(a.photo, budget.working_pixels, progress);
  }
  const cv::Mat& photo = loaded.working;
  placement.pixel_u *= static_cast<double>(photo.cols) / loaded.full_size.width;
  placement.pixel_v *= static_cast<double>(photo.rows) / loaded.full_size.height;
  if (a.scene_dir.empty()) {
    scene = infer_with_progress(photo, a.photo, a.camera_height, a.lens, progress, loaded.scale());
    if (!a.json_out) print_reports(scene);
    if (!a.save_scene.empty()) inference::save_scene(scene, a.save_scene);
  }
  render::RenderSettings settings;
  settings.samples_per_pixel = a.spp;
  settings.max_bounces = max_bounces;
  settings.seed = a.seed;
  settings.progress = progress.fraction_printer("render");
  progress.stage("render: " + std::to_string(a.spp) + " spp, " + std::to_string(a.bounces) + " bounces");
  CompositeOptions options;
  options.cull_tiles = !a.no_cull;
  options.plan.allow_skips = !a.no_cull;
  options.denoise = !a.no_denoise;
  options.match_camera = !a.no_camera_match;
  options.camera_match.seed = a.seed;
  options.light_layers = !a.light_scale.empty();
  options.time_budget_seconds = budget.render_seconds;
  // The prop's edges at the photo's own size, unless depth of field blurs them anyway.
  if (loaded.reduced() && a.aperture <= 0) options.full_size = loaded.full_size;
  options.scene_layers_width = a.relight_scene && !a.light_scale.empty() ? kSceneLayerWidth : 0;
  // Light is added in the photo's own linear space: its camera response
  // (fitted with the light intensities) undone, and redone at the end.
  const cv::Mat scene_photo = capture::srgb_linear_to_response_linear(photo, scene.gamma);
  const CompositeResult result = composite_prop(scene_photo, scene, prop, placement, settings, options);
  const json plan = render_plan_json(result);
  cv::Mat final_image = result.composite_linear;
  if (!a.light_scale.empty()) {
    const render::LightScales scales = parse_light_scales(a.light_scale, static_cast<int>(result.layers.change.size()));
    final_image = a.relight_scene ? render::relight_scene(scene_photo, result.layers, result.scene_layers, scales)
                                  : render::relight_prop(scene_photo, result.layers, scales);
    if (options.match_camera)
      final_image = render::match_camera(scene_photo, final_image, result.render.coverage, scene.imaging,
                                         options.camera_match, scene.gamma);
  }
  json dof_json = nullptr;
  if (a.aperture > 0) {
    render::DepthOfField dof;
    dof.aperture_m = a.aperture;
    // Focus on the prop unless told otherwise.
    dof.focus_distance_m = a.focus > 0 ? a.focus
                                       : scene.camera().world_to_camera(result.placed.base_world.cast<double>()).z();
    final_image = render::apply_depth_of_field(final_image, result.depth, scene.fx, dof);
    dof_json = {{"aperture_m", dof.aperture_m}, {"focus_m", dof.focus_distance_m}};
  }
  const cv::Size output_size = loaded.full_size;
  if (loaded.reduced()) {
    // The composite at the photo's own size: the working composite's change
    // carried up onto the full photo, in the same response-linear space.
    progress.stage("composite at " + std::to_string(output_size.width) + "x" + std::to_string(output_size.height));
    firmware::FullSizeDelivery delivery(scene_photo, final_image, result.render.coverage, output_size);
    delivery.use_sharp_coverage(result.full_size_coverage);
    firmware::write_full_size_composite(loaded, a.out, delivery, scene.gamma);
  } else {
    capture::write_image(a.out, capture::response_linear_to_srgb_linear(final_image, scene.gamma));
  }
  const auto& st = result.render.stats;
  const double skipped = st.camera_samples ? static_cast<double>(st.paths_prop_untouched) / st.camera_samples : 0.0;
  json summary = {{"output", a.out},
                  {"output_size", {output_size.width, output_size.height}},
                  {"working_size", size_json(photo)},
                  {"prop", a.prop},
                  {"base_world", {result.placed.base_world.x(), result.placed.base_world.y(), result.placed.base_world.z()}},
                  {"height_m", placement.height_m},
                  {"render_seconds", st.seconds},
                  {"scene_build_seconds", result.scene_build_seconds},
                  {"samples_per_pixel", result.samples_per_pixel},
                  {"time_budget", {{"seconds", budget.render_seconds}, {"stopped_render", result.stopped_by_time_budget}}},
                  {"rays", st.rays},
                  {"samples_untouched_by_prop", skipped},
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
                  {"total_seconds", progress.elapsed()}};
  if (a.json_out) std::cout << summary.dump(2) << std::endl;
  else {
    if (!Progress::all_silenced()) {
      std::fprintf(stderr, "render %.2fs, %.1f Mrays, %.0f%% of traced samples untouched by the prop (no second path)\n",
                   st.seconds, st.rays / 1e6, 100.0 * skipped);
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
    progress.stage("wrote " + a.out);
  }
  return 0;
}

struct PropsArgs {
  bool json_out = false;
  std::string thumbnails_dir;  // empty: list only
  std::string export_dir;      // empty: no export
  int thumbnail_size = 256, thumbnail_spp = 64;
};

// A preset's materials exactly as the renderer has them (the MTL rounds
// roughness through Ns): what another renderer needs to draw the same prop.
json prop_materials_json(const render::Mesh& mesh) {
  json materials = json::object();
  const auto rgb = [](const Eigen::Vector3f& c) { return json::array({c.x(), c.y(), c.z()}); };
  for (const render::Material& m : mesh.materials)
    materials[m.name] = {{"type", render::to_string(m.type)}, {"albedo", rgb(m.albedo)}, {"specular", m.specular},
                         {"roughness", m.roughness}, {"ior", m.ior}, {"emission", rgb(m.emission)}};
  return materials;
}

int cmd_props(const PropsArgs& a) {
  const bool json_out = a.json_out;
  if (!a.thumbnails_dir.empty()) {
    std::filesystem::create_directories(a.thumbnails_dir);
    for (const auto& p : render::prop_presets()) {
      const auto start = std::chrono::steady_clock::now();
      const cv::Mat thumbnail = render::render_prop_thumbnail(p.name, a.thumbnail_size, a.thumbnail_spp);
      const std::string path = (std::filesystem::path(a.thumbnails_dir) / (p.name + ".png")).string();
      capture::write_image(path, thumbnail);  // linear float: encoded to sRGB
      std::fprintf(stderr, "wrote %s (%.2fs)\n", path.c_str(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
  }
  if (!a.export_dir.empty()) {
    std::filesystem::create_directories(a.export_dir);
    for (const auto& p : render::prop_presets()) {
      const render::Mesh m = render::make_prop(p.name);
      const std::filesystem::path base = std::filesystem::path(a.export_dir) / p.name;
      render::save_obj(m, base.string() + ".obj");
      std::ofstream materials(base.string() + ".materials.json");
      materials << prop_materials_json(m).dump(2) << "\n";
      if (!materials) throw std::runtime_error("cannot write " + base.string() + ".materials.json");
    }
  }
  json list = json::array();
  for (const auto& p : render::prop_presets()) {
    const render::Mesh m = render::make_prop(p.name);
    list.push_back({{"name", p.name}, {"description", p.description}, {"height_m", p.natural_height_m},
                    {"triangles", m.triangles.size()}});
  }
  if (json_out) {
    std::cout << list.dump(2) << std::endl;
  } else {
    for (const auto& p : list)
      std::printf("%-14s %5.2f m  %6d tris  %s\n", p["name"].get<std::string>().c_str(), p["height_m"].get<double>(),
                  p["triangles"].get<int>(), p["description"].get<std::string>().c_str());
  }
  return 0;
}

struct SynthArgs {
  std::string out, size = "640x480", prop;
  uint64_t seed = 1;
  int spp = 64;
  double height = 0;
  bool json_out = false;
  bool street = false;
};

int cmd_synth(const SynthArgs& a) {
  Progress progress(a.json_out);
  int width = 0, height = 0;
  if (!parse_pair(a.size, width, height, 'x') || width < 16 || height < 16)
    throw std::invalid_argument("--size expects WxH of at least 16x16");
  render::RenderSettings settings;
  settings.samples_per_pixel = a.spp;
  settings.progress = progress.fraction_printer("synth photo");
  const SyntheticShot shot = a.street ? shoot_synthetic_street({width, height, a.seed, 0.0, 1.5}, settings)
                                      : shoot_synthetic_room({width, height, a.seed, 0.0, 1.5}, settings);
  fs::create_directories(a.out);
  capture::write_image((fs::path(a.out) / "photo.png").string(), shot.photo_linear);
  capture::write_image((fs::path(a.out) / "photo.exr").string(), shot.photo_linear);
  inference::save_scene(shot.truth, (fs::path(a.out) / "truth").string());
  const Eigen::Vector2d at = free_floor_pixel(shot.room);
  json summary = {{"photo", (fs::path(a.out) / "photo.png").string()},
                  {"truth", (fs::path(a.out) / "truth").string()},
                  {"free_floor_pixel", {at.x(), at.y()}},
                  {"render_seconds", shot.photo_stats.seconds}};
  if (!a.prop.empty()) {
    const render::Mesh prop = load_prop(a.prop);
    render::PropPlacement placement{at.x(), at.y(), a.height > 0 ? a.height : natural_height(a.prop, prop), 0.0};
    settings.progress = progress.fraction_printer("synth insertion");
    const cv::Mat inserted = render_full_insertion(shot.room, prop, placement, settings);
    capture::write_image((fs::path(a.out) / "insertion.png").string(), inserted);
    summary["insertion"] = (fs::path(a.out) / "insertion.png").string();
  }
  std::ofstream(fs::path(a.out) / "synth.json") << summary.dump(2) << "\n";
  if (a.json_out) std::cout << summary.dump(2) << std::endl;
  else progress.stage("wrote " + a.out);
  return 0;
}

struct ViewArgs {
  std::string panorama, out, size = "640x480";
  double fov = 60, yaw = 0, pitch = 0, roll = 0, camera_height = 1.5;
  double exposure_ev = 0;
  bool json_out = false;
};

// `propcam console`, the service's ExecStopPost: the appliance restores the
// console itself on exit and on fatal signals, but not after SIGKILL.
int cmd_console(const std::string& tty, bool restore) {
  std::string why;
  if (restore && !ui_fb::restore_console_text_mode(tty, why)) throw std::runtime_error(tty + ": " + why);
  const ui_fb::ConsoleMode mode = ui_fb::console_mode(tty, why);
  if (mode == ui_fb::ConsoleMode::Unknown) throw std::runtime_error(tty + ": " + why);
  std::cout << tty << ": " << (mode == ui_fb::ConsoleMode::Graphics ? "graphics" : "text") << std::endl;
  return 0;
}

// A rectilinear "photo" cut from an HDR panorama, exposed like a camera would.
int cmd_view(const ViewArgs& a) {
  render::ViewSpec spec;
  if (!parse_pair(a.size, spec.width, spec.height, 'x') || spec.width < 1 || spec.height < 1)
    throw std::invalid_argument("--size expects WxH");
  spec.horizontal_fov_deg = a.fov;
  spec.yaw_deg = a.yaw;
  spec.pitch_deg = a.pitch;
  spec.roll_deg = a.roll;
  spec.camera_height_m = a.camera_height;
  const render::PinholeCamera camera = render::view_camera(spec);
  cv::Mat view = render::rectilinear_view(capture::read_image_float(a.panorama), camera);
  const double scale = render::auto_expose(view) * std::exp2(a.exposure_ev);
  if (a.exposure_ev != 0) view *= std::exp2(a.exposure_ev);
  capture::write_image(a.out, view);
  if (a.json_out) {
    json k = {{"fx", camera.fx}, {"fy", camera.fy}, {"cx", camera.cx}, {"cy", camera.cy}};
    json r = json::array();
    for (int i = 0; i < 3; ++i) r.push_back({camera.R_world_from_cam(i, 0), camera.R_world_from_cam(i, 1), camera.R_world_from_cam(i, 2)});
    std::cout << json{{"output", a.out}, {"K", k}, {"R_world_from_cam", r}, {"exposure_scale", scale}}.dump(2) << std::endl;
  }
  return 0;
}

struct RenderArgs {
  std::string scene, out;
  int spp = 16, bounces = kDefaultCliBounces, threads = 0;
  double time_budget = 0;  // seconds; 0: render `spp` samples in one pass
  double clamp = render::kDefaultMaxSampleLuminance;  // 0: off
  uint64_t seed = 0x5eed;
  bool json_out = false;
};

// `--time`: passes of 1, 1, 2, 4, ... samples per pixel; at most this many
// passes (2^15 samples per pixel in all).
constexpr int kMaxTimedPasses = 16;

int cmd_render(const RenderArgs& a) {
  Progress progress(a.json_out);
  if (a.spp <= 0 || a.spp > kMaxCliSpp) throw std::invalid_argument("--spp must be in 1.." + std::to_string(kMaxCliSpp));
  if (a.threads < 0) throw std::invalid_argument("--threads must be >= 0 (0: all)");
  if (!(a.clamp >= 0) || !std::isfinite(a.clamp)) throw std::invalid_argument("--clamp must be a finite number >= 0 (0: off)");
  std::string ext = fs::path(a.out).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext != ".exr" && ext != ".png" && ext != ".jpg" && ext != ".jpeg")
    throw std::invalid_argument("-o expects an .exr, .png or .jpg file, got '" + a.out + "'");
  progress.stage("loading " + a.scene);
  const render::SceneFile file = render::load_scene_file(a.scene);
  const auto scene = render::build_scene(file);
  const render::PinholeCamera& camera = file.camera;

  render::RenderSettings settings;
  settings.max_bounces = renderer_bounces(a.bounces);
  settings.threads = a.threads;
  settings.max_sample_luminance = static_cast<float>(a.clamp);
  settings.seed = a.seed;
  cv::Mat sum(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  int total_spp = 0, passes = 0;
  uint64_t rays = 0;
  const auto start = std::chrono::steady_clock::now();
  const auto seconds_since_start = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  // One pass of the pixels' next `spp` samples, accumulated with its weight.
  const auto pass = [&](int spp, const std::string& what) {
    settings.samples_per_pixel = spp;
    settings.first_sample = total_spp;
    settings.progress = progress.fraction_printer(what);
    render::RenderStats stats;
    const cv::Mat image = render::render_image(*scene, camera, file.lights, settings, &stats);
    cv::scaleAdd(image, static_cast<double>(spp), sum, sum);
    total_spp += spp;
    rays += stats.rays;
    ++passes;
    return stats.seconds;
  };
  if (a.time_budget > 0) {
    // Passes of 1, 1, 2, 4, ... samples continuing each pixel's sequence, so
    // the total after each pass is a power of two (where the sequence is best
    // stratified); stop before a pass that would (taking about twice the
    // last one) end after the budget. The first always runs.
    for (int k = 0; k < kMaxTimedPasses; ++k) {
      const int spp = std::max(1, total_spp);
      progress.stage("render pass " + std::to_string(k + 1) + ": " + std::to_string(spp) + " spp");
      const double last = pass(spp, "pass " + std::to_string(k + 1));
      if (seconds_since_start() + 2.0 * last > a.time_budget) break;
    }
  } else {
    progress.stage("render: " + std::to_string(a.spp) + " spp, " + std::to_string(a.bounces) + " bounces");
    pass(a.spp, "render");
  }
  const double seconds = seconds_since_start();
  const cv::Mat image = sum / static_cast<double>(total_spp);
  capture::write_image(a.out, image);
  const double rays_per_s = seconds > 0 ? static_cast<double>(rays) / seconds : 0.0;
  json summary = {{"output", a.out},       {"width", camera.width}, {"height", camera.height},
                  {"spp", total_spp},      {"passes", passes},      {"seconds", seconds},
                  {"rays", rays},          {"rays_per_s", rays_per_s}};
  if (a.json_out) {
    std::cout << summary.dump(2) << std::endl;
  } else {
    std::fprintf(stderr, "render %dx%d, %d spp in %.2fs, %.1f Mrays (%.2f Mrays/s)\n", camera.width, camera.height,
                 total_spp, seconds, rays / 1e6, rays_per_s / 1e6);
    progress.stage("wrote " + a.out);
  }
  return 0;
}

// Why a command failed: on stderr for a person, at the journal's error
// priority under systemd (where stderr would reach it as plain info).
void report_failure(const std::string& message) {
  if (stderr_is_journal())
    spdlog::error("{}", message);
  else
    std::cerr << message << std::endl;
}

}  // namespace

int run_cli(int argc, char** argv) {
  CLI::App app{"PropCam: infer a scene from one photo and composite 3D props into it"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("propcam ") + PROPCAM_VERSION);
  // Options of the program, before or after the command (fallthrough).
  app.fallthrough();
  bool quiet = false, verbose = false;
  app.add_flag("-q,--quiet", quiet, "Warnings and errors only: no progress lines");
  app.add_flag("-v,--verbose", verbose, "Debug messages too");
  std::string data_dir;
  app.add_option("--data-dir", data_dir,
                 std::string("Folder of PropCam's data: models, boards (default: $") + inference::kDataDirEnv +
                     ", else share/propcam beside the executable's bin/)");

  InferArgs infer_args;
  auto* infer = app.add_subcommand("infer", "Infer the scene model (camera, depth, albedo, lights) of a photo");
  infer->add_option("photo", infer_args.photo, "Photo (PNG, JPEG, EXR, ...)");
  infer->add_option("-o,--output", infer_args.out, "Scene folder to write");
  infer->add_option("--lines", infer_args.lines_csv, "Run the camera stage on x1,y1,x2,y2 segments from a CSV file");
  infer->add_option("--size", infer_args.size, "Image size WxH for --lines");
  infer->add_option("--camera-height", infer_args.camera_height, "Camera height above the floor in metres")
      ->check(within(inference::kCameraHeightRange));
  infer->add_option("--focal", infer_args.lens.focal_px,
                    "Calibrated focal length in pixels at the photo's size (a prior for the camera stage)")
      ->check(within(inference::kFocalPxRange));
  infer->add_flag("--fixed-focal", infer_args.lens.fixed, "Use --focal as the focal length (estimate the rotation only)");
  infer->add_option("--working-size", infer_args.working_size,
                    "A larger photo is inferred reduced to this many pixels (WxH), its aspect kept")
      ->capture_default_str();
  add_memory_budget_option(*infer, infer_args.memory_mb);
  infer->add_flag("--json", infer_args.json_out, "Machine-readable output on stdout");

  CompositeArgs comp;
  auto* composite = app.add_subcommand("composite", "Place a prop in a photo and render the composite");
  composite->add_option("photo", comp.photo, "Photo")->required()->check(CLI::ExistingFile);
  composite->add_option("--scene", comp.scene_dir, "Scene folder from `propcam infer` (inferred if absent)");
  composite->add_option("--prop", comp.prop, "Preset name (see `propcam props`) or mesh file (OBJ)")->required();
  composite->add_option("--at", comp.at, "Pixel U,V of the support point under the prop")->required();
  composite->add_option("--height", comp.height, "Prop height in metres (default: its natural size)")
      ->check(within(inference::kPropHeightRange));
  composite->add_option("--yaw", comp.yaw, "Turn about the up axis, degrees counter-clockwise from above")
      ->check(within(inference::kYawDegRange));
  composite->add_option("--spp", comp.spp, "Samples per pixel")->check(CLI::Range(1, kMaxCliSpp));
  composite->add_option("--bounces", comp.bounces, "Light bounces as Blender Cycles counts them (0: direct light only)")
      ->check(CLI::Range(0, kMaxCliBounces));
  composite->add_option("--seed", comp.seed, "Random seed (same seed, same image)");
  composite->add_option("--material", comp.material,
                        "Override the prop's material: diffuse|plastic|glossy|metal|dielectric|glass")
      ->check(CLI::IsMember({"diffuse", "plastic", "glossy", "metal", "dielectric", "glass"}));
  composite->add_option("--albedo", comp.albedo, "Override the prop's albedo: R,G,B linear in 0..1");
  composite->add_option("--camera-height", comp.camera_height, "Camera height in metres when inferring")
      ->check(within(inference::kCameraHeightRange));
  composite->add_option("--focal", comp.lens.focal_px, "Calibrated focal length in pixels when inferring (a prior)")
      ->check(within(inference::kFocalPxRange));
  composite->add_flag("--fixed-focal", comp.lens.fixed, "Use --focal as the focal length when inferring");
  composite->add_option("--working-size", comp.working_size,
                        "A larger photo is inferred and rendered reduced to this many pixels (WxH) and the "
                        "composite delivered at the photo's size")
      ->capture_default_str();
  add_memory_budget_option(*composite, comp.memory_mb);
  composite->add_option("--time-budget", comp.time_budget,
                        "Seconds the render may take: no pass starts that would end after them (the samples "
                        "reached are reported)")
      ->capture_default_str()
      ->check(within(kTimeBudgetRange));
  composite->add_option("--save-scene", comp.save_scene, "Also write the inferred scene folder here");
  composite->add_option("-o,--output", comp.out, "Composite image to write (PNG, JPEG or EXR)")->required();
  composite->add_flag("--json", comp.json_out, "Machine-readable summary on stdout");
  composite->add_flag("--explain", comp.explain, "Print what the renderer traced and skipped, and why");
  composite->add_option("--light-scale", comp.light_scale,
                        "Relight after rendering: I=S,... scales light I (scene.json order; the last index is "
                        "emissive surfaces) on the prop and its shadows");
  composite->add_flag("--relight-scene", comp.relight_scene, "With --light-scale: relight the whole photo too");
  composite->add_option("--aperture", comp.aperture, "Depth of field: lens aperture diameter in metres (0: none)")
      ->check(within(inference::kApertureRange));
  composite->add_option("--focus", comp.focus, "Depth of field: focus distance in metres (default: the prop)")
      ->check(within(inference::kFocusDistanceRange));
  composite->add_flag("--no-cull", comp.no_cull, "Simulate everything: every tile, light and path (to measure what the plan saves)");
  composite->add_flag("--no-denoise", comp.no_denoise, "Keep the raw Monte Carlo change (no edge-aware filter of the prop's change)");
  composite->add_flag("--no-camera-match", comp.no_camera_match,
                      "Leave the prop as rendered (the photo's blur and noise not matched)");

  PropsArgs props_args;
  auto* props = app.add_subcommand("props", "List the preset props (and render their thumbnails)");
  props->add_flag("--json", props_args.json_out, "Machine-readable output");
  props->add_option("--thumbnails", props_args.thumbnails_dir, "Render every preset's thumbnail to DIR/<name>.png");
  props->add_option("--export", props_args.export_dir,
                    "Write every preset to DIR/<name>.obj (+ .mtl) and DIR/<name>.materials.json (exact materials)");
  props->add_option("--thumbnail-size", props_args.thumbnail_size, "Thumbnail width and height in pixels")
      ->check(CLI::Range(16, 4096));
  props->add_option("--thumbnail-spp", props_args.thumbnail_spp, "Thumbnail samples per pixel")
      ->check(CLI::Range(1, 65536));

  SynthArgs synth_args;
  auto* synth = app.add_subcommand("synth", "Render a synthetic room or street with exact ground truth (test fixtures)");
  synth->add_option("-o,--output", synth_args.out, "Folder to write")->required();
  synth->add_option("--seed", synth_args.seed, "Room seed");
  synth->add_option("--size", synth_args.size, "WxH");
  synth->add_option("--spp", synth_args.spp, "Samples per pixel")->check(CLI::PositiveNumber);
  synth->add_option("--prop", synth_args.prop, "Also render the room with this prop truly inserted");
  synth->add_option("--height", synth_args.height, "Prop height in metres");
  synth->add_flag("--json", synth_args.json_out, "Machine-readable summary");
  synth->add_flag("--street", synth_args.street, "A street (sun and sky) instead of a room");

  DepthDatabaseSpec depth_db_spec;
  std::string depth_db_out;
  LightTrainingArgs train_lights_args;
  auto* train_lights = add_train_light_classifier_command(app, train_lights_args);
  IblTrainingArgs train_ibl_args;
  auto* train_ibl = add_train_ibl_ranker_command(app, train_ibl_args);
  auto* build_depth_db = app.add_subcommand(
      "build-depth-db", "Render the depth-transfer database from generator scenes (scripts/build_depth_db.sh)");
  build_depth_db->add_option("-o,--output", depth_db_out, "Database file to write")->required();
  build_depth_db->add_option("--rooms", depth_db_spec.rooms, "Rooms")->check(CLI::NonNegativeNumber);
  build_depth_db->add_option("--streets", depth_db_spec.streets, "Streets")->check(CLI::NonNegativeNumber);
  build_depth_db->add_option("--first-seed", depth_db_spec.first_seed, "First generator seed");
  build_depth_db->add_option("--spp", depth_db_spec.spp, "Samples per pixel of the photos")->check(CLI::PositiveNumber);

  SceneReferenceArgs scene_refs_args;
  auto* build_scene_refs = add_build_scene_refs_command(app, scene_refs_args);

  inference::IblLibraryOptions ibl_options;
  std::string ibl_out;
  auto* build_ibl = app.add_subcommand(
      "build-ibl-library", "Build the annotated IBL panorama library (scripts/build_ibl_library.sh)");
  build_ibl->add_option("-o,--output", ibl_out, "Library folder to write (library.json + EXR panoramas)")->required();
  build_ibl->add_option("--width", ibl_options.width, "Stored panorama width (height is half)")->check(CLI::Range(8, 4096));
  build_ibl->add_option("--blender-dir", ibl_options.blender_dir, "blender-data world panoramas (skipped if absent)");
  build_ibl->add_option("--skies", ibl_options.procedural_skies, "Procedural skies")->check(CLI::NonNegativeNumber);
  build_ibl->add_option("--rooms", ibl_options.procedural_rooms, "Procedural rooms")->check(CLI::NonNegativeNumber);
  build_ibl
      ->add_option_function<std::vector<std::string>>(
          "--panoramas",
          [&ibl_options](const std::vector<std::string>& specs) {
            for (const auto& s : specs) ibl_options.extra_panoramas.push_back(inference::parse_extra_panorama(s));
          },
          "Further EXR panoramas as PATH=indoor|outdoor")
      ->delimiter(',');

  RenderArgs render_args;
  auto* render_cmd = app.add_subcommand("render", "Render a SCENE.json (camera, OBJ meshes, lights) to an image");
  render_cmd->add_option("scene", render_args.scene, "Scene file (see render/README.md)")->required();
  auto* spp_option = render_cmd->add_option("--spp", render_args.spp, "Samples per pixel");
  constexpr inference::PhysicalRange kRenderSecondsRange{1e-3, 86400.0, "s"}, kClampRange{0.0, 1e30, ""};
  render_cmd->add_option("--time", render_args.time_budget, "Render passes of doubling spp for about S seconds")
      ->check(within(kRenderSecondsRange))
      ->excludes(spp_option);
  render_cmd->add_option("--bounces", render_args.bounces, "Light bounces as Blender Cycles counts them (0: direct light only)")
      ->check(CLI::Range(0, kMaxCliBounces));
  render_cmd->add_option("--threads", render_args.threads, "Render threads (0: all hardware threads)")
      ->check(CLI::Range(0, kMaxCliThreads));
  render_cmd->add_option("--clamp", render_args.clamp,
                         "Largest luminance of one sample; brighter samples are scaled down (0: no clamp)")
      ->check(within(kClampRange));
  render_cmd->add_option("--seed", render_args.seed, "Random seed (same seed, same image)");
  render_cmd->add_option("-o,--output", render_args.out, "Image to write (EXR linear, or PNG/JPEG sRGB)")->required();
  render_cmd->add_flag("--json", render_args.json_out, "Machine-readable summary on stdout");

  BenchOptions bench_options;
  bool bench_json = false;
  std::string bench_size = "320x240";
  auto* bench = app.add_subcommand("bench", "Time and error of every stage, and the renderer's error-vs-time curve");
  bench->add_option("--size", bench_size, "Synthetic photo size WxH");
  bench->add_option("--seed", bench_options.seed, "Synthetic room seed");
  bench->add_option("--max-spp", bench_options.max_spp, "Largest samples per pixel in the sweep");
  bench->add_option("--reference-spp", bench_options.reference_spp, "Samples per pixel of the reference render");
  bench->add_option("--plot", bench_options.plot_dir, "Write PNG plots (gnuplot) to this folder");
  bench->add_flag("--json", bench_json, "Machine-readable output");
  CameraBenchArgs bench_camera_args;
  auto* bench_camera = add_bench_camera_command(*bench, bench_camera_args);
  GeometryBenchArgs bench_geometry_args;
  auto* bench_geometry = add_bench_geometry_command(*bench, bench_geometry_args);
  TransferBenchArgs bench_transfer_args;
  auto* bench_transfer = add_bench_transfer_command(*bench, bench_transfer_args);
  SceneClassBenchArgs bench_scene_class_args;
  auto* bench_scene_class = add_bench_scene_class_command(*bench, bench_scene_class_args);
  LightingBenchArgs bench_lighting_args;
  auto* bench_lighting = add_bench_lighting_command(*bench, bench_lighting_args);
  WorldsBenchArgs bench_worlds_args;
  auto* bench_worlds = add_bench_worlds_command(*bench, bench_worlds_args);
  LightTrainingArgs bench_lights_args;
  auto* bench_lights = add_bench_lights_command(*bench, bench_lights_args);
  IblTrainingArgs bench_ibl_args;
  auto* bench_ibl = add_bench_ibl_ranking_command(*bench, bench_ibl_args);
  CaptureBenchArgs bench_capture_args;
  auto* bench_capture = add_bench_capture_command(*bench, bench_capture_args);

  CamerasArgs cameras_args;
  auto* cameras = add_cameras_command(app, cameras_args);
  RecordArgs record_args;
  auto* record = add_record_command(app, record_args);
  ShootArgs shoot_args;
  auto* shoot = add_shoot_command(app, shoot_args);
  ExportArgs export_args;
  auto* export_cmd = add_export_command(app, export_args);
  SpoolArgs spool_args;
  auto* spool = add_spool_command(app, spool_args);
  RunArgs run_args;
  auto* run = add_run_command(app, run_args);

  RenderBenchOptions render_bench_options;
  bool render_bench_json = false;
  std::string render_bench_sizes = "640x480,1024x768";
  auto* bench_render = bench->add_subcommand(
      "render", "Renderer speed per size: rays/s vs a raw Embree loop, first snapshot, time to 1% error");
  bench_render->add_option("--sizes", render_bench_sizes, "Comma-separated WxH list");
  bench_render->add_option("--seed", render_bench_options.seed, "Synthetic room seed");
  bench_render->add_option("--prop", render_bench_options.prop, "Preset prop (see `propcam props`)");
  bench_render->add_option("--reference-spp", render_bench_options.reference_spp,
                           "Samples per pixel of the reference render (two independent halves)");
  bench_render->add_option("--max-spp", render_bench_options.max_spp,
                           "The measured session stops here if it never reaches 1%");
  bench_render->add_option("--threads", render_bench_options.threads, "Render threads (0: all hardware threads)");
  std::string skip_size = "320x240";
  bench_render->add_option("--skip-size", skip_size, "Room size WxH for the skip comparison");
  bench_render->add_option("--skip-spp", render_bench_options.skip_spp,
                           "Samples per pixel of the skip comparison (0: no skip comparison)")
      ->check(CLI::Range(0, 4096));
  bench_render->add_option("--skip-reference-spp", render_bench_options.skip_reference_spp,
                           "Samples per pixel of the skip comparison's reference")
      ->check(CLI::Range(1, 65536));
  bench_render->add_option("--plot", render_bench_options.plot_dir, "Write one PNG per size (gnuplot) to this folder");
  bench_render->add_flag("--json", render_bench_json, "Machine-readable output");

  ViewArgs view_args;
  auto* view = app.add_subcommand("view", "Cut a rectilinear photo with a known camera out of an HDR panorama");
  view->add_option("panorama", view_args.panorama, "Equirectangular panorama (EXR, HDR, PNG, ...)")
      ->required()->check(CLI::ExistingFile);
  view->add_option("-o,--output", view_args.out, "Photo to write")->required();
  view->add_option("--size", view_args.size, "WxH");
  constexpr inference::PhysicalRange kFovDegRange{1.0, 170.0, "degrees"}, kPitchDegRange{-90.0, 90.0, "degrees"},
      kRollDegRange{-180.0, 180.0, "degrees"}, kExposureEvRange{-30.0, 30.0, "stops"};
  view->add_option("--fov", view_args.fov, "Horizontal field of view, degrees")->check(within(kFovDegRange));
  view->add_option("--yaw", view_args.yaw, "Degrees counter-clockwise from above; 0 looks at the panorama's centre column")
      ->check(within(inference::kYawDegRange));
  view->add_option("--pitch", view_args.pitch, "Degrees, positive looks up")->check(within(kPitchDegRange));
  view->add_option("--roll", view_args.roll, "Degrees about the view axis")->check(within(kRollDegRange));
  view->add_option("--exposure", view_args.exposure_ev, "Exposure change in stops after auto exposure")
      ->check(within(kExposureEvRange));
  view->add_flag("--json", view_args.json_out, "Print the camera as JSON");

  std::string console_tty = "/dev/tty0";
  bool console_restore = false;
  auto* console = app.add_subcommand("console", "The VT under the display: its mode, or back to text mode (--restore)");
  console->add_option("--tty", console_tty, "The virtual terminal")->capture_default_str();
  console->add_flag("--restore", console_restore, "Switch it to text mode (after the appliance was killed)");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every bad argument exits 2, as the
    // checks after parsing do (CLI11's own codes run from 101 to 116).
    return app.exit(e) == 0 ? 0 : kExitBadArguments;
  }
  // Logs go to stderr, or to the journal with priorities under systemd;
  // stdout is for results and --json.
  set_up_logging("propcam", quiet ? Verbosity::Quiet : verbose ? Verbosity::Verbose : Verbosity::Normal);
  Progress::silence_all(quiet);
  try {
    inference::set_data_dir(data_dir);
    // Commands that infer scenes check their models now, not mid-way.
    if (*infer || *composite || *run || *bench) inference::require_data_files(inference::inference_data_files());
    if (*infer) return cmd_infer(infer_args);
    if (*composite) return cmd_composite(comp);
    if (*props) return cmd_props(props_args);
    if (*synth) return cmd_synth(synth_args);
    if (*train_lights) return run_train_light_classifier_command(train_lights_args);
    if (*train_ibl) return run_train_ibl_ranker_command(train_ibl_args);
    if (*build_depth_db) {
      const inference::DepthDatabase db = build_depth_database(depth_db_spec);
      db.save(depth_db_out);
      std::fprintf(stderr, "wrote %zu examples to %s\n", db.size(), depth_db_out.c_str());
      return 0;
    }
    if (*build_scene_refs) return run_build_scene_refs_command(scene_refs_args);
    if (*build_ibl) {
      const auto start = std::chrono::steady_clock::now();
      const inference::IblLibrary library = inference::build_ibl_library(ibl_options);
      inference::save_ibl_library(library, ibl_out);
      size_t lights = 0, indoor = 0;
      for (const auto& e : library.entries) {
        lights += e.lights.size();
        indoor += e.kind == inference::SceneKind::Indoor;
      }
      std::fprintf(stderr, "wrote %zu panoramas (%zu indoor, %zu outdoor, %zu light regions) to %s in %.2f s\n",
                   library.entries.size(), indoor, library.entries.size() - indoor, lights, ibl_out.c_str(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      return 0;
    }
    if (*view) return cmd_view(view_args);
    if (*console) return cmd_console(console_tty, console_restore);
    if (*render_cmd) return cmd_render(render_args);
    if (*bench_render) {
      render_bench_options.sizes = parse_sizes(render_bench_sizes);
      if (!parse_pair(skip_size, render_bench_options.skip_size.width, render_bench_options.skip_size.height, 'x') ||
          render_bench_options.skip_size.width < 16 || render_bench_options.skip_size.height < 16)
        throw std::invalid_argument("--skip-size expects WxH of at least 16x16");
      render_bench_options.quiet = render_bench_json;
      const json result = run_render_bench(render_bench_options);
      if (!render_bench_options.plot_dir.empty()) plot_render_bench(result, render_bench_options.plot_dir);
      if (render_bench_json) std::cout << result.dump(2) << std::endl;
      else std::cout << format_render_bench(result);
      return 0;
    }
    if (*bench_camera) return run_bench_camera_command(bench_camera_args);
    if (*bench_geometry) return run_bench_geometry_command(bench_geometry_args);
    if (*bench_transfer) return run_bench_transfer_command(bench_transfer_args);
    if (*bench_scene_class) return run_bench_scene_class_command(bench_scene_class_args);
    if (*bench_lighting) return run_bench_lighting_command(bench_lighting_args);
    if (*bench_worlds) return run_bench_worlds_command(bench_worlds_args);
    if (*bench_lights) return run_bench_lights_command(bench_lights_args);
    if (*bench_ibl) return run_bench_ibl_ranking_command(bench_ibl_args);
    if (*bench_capture) return run_bench_capture_command(bench_capture_args);
    if (*cameras) return run_cameras_command(cameras_args);
    if (*record) return run_record_command(record_args);
    if (*shoot) return run_shoot_command(shoot_args);
    if (*export_cmd) return run_export_command(export_args);
    if (*spool) return run_spool_command(spool_args);
    if (*run) return run_run_command(run_args);
    if (*bench) {
      if (!parse_pair(bench_size, bench_options.width, bench_options.height, 'x') || bench_options.width < 32 ||
          bench_options.height < 32)
        throw std::invalid_argument("--size expects WxH of at least 32x32");
      bench_options.quiet = bench_json;
      const json result = run_bench(bench_options);
      if (!bench_options.plot_dir.empty()) plot_bench(result, bench_options.plot_dir);
      if (bench_json) std::cout << result.dump(2) << std::endl;
      else std::cout << format_bench(result);
      return 0;
    }
  } catch (const std::invalid_argument& e) {
    report_failure(std::string("propcam: ") + e.what());
    return kExitBadArguments;
  } catch (const std::exception& e) {
    report_failure(std::string("propcam: error: ") + e.what());
    return 1;
  }
  return 0;
}

}  // namespace propcam::firmware
