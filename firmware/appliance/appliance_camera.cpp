#include "appliance/appliance_camera.h"

#include <algorithm>
#include <spdlog/spdlog.h>

#include "propcam/capture/camera_registry.h"
#include "propcam/capture/capture_client.h"
#include "propcam/capture/pixel_format.h"

namespace propcam::firmware {

ApplianceCamera::ApplianceCamera(ApplianceCameraOptions options, std::function<void(StillResult)> on_still)
    : options_(std::move(options)), on_still_(std::move(on_still)) {
  name_ = options_.daemon_socket.empty() ? options_.camera_id : "propcamd " + options_.daemon_socket;
  latest_.problem = "starting the camera";
  thread_ = std::thread([this] { run(); });
}

ApplianceCamera::~ApplianceCamera() {
  stop_ = true;
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

ViewfinderFrame ApplianceCamera::latest() const {
  std::lock_guard lock(mutex_);
  return latest_;
}

void ApplianceCamera::request_still(std::uint64_t request) {
  {
    std::lock_guard lock(mutex_);
    pending_still_ = request;
  }
  wake_.notify_all();
}

void ApplianceCamera::cancel_still() {
  std::lock_guard lock(mutex_);
  cancelled_still_ = pending_still_;
  pending_still_ = 0;
}

std::string ApplianceCamera::name() const { return name_; }

bool ApplianceCamera::ensure_open() {
  if (source_) return true;
  try {
    if (!options_.daemon_socket.empty()) {
      source_ = std::make_unique<capture::DaemonFrameSource>(
          options_.daemon_socket,
          options_.camera_id.empty() ? std::nullopt : std::optional<std::string>(options_.camera_id));
    } else {
      source_ = capture::open_camera(options_.camera_id);
    }
    capture::StreamConfig config = options_.viewfinder;
    if (source_->configure(config) == capture::ConfigStatus::Invalid)
      throw std::runtime_error("the camera cannot stream " + capture::to_string(config.pixel_format) + " " +
                               std::to_string(config.width) + "x" + std::to_string(config.height));
    source_->start();
    spdlog::info("camera {}: streaming {} {}x{}", name_, capture::to_string(config.pixel_format), config.width,
                 config.height);
    return true;
  } catch (const std::exception& e) {
    close_source(std::string("camera unavailable: ") + e.what());
    return false;
  }
}

void ApplianceCamera::close_source(const std::string& why) {
  if (source_) {
    try {
      source_->stop();
    } catch (const std::exception&) {
      // A lost camera may refuse to stop; it is dropped either way.
    }
    source_.reset();
  }
  spdlog::warn("camera {}: {}", name_, why);
  std::lock_guard lock(mutex_);
  latest_.problem = why;
}

void ApplianceCamera::take_still(std::uint64_t request) {
  StillResult result;
  result.request = request;
  try {
    // The shot keeps the exposure the viewfinder settled on.
    capture::CameraControls lock_exposure;
    lock_exposure.auto_exposure = false;
    source_->set_controls(lock_exposure);
    const capture::CaptureResult r = source_->capture_still(options_.still, options_.still_timeout);
    capture::CameraControls resume;
    resume.auto_exposure = true;
    if (source_) source_->set_controls(resume);
    if (r.status == capture::CaptureStatus::Ok && r.frame) {
      result.rgb8 = capture::frame_to_rgb8(*r.frame);
      result.linear = capture::frame_to_linear(*r.frame);
    } else {
      result.error = "no still: " + capture::to_string(r.status) + (r.message.empty() ? "" : " (" + r.message + ")");
      if (r.status == capture::CaptureStatus::DeviceLost) close_source("camera lost: reconnecting");
    }
  } catch (const std::exception& e) {
    result.error = std::string("no still: ") + e.what();
    close_source("camera failed: reconnecting");
  }
  {
    std::lock_guard lock(mutex_);
    if (cancelled_still_ == request) return;  // the user went back meanwhile
  }
  on_still_(std::move(result));
}

void ApplianceCamera::run() {
  std::chrono::milliseconds delay = options_.reopen_delay;
  while (!stop_) {
    std::uint64_t still = 0;
    {
      std::lock_guard lock(mutex_);
      still = pending_still_;
      pending_still_ = 0;
    }
    if (!ensure_open()) {
      if (still) {
        StillResult failed;
        failed.request = still;
        failed.error = "no camera: " + latest().problem;
        on_still_(std::move(failed));
      }
      std::unique_lock lock(mutex_);
      wake_.wait_for(lock, delay, [this] { return stop_.load() || pending_still_ != 0; });
      delay = std::min(delay * 2, options_.reopen_delay_max);
      continue;
    }
    delay = options_.reopen_delay;
    if (still) {
      take_still(still);
      continue;
    }
    capture::CaptureResult r;
    try {
      r = source_->next_frame(options_.frame_timeout);
    } catch (const std::exception& e) {
      close_source(std::string("camera failed: ") + e.what());
      continue;
    }
    switch (r.status) {
      case capture::CaptureStatus::Ok: {
        cv::Mat rgb = capture::frame_to_rgb8(*r.frame);
        std::lock_guard lock(mutex_);
        latest_.rgb8 = rgb;
        ++latest_.number;
        latest_.problem.clear();
        break;
      }
      case capture::CaptureStatus::Timeout: {
        std::lock_guard lock(mutex_);
        latest_.problem = "camera: no frame for " + std::to_string(options_.frame_timeout.count()) + " ms";
        break;
      }
      case capture::CaptureStatus::DeviceLost:
        close_source("camera lost: reconnecting");
        break;
      case capture::CaptureStatus::EndOfStream:
        close_source("recording ended: restarting");
        break;
    }
  }
  if (source_) {
    try {
      source_->stop();
    } catch (const std::exception&) {
    }
  }
}

}  // namespace propcam::firmware
