#include "bench/bench.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <thread>

#include "common/bench_common.h"
#include "common/compositor.h"
#include "common/progress.h"
#include "propcam/inference/albedo.h"
#include "propcam/inference/infer.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

double up_error_deg(const Eigen::Matrix3d& R_est, const Eigen::Matrix3d& R_true) {
  // Angle between the estimated and true up vectors, both in camera coordinates.
  const Eigen::Vector3d up_est = R_est.transpose() * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d up_true = R_true.transpose() * Eigen::Vector3d::UnitY();
  return std::acos(std::clamp(up_est.dot(up_true), -1.0, 1.0)) * kRadToDeg;
}

double depth_abs_rel(const cv::Mat& est, const cv::Mat& truth) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      const float t = truth.at<float>(y, x);
      if (!(t > 0)) continue;
      sum += std::abs(est.at<float>(y, x) - t) / t;
      ++n;
    }
  return n ? sum / n : 0.0;
}

// Relative RMS error after the best global scale (albedo is known up to scale).
double scale_invariant_rel_rmse(const cv::Mat& est, const cv::Mat& truth) {
  const double dot = est.dot(truth), norm2 = est.dot(est);
  const double alpha = norm2 > 0 ? dot / norm2 : 0.0;
  cv::Mat diff = est * alpha - truth;
  return std::sqrt(diff.dot(diff) / std::max(truth.dot(truth), 1e-12));
}

json stage_entry(const inference::StageReport& r, const char* error_name, double error) {
  json j = {{"stage", r.stage}, {"seconds", r.seconds}, {"why", r.why}, {"iterations", r.iterations}};
  if (error_name) j["error"] = {{"name", error_name}, {"value", error}};
  return j;
}

}  // namespace

json measure_render_skips(const cv::Mat& photo, const inference::SceneModel& truth, const render::Mesh& prop,
                          const render::PropPlacement& placement, const cv::Mat& reference, int spp) {
  CompositeOptions simulate_everything;
  simulate_everything.cull_tiles = false;
  simulate_everything.plan.allow_skips = false;
  const cv::Mat everywhere(photo.size(), CV_8U, cv::Scalar(255));
  render::RenderSettings s;
  s.samples_per_pixel = spp;
  const CompositeResult full = composite_prop(photo, truth, prop, placement, s, simulate_everything);
  const double noise = rmse_in_mask(full.composite_linear, reference, everywhere);
  json skips = json::array();
  auto measure = [&](const std::string& name, const CompositeOptions& o, const render::RenderSettings& rs) {
    const CompositeResult r = composite_prop(photo, truth, prop, placement, rs, o);
    const double err = rmse_in_mask(r.composite_linear, reference, everywhere);
    int culled = 0;
    for (const auto& t : r.tiles) culled += !t.affected;
    json decisions = json::array();
    for (const auto& d : r.plan.decisions)
      if (!d.simulated) decisions.push_back(d.effect + ": " + d.why);
    skips.push_back({{"skip", name}, {"spp", spp}, {"seconds_full", full.render.stats.seconds},
                     {"seconds_with_skip", r.render.stats.seconds}, {"tiles_skipped", culled},
                     {"tiles", r.tiles.size()}, {"rmse_full", noise}, {"rmse_with_skip", err},
                     {"error_added", err - noise}, {"skipped", decisions}});
  };
  CompositeOptions only_cull = simulate_everything;
  only_cull.cull_tiles = true;
  measure("tiles the prop cannot reach", only_cull, s);
  render::RenderSettings no_caustics = s;
  no_caustics.caustics = false;
  measure("caustics", simulate_everything, no_caustics);
  render::RenderSettings no_bounce = s;
  no_bounce.prop_interreflection = false;
  measure("prop interreflection", simulate_everything, no_bounce);
  CompositeOptions prune = simulate_everything;
  prune.plan.allow_skips = true;
  prune.plan.skip_caustics = false;
  prune.plan.skip_interreflection = false;
  measure("weak lights pruned", prune, s);
  measure("the plan (all it decides)", CompositeOptions{}, s);
  return skips;
}

