#include "bench/bench_render.h"

#include "bench/bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "common/bench_common.h"
#include "common/compositor.h"
#include "common/progress.h"
#include "propcam/render/ray_throughput.h"
#include "propcam/render/render_session.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

// The skip comparison's reference uses its own stream.
constexpr uint64_t kSkipReferenceSeed = 999;

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

// Independent random streams: the reference's two halves, the measured
// session, the synthetic photo and the raw loop's rays.
constexpr uint64_t kReferenceSeedA = 0x2ef0001;
constexpr uint64_t kReferenceSeedB = 0x2ef0002;
constexpr uint64_t kSessionSeed = 0x5eed;
constexpr uint64_t kPhotoSeed = 0x9407;
constexpr uint64_t kRawRaySeed = 0x4a3;
// The raw loop's batch: this many camera samples per traced pixel (each with
// its bounce ray), traced again and again for at least this long.
constexpr int kRawCameraSamplesPerPixel = 1;
constexpr double kMinRawLoopSeconds = 0.5;
constexpr int kMinSide = 16;
constexpr int kMaxSide = 8192;
constexpr int kMaxSpp = 65536;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

double mean_luminance(const cv::Mat& image, const cv::Mat& mask) {
  const cv::Scalar m = cv::mean(image, mask);
  return 0.2126 * m[0] + 0.7152 * m[1] + 0.0722 * m[2];
}

render::SessionSettings session_settings(const RenderBenchOptions& o, uint64_t seed, int max_spp) {
  render::SessionSettings s;
  s.render.seed = seed;
  s.render.threads = o.threads;
  s.max_samples_per_pixel = max_spp;
  return s;
}

// A session run to its sample limit.
render::DifferentialRender render_to_limit(const CompositeWorld& w, const cv::Mat& photo,
                                           const render::SessionSettings& settings) {
  render::RenderSession session(*w.scene, w.camera, w.lights, photo, w.prop_bounds, settings);
  while (!session.finished()) session.run_pass();
  return session.differential();
}

