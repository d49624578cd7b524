#include "cli/cli.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <iostream>
#include <map>
#include <stdexcept>

#include "cli/cli_options.h"
#include "cli/command_table.h"
#include "common/logging.h"
#include "common/progress.h"
#include "propcam/inference/data_dir.h"

namespace propcam::firmware {
namespace {

constexpr const char* kUserGroup = "Commands";
constexpr const char* kDeveloperGroup = "Development (benches, training, data builders, fixtures)";

// Why a command failed: on stderr for a person, at the journal's error
// priority under systemd (where stderr would reach it as plain info).
void report_failure(const std::string& message) {
  if (stderr_is_journal())
    spdlog::error("{}", message);
  else
    std::cerr << message << std::endl;
}

// The command table as CLI11 subcommands; `apps[i]` is row i's.
std::vector<CLI::App*> add_commands(CLI::App& app, const std::vector<Command>& commands) {
  std::map<std::string, CLI::App*> by_path;
  std::vector<CLI::App*> apps;
  for (const Command& c : commands) {
    const auto space = c.path.rfind(' ');
    CLI::App* parent = &app;
    if (space != std::string::npos) {
      const auto found = by_path.find(c.path.substr(0, space));
      if (found == by_path.end()) throw std::logic_error("command '" + c.path + "' comes before its parent");
      parent = found->second;
    }
    CLI::App* sub = parent->add_subcommand(c.path.substr(space == std::string::npos ? 0 : space + 1), c.summary);
    // --help groups the top level; a command's own subcommands list under it as CLI11 lists them.
    if (parent == &app) sub->group(c.group == CommandGroup::User ? kUserGroup : kDeveloperGroup);
    c.add_options(*sub);
    by_path[c.path] = sub;
    apps.push_back(sub);
  }
  return apps;
}

// The row chosen: the deepest parsed subcommand (a child's row follows its parent's).
const Command* chosen_command(const std::vector<Command>& commands, const std::vector<CLI::App*>& apps) {
  for (size_t i = commands.size(); i-- > 0;)
    if (apps[i]->parsed()) return &commands[i];
  return nullptr;
}

}  // namespace

int run_cli(int argc, char** argv) {
  CLI::App app{"PropCam: infer a scene from one photo and composite 3D props into it"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("propcam ") + PROPCAM_VERSION);
  // Options of the program, before or after the command (fallthrough).
  app.fallthrough();
  bool quiet = false, verbose = false;
  app.add_flag("-q,--quiet", quiet, "Warnings and errors only: no progress lines");
  app.add_flag("-v,--verbose", verbose, "Debug messages too");
  std::string data_dir;
  app.add_option("--data-dir", data_dir,
                 std::string("Folder of PropCam's data: models, boards (default: $") + inference::kDataDirEnv +
                     ", else share/propcam beside the executable's bin/)");
  const std::vector<Command> commands = propcam_commands();
  const std::vector<CLI::App*> apps = add_commands(app, commands);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every bad argument exits 2, as the
    // checks after parsing do.
    return app.exit(e) == 0 ? 0 : kExitBadArguments;
  }
  // Logs go to stderr, or to the journal with priorities under systemd;
  // stdout is for results and --json.
  set_up_logging("propcam", quiet ? Verbosity::Quiet : verbose ? Verbosity::Verbose : Verbosity::Normal);
  Progress::silence_all(quiet);
  try {
    inference::set_data_dir(data_dir);
    const Command* command = chosen_command(commands, apps);
    if (command == nullptr) return 0;
    // Commands that infer scenes check their models now, not mid-way.
    if (command->needs_models == NeedsModels::Yes) inference::require_data_files(inference::inference_data_files());
    return command->run();
  } catch (const std::invalid_argument& e) {
    report_failure(std::string("propcam: ") + e.what());
    return kExitBadArguments;
  } catch (const std::exception& e) {
    report_failure(std::string("propcam: error: ") + e.what());
    return 1;
  }
}

}  // namespace propcam::firmware
