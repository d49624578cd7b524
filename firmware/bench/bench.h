// `propcam bench`: every stage's time, its error against ground truth where a
// synthetic room provides it, and the renderer's error-versus-time curve.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>

#include "propcam/inference/scene_model.h"
#include "propcam/render/mesh.h"
#include "propcam/render/placement.h"

namespace propcam::firmware {

struct BenchOptions {
  int width = 320;
  int height = 240;
  uint64_t seed = 4;
  int reference_spp = 256;
  int max_spp = 64;
  int skip_spp = 16;  // samples at which each render skip is compared with simulating everything
  std::string plot_dir;  // empty: no plots
  bool quiet = false;
};

nlohmann::json run_bench(const BenchOptions& options);

// Each render skip of the transport plan (tile culling, caustics, prop
// interreflection, light pruning, and the whole plan) against simulating
// everything at `spp` samples: seconds, tiles skipped, RMSE over the whole
// image against `reference` (a high-spp render simulating everything).
nlohmann::json measure_render_skips(const cv::Mat& photo, const inference::SceneModel& truth, const render::Mesh& prop,
                                    const render::PropPlacement& placement, const cv::Mat& reference, int spp);
std::string format_render_skips(const nlohmann::json& skips);
// Human-readable table of a bench result.
std::string format_bench(const nlohmann::json& result);
// Writes PNG plots (error against seconds) with gnuplot; throws if it is missing.
void plot_bench(const nlohmann::json& result, const std::string& dir);

// `propcam bench`: a row of the command table (cli/command_table.cpp).
struct BenchArgs {
  BenchOptions options;
  std::string size = "320x240";
  bool json_out = false;
};
void add_bench_options(CLI::App& cmd, BenchArgs& args);
int run_bench_command(BenchArgs args);

}  // namespace propcam::firmware
