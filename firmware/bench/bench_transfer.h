// `propcam bench transfer`: depth transfer alone (inference/depth_transfer.h)
// on held-out generator rooms with their TRUE camera: the weighted median of
// the k nearest database examples against the exact depth, with and without
// the camera warp, and the time of one query.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

struct TransferBenchOptions {
  int rooms = 8;                     // synthetic room seeds 1..rooms (the database uses 1001..)
  int width = 320, height = 240;
  int spp = 16;
  std::vector<int> ks = {1, 3, 7, 15};
  std::string database;              // empty: inference::default_depth_database_path()
  bool oracle = true;                // also the best single example per room (an upper bound for retrieval)
  bool quiet = false;
};

nlohmann::json run_transfer_bench(const TransferBenchOptions& options);
std::string format_transfer_bench(const nlohmann::json& result);

struct TransferBenchArgs {
  TransferBenchOptions options;
  std::string size = "320x240";
  std::string ks = "1,3,7,15";
  bool json_out = false;
};
void add_bench_transfer_options(CLI::App& command, TransferBenchArgs& args);
int run_bench_transfer_command(TransferBenchArgs args);

}  // namespace propcam::firmware
