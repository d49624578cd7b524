#include "board_lookup.h"

#include <algorithm>

#include "propcam/inference/data_dir.h"

namespace propcam::firmware {
namespace fs = std::filesystem;

std::vector<fs::path> installed_board_roots() {
  return {inference::config_dir() / "boards", inference::data_dir() / "board"};
}

BoardConfig load_board(const std::vector<fs::path>& board_roots, const std::string& name) {
  if (!valid_board_name(name))
    throw BoardConfigError(board_roots.empty() ? fs::path{} : board_roots.back(), "",
                           "\"" + name + "\" is not a board name (lower-case letters, digits, - and _)");
  std::vector<std::string> all;
  std::string roots;
  for (const fs::path& root : board_roots) {
    const auto boards = list_boards(root);
    if (std::find(boards.begin(), boards.end(), name) != boards.end()) return load_board_file(root / name / "board.json");
    all.insert(all.end(), boards.begin(), boards.end());
    roots += (roots.empty() ? "" : ", ") + root.string();
  }
  std::sort(all.begin(), all.end());
  all.erase(std::unique(all.begin(), all.end()), all.end());
  std::string names;
  for (const std::string& board : all) names += (names.empty() ? "" : ", ") + board;
  throw BoardConfigError(board_roots.empty() ? fs::path{} : board_roots.back(), "",
                         "no board \"" + name + "\" in " + (roots.empty() ? "no folder" : roots) +
                             " (boards: " + (names.empty() ? "none" : names) + ")");
}

}  // namespace propcam::firmware
