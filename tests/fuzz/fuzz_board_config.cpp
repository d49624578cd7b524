// Board configuration files (board/<name>/board.json).
#include <cstddef>
#include <cstdint>
#include <exception>

#include "common/board_config.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto dir = propcam::fuzz::fresh_scratch_dir();
  propcam::fuzz::write_file(dir / "board.json", propcam::fuzz::as_text(data, size));
  try {
    propcam::firmware::load_board_file(dir / "board.json");
  } catch (const std::exception&) {
    // BoardConfigError names the file and the field: the expected rejection.
  }
  return 0;
}