json bench_size(const RenderBenchOptions& o, const render::Mesh& prop, double prop_height, cv::Size size, int threads,
               Progress& progress) {
  const std::string label = std::to_string(size.width) + "x" + std::to_string(size.height);
  progress.stage("bench render " + label + ": synthetic photo at " + std::to_string(o.photo_spp) + " spp");
  render::SyntheticRoomSpec spec;
  spec.width = size.width;
  spec.height = size.height;
  spec.seed = o.seed;
  render::RenderSettings photo_settings;
  photo_settings.samples_per_pixel = o.photo_spp;
  photo_settings.seed = kPhotoSeed;
  photo_settings.threads = o.threads;
  const SyntheticShot shot = shoot_synthetic_room(spec, photo_settings);
  const cv::Mat& photo = shot.photo_linear;

  const Eigen::Vector2d at = free_floor_pixel(shot.room);
  const CompositeWorld world = build_composite_world(shot.truth, prop, {at.x(), at.y(), prop_height, 0.0});

  // Reference: two independent halves; their difference estimates its own noise.
  progress.stage("bench render " + label + ": reference at " + std::to_string(o.reference_spp) + " spp");
  const auto ref_start = Clock::now();
  const int half_spp = o.reference_spp / 2;
  const render::DifferentialRender ref_a = render_to_limit(world, photo, session_settings(o, kReferenceSeedA, half_spp));
  const render::DifferentialRender ref_b = render_to_limit(world, photo, session_settings(o, kReferenceSeedB, half_spp));
  render::DifferentialRender ref_mean;
  ref_mean.change = (ref_a.change + ref_b.change) * 0.5;
  ref_mean.coverage = (ref_a.coverage + ref_b.coverage) * 0.5;
  const cv::Mat reference = render::composite_differential(photo, ref_mean);
  const double reference_seconds = seconds_since(ref_start);
  const cv::Mat region = changed_pixels(reference, photo);
  const int region_pixels = cv::countNonZero(region);
  if (region_pixels == 0)
    throw std::runtime_error("bench render " + label + ": the prop changes no pixel of the reference");
  const double region_luminance = mean_luminance(photo, region);
  if (!(region_luminance > 0)) throw std::runtime_error("bench render " + label + ": the prop's region is black");
  // Each half has noise s·√2 (s: the whole reference's); their difference s·2.
  const double reference_noise_rel =
      rmse_in_mask(render::composite_differential(photo, ref_a), render::composite_differential(photo, ref_b), region) /
      2.0 / region_luminance;

  // The measured session: passes of doubling samples until 1% (or max_spp).
  progress.stage("bench render " + label + ": session to " + std::to_string(o.max_spp) + " spp or 1%");
  const auto session_start = Clock::now();
  render::RenderSession session(*world.scene, world.camera, world.lights, photo, world.prop_bounds,
                                session_settings(o, kSessionSeed, o.max_spp));
  double elapsed = seconds_since(session_start);  // culling and tiles so far
  double tracing = 0.0, first_snapshot = 0.0;
  std::optional<double> time_to_target, time_to_target_denoised;
  std::optional<int> spp_to_target, spp_to_target_denoised;
  json curve = json::array();
  while (true) {
    const auto pass_start = Clock::now();
    const render::PassReport pass = session.run_pass();
    const double pass_seconds = seconds_since(pass_start);
    elapsed += pass_seconds;
    tracing += pass_seconds;
    if (curve.empty()) first_snapshot = elapsed;
    // Not timed: the error of this snapshot, raw and denoised (the filter's
    // own time is reported, and counted only in the denoised time to 1%).
    const double rmse = rmse_in_mask(session.composite(), reference, region);
    render::DenoiseReport denoise;
    const render::DifferentialRender denoised = session.denoised(&denoise);
    const double rmse_denoised = rmse_in_mask(render::composite_differential(photo, denoised), reference, region);
    curve.push_back({{"pass", pass.pass},
                     {"spp", pass.max_samples},
                     {"seconds", elapsed},
                     {"rmse", rmse},
                     {"rmse_rel", rmse / region_luminance},
                     {"rmse_rel_denoised", rmse_denoised / region_luminance},
                     {"denoise_seconds", denoise.seconds},
                     {"denoise_tiles_filtered", denoise.tiles_filtered},
                     {"denoise_tiles_judged", denoise.tiles_judged}});
    if (!time_to_target && rmse / region_luminance < kRenderBenchTargetRelativeRmse) {
      time_to_target = elapsed;
      spp_to_target = pass.max_samples;
    }
    if (!time_to_target_denoised && rmse_denoised / region_luminance < kRenderBenchTargetRelativeRmse) {
      time_to_target_denoised = elapsed + denoise.seconds;
      spp_to_target_denoised = pass.max_samples;
    }
    if ((time_to_target && time_to_target_denoised) || session.finished()) break;
  }
  const render::RenderStats stats = session.stats();
  const double rays_per_s = tracing > 0 ? static_cast<double>(stats.rays) / tracing : 0.0;
  int tiles_culled = 0;
  cv::Mat traced(photo.size(), CV_8U, cv::Scalar(0));
  for (const auto& t : session.tiles()) {
    if (t.affected) traced(t.rect).setTo(255);
    else ++tiles_culled;
  }

  // The raw loop: closest-hit queries alone, the same pixels, threads and BVH.
  progress.stage("bench render " + label + ": raw Embree loop");
  const render::RayBatch batch = render::camera_and_bounce_rays(*world.scene, world.camera, true,
                                                                kRawCameraSamplesPerPixel, kRawRaySeed, traced);
  const render::EmbreeRayLoop raw_loop({&world.scene->mesh(0), &world.scene->mesh(1)});
  const render::RayThroughput raw = raw_loop.trace(batch, threads, kMinRawLoopSeconds);
  const render::RayThroughput wrapped = render::trace_with_scene(*world.scene, true, batch, threads, kMinRawLoopSeconds);

  const auto null_or = [](const auto& v) { return v ? json(*v) : json(nullptr); };
  return {{"width", size.width},
          {"height", size.height},
          {"scene_build_s", world.build_seconds},
          {"reach_s", session.reach().seconds},
          {"first_snapshot_s", first_snapshot},
          {"time_to_1pct_s", null_or(time_to_target)},
          {"spp_to_1pct", null_or(spp_to_target)},
          {"time_to_1pct_denoised_s", null_or(time_to_target_denoised)},
          {"spp_to_1pct_denoised", null_or(spp_to_target_denoised)},
          {"rays_per_s", rays_per_s},
          {"embree_raw_rays_per_s", raw.rays_per_s()},
          {"scene_intersect_rays_per_s", wrapped.rays_per_s()},
          {"efficiency", raw.rays_per_s() > 0 ? rays_per_s / raw.rays_per_s() : 0.0},
          {"render", {{"rays", stats.rays},
                      {"tracing_seconds", tracing},
                      {"camera_samples", stats.camera_samples},
                      {"second_paths", stats.paths_without_prop},
                      {"tiles", session.tiles().size()},
                      {"tiles_culled", tiles_culled},
                      {"pixels_traced", cv::countNonZero(traced)}}},
          {"raw_loop", {{"batch_rays", batch.size()},
                        {"rays", raw.rays},
                        {"repeats", raw.repeats},
                        {"seconds", raw.seconds},
                        {"hit_fraction", raw.rays ? static_cast<double>(raw.hits) / raw.rays : 0.0}}},
          {"reference", {{"spp", 2 * half_spp},
                         {"seconds", reference_seconds},
                         {"noise_rel", reference_noise_rel},
                         {"region_pixels", region_pixels},
                         {"region_mean_luminance", region_luminance}}},
          {"curve", curve}};
}

}  // namespace

