#include "bench/bench_geometry.h"

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <numbers>
#include <sstream>

#include "common/bench_common.h"
#include "common/progress.h"
#include "propcam/inference/infer.h"
#include "propcam/render/depth_mesh.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using nlohmann::json;

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

struct Shot {
  std::string name;
  cv::Mat photo;
  inference::SceneModel truth;
};

struct Config {
  std::string sweep;   // which knob this row varies
  std::string label;   // the knob's value
  double value = 0;    // numeric value for plots
  std::function<void(inference::InferenceOptions&)> apply;
  bool calibrated = false;  // the lens's true focal length given as a calibrated board would
};

struct Errors {
  double focal_rel = 0, vp_deg = 0, pitch_deg = 0, roll_deg = 0;
  double abs_rel = 0, rmse_log = 0, normal_deg = 0, sky_disagreement = 0;
  double seconds = 0;
};

// Up in camera coordinates gives pitch (towards the optical axis) and roll.
void pitch_roll(const Matrix3d& R_world_from_cam, double& pitch, double& roll) {
  const Vector3d up = R_world_from_cam.transpose() * Vector3d::UnitY();  // camera y points down
  pitch = std::asin(std::clamp(up.z(), -1.0, 1.0)) * kRadToDeg;
  roll = std::atan2(up.x(), -up.y()) * kRadToDeg;
}

// Largest angle between a true Manhattan axis and the nearest estimated one
// (axes are lines: sign and labelling do not matter), in camera coordinates.
double vanishing_direction_error_deg(const Matrix3d& R_est, const Matrix3d& R_true) {
  double worst = 0;
  for (int a = 0; a < 3; ++a) {
    const Vector3d t = R_true.row(a).transpose();  // world axis a in camera coordinates
    double best = 90;
    for (int b = 0; b < 3; ++b) {
      const Vector3d e = R_est.row(b).transpose();
      best = std::min(best, std::acos(std::clamp(std::abs(t.dot(e)), 0.0, 1.0)) * kRadToDeg);
    }
    worst = std::max(worst, best);
  }
  return worst;
}

bool is_sky(float d) { return !(d > 0) || d >= 0.5 * render::kSkyDepthM; }

void depth_errors(const inference::SceneModel& est, const inference::SceneModel& truth, Errors& e) {
  double sum_rel = 0, sum_log2 = 0;
  int n = 0, disagree = 0, total = 0;
  std::vector<double> normal_err;
  for (int y = 0; y < truth.height; ++y)
    for (int x = 0; x < truth.width; ++x) {
      const float t = truth.depth.at<float>(y, x), d = est.depth.at<float>(y, x);
      ++total;
      if (is_sky(t) != is_sky(d)) ++disagree;
      if (is_sky(t) || is_sky(d)) continue;
      sum_rel += std::abs(d - t) / t;
      const double l = std::log(d) - std::log(t);
      sum_log2 += l * l;
      ++n;
      const cv::Vec3f ne = est.normals.at<cv::Vec3f>(y, x), nt = truth.normals.at<cv::Vec3f>(y, x);
      const Vector3d ce = est.R_world_from_cam.transpose() * Vector3d(ne[0], ne[1], ne[2]);
      const Vector3d ct = truth.R_world_from_cam.transpose() * Vector3d(nt[0], nt[1], nt[2]);
      if ((y + x) % 3 == 0) normal_err.push_back(std::acos(std::clamp(ce.dot(ct), -1.0, 1.0)) * kRadToDeg);
    }
  e.abs_rel = n ? sum_rel / n : 0;
  e.rmse_log = n ? std::sqrt(sum_log2 / n) : 0;
  e.sky_disagreement = total ? static_cast<double>(disagree) / total : 0;
  if (!normal_err.empty()) {
    std::nth_element(normal_err.begin(), normal_err.begin() + normal_err.size() / 2, normal_err.end());
    e.normal_deg = normal_err[normal_err.size() / 2];
  }
}

