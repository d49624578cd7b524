// Model files (databases, classifiers, rankers) are written under a temporary
// name in their own folder and renamed into place, so a reader, or a crash
// mid-write, never sees a half-written file.
#pragma once

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <unistd.h>

namespace propcam::inference {

// A hidden temporary name beside `path` that keeps its extensions (OpenCV's
// FileStorage picks its format, and gzip, from them).
inline std::filesystem::path temporary_sibling(const std::filesystem::path& path) {
  const std::string name = path.filename().string();
  const auto dot = name.find('.');
  const std::string stem = dot == std::string::npos ? name : name.substr(0, dot);
  const std::string extensions = dot == std::string::npos ? "" : name.substr(dot);
  return path.parent_path() / (".tmp-" + std::to_string(::getpid()) + "-" + stem + extensions);
}

// Creates the folder, calls write(temporary path), renames the result to
// `path`. A throwing write leaves `path` as it was and removes the temporary.
template <typename Write>
void write_atomically(const std::string& path, Write&& write) {
  const std::filesystem::path final_path(path);
  if (final_path.has_parent_path()) std::filesystem::create_directories(final_path.parent_path());
  const std::filesystem::path tmp = temporary_sibling(final_path);
  try {
    write(tmp.string());
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw;
  }
  std::filesystem::rename(tmp, final_path);
}

// The same for a binary stream filled by fill(std::ostream&).
template <typename Fill>
void write_binary_atomically(const std::string& path, Fill&& fill) {
  write_atomically(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    fill(out);
    out.flush();
    if (!out) throw std::runtime_error("cannot write '" + tmp + "'");
  });
}

}  // namespace propcam::inference
