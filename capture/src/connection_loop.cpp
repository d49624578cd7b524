// The epoll thread's loop: connections come, are read from, idle out and go.
#include "connection_loop.h"

#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace propcam::capture::detail {
namespace {

namespace proto = protocol;

constexpr std::uint64_t kListenTag = 0;
constexpr std::uint64_t kWakeTag = 1;
constexpr std::uint64_t kClientTag = std::uint64_t{1} << 32;
constexpr int kPacketsPerWakeup = 64;  // then other clients get their turn
constexpr int kLoopWaitMs = 1000;       // the epoll thread's longest sleep

std::int64_t to_ns(std::chrono::milliseconds d) { return std::int64_t{d.count()} * 1'000'000; }

// "30 s", "200 ms": for messages.
std::string duration_text(std::chrono::milliseconds d) {
  return d.count() % 1000 == 0 ? std::to_string(d.count() / 1000) + " s" : std::to_string(d.count()) + " ms";
}

}  // namespace

ConnectionLoop::ConnectionLoop(const CaptureServerOptions& opt, ClientHub& hub, CameraJobs& jobs,
                               CameraThread& camera)
    : opt_(opt), hub_(hub), jobs_(jobs), camera_(camera) {}

void ConnectionLoop::open(int listen_fd) {
  listen_fd_ = listen_fd;
  epoll_fd_.reset(::epoll_create1(EPOLL_CLOEXEC));
  if (!epoll_fd_) throw_errno("epoll_create1");
  wake_fd_.reset(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC));
  if (!wake_fd_) throw_errno("eventfd");
  epoll_add(listen_fd_, kListenTag);
  epoll_add(wake_fd_.get(), kWakeTag);
}

void ConnectionLoop::wake() {
  const std::uint64_t one = 1;
  ssize_t n;
  do n = ::write(wake_fd_.get(), &one, sizeof one);
  while (n < 0 && errno == EINTR);  // EAGAIN: the counter is already non-zero, the loop wakes anyway
}

void ConnectionLoop::epoll_add(int fd, std::uint64_t tag) {
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.u64 = tag;
  if (::epoll_ctl(epoll_fd_.get(), EPOLL_CTL_ADD, fd, &ev) != 0) throw_errno("epoll_ctl add");
}

void ConnectionLoop::accept_clients() {
  for (;;) {
    UniqueFd fd(::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
    if (!fd) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) hub_.log(std::string("accept: ") + std::strerror(errno));
      return;
    }
    std::lock_guard lock(hub_.mu);
    close_idle_locked(monotonic_ns());  // a newcomer at a full server: idle places first
    if (static_cast<int>(hub_.clients.size()) >= opt_.max_clients) {
      send_packet(fd.get(), proto::encode_error(0, "too many clients"));
      continue;
    }
    const std::uint32_t id = hub_.next_client_id++;
    try {
      epoll_add(fd.get(), kClientTag | id);
    } catch (const std::exception& e) {
      hub_.log(e.what());
      continue;
    }
    Client& c = hub_.clients[id];
    c.id = id;
    c.fd = std::move(fd);
    c.last_heard = monotonic_ns();
    proto::Welcome w;
    w.client_id = id;
    w.max_held_slots = static_cast<std::uint32_t>(opt_.max_held_slots);
    if (hub_.ring) w.ring = hub_.ring->info();
    hub_.send_must_locked(c, proto::encode(0, w), hub_.ring ? hub_.ring->fd() : -1);
  }
}

void ConnectionLoop::reap_dead() {
  std::uint64_t count;
  ssize_t n;
  do n = ::read(wake_fd_.get(), &count, sizeof count);
  while (n < 0 && errno == EINTR);
  std::lock_guard lock(hub_.mu);
  for (auto it = hub_.clients.begin(); it != hub_.clients.end();) {
    if (it->second.dead) {
      ::epoll_ctl(epoll_fd_.get(), EPOLL_CTL_DEL, it->second.fd.get(), nullptr);
      it = hub_.clients.erase(it);  // closes the fd
    } else {
      ++it;
    }
  }
}

void ConnectionLoop::disconnect(std::uint32_t id, const std::string& why) {
  std::lock_guard lock(hub_.mu);
  disconnect_locked(id, why);
}

