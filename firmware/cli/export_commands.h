// `propcam export` and `propcam spool`: the appliance's export path
// (storage_export.h) from the command line, for scripting and fault tests.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

// Where the stick and the spool are: the board's storage, overridden by
// --usb / --spool (required where the board says "runtime").
struct StorageChoice {
  std::string board = "virtual";
  std::string usb;    // empty: the board's
  std::string spool;  // empty: the board's
};

// Exit code when every export ended in the spool or some did (not an error:
// nothing is lost, but it is not on the stick yet).
inline constexpr int kExitSpooled = 3;

struct ExportArgs {
  std::vector<std::string> files;  // PNG / JPEG / EXR images, exported as composites
  StorageChoice storage;
  bool jpeg = true;
  bool layers = false;  // float inputs (EXR) also as the layers EXR
  bool json_out = false;
};
void add_export_options(CLI::App& command, ExportArgs& args);
int run_export_command(const ExportArgs& args);

struct SpoolArgs {
  StorageChoice storage;
  bool flush = false;
  bool json_out = false;
};
void add_spool_options(CLI::App& command, SpoolArgs& args);
int run_spool_command(const SpoolArgs& args);

}  // namespace propcam::firmware