Errors measure(const Shot& shot, const inference::InferenceOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const inference::GeometryEstimate g = inference::infer_geometry(shot.photo, options);
  Errors e;
  e.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const inference::SceneModel& t = shot.truth;
  e.focal_rel = std::abs(g.camera.fx - t.fx) / t.fx;
  e.vp_deg = vanishing_direction_error_deg(g.camera.R_world_from_cam, t.R_world_from_cam);
  double pe, re, pt, rt;
  pitch_roll(g.camera.R_world_from_cam, pe, re);
  pitch_roll(t.R_world_from_cam, pt, rt);
  e.pitch_deg = std::abs(pe - pt);
  e.roll_deg = std::abs(re - rt);
  inference::SceneModel est;
  est.width = t.width;
  est.height = t.height;
  est.depth = g.depth;
  est.normals = g.normals;
  est.R_world_from_cam = g.camera.R_world_from_cam;
  depth_errors(est, t, e);
  return e;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

std::vector<Config> make_configs(const std::vector<std::string>& wanted) {
  auto want = [&](const char* s) { return wanted.empty() || std::find(wanted.begin(), wanted.end(), s) != wanted.end(); };
  std::vector<Config> c;
  c.push_back({"default", "default", 0, [](inference::InferenceOptions&) {}});
  if (want("camera"))
    for (int it : {50, 100, 300, 600})
      c.push_back({"camera", std::to_string(it) + " line pairs", static_cast<double>(it),
                   [it](inference::InferenceOptions& o) { o.camera.ransac_iterations = it; }});
  if (want("camera")) {
    Config calibrated{"camera", "calibrated focal", 0, [](inference::InferenceOptions&) {}};
    calibrated.calibrated = true;
    c.push_back(calibrated);
  }
  if (want("resolution")) {
    c.push_back({"resolution", "box only", 0, [](inference::InferenceOptions& o) { o.geometry.solve = false; }});
    for (int w : {40, 60, 80, 120, 160})
      c.push_back({"resolution", std::to_string(w) + " px", static_cast<double>(w),
                   [w](inference::InferenceOptions& o) { o.geometry.solver.width = w; }});
  }
  if (want("iterations"))
    for (int it : {0, 5, 10, 20, 40, 80})
      c.push_back({"iterations", std::to_string(it) + " iterations", static_cast<double>(it), [it](inference::InferenceOptions& o) {
                     o.geometry.solver.max_iterations = it;
                     o.geometry.solver.max_seconds = 10.0;
                   }});
  if (want("transfer")) {
    // Depth transfer as the only data term: candidates and the warp.
    for (int k : {1, 3, 7, 15})
      c.push_back({"transfer", "k=" + std::to_string(k) + " alone", static_cast<double>(k), [k](inference::InferenceOptions& o) {
                     o.geometry.box_weight = o.geometry.contact_weight = 0;
                     o.geometry.transfer.k = k;
                   }});
    c.push_back({"transfer", "k=7 alone, no warp", 0, [](inference::InferenceOptions& o) {
                   o.geometry.box_weight = o.geometry.contact_weight = 0;
                   o.geometry.transfer.warp = false;
                 }});
  }
  if (want("priors")) {
    c.push_back({"priors", "no Manhattan", 1, [](inference::InferenceOptions& o) { o.geometry.solver.use_manhattan = false; }});
    c.push_back({"priors", "no orientation map", 2, [](inference::InferenceOptions& o) { o.geometry.solver.use_orientation = false; }});
    c.push_back({"priors", "no 3D smoothness", 3, [](inference::InferenceOptions& o) { o.geometry.solver.use_smoothness = false; }});
    c.push_back({"priors", "no floor contacts", 5, [](inference::InferenceOptions& o) { o.geometry.contact_weight = 0; }});
    c.push_back({"priors", "no depth transfer", 7, [](inference::InferenceOptions& o) { o.geometry.transfer_weight = 0; }});
    c.push_back({"priors", "transfer only", 8, [](inference::InferenceOptions& o) {
                   o.geometry.box_weight = o.geometry.contact_weight = 0;
                 }});
    c.push_back({"priors", "no box", 6, [](inference::InferenceOptions& o) { o.geometry.box_weight = 0; }});
    c.push_back({"priors", "data term only", 4, [](inference::InferenceOptions& o) {
                   o.geometry.solver.use_manhattan = o.geometry.solver.use_orientation = o.geometry.solver.use_smoothness = false;
                 }});
  }
  return c;
}

json errors_json(const std::vector<Errors>& per_scene) {
  auto col = [&](double Errors::*m) {
    std::vector<double> v;
    for (const auto& e : per_scene) v.push_back(e.*m);
    return v;
  };
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0.0 : s / v.size();
  };
  return {{"focal_rel_median", median(col(&Errors::focal_rel))},
          {"vp_deg_median", median(col(&Errors::vp_deg))},
          {"pitch_deg_median", median(col(&Errors::pitch_deg))},
          {"roll_deg_median", median(col(&Errors::roll_deg))},
          {"abs_rel_median", median(col(&Errors::abs_rel))},
          {"abs_rel_mean", mean(col(&Errors::abs_rel))},
          {"rmse_log_median", median(col(&Errors::rmse_log))},
          {"normal_deg_median", median(col(&Errors::normal_deg))},
          {"sky_disagreement_mean", mean(col(&Errors::sky_disagreement))},
          {"seconds_mean", mean(col(&Errors::seconds))}};
}

}  // namespace

