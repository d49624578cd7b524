#include "propcam/capture/capture_server.h"

#include <grp.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "capture_socket.h"
#include "frame_ring.h"
#include "listening_socket.h"
#include "propcam/capture/frame.h"
#include "request_queue.h"

namespace propcam::capture {
namespace {

using detail::FrameRing;
using detail::Mapping;
using detail::monotonic_ns;
using detail::Received;
using detail::SendResult;
using detail::UniqueFd;
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

const char* status_name(CaptureStatus s) {
  switch (s) {
    case CaptureStatus::Ok: return "ok";
    case CaptureStatus::Timeout: return "timeout";
    case CaptureStatus::DeviceLost: return "device lost";
    case CaptureStatus::EndOfStream: return "end of stream";
  }
  return "unknown";
}

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

}  // namespace

struct CaptureServer::Impl {
  FrameSourceFactory factory;
  CaptureServerOptions opt;

  // Clients, the ring and the statistics; never held across a camera call.
  mutable std::mutex mu;
  std::map<std::uint32_t, Client> clients;
  std::uint32_t next_client_id = 1;
  std::unique_ptr<FrameRing> ring;
  std::uint32_t next_generation = 1;
  std::string camera_id;
  StreamConfig stream_in_use;  // a copy of `config` for status()
  std::optional<CameraInfo> info;
  proto::DeviceState state = proto::DeviceState::Closed;
  std::uint64_t frames_captured = 0;
  std::uint64_t frames_unplaced = 0;
  std::uint64_t device_lost_count = 0;
  std::deque<std::int64_t> arrivals;  // the last second's frame times, for fps

  // Work for the camera thread; lock order: mu before job_mu.
  std::mutex job_mu;
  std::condition_variable job_cv;
  detail::RequestQueue requests{kMaxRequestsPerClient};  // sized from the options by the constructor
  RequestCounts counts;
  bool nudged = false;
  bool stopping = false;

  // Owned by the camera thread.
  std::unique_ptr<FrameSource> source;
  StreamConfig config;
  CameraControls controls;  // reapplied when the camera comes back
  bool ended = false;
  bool resume_pending = false;
  std::chrono::milliseconds backoff{0};
  std::chrono::steady_clock::time_point next_open{};

  detail::ListeningSocket listener;
  UniqueFd epoll_fd, wake_fd;
  std::thread camera_thread, loop_thread;
  std::int64_t next_idle_check = 0;  // epoll thread only
  bool started = false;

  std::mutex life_mu;
  std::condition_variable life_cv;
  bool stopped = false;

  void log(const std::string& line) const {
    if (opt.log) opt.log(line);
  }

  void wake_loop() {
    const std::uint64_t one = 1;
    ssize_t n;
    do n = ::write(wake_fd.get(), &one, sizeof one);
    while (n < 0 && errno == EINTR);  // EAGAIN: the counter is already non-zero, the loop wakes anyway
  }

  // ---- clients (mu held) ----------------------------------------------------

  void release_all_locked(Client& c) {
    if (ring) ring->release_all(c.id);
    c.held = 0;
  }

  void mark_dead_locked(Client& c, const std::string& why) {
    if (c.dead) return;
    c.dead = true;
    c.viewfinder = false;
    release_all_locked(c);
    {
      std::lock_guard jobs_lock(job_mu);
      counts.dropped += requests.drop(c.id);  // nobody to answer; a running one's reply goes nowhere
    }
    log("client " + std::to_string(c.id) + " gone: " + why);
    wake_loop();
  }

  // Replies, events and rings must arrive: a client whose socket cannot take
  // one is dropped rather than queued for.
  void send_must_locked(Client& c, const proto::Packet& packet, int fd = -1) {
    if (c.dead) return;
    const SendResult r = detail::send_packet(c.fd.get(), packet, fd);
    if (r == SendResult::WouldBlock) mark_dead_locked(c, "socket full");
    else if (r == SendResult::Closed) mark_dead_locked(c, "connection closed");
  }

