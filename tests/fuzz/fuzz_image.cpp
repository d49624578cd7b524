// Photos through OpenImageIO (load_photo_linear). The file is named by the
// bytes' signature, as a camera or a stick would name it, so each reader the
// appliance relies on is the one that gets the bytes.
#include <cstddef>
#include <cstdint>
#include <exception>
#include <string_view>

#include "fuzz_support.h"
#include "propcam/capture/image_file.h"

namespace {
std::string_view extension_for(std::string_view bytes) {
  if (bytes.starts_with("\x89PNG")) return ".png";
  if (bytes.starts_with("\xff\xd8")) return ".jpg";
  if (bytes.starts_with("\x76\x2f\x31\x01")) return ".exr";
  return ".png";
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace propcam;
  const std::string_view bytes = fuzz::as_text(data, size);
  const auto path = fuzz::fresh_scratch_dir() / ("photo" + std::string(extension_for(bytes)));
  fuzz::write_file(path, bytes);
  try {
    capture::load_photo_linear(path.string());
  } catch (const std::exception&) {
    // Unreadable, truncated or oversized images are rejected with a message.
  }
  return 0;
}
