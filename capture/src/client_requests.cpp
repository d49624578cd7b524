// What a client may ask: answered at once on the epoll thread (lists, info,
// status, viewfinder on or off, slot releases) or queued for the camera
// thread (select, configure, controls, stills).
#include "connection_loop.h"

namespace propcam::capture::detail {

namespace proto = protocol;

bool ConnectionLoop::handle_packet(std::uint32_t id, const std::vector<std::uint8_t>& bytes) {
  proto::Header h;
  try {
    h = proto::decode_header(bytes.data(), bytes.size());
  } catch (const proto::ProtocolError& e) {
    hub_.reply(id, proto::encode_error(0, e.what()));
    return false;
  }
  const proto::Payload p = proto::payload_of(bytes.data(), bytes.size());
  try {
    dispatch(id, h, p);
  } catch (const proto::ProtocolError& e) {
    hub_.reply(id, proto::encode_error(h.request_id, e.what()));
  } catch (const std::exception& e) {
    hub_.reply(id, proto::encode_error(h.request_id, e.what()));
  }
  return true;
}

void ConnectionLoop::dispatch(std::uint32_t id, const proto::Header& h, proto::Payload p) {
  using T = proto::MessageType;
  const std::uint32_t rid = h.request_id;
  switch (h.type) {
    case T::ListCameras: proto::decode_empty(p); return hub_.reply(id, list_reply(rid));
    case T::GetInfo: {
      proto::decode_empty(p);
      std::lock_guard lock(hub_.mu);
      const auto it = hub_.clients.find(id);
      if (it == hub_.clients.end()) return;
      hub_.send_must_locked(it->second,
                            hub_.info ? proto::encode_info(rid, *hub_.info) : proto::encode_error(rid, "no camera open"));
      return;
    }
    case T::GetStatus: {
      proto::decode_empty(p);
      proto::Status s = hub_.status_snapshot(id);
      return hub_.reply(id, proto::encode(rid, s));
    }
    case T::StartViewfinder:
    case T::StopViewfinder: {
      proto::decode_empty(p);
      hub_.set_viewfinder(id, h.type == T::StartViewfinder);
      jobs_.nudge();
      return hub_.reply(id, proto::encode(T::Ok, rid));
    }
    case T::ReleaseSlot: return hub_.release(id, rid, proto::decode_release_slot(p));
    case T::SelectCamera: {
      std::string camera = proto::decode_select_camera(p);
      return hub_.submit(id, rid, [this, id, rid, camera] { camera_.select(id, rid, camera); });
    }
    case T::Configure: {
      const StreamConfig c = proto::decode_configure(p);
      return hub_.submit(id, rid, [this, id, rid, c] { camera_.configure(id, rid, c); });
    }
    case T::SetControls: {
      const CameraControls c = proto::decode_controls(p);
      return hub_.submit(id, rid, [this, id, rid, c] { camera_.set_controls(id, rid, c); });
    }
    case T::CaptureStill: {
      const proto::CaptureStillRequest req = proto::decode_capture_still(p);
      return hub_.submit(id, rid, [this, id, rid, req] { camera_.take_still(id, rid, req); });
    }
    default: throw proto::ProtocolError("not a client message");
  }
}

proto::Packet ConnectionLoop::list_reply(std::uint32_t rid) {
  if (opt_.list_cameras) {
    try {
      return proto::encode_camera_list(rid, opt_.list_cameras());
    } catch (const std::exception& e) {
      return proto::encode_error(rid, std::string("listing cameras: ") + e.what());
    }
  }
  std::lock_guard lock(hub_.mu);
  std::vector<CameraInfo> cameras;
  if (hub_.info) cameras.push_back(*hub_.info);
  return proto::encode_camera_list(rid, cameras);
}

}  // namespace propcam::capture::detail
