#include "propcam/capture/capture_client.h"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>

#include <cerrno>
#include <cstring>
#include <variant>

#include "capture_socket.h"

namespace propcam::capture {
namespace {

using detail::Mapping;
using detail::Received;
using detail::UniqueFd;
namespace proto = protocol;
using Clock = std::chrono::steady_clock;

// The socket, shared with the frames so each can give its slot back even
// after the client object is gone.
struct Connection {
  UniqueFd fd;
};

struct RingView {
  proto::RingInfo info;
  Mapping map;
};

// A frame in the daemon's ring; its destructor releases the slot.
class SlotBuffer final : public FrameBuffer {
 public:
  SlotBuffer(std::shared_ptr<const RingView> ring, std::shared_ptr<Connection> conn, std::uint32_t slot)
      : ring_(std::move(ring)), conn_(std::move(conn)), slot_(slot) {}
  ~SlotBuffer() override {
    // Best effort: if the daemon is gone there is nothing to give back.
    const proto::ReleaseSlot m{ring_->info.generation, slot_};
    detail::send_packet(conn_->fd.get(), proto::encode(0, m));
  }
  std::span<const std::uint8_t> bytes() const override {
    return {ring_->map.data() + std::size_t{slot_} * ring_->info.slot_bytes, ring_->info.slot_bytes};
  }

 private:
  std::shared_ptr<const RingView> ring_;
  std::shared_ptr<Connection> conn_;
  std::uint32_t slot_;
};

// A still: its own read-only mapping.
class StillBuffer final : public FrameBuffer {
 public:
  StillBuffer(Mapping map, std::size_t size) : map_(std::move(map)), size_(size) {}
  std::span<const std::uint8_t> bytes() const override { return {map_.data(), size_}; }

 private:
  Mapping map_;
  std::size_t size_;
};

// Frames are wrapped on arrival, so dropping a queued one releases its slot.
using Incoming = std::variant<Frame, proto::Event>;

std::shared_ptr<const RingView> map_ring(const proto::RingInfo& info, const UniqueFd& fd) {
  if (!fd) throw CaptureClientError("the daemon sent a ring without its memfd");
  const std::size_t total = static_cast<std::size_t>(info.slot_bytes) * info.slot_count;
  if (detail::fd_size(fd.get()) < total) throw CaptureClientError("the ring memfd is smaller than announced");
  auto view = std::make_shared<RingView>();
  view->info = info;
  view->map = Mapping(fd.get(), total, false);
  return view;
}

}  // namespace

struct CaptureClient::Impl {
  std::shared_ptr<Connection> conn = std::make_shared<Connection>();
  std::chrono::milliseconds command_timeout{};
  proto::Welcome welcome;
  std::shared_ptr<const RingView> ring;
  std::deque<Incoming> incoming;
  std::vector<proto::Event> events;
  proto::DeviceState state = proto::DeviceState::Idle;
  std::uint32_t next_request = 1;
  bool closed = false;

