// The appliance's camera: one thread owns the FrameSource, keeps the newest
// viewfinder frame for the screen, takes the still when asked, and reopens
// the camera when it is pulled. The UI thread never blocks on the camera.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <opencv2/core.hpp>

#include "propcam/capture/frame_source.h"

namespace propcam::firmware {

struct ApplianceCameraOptions {
  std::string camera_id;       // capture/camera_registry.h id; ignored with daemon_socket
  std::string daemon_socket;   // non-empty: through propcamd
  capture::StreamConfig viewfinder;
  std::optional<capture::StreamConfig> still;  // nullopt: the camera's largest
  std::chrono::milliseconds frame_timeout{500};
  std::chrono::milliseconds still_timeout{5000};
  std::chrono::milliseconds reopen_delay{500};  // first retry after a lost camera; doubles up to reopen_delay_max
  std::chrono::milliseconds reopen_delay_max{5000};
  int settle_frames = 3;       // viewfinder frames between a reopen and the first still
};

// What the screen shows of the camera.
struct ViewfinderFrame {
  cv::Mat rgb8;              // CV_8UC3 RGB; empty before the first frame
  std::uint64_t number = 0;  // increases with every new frame
  std::string problem;       // non-empty while the camera is missing: "camera lost: reconnecting"
};

// A still, or why there is none.
struct StillResult {
  std::uint64_t request = 0;
  cv::Mat linear;            // CV_32FC3 linear sRGB, empty on failure
  cv::Mat rgb8;              // the same as the camera delivered it
  std::string error;         // empty on success
};

class ApplianceCamera {
 public:
  // Starts the camera thread; opening failures are retried there, not thrown.
  // `on_still` is called from the camera thread with each still result.
  ApplianceCamera(ApplianceCameraOptions options, std::function<void(StillResult)> on_still);
  ~ApplianceCamera();
  ApplianceCamera(const ApplianceCamera&) = delete;
  ApplianceCamera& operator=(const ApplianceCamera&) = delete;

  // The newest frame (shares pixels: do not write into it).
  ViewfinderFrame latest() const;
  // Asks for a still; its result comes through on_still with this request id.
  void request_still(std::uint64_t request);
  // Forgets a requested still (its result, if one comes, is dropped).
  void cancel_still();
  std::string name() const;

 private:
  void run();
  bool ensure_open();
  void close_source(const std::string& why);
  void take_still(std::uint64_t request);

  ApplianceCameraOptions options_;
  std::function<void(StillResult)> on_still_;
  std::unique_ptr<capture::FrameSource> source_;  // camera thread only
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  ViewfinderFrame latest_;
  std::uint64_t pending_still_ = 0;   // 0: none
  std::uint64_t cancelled_still_ = 0;
  std::string name_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace propcam::firmware