void ConnectionLoop::disconnect_locked(std::uint32_t id, const std::string& why) {
  const auto it = hub_.clients.find(id);
  if (it == hub_.clients.end()) return;
  hub_.mark_dead_locked(it->second, why);
  ::epoll_ctl(epoll_fd_.get(), EPOLL_CTL_DEL, it->second.fd.get(), nullptr);
  hub_.clients.erase(it);
}

void ConnectionLoop::serve_client(std::uint32_t id, std::uint32_t events) {
  int fd;
  {
    std::lock_guard lock(hub_.mu);
    const auto it = hub_.clients.find(id);
    if (it == hub_.clients.end() || it->second.dead) return;
    fd = it->second.fd.get();  // stays open: only this thread closes client fds
    if (events & EPOLLIN) it->second.last_heard = monotonic_ns();
  }
  if (events & EPOLLIN) {
    for (int i = 0; i < kPacketsPerWakeup; ++i) {
      Received r = recv_packet(fd, true);
      r.fd.reset();  // clients have no reason to send fds: closed before anything is answered
      if (r.kind == Received::Kind::WouldBlock) break;
      if (r.kind == Received::Kind::Closed) return disconnect(id, "disconnected");
      if (r.kind == Received::Kind::Truncated) {
        hub_.reply(id, proto::encode_error(0, "message larger than " + std::to_string(proto::kMaxMessageBytes)));
        return disconnect(id, "oversized message");
      }
      if (!handle_packet(id, r.bytes)) return disconnect(id, "protocol error");
    }
    return;
  }
  if (events & (EPOLLHUP | EPOLLERR)) disconnect(id, "hung up");
}

// While every place is taken, closes the connections silent for
// idle_timeout: they make room. Below the limit a quiet client keeps its
// connection (an appliance rendering for minutes, its viewfinder stopped).
// One waiting for a command of its own is not idle: its idle time starts
// again when it is answered.
void ConnectionLoop::close_idle() {
  const std::int64_t now = monotonic_ns(), limit = to_ns(opt_.idle_timeout);
  if (limit <= 0 || now < next_idle_check_) return;
  next_idle_check_ = now + limit;
  std::lock_guard lock(hub_.mu);
  close_idle_locked(now);
}

void ConnectionLoop::close_idle_locked(std::int64_t now) {
  const std::int64_t limit = to_ns(opt_.idle_timeout);
  if (limit <= 0 || static_cast<int>(hub_.clients.size()) < opt_.max_clients) return;
  std::vector<std::uint32_t> idle;
  for (auto& [id, c] : hub_.clients) {
    if (c.dead) continue;
    if (jobs_.pending(id) > 0) c.last_heard = now;
    if (now - c.last_heard >= limit) idle.push_back(id);
    else next_idle_check_ = std::min(next_idle_check_, c.last_heard + limit);
  }
  const std::string why = "idle for " + duration_text(opt_.idle_timeout);
  for (const std::uint32_t id : idle) {
    send_packet(hub_.clients.at(id).fd.get(), proto::encode_error(0, "connection closed: " + why));
    disconnect_locked(id, why);
  }
}

// Until the next idle check is due, at most kLoopWaitMs.
int ConnectionLoop::loop_wait_ms() const {
  if (opt_.idle_timeout.count() <= 0) return kLoopWaitMs;
  const std::int64_t left = next_idle_check_ - monotonic_ns();
  return static_cast<int>(std::clamp<std::int64_t>((left + 999'999) / 1'000'000, 0, kLoopWaitMs));
}

void ConnectionLoop::run() {
  epoll_event events[32];
  for (;;) {
    if (jobs_.stopping()) return;
    close_idle();
    const int n = ::epoll_wait(epoll_fd_.get(), events, 32, loop_wait_ms());
    if (n < 0) {
      if (errno == EINTR) continue;
      hub_.log(std::string("epoll_wait: ") + std::strerror(errno));
      return;
    }
    for (int i = 0; i < n; ++i) {
      const std::uint64_t tag = events[i].data.u64;
      if (tag == kListenTag) accept_clients();
      else if (tag == kWakeTag) reap_dead();
      else serve_client(static_cast<std::uint32_t>(tag & 0xffffffffu), events[i].events);
    }
  }
}

}  // namespace propcam::capture::detail
