// Progress on stderr for anything longer than a second.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>

namespace propcam::firmware {

class Progress {
 public:
  explicit Progress(bool quiet = false) : quiet_(quiet), start_(std::chrono::steady_clock::now()) {}
  // propcam -q: no progress from any Progress.
  static void silence_all(bool silent) { silenced().store(silent); }
  static bool all_silenced() { return silenced().load(); }

  void stage(const std::string& what) {
    if (quiet_ || silenced()) return;
    std::lock_guard lock(mutex_);
    std::fprintf(stderr, "[%6.2fs] %s\n", elapsed(), what.c_str());
  }
  // A callback for RenderSettings::progress that prints every 10%.
  auto fraction_printer(const std::string& what) {
    return [this, what, last = -1](double f) mutable {
      const int decile = static_cast<int>(f * 10.0);
      if (quiet_ || silenced() || decile == last) return;
      last = decile;
      std::lock_guard lock(mutex_);
      std::fprintf(stderr, "[%6.2fs] %s %3d%%\n", elapsed(), what.c_str(), decile * 10);
    };
  }
  double elapsed() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  static std::atomic<bool>& silenced() {
    static std::atomic<bool> flag{false};
    return flag;
  }
  bool quiet_;
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
};

}  // namespace propcam::firmware
