// Shared by storage_test.cpp and storage_fault_test.cpp: test folders,
// composites that tell which export they were, a look at the stick, and
// FaultIo, the write layer that injects a stick's faults into the real code.
#pragma once

#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cerrno>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "storage/storage_export.h"

namespace storage_test {

namespace fs = std::filesystem;
using namespace propcam::firmware;

inline constexpr int kItemWidth = 48, kItemHeight = 32;

// An empty folder for this test (and this case of it).
inline fs::path fresh_dir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(::testing::TempDir()) / "propcam_storage" /
                       (std::string(info->test_suite_name()) + "." + info->name()) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A composite whose pixels encode `index` (the red channel of the first row)
// on a pattern, so a file on the stick says which export it is.
inline cv::Mat item_pixels(int index) {
  cv::Mat m(kItemHeight, kItemWidth, CV_8UC3);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x)
      m.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uchar>(y == 0 ? index : (x * 5 + y) & 0xff),
                                        static_cast<uchar>((x * 7 + index * 13) & 0xff), static_cast<uchar>(y * 3));
  return m;
}

inline ExportItem make_item(int index, const std::string& prop = "chair") {
  ExportItem item;
  item.composite_srgb8 = item_pixels(index);
  item.prop_name = prop;
  item.taken = std::chrono::system_clock::time_point(std::chrono::seconds(1796166060));  // 2026-12-01 23:01 UTC
  item.metadata = {{"prop", prop}, {"index", index}};
  return item;
}

// make_item's file stem: its time as the local clock reads it (the names use
// local time) and its prop. Written out here, apart from dated_stem, as the oracle.
inline std::string item_stem(const std::string& prop = "chair") {
  const std::time_t t = std::chrono::system_clock::to_time_t(make_item(0).taken);
  std::tm tm{};
  localtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d_%H%M_", &tm);
  return text + prop;
}

// With linear layers, for the EXR.
inline ExportItem make_layered_item(int index) {
  ExportItem item = make_item(index);
  item.composite_srgb8.convertTo(item.composite_linear, CV_32FC3, 1.0 / 255);
  item.layers["photo"] = item.composite_linear * 0.5;
  item.layers["depth"] = cv::Mat(kItemHeight, kItemWidth, CV_32FC1, cv::Scalar(2.5f));
  return item;
}

// An 8-bit image file as stored (no conversion), and one string attribute.
struct Decoded {
  cv::Mat pixels;  // CV_8UC3 when 3 channels
  std::map<std::string, std::string> text;
};
inline std::optional<Decoded> decode(const fs::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) {
    OIIO::geterror();
    return std::nullopt;
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.nchannels != 3) return std::nullopt;
  Decoded d;
  d.pixels.create(spec.height, spec.width, CV_8UC3);
  if (!in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, d.pixels.data)) {
    in->geterror();
    return std::nullopt;
  }
  for (const char* key : {"Software", "DateTime", "ImageDescription", "PropCam:export_id", "PropCam:metadata"})
    d.text[key] = spec.get_string_attribute(key);
  return d;
}

