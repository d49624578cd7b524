#include "common/board_lookup.h"

#include "propcam/inference/data_dir.h"

namespace propcam::firmware {

std::vector<std::filesystem::path> installed_board_roots() {
  return {inference::config_dir() / "boards", inference::data_dir() / "board"};
}

}  // namespace propcam::firmware