std::vector<cv::Size> parse_sizes(const std::string& text) {
  std::vector<cv::Size> sizes;
  std::istringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    std::istringstream one(item);
    int w = 0, h = 0;
    char x = 0;
    if (!(one >> w >> x >> h) || x != 'x' || one.peek() != EOF || w < kMinSide || h < kMinSide || w > kMaxSide ||
        h > kMaxSide)
      throw std::invalid_argument("--sizes expects WxH[,WxH...] with sides in " + std::to_string(kMinSide) + ".." +
                                  std::to_string(kMaxSide) + ", got '" + text + "'");
    sizes.emplace_back(w, h);
  }
  if (sizes.empty()) throw std::invalid_argument("--sizes expects at least one WxH");
  return sizes;
}

json run_render_bench(const RenderBenchOptions& o) {
  if (o.sizes.empty()) throw std::invalid_argument("bench render: no sizes");
  if (o.reference_spp < 2 || o.reference_spp > kMaxSpp)
    throw std::invalid_argument("--reference-spp must be in 2.." + std::to_string(kMaxSpp));
  if (o.max_spp < 1 || o.max_spp > kMaxSpp) throw std::invalid_argument("--max-spp must be in 1.." + std::to_string(kMaxSpp));
  if (o.photo_spp < 1) throw std::invalid_argument("bench render: photo spp must be positive");
  if (o.threads < 0) throw std::invalid_argument("--threads must be >= 0");
  const render::Mesh prop = load_prop(o.prop);  // an unknown prop fails before any rendering
  const double prop_height = o.prop_height_m > 0 ? o.prop_height_m : natural_height(o.prop, prop);
  Progress progress(o.quiet);
  const int threads = o.threads > 0 ? o.threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  json sizes = json::array();
  for (const cv::Size& size : o.sizes) sizes.push_back(bench_size(o, prop, prop_height, size, threads, progress));
  json skips = json::array();
  if (o.skip_spp > 0 && o.skip_size.area() > 0) {
    progress.stage("bench render: skips at " + std::to_string(o.skip_size.width) + "x" +
                   std::to_string(o.skip_size.height));
    render::SyntheticRoomSpec spec;
    spec.width = o.skip_size.width;
    spec.height = o.skip_size.height;
    spec.seed = static_cast<uint32_t>(o.seed);
    render::RenderSettings photo_settings;
    photo_settings.samples_per_pixel = o.photo_spp;
    const SyntheticShot shot = shoot_synthetic_room(spec, photo_settings);
    const Eigen::Vector2d at = free_floor_pixel(shot.room);
    const render::PropPlacement placement{at.x(), at.y(), prop_height, 0.0};
    render::RenderSettings ref_settings;
    ref_settings.samples_per_pixel = std::max(o.skip_spp, o.skip_reference_spp);
    ref_settings.seed = kSkipReferenceSeed;
    CompositeOptions everything;
    everything.cull_tiles = false;
    everything.plan.allow_skips = false;
    const CompositeResult reference = composite_prop(shot.photo_linear, shot.truth, prop, placement, ref_settings, everything);
    skips = measure_render_skips(shot.photo_linear, shot.truth, prop, placement, reference.composite_linear, o.skip_spp);
  }
  return {{"bench", "render"},
          {"skips", skips},
          {"machine", {{"hardware_threads", std::thread::hardware_concurrency()}}},
          {"threads", threads},
          {"seed", o.seed},
          {"prop", o.prop},
          {"prop_height_m", prop_height},
          {"reference_spp", o.reference_spp},
          {"photo_spp", o.photo_spp},
          {"max_spp", o.max_spp},
          {"target_rmse_rel", kRenderBenchTargetRelativeRmse},
          {"raw_loop", "rtcIntersect1 straight on Embree (same meshes and build settings as Scene), one camera ray "
                       "per traced pixel plus a cosine-distributed ray from its first hit, tile order"},
          {"sizes", sizes}};
}