inline bool same_pixels(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

// The names in a folder, sorted ("" when it does not exist).
inline std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    names.push_back(it->path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

inline bool has_suffix(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// What a stick's export folder holds, checked: every final-named file is
// whole (PNGs decode to a known item's pixels, JPEGs decode, sidecars parse
// and name the same export as the PNG), no file is a temporary unless
// `allow_temporaries`. Returns the item indices found, one per PNG.
inline std::vector<int> check_stick(const fs::path& stick_dir, bool allow_temporaries = false) {
  std::vector<int> items;
  for (const std::string& name : names_in(stick_dir)) {
    const fs::path path = stick_dir / name;
    if (name.rfind(kStickTempPrefix, 0) == 0) {
      EXPECT_TRUE(allow_temporaries) << "temporary left: " << path;
      continue;
    }
    if (has_suffix(name, ".png")) {
      const auto d = decode(path);
      if (!d) {
        ADD_FAILURE() << "torn or unreadable: " << path;
        continue;
      }
      const int index = d->pixels.at<cv::Vec3b>(0, 0)[0];
      EXPECT_TRUE(same_pixels(d->pixels, item_pixels(index))) << path;
      items.push_back(index);
      EXPECT_EQ(d->text.at("Software"), "PropCam");
    } else if (has_suffix(name, ".jpg")) {
      EXPECT_TRUE(decode(path).has_value()) << "torn JPEG: " << path;
    } else if (has_suffix(name, ".json")) {
      std::ifstream in(path);
      const auto doc = nlohmann::json::parse(in, nullptr, false);
      EXPECT_FALSE(doc.is_discarded()) << "torn sidecar: " << path;
      const fs::path png = stick_dir / (name.substr(0, name.size() - 5) + ".png");
      if (!doc.is_discarded() && fs::exists(png)) {
        const auto d = decode(png);
        if (d) {
          EXPECT_EQ(doc["export_id"], d->text.at("PropCam:export_id")) << path;
        }
      }
    } else if (has_suffix(name, ".exr")) {
      auto in = OIIO::ImageInput::open(path.string());
      EXPECT_TRUE(in) << "torn EXR: " << path;
      if (!in) OIIO::geterror();
    }
  }
  std::sort(items.begin(), items.end());
  return items;
}

// The real syscalls, with faults on the calls whose path lies under `watched`
// (a write, fsync or close counts under the path its file was created at).
// Every such call is one step, numbered from 1.
class FaultIo : public StorageIo {
 public:
  explicit FaultIo(fs::path watched) : watched_(std::move(watched)) {}

  // Called before each watched step with its number, the call ("create",
  // "write", "fsync", "close", "rename", "mkdir", "fsync-dir", "remove") and
  // the path; returns an errno to fail the step, 0 to carry it out.
  std::function<int(int step, const std::string& op, const fs::path& path)> before_step;
  // Bytes the stick takes before it is full (short write, then ENOSPC).
  std::optional<std::uintmax_t> byte_budget;

  int steps() const { return steps_; }
  std::uintmax_t bytes_written() const { return bytes_; }
  // The cumulative byte offset at the start of each watched write call.
  const std::vector<std::uintmax_t>& write_offsets() const { return write_offsets_; }

  int create_file(const fs::path& path, int& fd) override {
    if (const int e = step("create", path)) return e;
    const int e = StorageIo::create_file(path, fd);
    if (e == 0 && watches(path)) watched_fds_[fd] = path;
    return e;
  }
  int write(int fd, const void* data, std::size_t size, std::size_t& written) override {
    written = 0;
    const auto it = watched_fds_.find(fd);
    if (it == watched_fds_.end()) return StorageIo::write(fd, data, size, written);
    if (const int e = step("write", it->second)) return e;
    write_offsets_.push_back(bytes_);
    std::size_t allowed = size;
    if (byte_budget) {
      if (bytes_ >= *byte_budget) return ENOSPC;
      allowed = static_cast<std::size_t>(std::min<std::uintmax_t>(size, *byte_budget - bytes_));
    }
    const int e = StorageIo::write(fd, data, allowed, written);
    bytes_ += written;
    return e;
  }
  int sync_file(int fd) override {
    const auto it = watched_fds_.find(fd);
    if (it != watched_fds_.end())
      if (const int e = step("fsync", it->second)) return e;
    return StorageIo::sync_file(fd);
  }
  int close_file(int fd) override {
    const auto it = watched_fds_.find(fd);
    int e = 0;
    if (it != watched_fds_.end()) {
      e = step("close", it->second);
      watched_fds_.erase(it);
    }
    const int closed = StorageIo::close_file(fd);  // the descriptor goes either way, as close(2) does
    return e ? e : closed;
  }
  int rename_new(const fs::path& from, const fs::path& to) override {
    if (const int e = step("rename", to)) return e;
    return StorageIo::rename_new(from, to);
  }
  int make_dir(const fs::path& dir) override {
    if (const int e = step("mkdir", dir)) return e;
    return StorageIo::make_dir(dir);
  }
  int sync_dir(const fs::path& dir) override {
    if (const int e = step("fsync-dir", dir)) return e;
    return StorageIo::sync_dir(dir);
  }
  int remove(const fs::path& path) override {
    if (const int e = step("remove", path)) return e;
    return StorageIo::remove(path);
  }

 private:
  bool watches(const fs::path& path) const {
    const std::string p = path.lexically_normal().string(), w = watched_.lexically_normal().string();
    return p.compare(0, w.size(), w) == 0 && (p.size() == w.size() || p[w.size()] == '/');
  }
  int step(const std::string& op, const fs::path& path) {
    if (!watches(path)) return 0;
    ++steps_;
    return before_step ? before_step(steps_, op, path) : 0;
  }

  fs::path watched_;
  std::map<int, fs::path> watched_fds_;
  int steps_ = 0;
  std::uintmax_t bytes_ = 0;
  std::vector<std::uintmax_t> write_offsets_;
};

}  // namespace storage_test
