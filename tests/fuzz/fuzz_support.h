// What the fuzz targets share: a scratch folder per process (the loaders
// take paths) and writing the fuzzer's bytes into it.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace propcam::fuzz {

// A folder of its own for this process, emptied before each input so no
// file of an earlier input is seen.
inline std::filesystem::path fresh_scratch_dir() {
  static const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                           ("propcam_fuzz_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline void write_file(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

}  // namespace propcam::fuzz
