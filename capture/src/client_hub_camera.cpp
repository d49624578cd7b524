// ClientHub's camera side: the camera's state as status() reports it, and
// each frame into the ring and out to the viewfinders.
#include "client_hub.h"

namespace propcam::capture::detail {

namespace proto = protocol;

std::string ClientHub::camera_id() const {
  std::lock_guard lock(mu);
  return camera_id_;
}

void ClientHub::camera_opened(const std::string& id, const StreamConfig& in_use, CameraInfo camera,
                              std::size_t expected_frame_bytes) {
  std::lock_guard lock(mu);
  camera_id_ = id;
  stream_in_use_ = in_use;
  info = std::move(camera);
  state_ = proto::DeviceState::Idle;
  ensure_ring_locked(expected_frame_bytes);
}

void ClientHub::stream_configured(const StreamConfig& in_use) {
  std::lock_guard lock(mu);
  stream_in_use_ = in_use;
  state_ = proto::DeviceState::Idle;
}

void ClientHub::device_lost(const std::string& why) {
  std::lock_guard lock(mu);
  state_ = proto::DeviceState::Lost;
  ++device_lost_count_;
  broadcast_locked(proto::encode(proto::Event{proto::EventKind::DeviceLost, why}));
}

void ClientHub::set_state(proto::DeviceState s) {
  std::lock_guard lock(mu);
  state_ = s;
}

void ClientHub::replace_ring_locked(std::size_t frame_bytes) {
  ring = std::make_unique<FrameRing>(next_generation_++, opt_.ring_slots, frame_bytes);
  // Holds were on the old ring; clients keep their own mapping of it.
  for (auto& [id, c] : clients) c.held = 0;
  broadcast_locked(proto::encode_ring_changed(ring->info()), ring->fd());
}

void ClientHub::ensure_ring_locked(std::size_t frame_bytes) {
  if (!ring || ring->info().slot_bytes < frame_bytes) replace_ring_locked(frame_bytes);
}

void ClientHub::publish(const Frame& frame) {
  const auto bytes = frame.data();
  std::uint32_t slot;
  FrameRing* target;
  {
    std::lock_guard lock(mu);
    ++frames_captured_;
    const std::int64_t now = monotonic_ns();
    arrivals_.push_back(now);
    while (!arrivals_.empty() && arrivals_.front() <= now - 1'000'000'000) arrivals_.pop_front();
    ensure_ring_locked(bytes.size());
    const auto free = ring->claim_free_slot();
    if (!free) {
      ++frames_unplaced_;
      for (auto& [id, c] : clients)
        if (c.viewfinder && !c.dead) ++c.dropped;
      return;
    }
    slot = *free;
    target = ring.get();  // only the camera thread replaces the ring
  }
  // The one copy, outside the lock: no client can hold a slot being written.
  target->write(slot, bytes);
  std::lock_guard lock(mu);
  target->finish_write(slot);
  proto::FrameReady ready;
  ready.generation = target->info().generation;
  ready.slot = slot;
  ready.bytes_used = bytes.size();
  ready.format = frame.format;
  ready.metadata = frame.metadata;
  const proto::Packet packet = proto::encode(ready);
  for (auto& [id, c] : clients) offer_locked(c, packet, slot);
}

void ClientHub::offer_locked(Client& c, const proto::Packet& packet, std::uint32_t slot) {
  if (!c.viewfinder || c.dead) return;
  if (c.held >= static_cast<std::uint32_t>(opt_.max_held_slots)) {
    ++c.dropped;  // it still holds every frame it may: it misses this one
    return;
  }
  switch (send_packet(c.fd.get(), packet)) {
    case SendResult::Sent:
      ring->hold(slot, c.id);
      ++c.held;
      ++c.sent;
      c.stalled = 0;
      break;
    case SendResult::WouldBlock:
      ++c.dropped;
      if (++c.stalled >= opt_.max_stalled_frames) mark_dead_locked(c, "stopped reading");
      break;
    case SendResult::Closed: mark_dead_locked(c, "connection closed"); break;
  }
}

}  // namespace propcam::capture::detail