  void reply(std::uint32_t client_id, const proto::Packet& packet, int fd = -1) {
    std::lock_guard lock(mu);
    const auto it = clients.find(client_id);
    if (it == clients.end()) return;
    it->second.last_heard = monotonic_ns();  // its idle time starts when it has its answer
    send_must_locked(it->second, packet, fd);
  }

  // A camera command's reply. Its place in the client's queue is freed first:
  // a client at its limit may send the next command as soon as it has this answer.
  void answer(std::uint32_t client_id, const proto::Packet& packet, int fd = -1) {
    {
      std::lock_guard lock(job_mu);
      requests.done(client_id);
    }
    reply(client_id, packet, fd);
  }

  void broadcast_locked(const proto::Packet& packet, int fd = -1) {
    for (auto& [id, c] : clients) send_must_locked(c, packet, fd);
  }

  void broadcast_event(proto::EventKind kind, const std::string& message) {
    std::lock_guard lock(mu);
    broadcast_locked(proto::encode(proto::Event{kind, message}));
  }

  bool anyone_wants_frames() const {
    std::lock_guard lock(mu);
    return std::any_of(clients.begin(), clients.end(),
                       [](const auto& kv) { return kv.second.viewfinder && !kv.second.dead; });
  }

  // ---- ring (camera thread, mu held) ------------------------------------------

  void replace_ring_locked(std::size_t frame_bytes) {
    ring = std::make_unique<FrameRing>(next_generation++, opt.ring_slots, frame_bytes);
    // Holds were on the old ring; clients keep their own mapping of it.
    for (auto& [id, c] : clients) c.held = 0;
    broadcast_locked(proto::encode_ring_changed(ring->info()), ring->fd());
  }

  void ensure_ring_locked(std::size_t frame_bytes) {
    if (!ring || ring->info().slot_bytes < frame_bytes) replace_ring_locked(frame_bytes);
  }

  // ---- camera thread ----------------------------------------------------------

