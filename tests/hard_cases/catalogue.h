// The hard-case catalogue (issue 8): one entry per hard input of a module,
// each run through the module's real public API. A case either gives output
// (its numbers and pixels folded into a Digest, every number finite) or a
// clear error (a std::exception whose message names the problem). The runner
// (hard_cases_test.cpp) runs every case twice and requires the same digest or
// the same message both times. README.md lists the cases.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>

namespace propcam::hard_cases {

// FNV-1a over everything a case produced, with a count of the numbers that
// were not finite (a Result case must have none).
class Digest {
 public:
  void number(double value);
  void integer(std::int64_t value);
  void text(std::string_view value);
  // Every element of every channel, any depth.
  void mat(const cv::Mat& image);
  std::uint64_t value() const { return hash_; }
  std::string hex() const;
  std::size_t items() const { return items_; }
  std::size_t non_finite() const { return non_finite_; }

 private:
  void bytes(const void* data, std::size_t size);
  std::uint64_t hash_ = 1469598103934665603ull;
  std::size_t items_ = 0;
  std::size_t non_finite_ = 0;
};

// A check inside a Result case that did not hold (not the clear error an
// Error case expects: the runner fails the case).
struct CheckFailed : std::logic_error {
  using std::logic_error::logic_error;
};
inline void check(bool ok, const std::string& what) {
  if (!ok) throw CheckFailed(what);
}

enum class Expect {
  Result,  // finite, deterministic output
  Error,   // a std::exception naming the problem
};

struct HardCase {
  std::string name;    // CamelCase, unique; the ctest name is HardCases/Catalogue.Run/<module>_<name>
  std::string module;  // capture, inference, render, ui_fb, firmware
  std::string input;   // what it feeds in (for README.md)
  std::string outcome; // what must come out (for README.md)
  Expect expect = Expect::Result;
  // Error: lower-case words the message must contain (what names the problem).
  std::vector<std::string> mentions;
  std::function<void(Digest&)> run;
};

// Every case, in README order.
const std::vector<HardCase>& catalogue();

// The modules' parts of the catalogue (cases_<module>.cpp).
void add_capture_cases(std::vector<HardCase>& cases);
void add_inference_cases(std::vector<HardCase>& cases);
void add_render_cases(std::vector<HardCase>& cases);
void add_ui_fb_cases(std::vector<HardCase>& cases);
void add_firmware_cases(std::vector<HardCase>& cases);

// A fresh, empty folder for one run of a case, named after the case and the
// process (so both runs see the same path, and an error naming a file is the
// same message twice). Removed when the guard goes.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& case_name);
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

void write_text_file(const std::filesystem::path& path, std::string_view text);

}  // namespace propcam::hard_cases
