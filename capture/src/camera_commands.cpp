// The clients' camera commands, run on the camera thread between frames:
// select, configure, controls and stills.
#include <cstring>

#include "camera_thread.h"

namespace propcam::capture::detail {
namespace {

namespace proto = protocol;

const char* status_name(CaptureStatus s) {
  switch (s) {
    case CaptureStatus::Ok: return "ok";
    case CaptureStatus::Timeout: return "timeout";
    case CaptureStatus::DeviceLost: return "device lost";
    case CaptureStatus::EndOfStream: return "end of stream";
  }
  return "unknown";
}

}  // namespace

void CameraThread::select(std::uint32_t client_id, std::uint32_t rid, const std::string& camera) {
  hub_.answer(client_id, do_select(rid, camera));
}

void CameraThread::configure(std::uint32_t client_id, std::uint32_t rid, StreamConfig c) {
  hub_.answer(client_id, do_configure(rid, c));
}

void CameraThread::set_controls(std::uint32_t client_id, std::uint32_t rid, const CameraControls& c) {
  hub_.answer(client_id, do_controls(rid, c));
}

proto::Packet CameraThread::do_select(std::uint32_t rid, const std::string& id) {
  std::string error;
  auto s = open_source(id, error);
  if (!s) return proto::encode_error(rid, "cannot open " + id + ": " + error);
  close_source();
  controls_ = CameraControls{};
  try {
    adopt_source(std::move(s), id);
  } catch (const std::exception& e) {
    source_.reset();
    hub_.set_state(proto::DeviceState::Lost);
    return proto::encode_error(rid, std::string("camera failed: ") + e.what());
  }
  if (resume_pending_) {
    resume_pending_ = false;
    hub_.broadcast_event(proto::EventKind::Resumed, "camera " + id + " selected");
  }
  return proto::encode(proto::MessageType::Ok, rid);
}

proto::Packet CameraThread::do_configure(std::uint32_t rid, StreamConfig c) {
  if (!source_) return proto::encode_error(rid, "no camera open");
  try {
    if (source_->running()) source_->stop();  // restarted by sync_streaming
    const ConfigStatus status = source_->configure(c);
    if (status != ConfigStatus::Invalid) {
      config_ = c;
      ended_ = false;
      hub_.stream_configured(c);
    }
    return proto::encode(rid, proto::ConfigureReply{status, c});
  } catch (const std::exception& e) {
    return proto::encode_error(rid, std::string("configure: ") + e.what());
  }
}

proto::Packet CameraThread::do_controls(std::uint32_t rid, const CameraControls& c) {
  if (!source_) return proto::encode_error(rid, "no camera open");
  try {
    const auto not_applied = source_->set_controls(c);
    auto merge = [](auto& into, const auto& from) {
      if (from) into = from;
    };
    merge(controls_.exposure_us, c.exposure_us);
    merge(controls_.analogue_gain, c.analogue_gain);
    merge(controls_.colour_gain_red, c.colour_gain_red);
    merge(controls_.colour_gain_blue, c.colour_gain_blue);
    merge(controls_.auto_exposure, c.auto_exposure);
    merge(controls_.auto_white_balance, c.auto_white_balance);
    return proto::encode_controls_reply(rid, not_applied);
  } catch (const std::exception& e) {
    return proto::encode_error(rid, std::string("set controls: ") + e.what());
  }
}

// A still is not a ring frame: it goes, with its reply, to the client that
// asked only, in a sealed memfd of its own.
void CameraThread::take_still(std::uint32_t client_id, std::uint32_t rid, const proto::CaptureStillRequest& req) {
  if (!source_) return hub_.answer(client_id, proto::encode_error(rid, "no camera open"));
  CaptureResult r;
  try {
    r = source_->capture_still(req.config, std::chrono::milliseconds(req.timeout_ms));
  } catch (const std::exception& e) {
    return hub_.answer(client_id, proto::encode_error(rid, std::string("still: ") + e.what()));
  }
  if (r.status != CaptureStatus::Ok || !r.frame) {
    proto::StillFrame failed;
    failed.status = r.status == CaptureStatus::Ok ? CaptureStatus::Timeout : r.status;
    failed.message = r.message.empty() ? std::string(status_name(failed.status)) : r.message;
    hub_.answer(client_id, proto::encode(rid, failed));
    if (r.status == CaptureStatus::DeviceLost) lose_device(failed.message);
    return;
  }
  try {
    const auto bytes = r.frame->data();
    const std::size_t size = round_to_page(bytes.size());
    UniqueFd fd = make_memfd("propcam-still", size);
    {
      Mapping map(fd.get(), size, true);
      std::memcpy(map.data(), bytes.data(), bytes.size());
    }
    seal_future_writes(fd.get());
    proto::StillFrame m;
    m.bytes_used = bytes.size();
    m.memfd_bytes = size;
    m.format = r.frame->format;
    m.metadata = r.frame->metadata;
    hub_.answer(client_id, proto::encode(rid, m), fd.get());
  } catch (const std::exception& e) {
    hub_.answer(client_id, proto::encode_error(rid, std::string("still: ") + e.what()));
  }
}

}  // namespace propcam::capture::detail
