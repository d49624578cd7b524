// Internal to the capture module: the capture daemon's epoll thread. It
// accepts clients (up to max_clients), reads their packets, answers what
// needs no camera and hands camera commands to the camera thread, closes
// connections that break the protocol or stay idle while the server is
// full, and reaps the clients the other thread marked dead.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "camera_jobs.h"
#include "camera_thread.h"
#include "capture_socket.h"
#include "client_hub.h"
#include "propcam/capture/capture_server.h"

namespace propcam::capture::detail {

class ConnectionLoop {
 public:
  ConnectionLoop(const CaptureServerOptions& opt, ClientHub& hub, CameraJobs& jobs, CameraThread& camera);

  // Creates the epoll set and the wake-up eventfd, watching `listen_fd`.
  void open(int listen_fd);
  bool is_open() const { return static_cast<bool>(wake_fd_); }
  // Any thread: the loop wakes to reap dead clients and look at stopping.
  void wake();
  // The thread's body: until CameraJobs stops.
  void run();

 private:
  void epoll_add(int fd, std::uint64_t tag);
  void accept_clients();
  void reap_dead();
  void disconnect(std::uint32_t id, const std::string& why);
  void disconnect_locked(std::uint32_t id, const std::string& why);
  void serve_client(std::uint32_t id, std::uint32_t events);
  void close_idle();
  void close_idle_locked(std::int64_t now);
  int loop_wait_ms() const;

  // The protocol (client_requests.cpp). False when the framing is broken
  // and the client must go.
  bool handle_packet(std::uint32_t id, const std::vector<std::uint8_t>& bytes);
  void dispatch(std::uint32_t id, const protocol::Header& h, protocol::Payload p);
  protocol::Packet list_reply(std::uint32_t rid);

  const CaptureServerOptions& opt_;
  ClientHub& hub_;
  CameraJobs& jobs_;
  CameraThread& camera_;

  int listen_fd_ = -1;
  UniqueFd epoll_fd_, wake_fd_;
  std::int64_t next_idle_check_ = 0;
};

}  // namespace propcam::capture::detail
