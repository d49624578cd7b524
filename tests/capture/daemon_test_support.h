// Test-only pieces for the daemon tests: a synthetic camera whose frames
// carry their sequence number in every byte's pattern (so a client can check
// it got exactly the frame sent) and that can be gated frame by frame (and still by still),
// unplugged and made to fail its reopening; a raw socket client for
// malformed traffic; bounded waits.
#pragma once

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "propcam/capture/capture_client.h"
#include "propcam/capture/capture_protocol.h"
#include "propcam/capture/capture_server.h"
#include "propcam/capture/frame_source.h"

namespace propcam::capture::test {

inline std::int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

inline std::size_t test_frame_bytes(const StreamConfig& c) {
  const std::size_t px = static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height);
  switch (c.pixel_format) {
    case PixelFormat::RGB24:
    case PixelFormat::BGR24: return px * 3;
    case PixelFormat::YUYV:
    case PixelFormat::UYVY: return px * 2;
    case PixelFormat::GREY: return px;
    default: return 0;
  }
}

inline std::uint8_t pattern_byte(std::uint64_t seq, std::size_t i) {
  return static_cast<std::uint8_t>(seq * 131 + i * 7 + (i >> 9));
}

inline std::vector<std::uint8_t> pattern(std::uint64_t seq, std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  for (std::size_t i = 0; i < size; ++i) bytes[i] = pattern_byte(seq, i);
  if (size >= 8) std::memcpy(bytes.data(), &seq, 8);
  return bytes;
}

// True when the frame's bytes are exactly what the camera made for its sequence.
inline bool intact(const Frame& f) {
  const auto d = f.data();
  if (d.size() != f.bytes_used || d.size() < 8) return false;
  std::uint64_t seq;
  std::memcpy(&seq, d.data(), 8);
  if (seq != f.metadata.sequence) return false;
  for (std::size_t i = 8; i < d.size(); ++i)
    if (d[i] != pattern_byte(seq, i)) return false;
  return true;
}

// Shared by every TestSource the factory opens: what the "hardware" does.
struct TestWorld {
  std::mutex mu;
  std::condition_variable cv;
  int permits = -1;          // frames the camera may still deliver; -1: free-running
  int fail_opens = 0;        // the factory throws this many times
  bool unplug = false;       // the next next_frame returns DeviceLost
  int end_after = -1;        // EndOfStream once this many frames were delivered
  int still_permits = -1;    // stills the camera may still take; -1: no gate
  int stills_started = 0;    // capture_still calls, the ones waiting at the gate included
  int stills_taken = 0;
  std::uint64_t sequence = 0;
  int open_attempts = 0;
  int starts = 0;
  CameraControls controls;

  void allow(int n) { grant(permits, n); }
  void free_run() { ungate(permits); }
  void allow_stills(int n) { grant(still_permits, n); }
  void free_stills() { ungate(still_permits); }
  // n more through `gate` (an open gate, -1, becomes one of n).
  void grant(int& gate, int n) {
    {
      std::lock_guard lock(mu);
      gate = gate < 0 ? n : gate + n;
    }
    cv.notify_all();
  }
  void ungate(int& gate) {
    {
      std::lock_guard lock(mu);
      gate = -1;
    }
    cv.notify_all();
  }
  int started_stills() {
    std::lock_guard lock(mu);
    return stills_started;
  }
  int taken_stills() {
    std::lock_guard lock(mu);
    return stills_taken;
  }
  void pull_the_plug() {
    {
      std::lock_guard lock(mu);
      unplug = true;
    }
    cv.notify_all();
  }
  std::uint64_t produced() {
    std::lock_guard lock(mu);
    return sequence;
  }
};

class TestSource final : public FrameSource {
 public:
  TestSource(std::shared_ptr<TestWorld> world, std::string id) : world_(std::move(world)), id_(std::move(id)) {}