json run_geometry_bench(const GeometryBenchOptions& o) {
  Progress progress(o.quiet);
  std::vector<Shot> shots;
  render::RenderSettings settings;
  settings.samples_per_pixel = o.spp;
  // Seeds 1..count of one generator (room or street spec, and its shoot function).
  const auto render_scenes = [&](const std::string& kind, int count, auto spec, auto shoot) {
    spec.width = o.width;
    spec.height = o.height;
    for (int seed = 1; seed <= count; ++seed) {
      progress.stage("rendering " + kind + " " + std::to_string(seed));
      spec.seed = static_cast<uint64_t>(seed);
      SyntheticShot s = shoot(spec, settings);
      shots.push_back({kind + " " + std::to_string(seed), s.photo_linear, s.truth});
    }
  };
  render_scenes("room", o.rooms, render::SyntheticRoomSpec{}, shoot_synthetic_room);
  render_scenes("street", o.streets, render::SyntheticStreetSpec{}, shoot_synthetic_street);
  if (shots.empty()) throw std::invalid_argument("bench geometry: no scenes (--rooms and --streets are 0)");

  json rows = json::array();
  for (const Config& c : make_configs(o.sweeps)) {
    progress.stage(c.sweep + ": " + c.label);
    inference::InferenceOptions options;
    c.apply(options);
    std::vector<Errors> all, rooms, streets;
    json scenes = json::array();
    for (const Shot& s : shots) {
      inference::InferenceOptions scene_options = options;
      if (c.calibrated) {
        scene_options.camera.prior_focal_px = s.truth.fx;
        scene_options.camera.fixed_focal = true;
      }
      const Errors e = measure(s, scene_options);
      all.push_back(e);
      (s.truth.indoor ? rooms : streets).push_back(e);
      scenes.push_back({{"scene", s.name}, {"abs_rel", e.abs_rel}, {"normal_deg", e.normal_deg}, {"focal_rel", e.focal_rel},
                        {"vp_deg", e.vp_deg}, {"seconds", e.seconds}});
    }
    json row = {{"sweep", c.sweep}, {"label", c.label}, {"value", c.value}, {"scenes", scenes}};
    row["all"] = errors_json(all);
    if (!rooms.empty()) row["rooms"] = errors_json(rooms);
    if (!streets.empty()) row["streets"] = errors_json(streets);
    rows.push_back(row);
  }
  json result = {{"size", {o.width, o.height}}, {"spp", o.spp}, {"rows", rows}};
  if (o.timing_width > 0) {
    // The target is stated at 1024x768: time the default pipeline there.
    render::SyntheticRoomSpec spec;
    spec.width = o.timing_width;
    spec.height = o.timing_width * 3 / 4;
    spec.seed = 1;
    progress.stage("timing at " + std::to_string(spec.width) + "x" + std::to_string(spec.height));
    const SyntheticShot s = shoot_synthetic_room(spec, settings);
    const inference::GeometryEstimate g = inference::infer_geometry(s.photo_linear, {});
    json stages = json::object();
    double total = 0;
    for (const auto& r : g.reports) {
      stages[r.stage] = r.seconds;
      total += r.seconds;
    }
    result["timing"] = {{"size", {spec.width, spec.height}}, {"stages", stages}, {"seconds", total}};
  }
  return result;
}

