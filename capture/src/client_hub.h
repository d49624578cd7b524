// Internal to the capture module: what the capture daemon's camera thread
// and epoll thread share, under one mutex: the connected clients, the frame
// ring they map, and the camera's state and counters for status(). Never
// held across a camera call; when both are held, it comes before the
// CameraJobs mutex.
//
// A client's replies, events and rings must arrive: one whose socket cannot
// take them is marked dead (its slots and queued commands freed at once) and
// reaped, its fd closed, by the epoll thread only.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "camera_jobs.h"
#include "capture_socket.h"
#include "frame_ring.h"
#include "propcam/capture/capture_server.h"
#include "propcam/capture/frame.h"

namespace propcam::capture::detail {

struct Client {
  std::uint32_t id = 0;
  UniqueFd fd;
  bool viewfinder = false;
  bool dead = false;  // reaped (fd closed) by the epoll thread only
  std::uint32_t held = 0;
  std::uint64_t sent = 0;
  std::uint64_t dropped = 0;
  int stalled = 0;
  std::int64_t last_heard = 0;  // monotonic ns of its last packet or reply, for the idle timeout
};

class ClientHub {
 public:
  ClientHub(const CaptureServerOptions& opt, CameraJobs& jobs);

  // ---- guarded by mu
  mutable std::mutex mu;
  std::map<std::uint32_t, Client> clients;
  std::uint32_t next_client_id = 1;
  std::unique_ptr<FrameRing> ring;
  std::optional<CameraInfo> info;  // of the open camera

  // Wakes the epoll thread to reap dead clients; set before any client connects.
  std::function<void()> wake;

  // ---- clients, mu held
  void mark_dead_locked(Client& c, const std::string& why);
  void send_must_locked(Client& c, const protocol::Packet& packet, int fd = -1);
  void broadcast_locked(const protocol::Packet& packet, int fd = -1);

  // ---- clients, taking mu
  void reply(std::uint32_t client_id, const protocol::Packet& packet, int fd = -1);
  // A camera command's reply. Its place in the client's queue is freed
  // first: a client at its limit may send the next command as soon as it
  // has this answer.
  void answer(std::uint32_t client_id, const protocol::Packet& packet, int fd = -1);
  void broadcast_event(protocol::EventKind kind, const std::string& message);
  // Queues a camera command of client `id`; one over its limit is answered with an Error instead.
  void submit(std::uint32_t id, std::uint32_t rid, RequestQueue::Job job);
  void set_viewfinder(std::uint32_t id, bool on);
  bool anyone_wants_frames() const;
  void release(std::uint32_t id, std::uint32_t rid, const protocol::ReleaseSlot& m);
  protocol::Status status_snapshot(std::uint32_t you) const;

  // ---- the camera thread's news, taking mu
  std::string camera_id() const;
  void camera_opened(const std::string& id, const StreamConfig& in_use, CameraInfo camera,
                     std::size_t expected_frame_bytes);
  void stream_configured(const StreamConfig& in_use);
  void device_lost(const std::string& why);
  void set_state(protocol::DeviceState s);
  // Copies the frame into a free slot and offers it to every viewfinder.
  void publish(const Frame& frame);

  void log(const std::string& line) const {
    if (opt_.log) opt_.log(line);
  }

 private:
  void release_all_locked(Client& c);
  void replace_ring_locked(std::size_t frame_bytes);
  void ensure_ring_locked(std::size_t frame_bytes);
  void offer_locked(Client& c, const protocol::Packet& packet, std::uint32_t slot);

  const CaptureServerOptions& opt_;
  CameraJobs& jobs_;

  // ---- guarded by mu
  std::uint32_t next_generation_ = 1;
  std::string camera_id_;
  StreamConfig stream_in_use_;  // a copy of the camera thread's config, for status()
  protocol::DeviceState state_ = protocol::DeviceState::Closed;
  std::uint64_t frames_captured_ = 0;
  std::uint64_t frames_unplaced_ = 0;
  std::uint64_t device_lost_count_ = 0;
  std::deque<std::int64_t> arrivals_;  // the last second's frame times, for fps
};

}  // namespace propcam::capture::detail
