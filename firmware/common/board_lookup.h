// Where boards are on an installed system. Apart from board_config.h, which
// parses and finds boards and knows nothing of where PropCam is installed
// (the fuzz target builds it alone, without inference).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "common/board_config.h"

namespace propcam::firmware {

// Where boards are looked up by name, first match winning: the
// administrator's (config_dir()/boards, e.g. /etc/propcam/boards) before the
// shipped ones (data_dir()/board). Either may be absent; pass them to
// board_config.h's load_board.
std::vector<std::filesystem::path> installed_board_roots();

}  // namespace propcam::firmware