  CameraInfo info() const override {
    CameraInfo i;
    i.id = id_;
    i.backend = "test";
    i.description = "synthetic test camera";
    i.formats.push_back(FormatSizes{PixelFormat::RGB24, {{64, 48}, {320, 240}}});
    i.formats.push_back(FormatSizes{PixelFormat::YUYV, {{64, 48}}});
    return i;
  }

  ConfigStatus configure(StreamConfig& c) override {
    if (running_) throw std::logic_error("configure while running");
    if (c.pixel_format == PixelFormat::MJPEG || c.pixel_format == PixelFormat::NV12) return ConfigStatus::Invalid;
    StreamConfig adjusted = c;
    adjusted.width = std::clamp(c.width, 16, 1024);
    adjusted.height = std::clamp(c.height, 16, 1024);
    const bool same = adjusted.width == c.width && adjusted.height == c.height;
    c = adjusted;
    config_ = adjusted;
    return same ? ConfigStatus::Valid : ConfigStatus::Adjusted;
  }
  StreamConfig configuration() const override { return config_; }
  void start() override {
    running_ = true;
    std::lock_guard lock(world_->mu);
    ++world_->starts;
  }
  void stop() override { running_ = false; }
  bool running() const override { return running_; }

  CaptureResult next_frame(std::chrono::milliseconds timeout) override {
    if (!running_) throw std::logic_error("next_frame before start");
    std::unique_lock lock(world_->mu);
    auto& w = *world_;
    const bool ready = w.cv.wait_for(lock, timeout, [&] { return w.unplug || w.permits != 0; });
    if (w.unplug) {
      w.unplug = false;
      return CaptureResult{CaptureStatus::DeviceLost, std::nullopt, "test camera unplugged"};
    }
    if (!ready) return CaptureResult{CaptureStatus::Timeout, std::nullopt, "no permit"};
    if (w.end_after >= 0 && w.sequence >= static_cast<std::uint64_t>(w.end_after))
      return CaptureResult{CaptureStatus::EndOfStream, std::nullopt, "recording ended"};
    if (w.permits > 0) --w.permits;
    const std::uint64_t seq = w.sequence++;
    const std::optional<double> exposure = w.controls.exposure_us;
    lock.unlock();
    return CaptureResult{CaptureStatus::Ok, make_frame(config_, seq, exposure), ""};
  }

  // Waits at the world's still gate for at most `timeout`.
  CaptureResult capture_still(const std::optional<StreamConfig>& still, std::chrono::milliseconds timeout) override {
    {
      std::unique_lock lock(world_->mu);
      auto& w = *world_;
      ++w.stills_started;
      w.cv.notify_all();
      if (!w.cv.wait_for(lock, timeout, [&] { return w.still_permits != 0; }))
        return CaptureResult{CaptureStatus::Timeout, std::nullopt, "no still permit"};
      if (w.still_permits > 0) --w.still_permits;
      ++w.stills_taken;
    }
    StreamConfig c = still.value_or(StreamConfig{PixelFormat::RGB24, 320, 240, 0});
    return CaptureResult{CaptureStatus::Ok, make_frame(c, 1'000'000 + stills_++, std::nullopt), ""};
  }

  std::vector<std::string> set_controls(const CameraControls& c) override {
    std::lock_guard lock(world_->mu);
    auto& w = world_->controls;
    if (c.exposure_us) w.exposure_us = c.exposure_us;
    if (c.analogue_gain) w.analogue_gain = c.analogue_gain;
    if (c.auto_exposure) w.auto_exposure = c.auto_exposure;
    if (c.auto_white_balance) w.auto_white_balance = c.auto_white_balance;
    std::vector<std::string> not_applied;
    if (c.colour_gain_red) not_applied.push_back("colour_gain_red");  // this "sensor" has no manual WB
    if (c.colour_gain_blue) not_applied.push_back("colour_gain_blue");
    return not_applied;
  }