std::string format_render_bench(const json& r) {
  const std::string skips = r.contains("skips") && !r["skips"].empty() ? format_render_skips(r["skips"]) : "";
  std::ostringstream out;
  char line[320];
  std::snprintf(line, sizeof line,
                "Render bench: %s (%.2f m) on the free floor of synthetic room %llu, %d threads; "
                "target RMSE %.0f%% of the region's mean luminance\n\n",
                r["prop"].get<std::string>().c_str(), r["prop_height_m"].get<double>(),
                static_cast<unsigned long long>(r["seed"].get<uint64_t>()), r["threads"].get<int>(),
                100.0 * r["target_rmse_rel"].get<double>());
  out << line
      << "  size       build_s  snapshot_s  Mrays/s  raw_Mrays/s  scene_Mrays/s  efficiency  to_1%_s  spp  denoised_1%_s  spp  ref_noise\n";
  for (const auto& s : r["sizes"]) {
    char to_target[32] = "    -", spp[16] = "   -", to_target_dn[32] = "    -", spp_dn[16] = "   -";
    if (!s["time_to_1pct_s"].is_null()) {
      std::snprintf(to_target, sizeof to_target, "%7.2f", s["time_to_1pct_s"].get<double>());
      std::snprintf(spp, sizeof spp, "%4d", s["spp_to_1pct"].get<int>());
    }
    if (!s["time_to_1pct_denoised_s"].is_null()) {
      std::snprintf(to_target_dn, sizeof to_target_dn, "%7.2f", s["time_to_1pct_denoised_s"].get<double>());
      std::snprintf(spp_dn, sizeof spp_dn, "%4d", s["spp_to_1pct_denoised"].get<int>());
    }
    const std::string size = std::to_string(s["width"].get<int>()) + "x" + std::to_string(s["height"].get<int>());
    std::snprintf(line, sizeof line, "  %-10s %7.3f  %10.3f  %7.2f  %11.2f  %13.2f  %9.1f%%  %7s  %4s  %13s  %4s  %8.2f%%\n",
                  size.c_str(), s["scene_build_s"].get<double>(), s["first_snapshot_s"].get<double>(),
                  s["rays_per_s"].get<double>() / 1e6, s["embree_raw_rays_per_s"].get<double>() / 1e6,
                  s["scene_intersect_rays_per_s"].get<double>() / 1e6, 100.0 * s["efficiency"].get<double>(),
                  to_target, spp, to_target_dn, spp_dn, 100.0 * s["reference"]["noise_rel"].get<double>());
    out << line;
  }
  for (const auto& s : r["sizes"]) {
    std::snprintf(line, sizeof line,
                  "\n%dx%d: error vs time (%d px region, reference %d spp in %.1f s)\n"
                  "   spp   seconds   rmse%%  denoised%%  denoise_s\n",
                  s["width"].get<int>(), s["height"].get<int>(), s["reference"]["region_pixels"].get<int>(),
                  s["reference"]["spp"].get<int>(), s["reference"]["seconds"].get<double>());
    out << line;
    for (const auto& p : s["curve"]) {
      std::snprintf(line, sizeof line, "  %4d  %8.3f  %6.2f  %6.2f  %6.3f\n", p["spp"].get<int>(),
                    p["seconds"].get<double>(), 100.0 * p["rmse_rel"].get<double>(),
                    100.0 * p["rmse_rel_denoised"].get<double>(), p["denoise_seconds"].get<double>());
      out << line;
    }
  }
  out << skips;
  return out.str();
}

