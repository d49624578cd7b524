// Internal to the capture module: the camera commands waiting for the
// capture daemon's camera thread (a RequestQueue: per client, in turn), the
// counts request_counts() reports, and the flag that stops both threads.
// Its mutex comes after the client mutex: ClientHub calls in with its own held.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>

#include "propcam/capture/capture_server.h"
#include "request_queue.h"

namespace propcam::capture::detail {

class CameraJobs {
 public:
  using Clock = std::chrono::steady_clock;

  explicit CameraJobs(std::size_t per_client_limit) : requests_(per_client_limit) {}

  // Queues a command of `client` and wakes the camera thread; false, counted
  // as refused, when the client already has its limit queued or running.
  bool submit(std::uint32_t client, RequestQueue::Job job);
  // The client's running command is answered: it may queue the next one.
  void done(std::uint32_t client);
  // The client is gone: its queued commands are dropped unrun (and counted).
  void drop(std::uint32_t client);
  // Commands of `client` queued or running.
  std::size_t pending(std::uint32_t client) const;
  // Wakes the camera thread to look at the clients again (viewfinders).
  void nudge();

  // Camera thread: runs queued commands, the clients in turn; first waits
  // until `until` unless there is work. False once stopping.
  bool run_or_wait(std::optional<Clock::time_point> until);

  // False when already stopping; wakes the camera thread otherwise.
  bool request_stop();
  bool stopping() const;
  RequestCounts counts() const;

 private:
  mutable std::mutex mu_;
  std::condition_variable cv_;
  RequestQueue requests_;
  RequestCounts counts_;
  bool nudged_ = false;
  bool stopping_ = false;
};

}  // namespace propcam::capture::detail
