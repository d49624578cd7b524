// Internal to the capture module: the capture daemon's camera thread. It
// owns the camera (a FrameSource from the factory): opens it, reopens it
// with backoff when it is lost, streams while any client wants the
// viewfinder, and between frames runs the clients' camera commands
// (select, configure, controls, stills), which CameraJobs queues for it.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "camera_jobs.h"
#include "client_hub.h"
#include "propcam/capture/capture_server.h"

namespace propcam::capture::detail {

class CameraThread {
 public:
  CameraThread(FrameSourceFactory factory, const CaptureServerOptions& opt, ClientHub& hub, CameraJobs& jobs);

  // The thread's body: until CameraJobs stops; closes the camera at the end.
  void run();

  // Commands, run on this thread (camera_commands.cpp); each answers its client.
  void select(std::uint32_t client_id, std::uint32_t rid, const std::string& camera);
  void configure(std::uint32_t client_id, std::uint32_t rid, StreamConfig c);
  void set_controls(std::uint32_t client_id, std::uint32_t rid, const CameraControls& c);
  void take_still(std::uint32_t client_id, std::uint32_t rid, const protocol::CaptureStillRequest& req);

 private:
  using Clock = std::chrono::steady_clock;

  void close_source();
  // Opens `id` and configures it; null on failure, with `error` set.
  std::unique_ptr<FrameSource> open_source(const std::string& id, std::string& error);
  void adopt_source(std::unique_ptr<FrameSource> s, const std::string& id);
  void try_reopen();
  void lose_device(const std::string& why);
  // Starts or stops the stream to match whether any client wants frames.
  void sync_streaming();
  void capture_once();
  void report_status(const std::string& line) const;
  // A wait's end, capped so the heartbeat keeps beating while the thread idles.
  Clock::time_point capped(Clock::time_point until) const;

  protocol::Packet do_select(std::uint32_t rid, const std::string& id);
  protocol::Packet do_configure(std::uint32_t rid, StreamConfig c);
  protocol::Packet do_controls(std::uint32_t rid, const CameraControls& c);

  FrameSourceFactory factory_;
  const CaptureServerOptions& opt_;
  ClientHub& hub_;
  CameraJobs& jobs_;

  std::unique_ptr<FrameSource> source_;
  StreamConfig config_;
  CameraControls controls_;  // reapplied when the camera comes back
  bool ended_ = false;
  bool resume_pending_ = false;
  std::chrono::milliseconds backoff_{0};
  Clock::time_point next_open_{};
};

}  // namespace propcam::capture::detail
