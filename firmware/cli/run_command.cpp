#include "cli/run_command.h"

#include <algorithm>
#include <csignal>
#include <numeric>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include <nlohmann/json.hpp>

#include "appliance/appliance.h"
#include "common/board_lookup.h"

namespace propcam::firmware {
namespace fs = std::filesystem;

namespace {

std::atomic<bool> g_stop{false};

extern "C" void request_stop(int) { g_stop = true; }

BoardConfig load_board_argument(const std::string& board) {
  // A path to a board.json (the systemd unit's form), else a board's name.
  if (board.find('/') != std::string::npos || board.ends_with(".json")) return load_board_file(board);
  return load_board(installed_board_roots(), board);
}

}  // namespace

void add_run_options(CLI::App& cmd, RunArgs& a) {
  cmd.add_option("--board", a.board, "Board name (board/<name>/board.json) or a board.json path");
  cmd.add_option("--script", a.script, "Button script to play (script boards; default: the board's demo session)")
      ->check(CLI::ExistingFile);
  cmd.add_option("--snapshots", a.snapshots, "Folder for a PNG of the screen after every state change and at the end");
  cmd.add_option("--usb", a.usb, "Folder that stands in for the USB stick");
  cmd.add_option("--spool", a.spool, "Spool folder (exports wait here without a stick)");
  cmd.add_option("--data", a.data, "The device's data folder (thumbnails, measured throughput)");
  cmd.add_option("--daemon", a.daemon_socket, "Take frames from propcamd at this socket");
  cmd.add_option("--threads", a.threads, "Render threads (0: all cores)")->check(CLI::Range(0, 256));
  cmd.add_flag("--json", a.json_out, "Print a JSON summary at the end");
}

int run_run_command(const RunArgs& a) {
  ApplianceOptions options;
  options.board = load_board_argument(a.board);
  options.script = a.script;
  options.snapshots_dir = a.snapshots;
  options.usb_dir = a.usb;
  options.spool_dir = a.spool;
  options.data_dir = a.data;
  options.daemon_socket = a.daemon_socket;
  options.render_threads = a.threads;
  std::signal(SIGTERM, request_stop);
  std::signal(SIGINT, request_stop);
  Appliance appliance(std::move(options));
  const ApplianceRunSummary summary = appliance.run(g_stop);
  nlohmann::json out = {{"final_state", summary.final_state},
                        {"state_changes", summary.state_changes},
                        {"rejected_inputs", summary.rejected_inputs},
                        {"spooled", summary.spooled}};
  out["snapshots"] = nlohmann::json::array();
  for (const auto& s : summary.snapshots) out["snapshots"].push_back(s.string());
  out["input_to_screen_ms"] = summary.input_to_screen_ms;
  out["props"] = summary.props;
  out["exported"] = nlohmann::json::array();
  for (const auto& e : summary.exported) out["exported"].push_back(e.string());
  if (a.json_out) {
    std::cout << out.dump(2) << std::endl;
  } else {
    std::fprintf(stderr, "run: ended in %s after %d state changes; %zu snapshots; %zu files exported, %d spooled\n",
                 summary.final_state.c_str(), summary.state_changes, summary.snapshots.size(), summary.exported.size(),
                 summary.spooled);
    for (const auto& e : summary.exported) std::fprintf(stderr, "  exported %s\n", e.string().c_str());
    if (!summary.input_to_screen_ms.empty()) {
      const auto& ms = summary.input_to_screen_ms;
      std::fprintf(stderr, "  button to screen: %zu inputs, worst %.1f ms, mean %.1f ms\n", ms.size(),
                   *std::max_element(ms.begin(), ms.end()),
                   std::accumulate(ms.begin(), ms.end(), 0.0) / static_cast<double>(ms.size()));
    }
  }
  return 0;
}

}  // namespace propcam::firmware
