// Scene models: the input is scene.json in an otherwise empty scene folder
// (the depth, albedo and normal maps are optional).
#include <cstddef>
#include <cstdint>
#include <exception>

#include "fuzz_support.h"
#include "propcam/inference/scene_model.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace propcam;
  const auto dir = fuzz::fresh_scratch_dir();
  fuzz::write_file(dir / "scene.json", fuzz::as_text(data, size));
  try {
    inference::load_scene(dir.string());
  } catch (const std::exception&) {
    // A bad scene.json is rejected with a message naming the folder.
  }
  return 0;
}
