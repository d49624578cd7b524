#pragma once

namespace propcam::firmware {
// Runs the `propcam` command line; returns the process exit code.
int run_cli(int argc, char** argv);
}  // namespace propcam::firmware
