#include "propcam/capture/capture_bench.h"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <exception>
#include <filesystem>
#include <map>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <thread>

#include "capture_socket.h"
#include "propcam/capture/frame.h"
#include "propcam/capture/capture_client.h"

namespace propcam::capture {
namespace {

using detail::monotonic_ns;
using Clock = std::chrono::steady_clock;

// Bytes of a synthetic frame: packed rows (frame.h's bound), and none for
// MJPEG (there is no JPEG to make).
std::size_t synthetic_bytes(const StreamConfig& c) {
  if (c.pixel_format == PixelFormat::MJPEG) return 0;
  FrameFormat format;
  format.pixel_format = c.pixel_format;
  format.width = c.width;
  format.height = c.height;
  return frame_bytes(format);
}

class SyntheticSource final : public FrameSource {
 public:
  explicit SyntheticSource(std::string id) : id_(std::move(id)) {}

  CameraInfo info() const override {
    CameraInfo i;
    i.id = id_;
    i.backend = "synthetic";
    i.description = "moving pattern for benchmarks";
    for (PixelFormat f : {PixelFormat::YUYV, PixelFormat::RGB24, PixelFormat::NV12, PixelFormat::GREY})
      i.formats.push_back(FormatSizes{f, {{640, 480}, {1280, 720}, {1920, 1080}}});
    return i;
  }
  ConfigStatus configure(StreamConfig& c) override {
    if (c.pixel_format == PixelFormat::MJPEG) return ConfigStatus::Invalid;
    const StreamConfig asked = c;
    c.width = std::clamp(c.width / 2 * 2, 2, 4096);
    c.height = std::clamp(c.height / 2 * 2, 2, 4096);
    c.fps = std::clamp(c.fps, 0.0, 1000.0);
    config_ = c;
    return asked.width == c.width && asked.height == c.height && asked.fps == c.fps ? ConfigStatus::Valid
                                                                                     : ConfigStatus::Adjusted;
  }
  StreamConfig configuration() const override { return config_; }
  void start() override {
    running_ = true;
    next_ = Clock::now();
  }
  void stop() override { running_ = false; }
  bool running() const override { return running_; }

  CaptureResult next_frame(std::chrono::milliseconds timeout) override {
    if (!running_) throw std::logic_error("next_frame before start");
    if (config_.fps > 0) {
      const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / config_.fps));
      if (next_ - Clock::now() > timeout) return CaptureResult{CaptureStatus::Timeout, std::nullopt, "not yet"};
      std::this_thread::sleep_until(next_);
      next_ = std::max(next_ + period, Clock::now() - period);  // no burst after a stall
    }
    return CaptureResult{CaptureStatus::Ok, make(config_), ""};
  }
  CaptureResult capture_still(const std::optional<StreamConfig>& still, std::chrono::milliseconds) override {
    return CaptureResult{CaptureStatus::Ok, make(still.value_or(config_)), ""};
  }
  std::vector<std::string> set_controls(const CameraControls&) override { return {}; }

 private:
  Frame make(const StreamConfig& c) {
    Frame f;
    f.format.pixel_format = c.pixel_format;
    f.format.width = c.width;
    f.format.height = c.height;
    f.bytes_used = synthetic_bytes(c);
    f.format.stride = c.height > 0 && c.pixel_format != PixelFormat::NV12
                          ? static_cast<int>(f.bytes_used / static_cast<std::size_t>(c.height))
                          : c.width;
    std::vector<std::uint8_t> bytes(f.bytes_used);
    const auto shift = static_cast<std::uint8_t>(sequence_);
    for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<std::uint8_t>(i + shift);
    f.buffer = std::make_shared<VectorFrameBuffer>(std::move(bytes));
    f.metadata.sequence = sequence_++;
    f.metadata.timestamp_ns = monotonic_ns();
    return f;
  }

  std::string id_;
  StreamConfig config_;
  bool running_ = false;
  Clock::time_point next_{};
  std::uint64_t sequence_ = 0;
};

// When next_frame returned, by sequence number, shared by the server's
// camera thread (writer) and the bench's client (reader).
struct DeliveryTimes {
  std::mutex mu;
  std::map<std::uint64_t, std::int64_t> by_sequence;
  void record(std::uint64_t seq, std::int64_t t) {
    std::lock_guard lock(mu);
    by_sequence[seq] = t;
    while (by_sequence.size() > 4096) by_sequence.erase(by_sequence.begin());
  }
  std::optional<std::int64_t> take(std::uint64_t seq) {
    std::lock_guard lock(mu);
    const auto it = by_sequence.find(seq);
    if (it == by_sequence.end()) return std::nullopt;
    const std::int64_t t = it->second;
    by_sequence.erase(by_sequence.begin(), std::next(it));
    return t;
  }
};