std::string format_render_skips(const json& skips) {
  std::ostringstream out;
  char line[256];
  out << "\nRender skips at equal samples (RMSE over the whole image vs the reference)\n"
         "  skip                          spp  s_full  s_skip  tiles_skipped  rmse_full  rmse_skip\n";
  for (const auto& s : skips) {
    std::snprintf(line, sizeof line, "  %-28s %4d  %6.3f  %6.3f  %6d/%-6d  %9.5f  %9.5f\n",
                  s["skip"].get<std::string>().c_str(), s["spp"].get<int>(), s["seconds_full"].get<double>(),
                  s["seconds_with_skip"].get<double>(), s["tiles_skipped"].get<int>(), s["tiles"].get<int>(),
                  s["rmse_full"].get<double>(), s["rmse_with_skip"].get<double>());
    out << line;
  }
  return out.str();
}

json run_bench(const BenchOptions& options) {
  Progress progress(options.quiet);
  json result;
  result["machine"] = {{"hardware_threads", std::thread::hardware_concurrency()}};

  // A synthetic room gives exact ground truth for every stage.
  progress.stage("bench: rendering synthetic room");
  render::SyntheticRoomSpec spec;
  spec.width = options.width;
  spec.height = options.height;
  spec.seed = options.seed;
  render::RenderSettings photo_settings;
  photo_settings.samples_per_pixel = 64;
  const SyntheticShot shot = shoot_synthetic_room(spec, photo_settings);
  const inference::SceneModel& truth = shot.truth;
  result["synthetic"] = {{"size", {spec.width, spec.height}}, {"seed", spec.seed},
                         {"photo_spp", photo_settings.samples_per_pixel}, {"photo_seconds", shot.photo_stats.seconds}};

  progress.stage("bench: inference");
  const auto infer_start = std::chrono::steady_clock::now();
  const inference::SceneModel est = inference::infer_scene(shot.photo_linear);
  const double infer_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - infer_start).count();
  json stages = json::array();
  for (const auto& r : est.reports) {
    if (r.stage == "camera") {
      stages.push_back(stage_entry(r, "focal_rel_error", std::abs(est.fx - truth.fx) / truth.fx));
      stages.back()["up_error_deg"] = up_error_deg(est.R_world_from_cam, truth.R_world_from_cam);
    } else if (r.stage == "geometry") {
      stages.push_back(stage_entry(r, "depth_abs_rel", depth_abs_rel(est.depth, truth.depth)));
    } else if (r.stage == "albedo") {
      stages.push_back(stage_entry(r, "albedo_lmse", inference::local_mse(est.albedo, truth.albedo)));
      stages.back()["albedo_si_rel_rmse"] = scale_invariant_rel_rmse(est.albedo, truth.albedo);
      // Each albedo method on the same photo: what accuracy costs.
      json methods = json::array();
      for (const auto method : {inference::AlbedoOptions::Method::BlurredShading, inference::AlbedoOptions::Method::Retinex}) {
        inference::AlbedoOptions o;
        o.method = method;
        inference::StageReport method_report;
        const cv::Mat a = inference::estimate_albedo(shot.photo_linear, o, method_report);
        methods.push_back({{"method", method_report.why},
                           {"albedo_lmse", inference::local_mse(a, truth.albedo)},
                           {"albedo_si_rel_rmse", scale_invariant_rel_rmse(a, truth.albedo)},
                           {"seconds", method_report.seconds}});
      }
      stages.back()["methods"] = methods;
    } else if (r.stage == "light_intensities") {
      stages.push_back(stage_entry(r, "rerender_rel_rms", r.error));
    } else {
      stages.push_back(stage_entry(r, nullptr, 0));
    }
  }
  result["stages"] = stages;
  result["inference_seconds"] = infer_seconds;

  // Camera knob: line-pair samples (vanishing-point candidates).
  progress.stage("bench: camera sweep");
  inference::StageReport lines_report;
  const auto lines = inference::detect_lines(shot.photo_linear, {}, lines_report);
  json camera_sweep = json::array();
  for (int iterations : {25, 50, 100, 200, 400, 800}) {
    inference::CameraOptions co;
    co.ransac_iterations = iterations;
    const auto cam = inference::estimate_camera(lines, spec.width, spec.height, co);
    camera_sweep.push_back({{"ransac_iterations", iterations}, {"seconds", cam.report.seconds},
                            {"focal_rel_error", std::abs(cam.fx - truth.fx) / truth.fx},
                            {"up_error_deg", up_error_deg(cam.R_world_from_cam, truth.R_world_from_cam)},
                            {"case", cam.report.why}});
  }
  result["sweeps"]["camera_ransac"] = camera_sweep;

  // Renderer knob: samples per pixel, against a high-spp reference of the
  // same composite (ground-truth scene model, so only rendering error counts).
  progress.stage("bench: render reference at " + std::to_string(options.reference_spp) + " spp");
  const render::Mesh prop = load_prop("sphere_plinth");
  const Eigen::Vector2d at = free_floor_pixel(shot.room);
  const render::PropPlacement placement{at.x(), at.y(), 0.5, 0.0};
  render::RenderSettings ref_settings;
  ref_settings.samples_per_pixel = options.reference_spp;
  ref_settings.seed = 999;
  CompositeOptions simulate_everything;
  simulate_everything.cull_tiles = false;
  simulate_everything.plan.allow_skips = false;
  const CompositeResult reference =
      composite_prop(shot.photo_linear, truth, prop, placement, ref_settings, simulate_everything);
  const cv::Mat affected = changed_pixels(reference.composite_linear, shot.photo_linear);
  json spp_sweep = json::array();
  for (int spp = 1; spp <= options.max_spp; spp *= 2) {
    progress.stage("bench: render " + std::to_string(spp) + " spp");
    render::RenderSettings s;
    s.samples_per_pixel = spp;
    const CompositeResult r = composite_prop(shot.photo_linear, truth, prop, placement, s);
    const auto& st = r.render.stats;
    spp_sweep.push_back({{"spp", spp}, {"seconds", st.seconds},
                         {"rmse_affected", rmse_in_mask(r.composite_linear, reference.composite_linear, affected)},
                         {"mrays", st.rays / 1e6},
                         {"untouched_fraction", st.camera_samples ? double(st.paths_prop_untouched) / st.camera_samples : 0.0}});
  }
  result["sweeps"]["render_spp"] = spp_sweep;

  progress.stage("bench: render skips at " + std::to_string(options.skip_spp) + " spp");
  result["skips"] = measure_render_skips(shot.photo_linear, truth, prop, placement, reference.composite_linear,
                                         options.skip_spp);
  result["render_reference"] = {{"spp", options.reference_spp}, {"seconds", reference.render.stats.seconds},
                                {"affected_pixels", cv::countNonZero(affected)}};
  return result;
}

