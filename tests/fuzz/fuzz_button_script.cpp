// Button scripts (ui_fb/README.md's grammar), parsed from memory.
#include <cstddef>
#include <cstdint>
#include <exception>

#include "fuzz_support.h"
#include "propcam/ui_fb/buttons.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    propcam::ui_fb::ButtonScript::parse(propcam::fuzz::as_text(data, size));
  } catch (const std::exception&) {
    // A clear rejection (ButtonScriptError) is the expected outcome of bad input.
  }
  return 0;
}
