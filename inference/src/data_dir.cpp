#include "propcam/inference/data_dir.h"

#include <cstdlib>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <system_error>

namespace propcam::inference {
namespace fs = std::filesystem;
namespace {

std::mutex g_mutex;
fs::path g_flag_dir;  // set_data_dir(); empty: not given

// The executable's <prefix>/bin/.. ; the build tree has the same shape
// (build/<preset>/firmware/propcam -> build/<preset>).
fs::path executable_prefix() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec || exe.empty()) return {};
  return exe.parent_path().parent_path();
}

fs::path beside_executable() {
  const fs::path prefix = executable_prefix();
  return prefix.empty() ? fs::path{} : prefix / "share" / "propcam";
}

}  // namespace

void set_data_dir(const fs::path& dir) {
  std::lock_guard lock(g_mutex);
  g_flag_dir = dir;
}

fs::path data_dir() {
  {
    std::lock_guard lock(g_mutex);
    if (!g_flag_dir.empty()) {
      if (!fs::is_directory(g_flag_dir)) throw std::runtime_error("data folder " + g_flag_dir.string() + " (--data-dir) is not a folder");
      return g_flag_dir;
    }
  }
  if (const char* env = std::getenv(kDataDirEnv); env && *env) {
    if (!fs::is_directory(env))
      throw std::runtime_error(std::string("data folder ") + env + " ($" + kDataDirEnv + ") is not a folder");
    return env;
  }
  const fs::path installed = beside_executable();
  std::error_code ec;
  if (!installed.empty() && fs::is_directory(installed, ec)) return installed;
  throw std::runtime_error("PropCam's data folder was not found (looked for " +
                           (installed.empty() ? std::string("<executable>/../share/propcam") : installed.string()) +
                           "); install the propcam package, or set $" + kDataDirEnv + " or --data-dir");
}

fs::path config_dir() {
  if (const char* env = std::getenv(kConfigDirEnv); env && *env) return env;
  const fs::path prefix = executable_prefix();
  if (prefix.empty()) return "/etc/propcam";
  // GNUInstallDirs: the prefix /usr keeps its settings in /etc, not /usr/etc.
  if (prefix.filename() == "usr") return prefix.parent_path() / "etc" / "propcam";
  return prefix / "etc" / "propcam";
}

fs::path data_file(const fs::path& relative) { return data_dir() / relative; }

std::vector<fs::path> inference_data_files() {
  return {"inference/depth_db.bin", "inference/scene_refs.bin", "inference/scene_classifier.yml.gz",
          "inference/light_classifier.yml.gz", "inference/ibl_ranker.yml.gz"};
}

void require_data_files(const std::vector<fs::path>& files) {
  const fs::path dir = data_dir();
  for (const fs::path& relative : files) {
    const fs::path path = dir / relative;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec))
      throw std::runtime_error("data file " + path.string() + " is missing (data folder " + dir.string() +
                               "; set $" + kDataDirEnv + " or --data-dir to another)");
    std::ifstream in(path, std::ios::binary);
    char byte = 0;
    if (!in || !in.read(&byte, 1))
      throw std::runtime_error("data file " + path.string() + " cannot be read (check its permissions)");
  }
}

}  // namespace propcam::inference