  void connect(const std::string& path) {
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    if (path.empty() || path.size() >= sizeof addr.sun_path) throw CaptureClientError("bad socket path " + path);
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    conn->fd.reset(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
    if (!conn->fd) throw CaptureClientError(std::string("socket: ") + std::strerror(errno));
    int rc;
    do rc = ::connect(conn->fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
    while (rc != 0 && errno == EINTR);
    // A non-blocking UNIX connect completes at once or fails (EAGAIN: backlog full).
    if (rc != 0) throw CaptureClientError("cannot connect to " + path + ": " + std::strerror(errno));
  }

  // Waits for one packet until `deadline`; nullopt on timeout.
  std::optional<Received> receive(Clock::time_point deadline) {
    for (;;) {
      if (closed) throw CaptureClientError("the connection to propcamd is closed");
      Received r = detail::recv_packet(conn->fd.get(), true);
      if (r.kind == Received::Kind::Packet) return r;
      if (r.kind == Received::Kind::Closed || r.kind == Received::Kind::Truncated) {
        closed = true;
        throw CaptureClientError("propcamd closed the connection");
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      if (left.count() <= 0) return std::nullopt;
      pollfd p{conn->fd.get(), POLLIN, 0};
      const int n = ::poll(&p, 1, static_cast<int>(std::min<std::int64_t>(left.count() + 1, 60000)));
      if (n < 0 && errno != EINTR) throw CaptureClientError(std::string("poll: ") + std::strerror(errno));
    }
  }

  // Handles an unsolicited packet; returns its header so the caller can match replies.
  proto::Header absorb(const Received& r) {
    const proto::Header h = proto::decode_header(r.bytes.data(), r.bytes.size());
    const proto::Payload p = proto::payload_of(r.bytes.data(), r.bytes.size());
    switch (h.type) {
      case proto::MessageType::RingChanged: ring = map_ring(proto::decode_ring_info(p), r.fd); break;
      case proto::MessageType::FrameReady: accept_frame(proto::decode_frame_ready(p)); break;
      case proto::MessageType::Event: {
        proto::Event e = proto::decode_event(p);
        state = e.kind == proto::EventKind::DeviceLost ? proto::DeviceState::Lost
                : e.kind == proto::EventKind::Resumed  ? proto::DeviceState::Streaming
                                                       : proto::DeviceState::Ended;
        events.push_back(e);
        incoming.push_back(std::move(e));
        break;
      }
      default: break;  // a reply: the caller looks at it
    }
    return h;
  }

  void accept_frame(const proto::FrameReady& m) {
    // A frame we cannot place is released at once so its slot is not lost.
    const bool fits = ring && m.generation == ring->info.generation && m.slot < ring->info.slot_count &&
                      m.bytes_used <= ring->info.slot_bytes;
    if (!fits) {
      detail::send_packet(conn->fd.get(), proto::encode(0, proto::ReleaseSlot{m.generation, m.slot}));
      return;
    }
    Frame f;
    f.format = m.format;
    f.metadata = m.metadata;
    f.bytes_used = m.bytes_used;
    f.buffer = std::make_shared<SlotBuffer>(ring, conn, m.slot);
    incoming.push_back(std::move(f));
  }

  // Sends a request and waits for its reply (Error becomes an exception).
  Received request(const proto::Packet& packet, std::chrono::milliseconds timeout) {
    if (closed) throw CaptureClientError("the connection to propcamd is closed");
    const std::uint32_t rid = packet_request_id(packet);
    const auto deadline = Clock::now() + timeout;
    send_until(packet, deadline);
    for (;;) {
      auto r = receive(deadline);
      if (!r) throw CaptureClientError("propcamd did not answer in time");
      const proto::Header h = absorb(*r);
      if (h.type == proto::MessageType::Error && (h.request_id == rid || h.request_id == 0))
        throw CaptureClientError("propcamd: " + proto::decode_error(proto::payload_of(r->bytes.data(), r->bytes.size())));
      if (h.request_id == rid && h.type >= static_cast<proto::MessageType>(proto::kFirstServerType)) return std::move(*r);
    }
  }

  static std::uint32_t packet_request_id(const proto::Packet& packet) {
    std::uint32_t rid;
    std::memcpy(&rid, packet.data() + 12, sizeof rid);
    return rid;
  }

  std::uint32_t rid() {
    const std::uint32_t id = next_request++;
    if (next_request == 0) next_request = 1;
    return id;
  }

  static proto::Payload payload(const Received& r) { return proto::payload_of(r.bytes.data(), r.bytes.size()); }

  static void expect(const Received& r, proto::MessageType type) {
    if (proto::decode_header(r.bytes.data(), r.bytes.size()).type != type)
      throw CaptureClientError("propcamd answered with an unexpected message");
  }

  // Blocking send on the non-blocking socket, bounded by `deadline`.
  void send_until(const proto::Packet& packet, Clock::time_point deadline) {
    for (;;) {
      const detail::SendResult r = detail::send_packet(conn->fd.get(), packet);
      if (r == detail::SendResult::Sent) return;
      if (r == detail::SendResult::Closed) {
        closed = true;
        throw CaptureClientError("propcamd closed the connection");
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      if (left.count() <= 0) throw CaptureClientError("propcamd does not read its socket");
      pollfd p{conn->fd.get(), POLLOUT, 0};
      if (::poll(&p, 1, static_cast<int>(std::min<std::int64_t>(left.count() + 1, 60000))) < 0 && errno != EINTR)
        throw CaptureClientError(std::string("poll: ") + std::strerror(errno));
    }
  }
};

CaptureClient::CaptureClient(const std::string& socket_path, std::chrono::milliseconds command_timeout)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.command_timeout = command_timeout;
  m.connect(socket_path);
  auto r = m.receive(Clock::now() + command_timeout);
  if (!r) throw CaptureClientError("propcamd did not greet in time");
  const proto::Header h = proto::decode_header(r->bytes.data(), r->bytes.size());
  if (h.type == proto::MessageType::Error) throw CaptureClientError("propcamd: " + proto::decode_error(m.payload(*r)));
  if (h.type != proto::MessageType::Welcome) throw CaptureClientError("propcamd did not send a welcome");
  m.welcome = proto::decode_welcome(m.payload(*r));
  if (m.welcome.ring) m.ring = map_ring(*m.welcome.ring, r->fd);
}

CaptureClient::~CaptureClient() = default;

std::uint32_t CaptureClient::client_id() const { return impl_->welcome.client_id; }
std::uint32_t CaptureClient::max_held_slots() const { return impl_->welcome.max_held_slots; }

std::vector<CameraInfo> CaptureClient::list_cameras() {
  auto r = impl_->request(proto::encode(proto::MessageType::ListCameras, impl_->rid()), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::CameraList);
  return proto::decode_camera_list(Impl::payload(r));
}

CameraInfo CaptureClient::info() {
  auto r = impl_->request(proto::encode(proto::MessageType::GetInfo, impl_->rid()), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::Info);
  return proto::decode_info(Impl::payload(r));
}

void CaptureClient::select_camera(const std::string& id) {
  auto r = impl_->request(proto::encode_select_camera(impl_->rid(), id), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::Ok);
}

ConfigStatus CaptureClient::configure(StreamConfig& config) {
  auto r = impl_->request(proto::encode_configure(impl_->rid(), config), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::ConfigureReply);
  const proto::ConfigureReply reply = proto::decode_configure_reply(Impl::payload(r));
  if (reply.status != ConfigStatus::Invalid) config = reply.config;
  return reply.status;
}

void CaptureClient::start_viewfinder() {
  auto r = impl_->request(proto::encode(proto::MessageType::StartViewfinder, impl_->rid()), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::Ok);
}

void CaptureClient::stop_viewfinder() {
  auto r = impl_->request(proto::encode(proto::MessageType::StopViewfinder, impl_->rid()), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::Ok);
}

std::vector<std::string> CaptureClient::set_controls(const CameraControls& controls) {
  auto r = impl_->request(proto::encode(impl_->rid(), controls), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::ControlsReply);
  return proto::decode_controls_reply(Impl::payload(r));
}

CaptureResult CaptureClient::capture_still(const std::optional<StreamConfig>& still, std::chrono::milliseconds timeout) {
  proto::CaptureStillRequest req;
  req.config = still;
  req.timeout_ms = static_cast<std::uint32_t>(std::clamp<std::int64_t>(timeout.count(), 0, 60000));
  auto r = impl_->request(proto::encode(impl_->rid(), req), std::chrono::milliseconds(req.timeout_ms) + impl_->command_timeout);
  Impl::expect(r, proto::MessageType::StillFrame);
  const proto::StillFrame m = proto::decode_still_frame(Impl::payload(r));
  CaptureResult result;
  result.status = m.status;
  result.message = m.message;
  if (m.status != CaptureStatus::Ok) return result;
  if (!r.fd) throw CaptureClientError("propcamd sent a still without its memfd");
  if (detail::fd_size(r.fd.get()) < m.memfd_bytes) throw CaptureClientError("the still memfd is smaller than announced");
  Frame f;
  f.format = m.format;
  f.metadata = m.metadata;
  f.bytes_used = m.bytes_used;
  if (m.memfd_bytes > 0) f.buffer = std::make_shared<StillBuffer>(Mapping(r.fd.get(), m.memfd_bytes, false), m.memfd_bytes);
  result.frame = std::move(f);
  return result;
}

protocol::Status CaptureClient::status() {
  auto r = impl_->request(proto::encode(proto::MessageType::GetStatus, impl_->rid()), impl_->command_timeout);
  Impl::expect(r, proto::MessageType::Status);
  return proto::decode_status(Impl::payload(r));
}

CaptureResult CaptureClient::next_frame(std::chrono::milliseconds timeout) {
  Impl& m = *impl_;
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    while (!m.incoming.empty()) {
      Incoming item = std::move(m.incoming.front());
      m.incoming.pop_front();
      if (auto* f = std::get_if<Frame>(&item)) {
        CaptureResult r;
        r.status = CaptureStatus::Ok;
        r.frame = std::move(*f);
        return r;
      }
      const auto& e = std::get<proto::Event>(item);
      if (e.kind == proto::EventKind::Resumed) continue;  // frames simply come back
      CaptureResult r;
      r.status = e.kind == proto::EventKind::DeviceLost ? CaptureStatus::DeviceLost : CaptureStatus::EndOfStream;
      r.message = e.message;
      return r;
    }
    std::optional<Received> r;
    try {
      r = m.receive(deadline);
    } catch (const CaptureClientError& e) {
      CaptureResult lost;
      lost.status = CaptureStatus::DeviceLost;
      lost.message = e.what();
      return lost;
    }
    if (!r) return CaptureResult{CaptureStatus::Timeout, std::nullopt, "no frame in time"};
    m.absorb(*r);  // replies to nobody (none are outstanding) are ignored
  }
}

std::vector<protocol::Event> CaptureClient::take_events() { return std::exchange(impl_->events, {}); }
protocol::DeviceState CaptureClient::device_state() const { return impl_->state; }
bool CaptureClient::connected() const { return !impl_->closed; }

// ---- DaemonFrameSource -------------------------------------------------------

DaemonFrameSource::DaemonFrameSource(const std::string& socket_path, const std::optional<std::string>& camera_id)
    : client_(std::make_unique<CaptureClient>(socket_path)) {
  if (camera_id) client_->select_camera(*camera_id);
}

CameraInfo DaemonFrameSource::info() const { return client_->info(); }
ConfigStatus DaemonFrameSource::configure(StreamConfig& config) { return client_->configure(config); }
StreamConfig DaemonFrameSource::configuration() const { return client_->status().stream; }

void DaemonFrameSource::start() {
  client_->start_viewfinder();
  running_ = true;
}

void DaemonFrameSource::stop() {
  client_->stop_viewfinder();
  running_ = false;
}

bool DaemonFrameSource::running() const { return running_; }

CaptureResult DaemonFrameSource::next_frame(std::chrono::milliseconds timeout) {
  if (!running_) throw std::logic_error("DaemonFrameSource::next_frame before start()");
  return client_->next_frame(timeout);
}

CaptureResult DaemonFrameSource::capture_still(const std::optional<StreamConfig>& still,
                                               std::chrono::milliseconds timeout) {
  return client_->capture_still(still, timeout);
}

std::vector<std::string> DaemonFrameSource::set_controls(const CameraControls& controls) {
  return client_->set_controls(controls);
}

}  // namespace propcam::capture
