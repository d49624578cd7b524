#include "bench/bench_transfer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "common/bench_common.h"
#include "common/progress.h"
#include "propcam/inference/depth_transfer.h"
#include "propcam/render/depth_mesh.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

using nlohmann::json;

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / v.size();
}

// abs-rel and RMSE(log) over the pixels where both depths are finite surfaces.
void depth_errors(const cv::Mat& est, const cv::Mat& truth, double& abs_rel, double& rmse_log) {
  double sum_rel = 0, sum_log2 = 0;
  long n = 0;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      const float t = truth.at<float>(y, x), d = est.at<float>(y, x);
      if (!(t > 0) || t >= 0.5 * render::kSkyDepthM || !(d > 0) || !std::isfinite(d)) continue;
      sum_rel += std::abs(d - t) / t;
      const double l = std::log(d) - std::log(t);
      sum_log2 += l * l;
      ++n;
    }
  abs_rel = n ? sum_rel / n : 0;
  rmse_log = n ? std::sqrt(sum_log2 / n) : 0;
}

}  // namespace

json run_transfer_bench(const TransferBenchOptions& o) {
  Progress progress(o.quiet);
  const std::string path = o.database.empty() ? inference::default_depth_database_path() : o.database;
  const inference::DepthDatabase db = inference::DepthDatabase::load(path);
  size_t indoor = 0;
  for (size_t i = 0; i < db.size(); ++i) indoor += db.at(i).indoor;
  struct Config {
    int k;
    bool warp;
    std::vector<double> abs_rel, rmse_log, seconds;
  };
  std::vector<Config> configs;
  for (bool warp : {true, false})
    for (int k : o.ks) configs.push_back({k, warp, {}, {}, {}});
  render::RenderSettings settings;
  settings.samples_per_pixel = o.spp;
  json scenes = json::array();
  std::vector<double> oracle;
  for (int seed = 1; seed <= o.rooms; ++seed) {
    progress.stage("room " + std::to_string(seed) + " of " + std::to_string(o.rooms));
    render::SyntheticRoomSpec spec;
    spec.width = o.width;
    spec.height = o.height;
    spec.seed = static_cast<uint64_t>(seed);
    const SyntheticShot shot = shoot_synthetic_room(spec, settings);
    json row = {{"seed", seed}};
    for (Config& c : configs) {
      inference::DepthTransferOptions t;
      t.k = c.k;
      t.warp = c.warp;
      // The first query of a configuration also pays for cold caches; time the second.
      inference::TransferredDepth d;
      double seconds = 0;
      for (int rep = 0; rep < 2; ++rep) {
        const auto start = std::chrono::steady_clock::now();
        d = inference::transfer_depth(shot.photo_linear, shot.room.camera, shot.truth.camera_height_m, true, db,
                                      shot.truth.depth.size(), t);
        seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      }
      double abs_rel = 0, rmse_log = 0;
      depth_errors(d.median, shot.truth.depth, abs_rel, rmse_log);
      c.abs_rel.push_back(abs_rel);
      c.rmse_log.push_back(rmse_log);
      c.seconds.push_back(seconds);
      row[std::string(c.warp ? "warp" : "resize") + "_k" + std::to_string(c.k)] = {{"abs_rel", abs_rel},
                                                                                   {"rmse_log", rmse_log},
                                                                                   {"nearest", d.indices.front()}};
    }
    if (o.oracle) {
      // The best single example the database holds for this room (warped): what a
      // perfect descriptor would pick, i.e. how much of the error is the database's.
      double best = std::numeric_limits<double>::infinity();
      size_t best_index = 0;
      for (size_t i = 0; i < db.size(); ++i) {
        if (!db.at(i).indoor) continue;
        inference::DepthDatabase one;
        one.add(db.at(i));
        const inference::TransferredDepth d = inference::transfer_depth(
            shot.photo_linear, shot.room.camera, shot.truth.camera_height_m, true, one, shot.truth.depth.size(), {1, true, true});
        double abs_rel = 0, rmse_log = 0;
        depth_errors(d.median, shot.truth.depth, abs_rel, rmse_log);
        if (abs_rel < best) best = abs_rel, best_index = i;
      }
      oracle.push_back(best);
      row["oracle"] = {{"abs_rel", best}, {"example", best_index}};
    }
    scenes.push_back(row);
  }
  json rows = json::array();
  for (const Config& c : configs)
    rows.push_back({{"k", c.k},
                    {"warp", c.warp},
                    {"abs_rel_median", median(c.abs_rel)},
                    {"abs_rel_mean", mean(c.abs_rel)},
                    {"rmse_log_median", median(c.rmse_log)},
                    {"rmse_log_mean", mean(c.rmse_log)},
                    {"seconds_median", median(c.seconds)},
                    {"seconds_max", *std::max_element(c.seconds.begin(), c.seconds.end())}});
  return {{"database", path},
          {"database_size", db.size()},
          {"database_indoor", indoor},
          {"rooms", o.rooms},
          {"size", std::to_string(o.width) + "x" + std::to_string(o.height)},
          {"spp", o.spp},
          {"rows", rows},
          {"oracle_abs_rel_median", median(oracle)},
          {"oracle_abs_rel_mean", mean(oracle)},
          {"scenes", scenes}};
}

