// ClientHub's client side: connections, replies, commands and status.
#include "client_hub.h"

#include <algorithm>

namespace propcam::capture::detail {

namespace proto = protocol;

ClientHub::ClientHub(const CaptureServerOptions& opt, CameraJobs& jobs)
    : opt_(opt), jobs_(jobs), camera_id_(opt.camera_id), stream_in_use_(opt.stream) {}

void ClientHub::release_all_locked(Client& c) {
  if (ring) ring->release_all(c.id);
  c.held = 0;
}

void ClientHub::mark_dead_locked(Client& c, const std::string& why) {
  if (c.dead) return;
  c.dead = true;
  c.viewfinder = false;
  release_all_locked(c);
  jobs_.drop(c.id);
  log("client " + std::to_string(c.id) + " gone: " + why);
  wake();
}

void ClientHub::send_must_locked(Client& c, const proto::Packet& packet, int fd) {
  if (c.dead) return;
  const SendResult r = send_packet(c.fd.get(), packet, fd);
  if (r == SendResult::WouldBlock) mark_dead_locked(c, "socket full");
  else if (r == SendResult::Closed) mark_dead_locked(c, "connection closed");
}

void ClientHub::broadcast_locked(const proto::Packet& packet, int fd) {
  for (auto& [id, c] : clients) send_must_locked(c, packet, fd);
}

void ClientHub::reply(std::uint32_t client_id, const proto::Packet& packet, int fd) {
  std::lock_guard lock(mu);
  const auto it = clients.find(client_id);
  if (it == clients.end()) return;
  it->second.last_heard = monotonic_ns();  // its idle time starts when it has its answer
  send_must_locked(it->second, packet, fd);
}

void ClientHub::answer(std::uint32_t client_id, const proto::Packet& packet, int fd) {
  jobs_.done(client_id);
  reply(client_id, packet, fd);
}

void ClientHub::broadcast_event(proto::EventKind kind, const std::string& message) {
  std::lock_guard lock(mu);
  broadcast_locked(proto::encode(proto::Event{kind, message}));
}

void ClientHub::submit(std::uint32_t id, std::uint32_t rid, RequestQueue::Job job) {
  std::lock_guard lock(mu);
  const auto it = clients.find(id);
  if (it == clients.end() || it->second.dead) return;  // gone: its commands are dropped
  if (jobs_.submit(id, std::move(job))) return;
  send_must_locked(it->second, proto::encode_error(rid, "too many requests: at most " +
                                                            std::to_string(opt_.max_requests_per_client) +
                                                            " camera commands queued or running per client"));
}

void ClientHub::set_viewfinder(std::uint32_t id, bool on) {
  std::lock_guard lock(mu);
  const auto it = clients.find(id);
  if (it != clients.end()) it->second.viewfinder = on;
}

bool ClientHub::anyone_wants_frames() const {
  std::lock_guard lock(mu);
  return std::any_of(clients.begin(), clients.end(),
                     [](const auto& kv) { return kv.second.viewfinder && !kv.second.dead; });
}

void ClientHub::release(std::uint32_t id, std::uint32_t rid, const proto::ReleaseSlot& m) {
  std::lock_guard lock(mu);
  const auto it = clients.find(id);
  if (it == clients.end() || it->second.dead) return;
  Client& c = it->second;
  if (!ring || m.generation != ring->info().generation) return;  // a frame of an old ring: nothing to free
  switch (ring->release(m.slot, id)) {
    case FrameRing::Release::OutOfRange:
      return send_must_locked(c, proto::encode_error(rid, "slot index out of range"));
    case FrameRing::Release::NotHeld: return send_must_locked(c, proto::encode_error(rid, "slot not held"));
    case FrameRing::Release::Released: --c.held; return;
  }
}

proto::Status ClientHub::status_snapshot(std::uint32_t you) const {
  std::lock_guard lock(mu);
  proto::Status s;
  s.camera_id = camera_id_;
  s.stream = stream_in_use_;
  s.device_state = state_;
  const std::int64_t now = monotonic_ns();
  s.fps = static_cast<double>(
      std::count_if(arrivals_.begin(), arrivals_.end(), [&](std::int64_t t) { return t > now - 1'000'000'000; }));
  s.frames_captured = frames_captured_;
  s.frames_unplaced = frames_unplaced_;
  s.device_lost_count = device_lost_count_;
  s.you = you;
  for (const auto& [id, c] : clients) {
    if (c.dead) continue;
    if (s.clients.size() >= proto::kMaxListItems) break;
    s.clients.push_back(proto::ClientStatus{c.id, c.sent, c.dropped, c.held, c.viewfinder});
  }
  return s;
}

}  // namespace propcam::capture::detail