  void publish(const Frame& frame) {
    const auto bytes = frame.data();
    std::uint32_t slot;
    FrameRing* target;
    {
      std::lock_guard lock(mu);
      ++frames_captured;
      const std::int64_t now = monotonic_ns();
      arrivals.push_back(now);
      while (!arrivals.empty() && arrivals.front() <= now - 1'000'000'000) arrivals.pop_front();
      ensure_ring_locked(bytes.size());
      const auto free = ring->claim_free_slot();
      if (!free) {
        ++frames_unplaced;
        for (auto& [id, c] : clients)
          if (c.viewfinder && !c.dead) ++c.dropped;
        return;
      }
      slot = *free;
      target = ring.get();  // only this thread replaces the ring
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

  void offer_locked(Client& c, const proto::Packet& packet, std::uint32_t slot) {
    if (!c.viewfinder || c.dead) return;
    if (c.held >= static_cast<std::uint32_t>(opt.max_held_slots)) {
      ++c.dropped;  // it still holds every frame it may: it misses this one
      return;
    }
    switch (detail::send_packet(c.fd.get(), packet)) {
      case SendResult::Sent:
        ring->hold(slot, c.id);
        ++c.held;
        ++c.sent;
        c.stalled = 0;
        break;
      case SendResult::WouldBlock:
        ++c.dropped;
        if (++c.stalled >= opt.max_stalled_frames) mark_dead_locked(c, "stopped reading");
        break;
      case SendResult::Closed: mark_dead_locked(c, "connection closed"); break;
    }
  }

  void set_state(proto::DeviceState s) {
    std::lock_guard lock(mu);
    state = s;
  }

  void close_source() {
    if (!source) return;
    try {
      if (source->running()) source->stop();
    } catch (const std::exception& e) {
      log(std::string("stopping the camera: ") + e.what());
    }
    source.reset();
  }

  // Opens `id`, configures it and reapplies the controls; null on failure.
  std::unique_ptr<FrameSource> open_source(const std::string& id, std::string& error) {
    try {
      auto s = factory(id);
      if (!s) {
        error = "no camera " + id;
        return nullptr;
      }
      StreamConfig c = config;
      if (s->configure(c) != ConfigStatus::Invalid) config = c;
      return s;
    } catch (const std::exception& e) {
      error = e.what();
      return nullptr;
    }
  }

  void adopt_source(std::unique_ptr<FrameSource> s, const std::string& id) {
    source = std::move(s);
    ended = false;
    CameraInfo camera = source->info();
    const std::size_t expected = detail::expected_frame_bytes(source->configuration());

    const StreamConfig in_use = source->configuration();
    std::lock_guard lock(mu);
    camera_id = id;
    stream_in_use = in_use;
    info = std::move(camera);
    state = proto::DeviceState::Idle;
    ensure_ring_locked(expected);
  }

  void try_reopen() {
    std::string id;
    {
      std::lock_guard lock(mu);
      id = camera_id;
    }
    std::string error;
    auto s = open_source(id, error);
    if (!s) {
      backoff = std::clamp(backoff * 2, opt.reopen_backoff_min, opt.reopen_backoff_max);
      next_open = std::chrono::steady_clock::now() + backoff;
      return;
    }
    try {
      if (controls.exposure_us || controls.analogue_gain || controls.colour_gain_red || controls.colour_gain_blue ||
          controls.auto_exposure || controls.auto_white_balance)
        s->set_controls(controls);
      adopt_source(std::move(s), id);
    } catch (const std::exception& e) {
      log(std::string("reopening the camera: ") + e.what());
      source.reset();
      next_open = std::chrono::steady_clock::now() + backoff;
      return;
    }
    backoff = opt.reopen_backoff_min / 2;
    log("camera " + id + " open");
    report_status(resume_pending ? "camera " + id + " is back" : "camera " + id + " open");
    if (resume_pending) {
      resume_pending = false;
      broadcast_event(proto::EventKind::Resumed, "camera " + id + " is back");
    }
  }

  void lose_device(const std::string& why) {
    log("camera lost: " + why);
    report_status("camera lost: " + why);
    close_source();
    {
      std::lock_guard lock(mu);
      state = proto::DeviceState::Lost;
      ++device_lost_count;
      broadcast_locked(proto::encode(proto::Event{proto::EventKind::DeviceLost, why}));
    }
    resume_pending = true;
    backoff = opt.reopen_backoff_min;
    next_open = std::chrono::steady_clock::now() + backoff;
  }

  // Starts or stops the stream to match whether any client wants frames.
  void sync_streaming() {
    const bool want = anyone_wants_frames() && !ended;
    try {
      if (want && !source->running()) {
        source->start();
        set_state(proto::DeviceState::Streaming);
      } else if (!want && source->running()) {
        source->stop();
        set_state(ended ? proto::DeviceState::Ended : proto::DeviceState::Idle);
      }
    } catch (const std::exception& e) {
      lose_device(e.what());
    }
  }

  void capture_once() {
    CaptureResult r;
    try {
      r = source->next_frame(opt.frame_timeout);
    } catch (const std::exception& e) {
      r.status = CaptureStatus::DeviceLost;
      r.message = e.what();
    }
    switch (r.status) {
      case CaptureStatus::Ok:
        try {
          if (r.frame) publish(*r.frame);
        } catch (const std::exception& e) {
          log(std::string("cannot share a frame: ") + e.what());  // e.g. no memory for a bigger ring
        }
        break;
      case CaptureStatus::Timeout: break;
      case CaptureStatus::DeviceLost: lose_device(r.message.empty() ? "device lost" : r.message); break;
      case CaptureStatus::EndOfStream:
        ended = true;
        try {
          source->stop();
        } catch (const std::exception&) {
        }
        set_state(proto::DeviceState::Ended);
        broadcast_event(proto::EventKind::EndOfStream, r.message);
        break;
    }
  }

  // Runs queued commands, the clients in turn; then waits until `until` unless there is work.
  bool run_jobs_or_wait(std::optional<std::chrono::steady_clock::time_point> until) {
    std::unique_lock lock(job_mu);
    if (until && requests.empty() && !nudged && !stopping) {
      job_cv.wait_until(lock, *until, [&] { return !requests.empty() || nudged || stopping; });
    }
    nudged = false;
    while (!stopping) {
      auto next = requests.pop();
      if (!next) break;
      ++counts.run;
      lock.unlock();
      next->job();
      lock.lock();
      requests.done(next->client);  // a no-op when the job answered (one job of a client runs at a time)
    }
    return !stopping;
  }

  void report_status(const std::string& line) const {
    if (opt.status) opt.status(line);
  }

  // A wait's end, capped so the heartbeat keeps beating while the thread idles.
  std::chrono::steady_clock::time_point capped(std::chrono::steady_clock::time_point until) const {
    if (!opt.heartbeat) return until;
    return std::min(until, std::chrono::steady_clock::now() + opt.heartbeat_interval);
  }

  void camera_loop() {
    backoff = opt.reopen_backoff_min / 2;
    next_open = std::chrono::steady_clock::now();
    try_reopen();  // before any command: those sent right after connecting find the camera open
    while (run_jobs_or_wait(std::nullopt)) {
      if (opt.heartbeat) opt.heartbeat();
      const auto now = std::chrono::steady_clock::now();
      if (!source) {
        if (now >= next_open) try_reopen();
        if (!source) run_jobs_or_wait(capped(next_open));
        continue;
      }
      sync_streaming();
      if (source && source->running()) capture_once();
      else run_jobs_or_wait(capped(now + std::chrono::milliseconds(500)));
    }
    close_source();
  }

  // Queues a camera command of client `id`; one over its limit is answered with an Error instead.
  void submit(std::uint32_t id, std::uint32_t rid, std::function<void()> job) {
    std::lock_guard lock(mu);
    const auto it = clients.find(id);
    if (it == clients.end() || it->second.dead) return;  // gone: its commands are dropped
    bool queued;
    {
      std::lock_guard jobs_lock(job_mu);
      queued = requests.push(id, std::move(job));
      if (!queued) ++counts.refused;
    }
    if (queued) return job_cv.notify_one();
    send_must_locked(it->second, proto::encode_error(rid, "too many requests: at most " +
                                                              std::to_string(opt.max_requests_per_client) +
                                                              " camera commands queued or running per client"));
  }

  void nudge() {
    {
      std::lock_guard lock(job_mu);
      nudged = true;
    }
    job_cv.notify_one();
  }

  // ---- commands run on the camera thread --------------------------------------

  proto::Packet do_select(std::uint32_t rid, const std::string& id) {
    std::string error;
    auto s = open_source(id, error);
    if (!s) return proto::encode_error(rid, "cannot open " + id + ": " + error);
    close_source();
    controls = CameraControls{};
    try {
      adopt_source(std::move(s), id);
    } catch (const std::exception& e) {
      source.reset();
      set_state(proto::DeviceState::Lost);
      return proto::encode_error(rid, std::string("camera failed: ") + e.what());
    }
    if (resume_pending) {
      resume_pending = false;
      broadcast_event(proto::EventKind::Resumed, "camera " + id + " selected");
    }
    return proto::encode(proto::MessageType::Ok, rid);
  }

  proto::Packet do_configure(std::uint32_t rid, StreamConfig c) {
    if (!source) return proto::encode_error(rid, "no camera open");
    try {
      if (source->running()) source->stop();  // restarted by sync_streaming
      const ConfigStatus status = source->configure(c);
      if (status != ConfigStatus::Invalid) {
        config = c;
        ended = false;
        std::lock_guard lock(mu);
        stream_in_use = c;
        state = proto::DeviceState::Idle;
      }
      return proto::encode(rid, proto::ConfigureReply{status, c});
    } catch (const std::exception& e) {
      return proto::encode_error(rid, std::string("configure: ") + e.what());
    }
  }

  proto::Packet do_controls(std::uint32_t rid, const CameraControls& c) {
    if (!source) return proto::encode_error(rid, "no camera open");
    try {
      const auto not_applied = source->set_controls(c);
      auto merge = [](auto& into, const auto& from) {
        if (from) into = from;
      };
      merge(controls.exposure_us, c.exposure_us);
      merge(controls.analogue_gain, c.analogue_gain);
      merge(controls.colour_gain_red, c.colour_gain_red);
      merge(controls.colour_gain_blue, c.colour_gain_blue);
      merge(controls.auto_exposure, c.auto_exposure);
      merge(controls.auto_white_balance, c.auto_white_balance);
      return proto::encode_controls_reply(rid, not_applied);
    } catch (const std::exception& e) {
      return proto::encode_error(rid, std::string("set controls: ") + e.what());
    }
  }

  void do_still(std::uint32_t client_id, std::uint32_t rid, const proto::CaptureStillRequest& req) {
    if (!source) return answer(client_id, proto::encode_error(rid, "no camera open"));
    CaptureResult r;
    try {
      r = source->capture_still(req.config, std::chrono::milliseconds(req.timeout_ms));
    } catch (const std::exception& e) {
      return answer(client_id, proto::encode_error(rid, std::string("still: ") + e.what()));
    }
    if (r.status != CaptureStatus::Ok || !r.frame) {
      proto::StillFrame failed;
      failed.status = r.status == CaptureStatus::Ok ? CaptureStatus::Timeout : r.status;
      failed.message = r.message.empty() ? std::string(status_name(failed.status)) : r.message;
      answer(client_id, proto::encode(rid, failed));
      if (r.status == CaptureStatus::DeviceLost) lose_device(failed.message);
      return;
    }
    try {
      const auto bytes = r.frame->data();
      const std::size_t size = detail::round_to_page(bytes.size());
      UniqueFd fd = detail::make_memfd("propcam-still", size);
      {
        Mapping map(fd.get(), size, true);
        std::memcpy(map.data(), bytes.data(), bytes.size());
      }
      detail::seal_future_writes(fd.get());
      proto::StillFrame m;
      m.bytes_used = bytes.size();
      m.memfd_bytes = size;
      m.format = r.frame->format;
      m.metadata = r.frame->metadata;
      answer(client_id, proto::encode(rid, m), fd.get());
    } catch (const std::exception& e) {
      answer(client_id, proto::encode_error(rid, std::string("still: ") + e.what()));
    }
  }

  // ---- epoll thread -------------------------------------------------------------

  void epoll_add(int fd, std::uint64_t tag) {
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = tag;
    if (::epoll_ctl(epoll_fd.get(), EPOLL_CTL_ADD, fd, &ev) != 0) detail::throw_errno("epoll_ctl add");
  }

  void accept_clients() {
    for (;;) {
      UniqueFd fd(::accept4(listener.fd(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
      if (!fd) {
        if (errno == EINTR || errno == ECONNABORTED) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK) log(std::string("accept: ") + std::strerror(errno));
        return;
      }
      std::lock_guard lock(mu);
      close_idle_locked(monotonic_ns());  // a newcomer at a full server: idle places first
      if (static_cast<int>(clients.size()) >= opt.max_clients) {
        detail::send_packet(fd.get(), proto::encode_error(0, "too many clients"));
        continue;
      }
      const std::uint32_t id = next_client_id++;
      try {
        epoll_add(fd.get(), kClientTag | id);
      } catch (const std::exception& e) {
        log(e.what());
        continue;
      }
      Client& c = clients[id];
      c.id = id;
      c.fd = std::move(fd);
      c.last_heard = monotonic_ns();
      proto::Welcome w;
      w.client_id = id;
      w.max_held_slots = static_cast<std::uint32_t>(opt.max_held_slots);
      if (ring) w.ring = ring->info();
      send_must_locked(c, proto::encode(0, w), ring ? ring->fd() : -1);
    }
  }

  void reap_dead() {
    std::uint64_t count;
    ssize_t n;
    do n = ::read(wake_fd.get(), &count, sizeof count);
    while (n < 0 && errno == EINTR);
    std::lock_guard lock(mu);
    for (auto it = clients.begin(); it != clients.end();) {
      if (it->second.dead) {
        ::epoll_ctl(epoll_fd.get(), EPOLL_CTL_DEL, it->second.fd.get(), nullptr);
        it = clients.erase(it);  // closes the fd
      } else {
        ++it;
      }
    }
  }

  void disconnect(std::uint32_t id, const std::string& why) {
    std::lock_guard lock(mu);
    disconnect_locked(id, why);
  }

  void disconnect_locked(std::uint32_t id, const std::string& why) {
    const auto it = clients.find(id);
    if (it == clients.end()) return;
    mark_dead_locked(it->second, why);
    ::epoll_ctl(epoll_fd.get(), EPOLL_CTL_DEL, it->second.fd.get(), nullptr);
    clients.erase(it);
  }

  void serve_client(std::uint32_t id, std::uint32_t events) {
    int fd;
    {
      std::lock_guard lock(mu);
      const auto it = clients.find(id);
      if (it == clients.end() || it->second.dead) return;
      fd = it->second.fd.get();  // stays open: only this thread closes client fds
      if (events & EPOLLIN) it->second.last_heard = monotonic_ns();
    }
    if (events & EPOLLIN) {
      for (int i = 0; i < kPacketsPerWakeup; ++i) {
        Received r = detail::recv_packet(fd, true);
        r.fd.reset();  // clients have no reason to send fds: closed before anything is answered
        if (r.kind == Received::Kind::WouldBlock) break;
        if (r.kind == Received::Kind::Closed) return disconnect(id, "disconnected");
        if (r.kind == Received::Kind::Truncated) {
          reply(id, proto::encode_error(0, "message larger than " + std::to_string(proto::kMaxMessageBytes)));
          return disconnect(id, "oversized message");
        }
        if (!handle_packet(id, r.bytes)) return disconnect(id, "protocol error");
      }
      return;
    }
    if (events & (EPOLLHUP | EPOLLERR)) disconnect(id, "hung up");
  }

  // False when the framing is broken and the client must go.
  bool handle_packet(std::uint32_t id, const std::vector<std::uint8_t>& bytes) {
    proto::Header h;
    try {
      h = proto::decode_header(bytes.data(), bytes.size());
    } catch (const proto::ProtocolError& e) {
      reply(id, proto::encode_error(0, e.what()));
      return false;
    }
    const proto::Payload p = proto::payload_of(bytes.data(), bytes.size());
    try {
      dispatch(id, h, p);
    } catch (const proto::ProtocolError& e) {
      reply(id, proto::encode_error(h.request_id, e.what()));
    } catch (const std::exception& e) {
      reply(id, proto::encode_error(h.request_id, e.what()));
    }
    return true;
  }

  void dispatch(std::uint32_t id, const proto::Header& h, proto::Payload p) {
    using T = proto::MessageType;
    const std::uint32_t rid = h.request_id;
    switch (h.type) {
      case T::ListCameras: proto::decode_empty(p); return reply(id, list_reply(rid));
      case T::GetInfo: {
        proto::decode_empty(p);
        std::lock_guard lock(mu);
        const auto it = clients.find(id);
        if (it == clients.end()) return;
        send_must_locked(it->second, info ? proto::encode_info(rid, *info) : proto::encode_error(rid, "no camera open"));
        return;
      }
      case T::GetStatus: {
        proto::decode_empty(p);
        proto::Status s = status_snapshot(id);
        return reply(id, proto::encode(rid, s));
      }
      case T::StartViewfinder:
      case T::StopViewfinder: {
        proto::decode_empty(p);
        set_viewfinder(id, h.type == T::StartViewfinder);
        nudge();
        return reply(id, proto::encode(T::Ok, rid));
      }
      case T::ReleaseSlot: return release(id, rid, proto::decode_release_slot(p));
      case T::SelectCamera: {
        std::string camera = proto::decode_select_camera(p);
        return submit(id, rid, [this, id, rid, camera] { answer(id, do_select(rid, camera)); });
      }
      case T::Configure: {
        const StreamConfig c = proto::decode_configure(p);
        return submit(id, rid, [this, id, rid, c] { answer(id, do_configure(rid, c)); });
      }
      case T::SetControls: {
        const CameraControls c = proto::decode_controls(p);
        return submit(id, rid, [this, id, rid, c] { answer(id, do_controls(rid, c)); });
      }
      case T::CaptureStill: {
        const proto::CaptureStillRequest req = proto::decode_capture_still(p);
        return submit(id, rid, [this, id, rid, req] { do_still(id, rid, req); });
      }
      default: throw proto::ProtocolError("not a client message");
    }
  }

  proto::Packet list_reply(std::uint32_t rid) {
    if (opt.list_cameras) {
      try {
        return proto::encode_camera_list(rid, opt.list_cameras());
      } catch (const std::exception& e) {
        return proto::encode_error(rid, std::string("listing cameras: ") + e.what());
      }
    }
    std::lock_guard lock(mu);
    std::vector<CameraInfo> cameras;
    if (info) cameras.push_back(*info);
    return proto::encode_camera_list(rid, cameras);
  }

  void set_viewfinder(std::uint32_t id, bool on) {
    std::lock_guard lock(mu);
    const auto it = clients.find(id);
    if (it != clients.end()) it->second.viewfinder = on;
  }

  void release(std::uint32_t id, std::uint32_t rid, const proto::ReleaseSlot& m) {
    std::lock_guard lock(mu);
    const auto it = clients.find(id);
    if (it == clients.end() || it->second.dead) return;
    Client& c = it->second;
    if (!ring || m.generation != ring->info().generation) return;  // a frame of an old ring: nothing to free
    switch (ring->release(m.slot, id)) {
      case FrameRing::Release::OutOfRange: return send_must_locked(c, proto::encode_error(rid, "slot index out of range"));
      case FrameRing::Release::NotHeld: return send_must_locked(c, proto::encode_error(rid, "slot not held"));
      case FrameRing::Release::Released: --c.held; return;
    }
  }

  proto::Status status_snapshot(std::uint32_t you) const {
    std::lock_guard lock(mu);
    proto::Status s;
    s.camera_id = camera_id;
    s.stream = stream_in_use;
    s.device_state = state;
    const std::int64_t now = monotonic_ns();
    s.fps = static_cast<double>(
        std::count_if(arrivals.begin(), arrivals.end(), [&](std::int64_t t) { return t > now - 1'000'000'000; }));
    s.frames_captured = frames_captured;
    s.frames_unplaced = frames_unplaced;
    s.device_lost_count = device_lost_count;
    s.you = you;
    for (const auto& [id, c] : clients) {
      if (c.dead) continue;
      if (s.clients.size() >= proto::kMaxListItems) break;
      s.clients.push_back(proto::ClientStatus{c.id, c.sent, c.dropped, c.held, c.viewfinder});
    }
    return s;
  }

  // While every place is taken, closes the connections silent for
  // idle_timeout: they make room. Below the limit a quiet client keeps its
  // connection (an appliance rendering for minutes, its viewfinder stopped).
  // One waiting for a command of its own is not idle: its idle time starts
  // again when it is answered.
  void close_idle() {
    const std::int64_t now = monotonic_ns(), limit = to_ns(opt.idle_timeout);
    if (limit <= 0 || now < next_idle_check) return;
    next_idle_check = now + limit;
    std::lock_guard lock(mu);
    close_idle_locked(now);
  }

  void close_idle_locked(std::int64_t now) {
    const std::int64_t limit = to_ns(opt.idle_timeout);
    if (limit <= 0 || static_cast<int>(clients.size()) < opt.max_clients) return;
    std::vector<std::uint32_t> idle;
    {
      std::lock_guard jobs_lock(job_mu);
      for (auto& [id, c] : clients) {
        if (c.dead) continue;
        if (requests.pending(id) > 0) c.last_heard = now;
        if (now - c.last_heard >= limit) idle.push_back(id);
        else next_idle_check = std::min(next_idle_check, c.last_heard + limit);
      }
    }
    const std::string why = "idle for " + duration_text(opt.idle_timeout);
    for (const std::uint32_t id : idle) {
      detail::send_packet(clients.at(id).fd.get(), proto::encode_error(0, "connection closed: " + why));
      disconnect_locked(id, why);
    }
  }

  // Until the next idle check is due, at most kLoopWaitMs.
  int loop_wait_ms() const {
    if (opt.idle_timeout.count() <= 0) return kLoopWaitMs;
    const std::int64_t left = next_idle_check - monotonic_ns();
    return static_cast<int>(std::clamp<std::int64_t>((left + 999'999) / 1'000'000, 0, kLoopWaitMs));
  }

  void event_loop() {
    epoll_event events[32];
    for (;;) {
      {
        std::lock_guard lock(job_mu);
        if (stopping) return;
      }
      close_idle();
      const int n = ::epoll_wait(epoll_fd.get(), events, 32, loop_wait_ms());
      if (n < 0) {
        if (errno == EINTR) continue;
        log(std::string("epoll_wait: ") + std::strerror(errno));
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
};

CaptureServer::CaptureServer(FrameSourceFactory factory, CaptureServerOptions options)
    : impl_(std::make_unique<Impl>()) {
  if (!factory) throw std::invalid_argument("CaptureServer needs a camera factory");
  if (options.max_held_slots < 1 || options.ring_slots < 1) throw std::invalid_argument("ring and held slots must be >= 1");
  if (options.max_requests_per_client < 1) throw std::invalid_argument("max_requests_per_client must be >= 1");
  impl_->requests = detail::RequestQueue(static_cast<std::size_t>(options.max_requests_per_client));
  impl_->factory = std::move(factory);
  impl_->opt = std::move(options);
  impl_->opt.max_stalled_frames = std::max(1, impl_->opt.max_stalled_frames);
  impl_->camera_id = impl_->opt.camera_id;
  impl_->config = impl_->opt.stream;
  impl_->stream_in_use = impl_->opt.stream;
}

CaptureServer::~CaptureServer() { stop(); }

void CaptureServer::start() {
  Impl& m = *impl_;
  if (m.started) throw std::logic_error("CaptureServer started twice");
  m.listener.bind(m.opt.socket_path, m.opt.socket_group, m.opt.log);
  m.epoll_fd.reset(::epoll_create1(EPOLL_CLOEXEC));
  if (!m.epoll_fd) detail::throw_errno("epoll_create1");
  m.wake_fd.reset(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC));
  if (!m.wake_fd) detail::throw_errno("eventfd");
  m.epoll_add(m.listener.fd(), kListenTag);
  m.epoll_add(m.wake_fd.get(), kWakeTag);
  m.started = true;
  m.camera_thread = std::thread([&m] { m.camera_loop(); });
  m.loop_thread = std::thread([&m] { m.event_loop(); });
}

void CaptureServer::stop() {
  Impl& m = *impl_;
  {
    std::lock_guard lock(m.job_mu);
    if (m.stopping) return;
    m.stopping = true;
  }
  m.job_cv.notify_all();
  if (m.wake_fd) m.wake_loop();
  if (m.camera_thread.joinable()) m.camera_thread.join();
  if (m.loop_thread.joinable()) m.loop_thread.join();
  {
    std::lock_guard lock(m.mu);
    m.clients.clear();
    m.ring.reset();
  }
  m.listener.close();
  m.listener.remove_file();
  {
    std::lock_guard lock(m.life_mu);
    m.stopped = true;
  }
  m.life_cv.notify_all();
}

bool CaptureServer::running() const {
  std::lock_guard lock(impl_->job_mu);
  return impl_->started && !impl_->stopping;
}

void CaptureServer::wait() {
  std::unique_lock lock(impl_->life_mu);
  impl_->life_cv.wait(lock, [&] { return impl_->stopped; });
}

protocol::Status CaptureServer::status() const { return impl_->status_snapshot(0); }

RequestCounts CaptureServer::request_counts() const {
  std::lock_guard lock(impl_->job_mu);
  return impl_->counts;
}

const std::string& CaptureServer::socket_path() const { return impl_->opt.socket_path; }

}  // namespace propcam::capture