std::string format_geometry_bench(const json& r) {
  std::ostringstream out;
  char line[512];
  std::snprintf(line, sizeof line, "Geometry on generator scenes (%dx%d): medians over scenes, time = mean per scene\n",
                r["size"][0].get<int>(), r["size"][1].get<int>());
  out << line;
  for (const char* group : {"rooms", "streets"}) {
    if (!r["rows"][0].contains(group)) continue;
    out << "\n" << group << ":\n";
    std::snprintf(line, sizeof line, "%-11s %-22s %8s %7s %6s %6s %8s %8s %8s %7s %8s\n", "sweep", "knob", "focal", "VP",
                  "pitch", "roll", "abs-rel", "rmse-log", "normal", "sky", "seconds");
    out << line;
    for (const auto& row : r["rows"]) {
      const json& a = row[group];
      std::snprintf(line, sizeof line, "%-11s %-22s %7.1f%% %6.2f° %5.2f° %5.2f° %8.3f %8.3f %7.1f° %6.1f%% %8.3f\n",
                    row["sweep"].get<std::string>().c_str(), row["label"].get<std::string>().c_str(),
                    100 * a["focal_rel_median"].get<double>(), a["vp_deg_median"].get<double>(),
                    a["pitch_deg_median"].get<double>(), a["roll_deg_median"].get<double>(),
                    a["abs_rel_median"].get<double>(), a["rmse_log_median"].get<double>(),
                    a["normal_deg_median"].get<double>(), 100 * a["sky_disagreement_mean"].get<double>(),
                    a["seconds_mean"].get<double>());
      out << line;
    }
  }
  if (r.contains("timing")) {
    const json& t = r["timing"];
    std::snprintf(line, sizeof line, "\nDefault pipeline at %dx%d: %.3f s (", t["size"][0].get<int>(), t["size"][1].get<int>(),
                  t["seconds"].get<double>());
    out << line;
    bool first = true;
    for (auto it = t["stages"].begin(); it != t["stages"].end(); ++it) {
      std::snprintf(line, sizeof line, "%s%s %.3f", first ? "" : ", ", it.key().c_str(), it.value().get<double>());
      out << line;
      first = false;
    }
    out << ")\n";
  }
  return out.str();
}

void plot_geometry_bench(const json& r, const std::string& dir) {
  // One plot per scene class: rooms and streets do not share a scale.
  for (const char* group : {"rooms", "streets"}) {
    if (!r["rows"][0].contains(group)) continue;
    std::ostringstream dat;
    std::string last;
    for (const auto& row : r["rows"]) {
      const std::string sweep = row["sweep"];
      if (sweep == "default") continue;
      if (sweep != last) dat << (last.empty() ? "" : "\n\n") << "\"" << sweep << "\" seconds abs_rel normal_deg label\n";
      last = sweep;
      const json& a = row[group];
      std::string label = row["label"];
      std::replace(label.begin(), label.end(), ' ', '_');
      dat << row["value"].get<double>() << " " << a["seconds_mean"].get<double>() << " " << a["abs_rel_median"].get<double>()
          << " " << a["normal_deg_median"].get<double>() << " \"" << label << "\"\n";
    }
    const std::string name = std::string("geometry_") + group;
    std::ostringstream gp;
    gp << "$data << EOD\n" << dat.str() << "\nEOD\n"
       << "set terminal png size 1100,480 noenhanced\nset grid\nset key top right\nset output '"
       << (std::filesystem::path(dir) / (name + ".png")).string() << "'\n"
       << "set multiplot layout 1,2 title 'Geometry on generator " << group
       << ": error against seconds per scene (labels: the knob)'\n"
          "set xlabel 'seconds per scene'\nset ylabel 'depth abs-rel (median)'\n"
          "plot for [i=0:*] $data index i using 2:3 with linespoints pt 7 title columnhead(1), "
          "$data using 2:3:5 with labels offset 0,1 font ',7' notitle\n"
          "set ylabel 'surface-normal error (median, deg)'\n"
          "plot for [i=0:*] $data index i using 2:4 with linespoints pt 7 title columnhead(1), "
          "$data using 2:4:5 with labels offset 0,1 font ',7' notitle\n"
          "unset multiplot\n";
    run_gnuplot(dir, name + ".gp", gp.str());
  }
}

void add_bench_geometry_options(CLI::App& cmd, GeometryBenchArgs& a) {
  cmd.add_option("--rooms", a.options.rooms, "Synthetic rooms (seeds 1..N)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--streets", a.options.streets, "Synthetic streets (seeds 1..N)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--size", a.size, "Photo size WxH");
  cmd.add_option("--spp", a.options.spp, "Samples per pixel of the photos")->check(CLI::PositiveNumber);
  cmd.add_option("--timing-width", a.options.timing_width, "Also time the default pipeline at this width, 4:3 (0: skip)")
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--sweeps", a.sweeps, "Comma-separated subset of default,camera,resolution,iterations,transfer,priors (default: all; the default row always runs)");
  cmd.add_option("--plot", a.options.plot_dir, "Write PNG plots (gnuplot) to this folder");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_geometry_command(GeometryBenchArgs a) {
  parse_bench_size(a.size, 16, a.options.width, a.options.height);
  a.options.sweeps = parse_sweeps(a.sweeps, {"default", "camera", "resolution", "iterations", "transfer", "priors"});
  a.options.quiet = a.json_out;
  return report_bench_result(run_geometry_bench(a.options),
                             a.json_out, a.options.plot_dir, plot_geometry_bench, format_geometry_bench);
}

}  // namespace propcam::firmware
