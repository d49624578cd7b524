// The `propcam` command table: every command is one row — where it sits
// (its path: "infer", "bench camera"), its summary, its group in --help,
// whether it needs the inference models, how it adds its options and how it
// runs. run_cli builds the command line from the rows and runs the one
// chosen; nothing else registers commands.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace propcam::firmware {

enum class CommandGroup {
  User,       // what a user of the camera does: infer, composite, run, shoot, export, ...
  Developer,  // benches, training and data builders, listed apart in --help
};

// Whether the command runs inference, so the models are checked before it
// starts rather than found missing half-way.
enum class NeedsModels { No, Yes };

struct Command {
  std::string path;     // words from `propcam`: "bench" or "bench camera" (its parent's row comes first)
  std::string summary;  // one line for --help
  CommandGroup group = CommandGroup::User;
  NeedsModels needs_models = NeedsModels::No;
  std::function<void(CLI::App&)> add_options;  // onto the command's own CLI::App
  std::function<int()> run;                    // after parsing; returns the exit code
};

// A row whose options live in an `Args` both functions share.
template <typename Args, typename AddOptions, typename Run>
Command command(std::string path, std::string summary, CommandGroup group, NeedsModels needs_models,
                AddOptions add_options, Run run) {
  auto args = std::make_shared<Args>();
  return {std::move(path), std::move(summary), group, needs_models,
          [args, add_options](CLI::App& app) { add_options(app, *args); }, [args, run] { return run(*args); }};
}

// Every command, in the order --help lists them.
std::vector<Command> propcam_commands();

}  // namespace propcam::firmware
