#include "cli/scene_commands.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "cli/cli_checks.h"
#include "common/compositor.h"
#include "common/progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/physical_ranges.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/mesh_io.h"
#include "propcam/render/panorama.h"
#include "propcam/render/props.h"
#include "propcam/render/scene_file.h"
#include "propcam/ui_fb/console.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

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

// `--time`: passes of 1, 1, 2, 4, ... samples per pixel; at most this many
// passes (2^15 samples per pixel in all).
constexpr int kMaxTimedPasses = 16;

}  // namespace

void add_props_options(CLI::App& cmd, PropsArgs& a) {
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
  cmd.add_option("--thumbnails", a.thumbnails_dir, "Render every preset's thumbnail to DIR/<name>.png");
  cmd.add_option("--export", a.export_dir,
                 "Write every preset to DIR/<name>.obj (+ .mtl) and DIR/<name>.materials.json (exact materials)");
  cmd.add_option("--thumbnail-size", a.thumbnail_size, "Thumbnail width and height in pixels")
      ->check(CLI::Range(16, 4096));
  cmd.add_option("--thumbnail-spp", a.thumbnail_spp, "Thumbnail samples per pixel")
      ->check(CLI::Range(1, 65536));
}

int run_props_command(const PropsArgs& a) {
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

void add_synth_options(CLI::App& cmd, SynthArgs& a) {
  cmd.add_option("-o,--output", a.out, "Folder to write")->required();
  cmd.add_option("--seed", a.seed, "Room seed");
  cmd.add_option("--size", a.size, "WxH");
  cmd.add_option("--spp", a.spp, "Samples per pixel")->check(CLI::PositiveNumber);
  cmd.add_option("--prop", a.prop, "Also render the room with this prop truly inserted");
  cmd.add_option("--height", a.height, "Prop height in metres");
  cmd.add_flag("--json", a.json_out, "Machine-readable summary");
  cmd.add_flag("--street", a.street, "A street (sun and sky) instead of a room");
}

int run_synth_command(const SynthArgs& a) {
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

void add_view_options(CLI::App& cmd, ViewArgs& a) {
  cmd.add_option("panorama", a.panorama, "Equirectangular panorama (EXR, HDR, PNG, ...)")
      ->required()->check(CLI::ExistingFile);
  cmd.add_option("-o,--output", a.out, "Photo to write")->required();
  cmd.add_option("--size", a.size, "WxH");
  constexpr inference::PhysicalRange kFovDegRange{1.0, 170.0, "degrees"}, kPitchDegRange{-90.0, 90.0, "degrees"},
      kRollDegRange{-180.0, 180.0, "degrees"}, kExposureEvRange{-30.0, 30.0, "stops"};
  cmd.add_option("--fov", a.fov, "Horizontal field of view, degrees")->check(within(kFovDegRange));
  cmd.add_option("--yaw", a.yaw, "Degrees counter-clockwise from above; 0 looks at the panorama's centre column")
      ->check(within(inference::kYawDegRange));
  cmd.add_option("--pitch", a.pitch, "Degrees, positive looks up")->check(within(kPitchDegRange));
  cmd.add_option("--roll", a.roll, "Degrees about the view axis")->check(within(kRollDegRange));
  cmd.add_option("--exposure", a.exposure_ev, "Exposure change in stops after auto exposure")
      ->check(within(kExposureEvRange));
  cmd.add_flag("--json", a.json_out, "Print the camera as JSON");
}

// A rectilinear "photo" cut from an HDR panorama, exposed like a camera would.
int run_view_command(const ViewArgs& a) {
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

void add_render_options(CLI::App& cmd, RenderArgs& a) {
  cmd.add_option("scene", a.scene, "Scene file (see render/README.md)")->required();
  auto* spp_option = cmd.add_option("--spp", a.spp, "Samples per pixel");
  constexpr inference::PhysicalRange kRenderSecondsRange{1e-3, 86400.0, "s"}, kClampRange{0.0, 1e30, ""};
  cmd.add_option("--time", a.time_budget, "Render passes of doubling spp for about S seconds")
      ->check(within(kRenderSecondsRange))
      ->excludes(spp_option);
  cmd.add_option("--bounces", a.bounces, "Light bounces as Blender Cycles counts them (0: direct light only)")
      ->check(CLI::Range(0, kMaxCliBounces));
  cmd.add_option("--threads", a.threads, "Render threads (0: all hardware threads)")
      ->check(CLI::Range(0, kMaxCliThreads));
  cmd.add_option("--clamp", a.clamp,
                 "Largest luminance of one sample; brighter samples are scaled down (0: no clamp)")
      ->check(within(kClampRange));
  cmd.add_option("--seed", a.seed, "Random seed (same seed, same image)");
  cmd.add_option("-o,--output", a.out, "Image to write (EXR linear, or PNG/JPEG sRGB)")->required();
  cmd.add_flag("--json", a.json_out, "Machine-readable summary on stdout");
}

int run_render_command(const RenderArgs& a) {
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

void add_console_options(CLI::App& cmd, ConsoleArgs& a) {
  cmd.add_option("--tty", a.tty, "The virtual terminal")->capture_default_str();
  cmd.add_flag("--restore", a.restore, "Switch it to text mode (after the appliance was killed)");
}

// `propcam console`, the service's ExecStopPost: the appliance restores the
// console itself on exit and on fatal signals, but not after SIGKILL.
int run_console_command(const ConsoleArgs& a) {
  const std::string& tty = a.tty;
  std::string why;
  if (a.restore && !ui_fb::restore_console_text_mode(tty, why)) throw std::runtime_error(tty + ": " + why);
  const ui_fb::ConsoleMode mode = ui_fb::console_mode(tty, why);
  if (mode == ui_fb::ConsoleMode::Unknown) throw std::runtime_error(tty + ": " + why);
  std::cout << tty << ": " << (mode == ui_fb::ConsoleMode::Graphics ? "graphics" : "text") << std::endl;
  return 0;
}

}  // namespace propcam::firmware
