#include "catalogue.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>

namespace propcam::hard_cases {

void Digest::bytes(const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    hash_ ^= p[i];
    hash_ *= 1099511628211ull;
  }
}

void Digest::number(double value) {
  ++items_;
  if (!std::isfinite(value)) ++non_finite_;
  if (value == 0.0) value = 0.0;  // -0 and +0 are the same output
  bytes(&value, sizeof value);
}

void Digest::integer(std::int64_t value) {
  ++items_;
  bytes(&value, sizeof value);
}

void Digest::text(std::string_view value) {
  ++items_;
  const std::uint64_t n = value.size();
  bytes(&n, sizeof n);
  bytes(value.data(), value.size());
}

void Digest::mat(const cv::Mat& image) {
  integer(image.rows);
  integer(image.cols);
  integer(image.type());
  if (image.empty()) return;
  cv::Mat m;
  image.reshape(1, static_cast<int>(image.total())).convertTo(m, CV_64F);
  for (int r = 0; r < m.rows; ++r)
    for (int c = 0; c < m.cols; ++c) number(m.at<double>(r, c));
}

std::string Digest::hex() const {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(hash_));
  return buf;
}

ScratchDir::ScratchDir(const std::string& case_name)
    : path_(std::filesystem::temp_directory_path() /
            ("propcam_hard_case_" + std::to_string(::getpid()) + "_" + case_name)) {
  std::filesystem::remove_all(path_);
  std::filesystem::create_directories(path_);
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

void write_text_file(const std::filesystem::path& path, std::string_view text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  if (!out) throw std::runtime_error("hard case setup: cannot write " + path.string());
}

const std::vector<HardCase>& catalogue() {
  static const std::vector<HardCase> cases = [] {
    std::vector<HardCase> all;
    add_capture_cases(all);
    add_inference_cases(all);
    add_render_cases(all);
    add_ui_fb_cases(all);
    add_firmware_cases(all);
    return all;
  }();
  return cases;
}

}  // namespace propcam::hard_cases