void plot_render_bench(const json& r, const std::string& dir) {
  fs::create_directories(dir);
  const fs::path d(dir);
  std::ostringstream gp;
  gp << "set terminal png size 800,560\nset grid\nset logscale xy\n"
        "set xlabel 'seconds since the session started (culling included)'\n"
        "set ylabel 'RMSE / mean luminance of the prop region'\n";
  for (const auto& s : r["sizes"]) {
    const std::string size = std::to_string(s["width"].get<int>()) + "x" + std::to_string(s["height"].get<int>());
    const fs::path dat = d / ("render_" + size + ".dat");
    {
      std::ofstream out(dat);
      out << "# spp seconds rmse_rel rmse_rel_denoised\n";
      for (const auto& p : s["curve"])
        out << p["spp"] << " " << p["seconds"] << " " << p["rmse_rel"] << " " << p["rmse_rel_denoised"] << "\n";
    }
    gp << "set output '" << (d / ("render_" + size + ".png")).string() << "'\n"
       << "set title 'Differential render " << size << ": error vs time (labels: samples per pixel)'\n"
       << "plot '" << dat.string() << "' using 2:3 with linespoints pt 7 title 'session', "
       << "'' using 2:4 with linespoints pt 5 title 'session, denoised', "
       << "'' using 2:3:1 with labels offset 1,1 notitle, "
       << r["target_rmse_rel"].get<double>() << " with lines dt 2 title 'target'\n";
  }
  run_gnuplot(dir, "render_bench.gp", gp.str());
}

void add_bench_render_options(CLI::App& cmd, RenderBenchArgs& a) {
  cmd.add_option("--sizes", a.sizes, "Comma-separated WxH list");
  cmd.add_option("--seed", a.options.seed, "Synthetic room seed");
  cmd.add_option("--prop", a.options.prop, "Preset prop (see `propcam props`)");
  cmd.add_option("--reference-spp", a.options.reference_spp,
                 "Samples per pixel of the reference render (two independent halves)");
  cmd.add_option("--max-spp", a.options.max_spp, "The measured session stops here if it never reaches 1%");
  cmd.add_option("--threads", a.options.threads, "Render threads (0: all hardware threads)");
  cmd.add_option("--skip-size", a.skip_size, "Room size WxH for the skip comparison");
  cmd.add_option("--skip-spp", a.options.skip_spp, "Samples per pixel of the skip comparison (0: no skip comparison)")
      ->check(CLI::Range(0, 4096));
  cmd.add_option("--skip-reference-spp", a.options.skip_reference_spp,
                 "Samples per pixel of the skip comparison's reference")
      ->check(CLI::Range(1, 65536));
  cmd.add_option("--plot", a.options.plot_dir, "Write one PNG per size (gnuplot) to this folder");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_render_command(RenderBenchArgs a) {
  constexpr int kMinSkipSide = 16;
  a.options.sizes = parse_sizes(a.sizes);
  parse_bench_size(a.skip_size, kMinSkipSide, a.options.skip_size.width, a.options.skip_size.height, "--skip-size");
  a.options.quiet = a.json_out;
  return report_bench_result(run_render_bench(a.options),
                             a.json_out, a.options.plot_dir, plot_render_bench, format_render_bench);
}

}  // namespace propcam::firmware