  static Frame make_frame(const StreamConfig& c, std::uint64_t seq, std::optional<double> exposure) {
    Frame f;
    f.format.pixel_format = c.pixel_format;
    f.format.width = c.width;
    f.format.height = c.height;
    f.format.stride = static_cast<int>(test_frame_bytes(c) / static_cast<std::size_t>(std::max(c.height, 1)));
    f.bytes_used = test_frame_bytes(c);
    f.buffer = std::make_shared<VectorFrameBuffer>(pattern(seq, f.bytes_used));
    f.metadata.sequence = seq;
    f.metadata.timestamp_ns = now_ns();
    f.metadata.exposure_us = exposure;
    return f;
  }

 private:
  std::shared_ptr<TestWorld> world_;
  std::string id_;
  StreamConfig config_{PixelFormat::RGB24, 64, 48, 30};
  bool running_ = false;
  std::uint64_t stills_ = 0;
};

inline FrameSourceFactory test_factory(std::shared_ptr<TestWorld> world) {
  return [world](const std::string& id) -> std::unique_ptr<FrameSource> {
    {
      std::lock_guard lock(world->mu);
      ++world->open_attempts;
      if (id.rfind("bad", 0) == 0) throw std::runtime_error("no such camera " + id);
      if (world->fail_opens > 0) {
        --world->fail_opens;
        throw std::runtime_error("camera not there yet");
      }
    }
    return std::make_unique<TestSource>(world, id);
  };
}

// This process's folder of test sockets, removed when the tests exit.
struct TempRoot {
  std::filesystem::path path = std::filesystem::temp_directory_path() / ("propcamd_test_" + std::to_string(::getpid()));
  ~TempRoot() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};
inline TempRoot temp_root;

