// Model files (the depth database, the light classifier) are read once per
// path and shared; a file that fails to load is not cached, and the caller
// gets the reason instead.
#pragma once

#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace propcam::inference {

// T::load(path) returns a T or throws; on failure `why` holds its message.
template <typename T>
std::shared_ptr<const T> load_once(const std::string& path, std::string& why) {
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<const T>> cache;
  std::lock_guard lock(mutex);
  if (auto it = cache.find(path); it != cache.end()) return it->second;
  try {
    auto loaded = std::make_shared<const T>(T::load(path));
    cache[path] = loaded;
    return loaded;
  } catch (const std::exception& e) {
    why = e.what();
    return nullptr;
  }
}

}  // namespace propcam::inference