std::string format_bench(const json& r) {
  std::ostringstream out;
  char line[256];
  out << "Synthetic room " << r["synthetic"]["size"][0] << "x" << r["synthetic"]["size"][1] << " (seed "
      << r["synthetic"]["seed"] << ")\n\nStage               seconds   error\n";
  for (const auto& s : r["stages"]) {
    std::string err = "-";
    if (s.contains("error")) {
      std::snprintf(line, sizeof line, "%s = %.4f", s["error"]["name"].get<std::string>().c_str(),
                    s["error"]["value"].get<double>());
      err = line;
    }
    if (s.contains("up_error_deg")) err += ", up " + std::to_string(s["up_error_deg"].get<double>()).substr(0, 5) + " deg";
    std::snprintf(line, sizeof line, "%-18s %8.3f   %s\n", s["stage"].get<std::string>().c_str(),
                  s["seconds"].get<double>(), err.c_str());
    out << line;
  }
  std::snprintf(line, sizeof line, "%-18s %8.3f\n\n", "inference total", r["inference_seconds"].get<double>());
  out << line << "Camera: line-pair samples (RANSAC iterations)\n  iterations  seconds  focal_err  up_err_deg\n";
  for (const auto& s : r["sweeps"]["camera_ransac"]) {
    std::snprintf(line, sizeof line, "  %10d  %7.3f  %9.4f  %10.3f\n", s["ransac_iterations"].get<int>(),
                  s["seconds"].get<double>(), s["focal_rel_error"].get<double>(), s["up_error_deg"].get<double>());
    out << line;
  }
  out << "\nRender: samples per pixel vs " << r["render_reference"]["spp"] << "-spp reference (RMSE over "
      << r["render_reference"]["affected_pixels"] << " affected pixels)\n  spp   seconds   rmse      Mrays  untouched\n";
  for (const auto& s : r["sweeps"]["render_spp"]) {
    std::snprintf(line, sizeof line, "  %4d  %7.3f  %8.5f  %6.2f  %5.1f%%\n", s["spp"].get<int>(), s["seconds"].get<double>(),
                  s["rmse_affected"].get<double>(), s["mrays"].get<double>(), 100.0 * s["untouched_fraction"].get<double>());
    out << line;
  }
  out << format_render_skips(r["skips"]);
  return out.str();
}