std::string format_transfer_bench(const json& r) {
  std::ostringstream out;
  out << "depth transfer alone, true camera: rooms 1.." << r["rooms"].get<int>() << " at " << r["size"].get<std::string>()
      << ", database " << r["database"].get<std::string>() << " (" << r["database_size"].get<size_t>() << " examples, "
      << r["database_indoor"].get<size_t>() << " indoor)\n";
  char line[256];
  std::snprintf(line, sizeof line, "%-7s %4s %15s %15s %12s %12s\n", "warp", "k", "abs-rel med", "abs-rel mean",
                "rmse-log med", "ms/query med");
  out << line;
  for (const json& row : r["rows"]) {
    std::snprintf(line, sizeof line, "%-7s %4d %15.3f %15.3f %12.3f %12.1f\n", row["warp"].get<bool>() ? "warp" : "resize",
                  row["k"].get<int>(), row["abs_rel_median"].get<double>(), row["abs_rel_mean"].get<double>(),
                  row["rmse_log_median"].get<double>(), 1e3 * row["seconds_median"].get<double>());
    out << line;
  }
  if (r["oracle_abs_rel_median"].get<double>() > 0)
    out << "oracle (the best single example, warped): abs-rel median " << r["oracle_abs_rel_median"].get<double>()
        << ", mean " << r["oracle_abs_rel_mean"].get<double>() << "\n";
  return out.str();
}

void add_bench_transfer_options(CLI::App& cmd, TransferBenchArgs& a) {
  cmd.add_option("--rooms", a.options.rooms, "Synthetic rooms (seeds 1..N)")->check(CLI::PositiveNumber);
  cmd.add_option("--size", a.size, "Photo size WxH");
  cmd.add_option("--spp", a.options.spp, "Samples per pixel of the photos")->check(CLI::PositiveNumber);
  cmd.add_option("--k", a.ks, "Comma-separated candidate counts");
  cmd.add_option("--db", a.options.database, "Database file (default: PROPCAM_DEPTH_DB or the committed one)");
  cmd.add_flag("--oracle,!--no-oracle", a.options.oracle,
                "Also find the best single example per room (every indoor example warped and scored)");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_transfer_command(TransferBenchArgs a) {
  char x = 0;
  std::istringstream size(a.size);
  if (!(size >> a.options.width >> x >> a.options.height) || x != 'x' || a.options.width < 16 || a.options.height < 16)
    throw std::invalid_argument("--size expects WxH of at least 16x16");
  a.options.ks.clear();
  std::istringstream ks(a.ks);
  for (std::string s; std::getline(ks, s, ',');)
    if (!s.empty()) {
      const int k = std::stoi(s);
      if (k < 1) throw std::invalid_argument("--k: candidate counts are positive");
      a.options.ks.push_back(k);
    }
  if (a.options.ks.empty()) throw std::invalid_argument("--k: at least one candidate count");
  a.options.quiet = a.json_out;
  return report_bench_result(run_transfer_bench(a.options), a.json_out, "", nullptr, format_transfer_bench);
}

}  // namespace propcam::firmware
