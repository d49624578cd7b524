// `propcam bench`: every stage's time, its error against ground truth where a
// synthetic room provides it, and the renderer's error-versus-time curve.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

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
// Human-readable table of a bench result.
std::string format_bench(const nlohmann::json& result);
// Writes PNG plots (error against seconds) with gnuplot; throws if it is missing.
void plot_bench(const nlohmann::json& result, const std::string& dir);

}  // namespace propcam::firmware
