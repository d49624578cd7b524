// The camera thread's loop: the camera's life (open, lost, reopened) and
// its frames.
#include "camera_thread.h"

#include <algorithm>

namespace propcam::capture::detail {

namespace proto = protocol;

CameraThread::CameraThread(FrameSourceFactory factory, const CaptureServerOptions& opt, ClientHub& hub,
                           CameraJobs& jobs)
    : factory_(std::move(factory)), opt_(opt), hub_(hub), jobs_(jobs), config_(opt.stream) {}

void CameraThread::close_source() {
  if (!source_) return;
  try {
    if (source_->running()) source_->stop();
  } catch (const std::exception& e) {
    hub_.log(std::string("stopping the camera: ") + e.what());
  }
  source_.reset();
}

std::unique_ptr<FrameSource> CameraThread::open_source(const std::string& id, std::string& error) {
  try {
    auto s = factory_(id);
    if (!s) {
      error = "no camera " + id;
      return nullptr;
    }
    StreamConfig c = config_;
    if (s->configure(c) != ConfigStatus::Invalid) config_ = c;
    return s;
  } catch (const std::exception& e) {
    error = e.what();
    return nullptr;
  }
}

void CameraThread::adopt_source(std::unique_ptr<FrameSource> s, const std::string& id) {
  source_ = std::move(s);
  ended_ = false;
  CameraInfo camera = source_->info();
  const std::size_t expected = expected_frame_bytes(source_->configuration());
  const StreamConfig in_use = source_->configuration();
  hub_.camera_opened(id, in_use, std::move(camera), expected);
}

void CameraThread::try_reopen() {
  const std::string id = hub_.camera_id();
  std::string error;
  auto s = open_source(id, error);
  if (!s) {
    backoff_ = std::clamp(backoff_ * 2, opt_.reopen_backoff_min, opt_.reopen_backoff_max);
    next_open_ = Clock::now() + backoff_;
    return;
  }
  try {
    if (controls_.exposure_us || controls_.analogue_gain || controls_.colour_gain_red || controls_.colour_gain_blue ||
        controls_.auto_exposure || controls_.auto_white_balance)
      s->set_controls(controls_);
    adopt_source(std::move(s), id);
  } catch (const std::exception& e) {
    hub_.log(std::string("reopening the camera: ") + e.what());
    source_.reset();
    next_open_ = Clock::now() + backoff_;
    return;
  }
  backoff_ = opt_.reopen_backoff_min / 2;
  hub_.log("camera " + id + " open");
  report_status(resume_pending_ ? "camera " + id + " is back" : "camera " + id + " open");
  if (resume_pending_) {
    resume_pending_ = false;
    hub_.broadcast_event(proto::EventKind::Resumed, "camera " + id + " is back");
  }
}

void CameraThread::lose_device(const std::string& why) {
  hub_.log("camera lost: " + why);
  report_status("camera lost: " + why);
  close_source();
  hub_.device_lost(why);
  resume_pending_ = true;
  backoff_ = opt_.reopen_backoff_min;
  next_open_ = Clock::now() + backoff_;
}

void CameraThread::sync_streaming() {
  const bool want = hub_.anyone_wants_frames() && !ended_;
  try {
    if (want && !source_->running()) {
      source_->start();
      hub_.set_state(proto::DeviceState::Streaming);
    } else if (!want && source_->running()) {
      source_->stop();
      hub_.set_state(ended_ ? proto::DeviceState::Ended : proto::DeviceState::Idle);
    }
  } catch (const std::exception& e) {
    lose_device(e.what());
  }
}

void CameraThread::capture_once() {
  CaptureResult r;
  try {
    r = source_->next_frame(opt_.frame_timeout);
  } catch (const std::exception& e) {
    r.status = CaptureStatus::DeviceLost;
    r.message = e.what();
  }
  switch (r.status) {
    case CaptureStatus::Ok:
      try {
        if (r.frame) hub_.publish(*r.frame);
      } catch (const std::exception& e) {
        hub_.log(std::string("cannot share a frame: ") + e.what());  // e.g. no memory for a bigger ring
      }
      break;
    case CaptureStatus::Timeout: break;
    case CaptureStatus::DeviceLost: lose_device(r.message.empty() ? "device lost" : r.message); break;
    case CaptureStatus::EndOfStream:
      ended_ = true;
      try {
        source_->stop();
      } catch (const std::exception&) {
      }
      hub_.set_state(proto::DeviceState::Ended);
      hub_.broadcast_event(proto::EventKind::EndOfStream, r.message);
      break;
  }
}

void CameraThread::report_status(const std::string& line) const {
  if (opt_.status) opt_.status(line);
}

CameraThread::Clock::time_point CameraThread::capped(Clock::time_point until) const {
  if (!opt_.heartbeat) return until;
  return std::min(until, Clock::now() + opt_.heartbeat_interval);
}

void CameraThread::run() {
  backoff_ = opt_.reopen_backoff_min / 2;
  next_open_ = Clock::now();
  try_reopen();  // before any command: those sent right after connecting find the camera open
  while (jobs_.run_or_wait(std::nullopt)) {
    if (opt_.heartbeat) opt_.heartbeat();
    const auto now = Clock::now();
    if (!source_) {
      if (now >= next_open_) try_reopen();
      if (!source_) jobs_.run_or_wait(capped(next_open_));
      continue;
    }
    sync_streaming();
    if (source_ && source_->running()) capture_once();
    else jobs_.run_or_wait(capped(now + std::chrono::milliseconds(500)));
  }
  close_source();
}

}  // namespace propcam::capture::detail
