// `propcam run`: the appliance on a board, until SIGTERM or, on the virtual
// board, until its button script has played.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

namespace propcam::firmware {

struct RunArgs {
  std::string board = "virtual";  // a board name (board/<name>/) or a board.json path
  std::string script;             // script boards: replaces the board's session
  std::string snapshots;          // a PNG of the screen after every state change
  std::string usb;                // the stick's folder (runtime boards, or to override)
  std::string spool;
  std::string data;
  std::string daemon_socket;      // frames through propcamd
  int threads = 0;
  bool json_out = false;
};

void add_run_options(CLI::App& command, RunArgs& args);
int run_run_command(const RunArgs& args);

}  // namespace propcam::firmware