// Forwards to the real source and notes when each frame left it.
class TimedSource final : public FrameSource {
 public:
  TimedSource(std::unique_ptr<FrameSource> inner, std::shared_ptr<DeliveryTimes> times)
      : inner_(std::move(inner)), times_(std::move(times)) {}
  CameraInfo info() const override { return inner_->info(); }
  ConfigStatus configure(StreamConfig& c) override { return inner_->configure(c); }
  StreamConfig configuration() const override { return inner_->configuration(); }
  void start() override { inner_->start(); }
  void stop() override { inner_->stop(); }
  bool running() const override { return inner_->running(); }
  CaptureResult next_frame(std::chrono::milliseconds timeout) override {
    CaptureResult r = inner_->next_frame(timeout);
    if (r.status == CaptureStatus::Ok && r.frame) times_->record(r.frame->metadata.sequence, monotonic_ns());
    return r;
  }
  CaptureResult capture_still(const std::optional<StreamConfig>& s, std::chrono::milliseconds t) override {
    return inner_->capture_still(s, t);
  }
  std::vector<std::string> set_controls(const CameraControls& c) override { return inner_->set_controls(c); }

 private:
  std::unique_ptr<FrameSource> inner_;
  std::shared_ptr<DeliveryTimes> times_;
};

// Forwards to the real source; each still first takes `still_time`, as on a real camera.
class SlowStillSource final : public FrameSource {
 public:
  SlowStillSource(std::unique_ptr<FrameSource> inner, std::chrono::milliseconds still_time)
      : inner_(std::move(inner)), still_time_(still_time) {}
  CameraInfo info() const override { return inner_->info(); }
  ConfigStatus configure(StreamConfig& c) override { return inner_->configure(c); }
  StreamConfig configuration() const override { return inner_->configuration(); }
  void start() override { inner_->start(); }
  void stop() override { inner_->stop(); }
  bool running() const override { return inner_->running(); }
  CaptureResult next_frame(std::chrono::milliseconds timeout) override { return inner_->next_frame(timeout); }
  CaptureResult capture_still(const std::optional<StreamConfig>& s, std::chrono::milliseconds t) override {
    std::this_thread::sleep_for(still_time_);
    return inner_->capture_still(s, t);
  }
  std::vector<std::string> set_controls(const CameraControls& c) override { return inner_->set_controls(c); }

 private:
  std::unique_ptr<FrameSource> inner_;
  std::chrono::milliseconds still_time_;
};

// The flooding client: a bare socket that keeps `depth` still requests
// unanswered (a refused one is sent again at once) until `stop`.
struct Flood {
  std::atomic<bool> stop{false};
  std::atomic<bool> primed{false};  // the first `depth` requests are sent
  std::uint64_t stills = 0, refused = 0;
  std::exception_ptr error;  // read after the thread is joined

  void run(const std::string& path, int depth) try {
    detail::UniqueFd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
    if (!fd) detail::throw_errno("socket");
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
      detail::throw_errno("flood: connect " + path);
    std::uint32_t rid = 0;
    int outstanding = 0;
    while (!stop) {
      while (outstanding < depth) {
        protocol::CaptureStillRequest req;
        req.timeout_ms = 10000;
        const auto sent = detail::send_packet(fd.get(), protocol::encode(++rid, req));
        if (sent == detail::SendResult::Closed) throw std::runtime_error("flood: the server closed the connection");
        if (sent == detail::SendResult::WouldBlock) break;
        ++outstanding;
      }
      primed = true;
      pollfd p{fd.get(), POLLIN, 0};
      ::poll(&p, 1, 20);
      for (;;) {
        const detail::Received r = detail::recv_packet(fd.get(), true);
        if (r.kind == detail::Received::Kind::WouldBlock) break;
        if (r.kind != detail::Received::Kind::Packet)
          throw std::runtime_error("flood: the server closed the connection");
        const auto type = protocol::decode_header(r.bytes.data(), r.bytes.size()).type;
        if (type == protocol::MessageType::StillFrame) ++stills;
        else if (type == protocol::MessageType::Error) ++refused;
        else continue;  // the welcome
        --outstanding;
      }
    }
  } catch (...) {
    error = std::current_exception();
    primed = true;
  }
};

LatencyStats stats_of(std::vector<double> ms) {
  LatencyStats s;
  if (ms.empty()) return s;
  std::sort(ms.begin(), ms.end());
  s.mean_ms = std::accumulate(ms.begin(), ms.end(), 0.0) / static_cast<double>(ms.size());
  s.p95_ms = ms[std::min(ms.size() - 1, static_cast<std::size_t>(0.95 * static_cast<double>(ms.size())))];
  s.max_ms = ms.back();
  return s;
}

std::string bench_socket_path() {
  static std::atomic<int> counter{0};
  const auto dir = std::filesystem::temp_directory_path() /
                   ("propcam_bench_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::create_directories(dir);
  return (dir / "capture.sock").string();
}

// A daemon for one bench run, started: on the given socket, or on one in a
// fresh folder that is removed with it.
class BenchDaemon {
 public:
  BenchDaemon(FrameSourceFactory factory, const std::string& socket_path, const std::string& camera_id,
              const StreamConfig& stream)
      : own_folder_(socket_path.empty()) {
    CaptureServerOptions so;
    so.socket_path = own_folder_ ? bench_socket_path() : socket_path;
    so.camera_id = camera_id;
    so.stream = stream;
    socket_path_ = so.socket_path;
    server_ = std::make_unique<CaptureServer>(std::move(factory), so);
    server_->start();
  }
  ~BenchDaemon() {
    server_->stop();
    if (own_folder_) {
      std::error_code ec;
      std::filesystem::remove_all(std::filesystem::path(socket_path_).parent_path(), ec);
    }
  }
  BenchDaemon(const BenchDaemon&) = delete;
  BenchDaemon& operator=(const BenchDaemon&) = delete;
  const std::string& socket_path() const { return socket_path_; }

 private:
  bool own_folder_;
  std::string socket_path_;
  std::unique_ptr<CaptureServer> server_;
};

}  // namespace

