// Runs a shell command (the real `propcam` executable, usually) and collects
// its exit code and standard output, for the tests that drive the CLI.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace propcam::test {

struct CliRun {
  int exit_code = -1;
  std::string out;  // stdout (and stderr when the command redirects it)
};

inline CliRun run_shell(const std::string& command) {
  CliRun r;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) r.out += buf.data();
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// `propcam ARGS` with stderr folded into the output.
inline CliRun propcam(const std::string& args) { return run_shell(std::string(PROPCAM_CLI) + " " + args + " 2>&1"); }

}  // namespace propcam::test
