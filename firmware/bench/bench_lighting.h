// `propcam bench lighting`: the materials-and-lighting half of inference
// (albedo, light sources, basis renders, the intensity and camera-response
// fit) on generator scenes with exact lights, sweeping its knobs against
// seconds: dominant light direction and irradiance at the prop's base,
// re-render error of the empty scene, and the composite's error in the prop's
// region against a render with the prop truly in the scene, beside the
// Khan-style baseline (the photo wrapped into an environment, as the only light).
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

struct LightingBenchOptions {
  int rooms = 4;            // synthetic room seeds 1..rooms
  int streets = 2;          // synthetic street seeds 1..streets
  int width = 320, height = 240;
  int spp = 32;             // photo, reference and composite samples per pixel
  std::string prop = "cube";
  double prop_height_m = 0.4;
  std::vector<std::string> sweeps;  // empty: all knobs (basis_spp, basis_width, ...); "oracle" only when named
  std::string plot_dir;     // empty: no plots
  bool quiet = false;
};

nlohmann::json run_lighting_bench(const LightingBenchOptions& options);
std::string format_lighting_bench(const nlohmann::json& result);
// lighting.png: composite error in the prop region and light-direction error
// against seconds, one point per knob setting, the baseline as a line.
void plot_lighting_bench(const nlohmann::json& result, const std::string& dir);

struct LightingBenchArgs {
  LightingBenchOptions options;
  std::string size = "320x240";
  std::string sweeps;  // comma-separated
  bool json_out = false;
};
void add_bench_lighting_options(CLI::App& command, LightingBenchArgs& args);
int run_bench_lighting_command(LightingBenchArgs args);

}  // namespace propcam::firmware
