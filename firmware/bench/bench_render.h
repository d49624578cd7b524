// `propcam bench render`: the differential renderer's speed per image size —
// its rays per second against a raw Embree loop on the same scene, the time
// to the first snapshot, and the time to 1% error in the prop's region.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

// The error at which `time_to_1pct_s` is taken: RMSE of the composite against
// the reference over the prop's region, relative to the photo's mean luminance there.
constexpr double kRenderBenchTargetRelativeRmse = 0.01;

struct RenderBenchOptions {
  std::vector<cv::Size> sizes{{640, 480}, {1024, 768}};
  uint64_t seed = 4;            // synthetic room
  // A diffuse prop: a chrome or glossy one adds caustics whose noise needs
  // thousands of samples per pixel to reach 1%, minutes per size.
  std::string prop = "cube";
  double prop_height_m = 0.0;   // <= 0: the prop's natural height
  int reference_spp = 512;      // reference render, in two independent halves
  int max_spp = 1024;           // the measured session stops here if it never reaches 1%
  int photo_spp = 16;           // the synthetic photo (its noise cancels: reference and session share it)
  int threads = 0;              // 0: all hardware threads (session and raw loop alike)
  std::string plot_dir;         // empty: no plots
  // Each render skip against simulating everything, on a room this size at
  // `skip_spp` (reference: `skip_reference_spp`, simulating everything). 0: off.
  cv::Size skip_size{320, 240};
  int skip_spp = 16;
  int skip_reference_spp = 256;
  bool quiet = false;
};

// "640x480,1024x768" -> sizes; throws std::invalid_argument on anything else
// (each side in 16..8192).
std::vector<cv::Size> parse_sizes(const std::string& text);

nlohmann::json run_render_bench(const RenderBenchOptions& options);
// Human-readable table of a run_render_bench result.
std::string format_render_bench(const nlohmann::json& result);
// One PNG per size (relative RMSE against seconds, log-log) with gnuplot.
void plot_render_bench(const nlohmann::json& result, const std::string& dir);

// `propcam bench render`: a row of the command table (cli/command_table.cpp).
struct RenderBenchArgs {
  RenderBenchOptions options;
  std::string sizes = "640x480,1024x768";
  std::string skip_size = "320x240";
  bool json_out = false;
};
void add_bench_render_options(CLI::App& cmd, RenderBenchArgs& args);
int run_bench_render_command(RenderBenchArgs args);

}  // namespace propcam::firmware
