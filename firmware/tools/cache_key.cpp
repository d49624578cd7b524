#include "tools/cache_key.h"

#include <fstream>
#include <stdexcept>

namespace propcam::firmware {

namespace fs = std::filesystem;

std::string file_stamp(const std::string& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return ec ? std::string("missing") : std::to_string(size);
}

bool key_matches(const fs::path& key_file, const nlohmann::json& key) {
  std::ifstream in(key_file);
  if (!in) return false;
  try {
    nlohmann::json stored;
    in >> stored;
    return stored == key;
  } catch (const std::exception&) {
    return false;
  }
}

void write_key(const fs::path& key_file, const nlohmann::json& key) {
  const fs::path tmp = key_file.string() + ".tmp";
  {
    std::ofstream out(tmp);
    out << key.dump(2) << "\n";
    if (!out) throw std::runtime_error("cannot write " + tmp.string());
  }
  fs::rename(tmp, key_file);
}

}  // namespace propcam::firmware
