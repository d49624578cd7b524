// Internal to the capture module: the daemon's camera-thread work (select,
// configure, controls, stills), queued per client and served round-robin, so
// a client that sends a burst delays another client's request by about one
// request, not by the whole burst, and a client's work goes when it does.
//
// Round-robin here means "the client served longest ago goes next": clients
// that keep requests waiting take turns, and a client arriving with one
// request goes before everyone served since. Not thread-safe (the server
// guards it with its job mutex).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>

namespace propcam::capture::detail {

class RequestQueue {
 public:
  using Job = std::function<void()>;
  using ClientId = std::uint32_t;

  // At most `per_client_limit` (>= 1) requests of one client queued or running.
  explicit RequestQueue(std::size_t per_client_limit);

  std::size_t limit() const { return limit_; }
  // Queues `job` for `client`; false, and nothing queued, when the client
  // already has `limit()` requests queued or running.
  bool push(ClientId client, Job job);

  struct Next {
    ClientId client = 0;
    Job job;
  };
  // The next job; it counts as running for its client until done(client).
  std::optional<Next> pop();
  // The client's running job has ended (a dropped client's is ignored).
  void done(ClientId client);
  // Forgets the client: its queued jobs are discarded unrun. Returns how many.
  std::size_t drop(ClientId client);

  bool empty() const { return queued_ == 0; }  // nothing waiting to run
  std::size_t queued() const { return queued_; }
  // The client's requests queued or running.
  std::size_t pending(ClientId client) const;

 private:
  struct Waiting {
    std::uint64_t order = 0;  // arrival, across clients: ties go to the older request
    Job job;
  };
  struct PerClient {
    std::deque<Waiting> waiting;
    std::size_t running = 0;
    std::uint64_t served_at = 0;  // pop count when it was last served; 0: never
  };

  std::size_t limit_;
  std::map<ClientId, PerClient> clients_;  // until drop(): a client keeps its place in the turns
  std::size_t queued_ = 0;
  std::uint64_t arrivals_ = 0;
  std::uint64_t pops_ = 0;
};

}  // namespace propcam::capture::detail