void plot_bench(const json& r, const std::string& dir) {
  fs::create_directories(dir);
  const fs::path d(dir);
  {
    std::ofstream dat(d / "render_spp.dat");
    dat << "# spp seconds rmse\n";
    for (const auto& s : r["sweeps"]["render_spp"])
      dat << s["spp"] << " " << s["seconds"] << " " << s["rmse_affected"] << "\n";
    std::ofstream cam(d / "camera_ransac.dat");
    cam << "# iterations seconds focal_rel_error up_error_deg\n";
    for (const auto& s : r["sweeps"]["camera_ransac"])
      cam << s["ransac_iterations"] << " " << s["seconds"] << " " << s["focal_rel_error"] << " " << s["up_error_deg"] << "\n";
  }
  std::ostringstream gp;
  gp << "set terminal png size 800,560\n"
        "set grid\nset logscale xy\n"
        "set output '" << (d / "render_spp.png").string() << "'\n"
        "set title 'Differential render: error vs time (labels: samples per pixel)'\n"
        "set xlabel 'render seconds'\nset ylabel 'RMSE vs reference (linear, affected pixels)'\n"
        "plot '" << (d / "render_spp.dat").string() << "' using 2:3 with linespoints pt 7 title 'composite', "
        "'' using 2:3:1 with labels offset 1,1 notitle\n"
        "unset logscale y\nset logscale x\n"
        "set output '" << (d / "camera_ransac.png").string() << "'\n"
        "set title 'Camera stage: focal error vs time (labels: line-pair samples)'\n"
        "set xlabel 'camera stage seconds'\nset ylabel 'relative focal error'\n"
        "plot '" << (d / "camera_ransac.dat").string() << "' using 2:3 with linespoints pt 7 title 'focal', "
        "'' using 2:3:1 with labels offset 1,1 notitle\n";
  run_gnuplot(dir, "plots.gp", gp.str());
}

void add_bench_options(CLI::App& cmd, BenchArgs& a) {
  cmd.add_option("--size", a.size, "Synthetic photo size WxH");
  cmd.add_option("--seed", a.options.seed, "Synthetic room seed");
  cmd.add_option("--max-spp", a.options.max_spp, "Largest samples per pixel in the sweep");
  cmd.add_option("--reference-spp", a.options.reference_spp, "Samples per pixel of the reference render");
  cmd.add_option("--plot", a.options.plot_dir, "Write PNG plots (gnuplot) to this folder");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_command(BenchArgs a) {
  constexpr int kMinBenchSide = 32;
  parse_bench_size(a.size, kMinBenchSide, a.options.width, a.options.height);
  a.options.quiet = a.json_out;
  return report_bench_result(run_bench(a.options), a.json_out, a.options.plot_dir, plot_bench, format_bench);
}

}  // namespace propcam::firmware
