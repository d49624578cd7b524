// Prop meshes: an OBJ and, after a line "#MTL", the mesh.mtl it may name
// (`mtllib mesh.mtl`), so the materials are fuzzed with the geometry.
#include <cstddef>
#include <cstdint>
#include <exception>
#include <string_view>

#include "fuzz_support.h"
#include "propcam/render/mesh_io.h"

namespace {
constexpr std::string_view kMtlSeparator = "\n#MTL\n";
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace propcam;
  const std::string_view bytes = fuzz::as_text(data, size);
  const std::size_t split = bytes.find(kMtlSeparator);
  const auto dir = fuzz::fresh_scratch_dir();
  fuzz::write_file(dir / "mesh.obj", bytes.substr(0, split));
  if (split != std::string_view::npos)
    fuzz::write_file(dir / "mesh.mtl", bytes.substr(split + kMtlSeparator.size()));
  try {
    render::load_mesh_file((dir / "mesh.obj").string());
  } catch (const std::exception&) {
    // Unparsable, empty or non-finite meshes are rejected naming the file.
  }
  return 0;
}
