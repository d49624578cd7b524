#include "request_queue.h"

#include <algorithm>
#include <stdexcept>
#include <tuple>

namespace propcam::capture::detail {

RequestQueue::RequestQueue(std::size_t per_client_limit) : limit_(per_client_limit) {
  if (limit_ < 1) throw std::invalid_argument("RequestQueue: the per-client limit must be >= 1");
}

bool RequestQueue::push(ClientId client, Job job) {
  PerClient& c = clients_[client];
  if (c.waiting.size() + c.running >= limit_) return false;
  c.waiting.push_back(Waiting{++arrivals_, std::move(job)});
  ++queued_;
  return true;
}

std::optional<RequestQueue::Next> RequestQueue::pop() {
  // A linear scan: the server has at most a few dozen clients.
  auto best = clients_.end();
  for (auto it = clients_.begin(); it != clients_.end(); ++it) {
    if (it->second.waiting.empty()) continue;
    const auto key = [](const PerClient& c) { return std::tuple(c.served_at, c.waiting.front().order); };
    if (best == clients_.end() || key(it->second) < key(best->second)) best = it;
  }
  if (best == clients_.end()) return std::nullopt;
  PerClient& c = best->second;
  Next next{best->first, std::move(c.waiting.front().job)};
  c.waiting.pop_front();
  --queued_;
  ++c.running;
  c.served_at = ++pops_;
  return next;
}

void RequestQueue::done(ClientId client) {
  const auto it = clients_.find(client);
  if (it != clients_.end() && it->second.running > 0) --it->second.running;
}

std::size_t RequestQueue::drop(ClientId client) {
  const auto it = clients_.find(client);
  if (it == clients_.end()) return 0;
  const std::size_t dropped = it->second.waiting.size();
  queued_ -= dropped;
  clients_.erase(it);
  return dropped;
}

std::size_t RequestQueue::pending(ClientId client) const {
  const auto it = clients_.find(client);
  return it == clients_.end() ? 0 : it->second.waiting.size() + it->second.running;
}

}  // namespace propcam::capture::detail
