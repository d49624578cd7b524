// propcamd's core: owns one camera (a FrameSource from a factory, so it can
// switch cameras and reopen one that was unplugged) and serves its frames to
// clients over a UNIX SOCK_SEQPACKET socket (capture_protocol.h).
//
// A camera thread copies each frame once into a free slot of a shared-memory
// ring and tells every client that wants the viewfinder; an epoll thread
// accepts clients and answers their commands. The camera never waits for a
// client: a slot a client still holds is never overwritten, a client holding
// its allowed slots misses frames (counted), a client whose socket is full
// misses frames and is dropped after a bound, and a client that goes away
// has its slots freed. Commands that touch the camera run on the camera
// thread between frames, taken from the clients in turn; a client has a
// bounded number of them waiting, they go when it does, and a connection
// that stays silent is closed (so idle connections cannot fill the server).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "propcam/capture/capture_protocol.h"
#include "propcam/capture/frame_source.h"

namespace propcam::capture {

// Opens a camera by id; throws (or returns null) when it cannot.
using FrameSourceFactory = std::function<std::unique_ptr<FrameSource>(const std::string& camera_id)>;

// Camera commands (select, configure, controls, still) one client may have
// queued or running; one more is answered with an Error and not queued.
inline constexpr int kMaxRequestsPerClient = 8;
// A connection that sends nothing for this long, with no command of its own
// queued or running, is closed.
inline constexpr std::chrono::milliseconds kIdleTimeout{30000};

struct CaptureServerOptions {
  std::string socket_path = "/run/propcam/capture.sock";
  std::string camera_id;
  StreamConfig stream;                // asked of every camera opened
  int ring_slots = 8;                 // frames in the shared ring
  int max_held_slots = 2;             // frames one client may hold at a time
  int max_stalled_frames = 32;        // frames in a row a full socket may miss before the client is dropped
  int max_clients = 64;
  int max_requests_per_client = kMaxRequestsPerClient;
  std::chrono::milliseconds idle_timeout = kIdleTimeout;  // 0: connections never time out
  std::chrono::milliseconds frame_timeout{100};   // next_frame's wait (commands run between frames)
  std::chrono::milliseconds reopen_backoff_min{100};
  std::chrono::milliseconds reopen_backoff_max{2000};
  std::string socket_group = "propcam";  // chowned to it when the group exists
  // What ListCameras answers; empty: the current camera only.
  std::function<std::vector<CameraInfo>()> list_cameras;
  // Where the server reports what it does (clients dropped, camera lost, ...).
  std::function<void(const std::string&)> log;
  // One-line camera state changes (open, lost, back), e.g. for a service
  // manager's status line. Called on the camera thread.
  std::function<void(const std::string&)> status;
  // Called on the camera thread at least every heartbeat_interval while it
  // runs (its waits are capped), so a watchdog fed from it notices a stuck
  // camera thread. Unset: no cap.
  std::function<void()> heartbeat;
  std::chrono::milliseconds heartbeat_interval{1000};
};

// Camera commands since start().
struct RequestCounts {
  std::uint64_t run = 0;      // run on the camera thread
  std::uint64_t refused = 0;  // over the client's limit: answered with an Error
  std::uint64_t dropped = 0;  // still queued when their client left: never run
};

class CaptureServer {
 public:
  CaptureServer(FrameSourceFactory factory, CaptureServerOptions options);
  ~CaptureServer();  // stop()
  CaptureServer(const CaptureServer&) = delete;
  CaptureServer& operator=(const CaptureServer&) = delete;

  // Binds the socket (mode 0660; a stale socket file nobody listens on is
  // replaced, a live one makes this throw) and starts both threads. The
  // camera is opened on the camera thread: a camera that cannot be opened
  // yet is retried with backoff, it does not fail start().
  void start();
  // Disconnects every client, closes the camera, removes the socket file.
  // Idempotent; safe from any thread except the server's own.
  void stop();
  bool running() const;
  // Blocks until stop() (from another thread or a signal handler's thread).
  void wait();

  protocol::Status status() const;
  RequestCounts request_counts() const;
  const std::string& socket_path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace propcam::capture