// A fresh folder per test for the socket.
inline std::string temp_socket(const std::string& name) {
  static std::atomic<int> counter{0};
  const auto dir = temp_root.path / std::to_string(counter++);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

inline CaptureServerOptions test_options(const std::string& socket) {
  CaptureServerOptions o;
  o.socket_path = socket;
  o.camera_id = "test:a";
  o.stream = StreamConfig{PixelFormat::RGB24, 64, 48, 30};
  o.frame_timeout = std::chrono::milliseconds(20);
  o.reopen_backoff_min = std::chrono::milliseconds(5);
  o.reopen_backoff_max = std::chrono::milliseconds(40);
  return o;
}

// Polls `done` until it holds or `limit` passes (a bound against hangs, not a timing check).
inline bool eventually(const std::function<bool()>& done, std::chrono::seconds limit = std::chrono::seconds(20)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return done();
}

// A server on a fresh socket with the test camera, started, its camera open.
// `permits`: viewfinder frames the camera may deliver (TestWorld::allow;
// -1: free run). Gated stills wait for TestWorld::allow_stills.
// PROPCAMD_TEST_LOG set: the server's log on stderr.
struct Daemon {
  enum class Stills { Free, Gated };
  std::shared_ptr<TestWorld> world = std::make_shared<TestWorld>();
  CaptureServerOptions options;
  std::unique_ptr<CaptureServer> server;

  explicit Daemon(const std::function<void(CaptureServerOptions&)>& tweak = {}, int permits = 0,
                  Stills stills = Stills::Free) {
    options = test_options(temp_socket("capture.sock"));
    if (tweak) tweak(options);
    if (std::getenv("PROPCAMD_TEST_LOG"))
      options.log = [](const std::string& l) { std::fprintf(stderr, "propcamd: %s\n", l.c_str()); };
    world->permits = permits;
    if (stills == Stills::Gated) world->still_permits = 0;
    server = std::make_unique<CaptureServer>(test_factory(world), options);
    server->start();
    // The camera opens on the server's thread; tests start from an open camera.
    eventually([&] { return server->status().device_state != protocol::DeviceState::Closed; });
  }
  ~Daemon() { world->free_stills(); }  // no still left waiting while the server stops
  const std::string& path() const { return options.socket_path; }
};

// The next frame within a generous bound, skipping timeouts.
inline CaptureResult next_non_timeout(CaptureClient& c, std::chrono::seconds limit = std::chrono::seconds(20)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  CaptureResult r;
  while (std::chrono::steady_clock::now() < end) {
    r = c.next_frame(std::chrono::milliseconds(200));
    if (r.status != CaptureStatus::Timeout) return r;
  }
  return r;
}

// By value: callers often pass a temporary Status.
inline std::optional<protocol::ClientStatus> find_client(const protocol::Status& s, std::uint32_t id) {
  for (const auto& c : s.clients)
    if (c.client_id == id) return c;
  return std::nullopt;
}

// A bare SOCK_SEQPACKET connection that sends whatever bytes it is given.
class RawClient {
 public:
  explicit RawClient(const std::string& path) {
    fd_ = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error("socket");
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
      ::close(fd_);
      throw std::runtime_error("connect");
    }
  }
  ~RawClient() { close(); }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;

  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  int fd() const { return fd_; }

  // False when the socket would block or is broken.
  bool send(const std::vector<std::uint8_t>& bytes, int pass_fd = -1) {
    iovec iov{const_cast<std::uint8_t*>(bytes.data()), bytes.size()};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))] = {};
    if (pass_fd >= 0) {
      msg.msg_control = control;
      msg.msg_controllen = sizeof control;
      cmsghdr* c = CMSG_FIRSTHDR(&msg);
      c->cmsg_level = SOL_SOCKET;
      c->cmsg_type = SCM_RIGHTS;
      c->cmsg_len = CMSG_LEN(sizeof(int));
      std::memcpy(CMSG_DATA(c), &pass_fd, sizeof(int));
    }
    return ::sendmsg(fd_, &msg, MSG_NOSIGNAL | MSG_DONTWAIT) == static_cast<ssize_t>(bytes.size());
  }

  struct Packet {
    bool closed = false;  // the server hung up
    std::vector<std::uint8_t> bytes;
  };
  // One packet within `limit`; nullopt when none came (any fds received are closed).
  std::optional<Packet> receive(std::chrono::milliseconds limit = std::chrono::milliseconds(20000)) {
    pollfd p{fd_, POLLIN, 0};
    const int n = ::poll(&p, 1, static_cast<int>(limit.count()));
    if (n <= 0) return std::nullopt;
    Packet out;
    out.bytes.resize(protocol::kMaxMessageBytes);
    iovec iov{out.bytes.data(), out.bytes.size()};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int) * 4)];
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t got = ::recvmsg(fd_, &msg, MSG_CMSG_CLOEXEC);
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); got >= 0 && c; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_type != SCM_RIGHTS) continue;
      for (std::size_t i = 0; i < (c->cmsg_len - CMSG_LEN(0)) / sizeof(int); ++i) {
        int fd;
        std::memcpy(&fd, CMSG_DATA(c) + i * sizeof(int), sizeof fd);
        ::close(fd);
      }
    }
    if (got <= 0) {
      out.closed = true;
      out.bytes.clear();
      return out;
    }
    out.bytes.resize(static_cast<std::size_t>(got));
    return out;
  }

  // Reads until the server hangs up (true) or nothing more comes within the bound.
  bool hung_up(std::chrono::milliseconds limit = std::chrono::milliseconds(20000)) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      auto p = receive(std::chrono::milliseconds(200));
      if (p && p->closed) return true;
    }
    return false;
  }

 private:
  int fd_ = -1;
};

inline protocol::MessageType type_of(const std::vector<std::uint8_t>& packet) {
  return protocol::decode_header(packet.data(), packet.size()).type;
}

// The next packet that is not unsolicited (frames, events, a new ring).
inline std::optional<RawClient::Packet> receive_reply(RawClient& raw) {
  for (;;) {
    auto p = raw.receive();
    if (!p || p->closed) return p;
    const auto t = type_of(p->bytes);
    if (t != protocol::MessageType::FrameReady && t != protocol::MessageType::Event &&
        t != protocol::MessageType::RingChanged)
      return p;
  }
}

}  // namespace propcam::capture::test
