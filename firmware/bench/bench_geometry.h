// `propcam bench geometry`: the geometry half of inference (lines, camera,
// scene class, box layout, orientation map, depth transfer, the depth energy,
// support planes) on generator scenes with exact ground truth, sweeping its
// quality knobs: focal error, vanishing-direction error, pitch and roll,
// depth abs-rel and RMSE(log), surface-normal error, against seconds.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

struct GeometryBenchOptions {
  int rooms = 6;            // synthetic room seeds 1..rooms
  int streets = 4;          // synthetic street seeds 1..streets
  int width = 640, height = 480;
  int spp = 16;             // photo render samples (enough for lines and appearance)
  int timing_width = 1024;  // one more room at this size times the default pipeline (0: skip)
  std::vector<std::string> sweeps;  // empty: all (camera, resolution, iterations, transfer, priors)
  std::string plot_dir;     // empty: no plots
  bool quiet = false;
};

nlohmann::json run_geometry_bench(const GeometryBenchOptions& options);
std::string format_geometry_bench(const nlohmann::json& result);
// geometry_rooms.png and geometry_streets.png: depth abs-rel and normal error
// against seconds, one line per sweep. Throws if gnuplot is missing.
void plot_geometry_bench(const nlohmann::json& result, const std::string& dir);

struct GeometryBenchArgs {
  GeometryBenchOptions options;
  std::string size = "640x480";
  std::string sweeps;  // comma-separated
  bool json_out = false;
};
void add_bench_geometry_options(CLI::App& command, GeometryBenchArgs& args);
int run_bench_geometry_command(GeometryBenchArgs args);

}  // namespace propcam::firmware