FrameSourceFactory synthetic_source_factory() {
  return [](const std::string& id) { return std::make_unique<SyntheticSource>(id); };
}

DaemonBenchResult measure_daemon_throughput(const FrameSourceFactory& factory, const DaemonBenchOptions& options) {
  if (options.frames <= 0 && options.duration.count() <= 0)
    throw std::invalid_argument("measure_daemon_throughput: set frames or duration");
  auto times = std::make_shared<DeliveryTimes>();
  FrameSourceFactory timed = [factory, times](const std::string& id) -> std::unique_ptr<FrameSource> {
    auto inner = factory(id);
    if (!inner) return nullptr;
    return std::make_unique<TimedSource>(std::move(inner), times);
  };
  DaemonBenchResult result;
  std::vector<double> total, source, daemon;
  {
    const BenchDaemon server(timed, options.socket_path, options.camera_id, options.stream);
    CaptureClient client(server.socket_path());
    client.start_viewfinder();
    const auto start = Clock::now();
    const auto end = options.duration.count() > 0 ? start + options.duration : Clock::time_point::max();
    std::optional<std::uint64_t> last_seq;
    for (;;) {
      if (options.frames > 0 && result.frames_received >= options.frames) {
        result.stopped_because = "frames";
        break;
      }
      if (Clock::now() >= end) {
        result.stopped_because = "duration";
        break;
      }
      const CaptureResult r = client.next_frame(options.frame_timeout);
      const std::int64_t now = monotonic_ns();
      if (r.status != CaptureStatus::Ok || !r.frame) {
        result.stopped_because = r.status == CaptureStatus::Timeout ? "timeout" : r.message;
        break;
      }
      const FrameMetadata& m = r.frame->metadata;
      ++result.frames_received;
      total.push_back(static_cast<double>(now - m.timestamp_ns) * 1e-6);
      if (const auto delivered = times->take(m.sequence)) {
        source.push_back(static_cast<double>(*delivered - m.timestamp_ns) * 1e-6);
        daemon.push_back(static_cast<double>(now - *delivered) * 1e-6);
      }
      if (last_seq && m.sequence > *last_seq + 1) result.sequence_gaps += m.sequence - *last_seq - 1;
      last_seq = m.sequence;
    }
    result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    const protocol::Status st = client.status();
    result.frames_captured = st.frames_captured;
    for (const auto& c : st.clients)
      if (c.client_id == client.client_id()) result.frames_dropped = c.frames_dropped;
  }
  result.fps = result.seconds > 0 ? result.frames_received / result.seconds : 0;
  result.total = stats_of(std::move(total));
  result.source = stats_of(std::move(source));
  result.daemon = stats_of(std::move(daemon));
  return result;
}

FloodBenchResult measure_still_latency_under_flood(const FrameSourceFactory& factory,
                                                   const FloodBenchOptions& options) {
  if (options.stills <= 0 || options.flood_depth <= 0)
    throw std::invalid_argument("measure_still_latency_under_flood: stills and flood_depth must be > 0");
  const auto still_time = options.still_time;
  FrameSourceFactory slow = [factory, still_time](const std::string& id) -> std::unique_ptr<FrameSource> {
    auto inner = factory(id);
    if (!inner) return nullptr;
    return std::make_unique<SlowStillSource>(std::move(inner), still_time);
  };
  FloodBenchResult result;
  std::vector<double> latency;
  std::exception_ptr failure;
  {
    const BenchDaemon server(slow, options.socket_path, options.camera_id, options.stream);
    CaptureClient client(server.socket_path());
    Flood flood;
    std::thread flooder([&] { flood.run(server.socket_path(), options.flood_depth); });
    try {
      while (!flood.primed) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      const auto start = Clock::now();
      for (int i = 0; i < options.stills; ++i) {
        const auto t0 = Clock::now();
        const CaptureResult r = client.capture_still(std::nullopt, options.still_timeout);
        if (r.status != CaptureStatus::Ok || !r.frame) throw std::runtime_error("still: " + r.message);
        latency.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
        ++result.stills;
      }
      result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    } catch (...) {
      failure = std::current_exception();
    }
    flood.stop = true;
    flooder.join();
    if (!failure) failure = flood.error;
    result.flood_stills = flood.stills;
    result.flood_refused = flood.refused;
  }
  if (failure) std::rethrow_exception(failure);
  result.latency = stats_of(std::move(latency));
  return result;
}

}  // namespace propcam::capture
