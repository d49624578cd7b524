// Boards by name on an installed system: the administrator's before the
// shipped ones. Apart from board_config.h, which parses a board file and
// knows nothing of where PropCam is installed (the fuzz target builds it alone).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "board_config.h"

namespace propcam::firmware {

// Where boards are looked up by name, first match winning: the
// administrator's (config_dir()/boards, e.g. /etc/propcam/boards) before the
// shipped ones (data_dir()/board). Either may be absent.
std::vector<std::filesystem::path> installed_board_roots();

// load_board over several roots: the first that holds the name wins; an
// unknown name lists the boards of all of them.
BoardConfig load_board(const std::vector<std::filesystem::path>& board_roots, const std::string& name);

}  // namespace propcam::firmware
