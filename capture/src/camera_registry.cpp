#include "propcam/capture/camera_registry.h"

#include <algorithm>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "propcam/capture/libcamera_source.h"
#include "propcam/capture/recording.h"
#include "propcam/capture/replay_source.h"
#include "propcam/capture/v4l2_source.h"

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kV4l2Prefix = "v4l2:", kLibcameraPrefix = "libcamera:", kReplayPrefix = "replay:";
// The first camera libcamera lists (boards with one CSI camera).
constexpr std::string_view kLibcameraAuto = "libcamera:auto";

bool is_recording(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(dir / kRecordingManifest, ec);
}

// A folder that is a recording, or holds recordings one level down (sorted,
// so the list is the same on every run).
std::vector<fs::path> recordings_in(const fs::path& dir) {
  if (is_recording(dir)) return {dir};
  std::vector<fs::path> found;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->is_directory(ec) && is_recording(it->path())) found.push_back(it->path());
  std::sort(found.begin(), found.end());
  return found;
}

CameraInfo replay_info(const fs::path& dir) {
  try {
    return ReplaySource(dir, ReplayOptions{}).info();
  } catch (const std::exception& e) {
    // Listed, so the user sees why it cannot be used, but without formats.
    return CameraInfo{std::string(kReplayPrefix) + dir.string(), "replay", std::string("unusable: ") + e.what(), {}};
  }
}

}  // namespace

std::vector<CameraInfo> list_cameras(const std::vector<std::string>& recording_dirs) {
  std::vector<CameraInfo> cameras = list_libcamera_cameras();
  for (CameraInfo& v4l2 : list_v4l2_cameras()) {
    const std::string node = v4l2.id.substr(kV4l2Prefix.size());
    if (!libcamera_owns_device(node)) cameras.push_back(std::move(v4l2));
  }
  for (const std::string& dir : recording_dirs)
    for (const fs::path& recording : recordings_in(dir)) cameras.push_back(replay_info(recording));
  return cameras;
}

std::unique_ptr<FrameSource> open_camera(const std::string& id) {
  const auto starts = [&](std::string_view prefix) { return id.rfind(prefix, 0) == 0; };
  const auto rest = [&](std::string_view prefix) { return id.substr(prefix.size()); };
  try {
    if (starts(kV4l2Prefix)) return std::make_unique<V4l2Source>(rest(kV4l2Prefix));
    if (id == kLibcameraAuto) {
      const std::vector<CameraInfo> cameras = list_libcamera_cameras();
      if (cameras.empty()) throw std::runtime_error("libcamera sees no camera");
      return std::make_unique<LibcameraSource>(cameras.front().id.substr(kLibcameraPrefix.size()));
    }
    if (starts(kLibcameraPrefix)) return std::make_unique<LibcameraSource>(rest(kLibcameraPrefix));
    if (starts(kReplayPrefix)) return std::make_unique<ReplaySource>(fs::path(rest(kReplayPrefix)), ReplayOptions{});
  } catch (const std::exception& e) {
    throw std::runtime_error("camera " + id + ": " + e.what());
  }
  throw std::runtime_error("camera " + id + ": unknown backend (ids start with v4l2:, libcamera: or replay:)");
}

}  // namespace propcam::capture
