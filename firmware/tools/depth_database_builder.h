// `propcam build-depth-db`: the depth-transfer database, rendered from the
// project's own scene generator (appearance at low resolution, exact depth).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

#include "propcam/inference/depth_transfer.h"

namespace propcam::firmware {

struct DepthDatabaseSpec {
  int rooms = 160;
  int streets = 120;
  uint64_t first_seed = 1001;  // disjoint from the seeds tests and benchmarks use (1..99)
  int photo_width = 160, photo_height = 120;
  int depth_width = 64, depth_height = 48;
  int spp = 16;
  bool quiet = false;
};

inference::DepthDatabase build_depth_database(const DepthDatabaseSpec& spec);

// `propcam build-depth-db`: a row of the command table (cli/command_table.cpp).
struct DepthDatabaseArgs {
  DepthDatabaseSpec spec;
  std::string output;
};
void add_build_depth_db_options(CLI::App& cmd, DepthDatabaseArgs& args);
int run_build_depth_db_command(const DepthDatabaseArgs& args);

}  // namespace propcam::firmware
