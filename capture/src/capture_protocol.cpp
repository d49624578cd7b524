#include "propcam/capture/capture_protocol.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace propcam::capture::protocol {
namespace {

static_assert(std::endian::native == std::endian::little, "the wire format is little-endian");

// Appends little-endian fields; the header's payload size is patched at the end.
class Writer {
 public:
  Writer(MessageType type, std::uint32_t request_id) {
    bytes_.reserve(256);
    put_u32(kMagic);
    put_u16(kVersion);
    put_u16(static_cast<std::uint16_t>(type));
    put_u32(0);
    put_u32(request_id);
  }
  void put_u8(std::uint8_t v) { bytes_.push_back(v); }
  void put_bool(bool v) { put_u8(v ? 1 : 0); }
  void put_u16(std::uint16_t v) { put_raw(&v, sizeof v); }
  void put_u32(std::uint32_t v) { put_raw(&v, sizeof v); }
  void put_u64(std::uint64_t v) { put_raw(&v, sizeof v); }
  void put_i32(std::int32_t v) { put_raw(&v, sizeof v); }
  void put_i64(std::int64_t v) { put_raw(&v, sizeof v); }
  void put_f64(double v) { put_raw(&v, sizeof v); }
  void put_string(const std::string& s) {
    if (s.size() > kMaxStringBytes) throw ProtocolError("string too long to send");
    put_u32(static_cast<std::uint32_t>(s.size()));
    put_raw(s.data(), s.size());
  }
  void put_opt_f64(const std::optional<double>& v) {
    put_bool(v.has_value());
    if (v) put_f64(*v);
  }
  void put_opt_bool(const std::optional<bool>& v) {
    put_bool(v.has_value());
    if (v) put_bool(*v);
  }
  void put_count(std::size_t n) {
    if (n > kMaxListItems) throw ProtocolError("list too long to send");
    put_u32(static_cast<std::uint32_t>(n));
  }
  Packet finish() {
    if (bytes_.size() > kMaxMessageBytes) throw ProtocolError("message too large to send");
    const auto payload = static_cast<std::uint32_t>(bytes_.size() - kHeaderBytes);
    std::memcpy(bytes_.data() + 8, &payload, sizeof payload);
    return std::move(bytes_);
  }

 private:
  void put_raw(const void* p, std::size_t n) {
    if (n == 0) return;
    const std::size_t old = bytes_.size();
    bytes_.resize(old + n);
    std::memcpy(bytes_.data() + old, p, n);
  }
  Packet bytes_;
};

// Reads fields back, throwing on anything short, out of range or left over.
class Reader {
 public:
  explicit Reader(Payload p) : p_(p) {}
  std::uint8_t u8() {
    std::uint8_t v;
    raw(&v, 1);
    return v;
  }
  bool boolean() {
    const std::uint8_t v = u8();
    if (v > 1) throw ProtocolError("bad boolean");
    return v == 1;
  }
  std::uint16_t u16() { return get<std::uint16_t>(); }
  std::uint32_t u32() { return get<std::uint32_t>(); }
  std::uint64_t u64() { return get<std::uint64_t>(); }
  std::int32_t i32() { return get<std::int32_t>(); }
  std::int64_t i64() { return get<std::int64_t>(); }
  double f64() {
    const double v = get<double>();
    if (!std::isfinite(v)) throw ProtocolError("non-finite number");
    return v;
  }
  std::string string() {
    const std::uint32_t n = u32();
    if (n > kMaxStringBytes || n > left()) throw ProtocolError("bad string length");
    std::string s(reinterpret_cast<const char*>(p_.data + pos_), n);
    pos_ += n;
    return s;
  }
  std::optional<double> opt_f64() {
    if (!boolean()) return std::nullopt;
    return f64();
  }
  std::optional<bool> opt_bool() {
    if (!boolean()) return std::nullopt;
    return boolean();
  }
  std::size_t count() {
    const std::uint32_t n = u32();
    if (n > kMaxListItems || n > left()) throw ProtocolError("bad list length");
    return n;
  }
  template <typename E>
  E enumeration(std::uint8_t last) {
    const std::uint8_t v = u8();
    if (v > last) throw ProtocolError("enum value out of range");
    return static_cast<E>(v);
  }
  int dimension() {
    const std::int32_t v = i32();
    if (v < 0 || v > kMaxDimension) throw ProtocolError("dimension out of range");
    return v;
  }
  void finish() const {
    if (pos_ != p_.size) throw ProtocolError("trailing bytes in message");
  }

 private:
  std::size_t left() const { return p_.size - pos_; }
  void raw(void* out, std::size_t n) {
    if (n > left()) throw ProtocolError("message truncated");
    std::memcpy(out, p_.data + pos_, n);
    pos_ += n;
  }
  template <typename T>
  T get() {
    T v;
    raw(&v, sizeof v);
    return v;
  }
  Payload p_;
  std::size_t pos_ = 0;
};

constexpr std::uint8_t kLastPixelFormat = static_cast<std::uint8_t>(PixelFormat::GREY);

void put_format(Writer& w, const FrameFormat& f) {
  w.put_u8(static_cast<std::uint8_t>(f.pixel_format));
  w.put_i32(f.width);
  w.put_i32(f.height);
  w.put_i32(f.stride);
  w.put_u8(static_cast<std::uint8_t>(f.encoding));
  w.put_u8(static_cast<std::uint8_t>(f.range));
}

FrameFormat get_format(Reader& r) {
  FrameFormat f;
  f.pixel_format = r.enumeration<PixelFormat>(kLastPixelFormat);
  f.width = r.dimension();
  f.height = r.dimension();
  const std::int32_t stride = r.i32();
  if (stride < 0 || stride > kMaxDimension * 4) throw ProtocolError("stride out of range");
  f.stride = stride;
  f.encoding = r.enumeration<YcbcrEncoding>(static_cast<std::uint8_t>(YcbcrEncoding::Bt709));
  f.range = r.enumeration<QuantisationRange>(static_cast<std::uint8_t>(QuantisationRange::Full));
  return f;
}

void put_metadata(Writer& w, const FrameMetadata& m) {
  w.put_i64(m.timestamp_ns);
  w.put_u64(m.sequence);
  w.put_opt_f64(m.exposure_us);
  w.put_opt_f64(m.analogue_gain);
  w.put_opt_f64(m.colour_gain_red);
  w.put_opt_f64(m.colour_gain_blue);
  w.put_opt_f64(m.colour_temperature_k);
}

FrameMetadata get_metadata(Reader& r) {
  FrameMetadata m;
  m.timestamp_ns = r.i64();
  m.sequence = r.u64();
  m.exposure_us = r.opt_f64();
  m.analogue_gain = r.opt_f64();
  m.colour_gain_red = r.opt_f64();
  m.colour_gain_blue = r.opt_f64();
  m.colour_temperature_k = r.opt_f64();
  return m;
}

void put_config(Writer& w, const StreamConfig& c) {
  w.put_u8(static_cast<std::uint8_t>(c.pixel_format));
  w.put_i32(c.width);
  w.put_i32(c.height);
  w.put_f64(c.fps);
}

StreamConfig get_config(Reader& r) {
  StreamConfig c;
  c.pixel_format = r.enumeration<PixelFormat>(kLastPixelFormat);
  c.width = r.dimension();
  c.height = r.dimension();
  c.fps = r.f64();
  if (c.fps < 0 || c.fps > 10000) throw ProtocolError("fps out of range");
  return c;
}

void put_camera(Writer& w, const CameraInfo& c) {
  w.put_string(c.id);
  w.put_string(c.backend);
  w.put_string(c.description);
  w.put_count(c.formats.size());
  for (const auto& f : c.formats) {
    w.put_u8(static_cast<std::uint8_t>(f.pixel_format));
    w.put_count(f.sizes.size());
    for (const auto& s : f.sizes) {
      w.put_i32(s.width);
      w.put_i32(s.height);
    }
  }
}

CameraInfo get_camera(Reader& r) {
  CameraInfo c;
  c.id = r.string();
  c.backend = r.string();
  c.description = r.string();
  const std::size_t formats = r.count();
  for (std::size_t i = 0; i < formats; ++i) {
    FormatSizes f;
    f.pixel_format = r.enumeration<PixelFormat>(kLastPixelFormat);
    const std::size_t sizes = r.count();
    for (std::size_t j = 0; j < sizes; ++j) {
      FormatSizes::Size s;
      s.width = r.dimension();
      s.height = r.dimension();
      f.sizes.push_back(s);
    }
    c.formats.push_back(std::move(f));
  }
  return c;
}

void put_ring(Writer& w, const RingInfo& m) {
  w.put_u32(m.generation);
  w.put_u32(m.slot_count);
  w.put_u64(m.slot_bytes);
}

RingInfo get_ring(Reader& r) {
  RingInfo m;
  m.generation = r.u32();
  m.slot_count = r.u32();
  m.slot_bytes = r.u64();
  // Bounds that keep slot_count * slot_bytes far from overflowing.
  if (m.slot_count == 0 || m.slot_count > 1024) throw ProtocolError("bad ring slot count");
  if (m.slot_bytes == 0 || m.slot_bytes > (std::uint64_t{1} << 32)) throw ProtocolError("bad ring slot size");
  return m;
}

template <typename Fn>
auto decode_with(Payload p, Fn fn) {
  Reader r(p);
  auto v = fn(r);
  r.finish();
  return v;
}

}  // namespace

bool valid_message_type(std::uint16_t type) {
  return (type >= static_cast<std::uint16_t>(MessageType::ListCameras) &&
          type <= static_cast<std::uint16_t>(MessageType::ReleaseSlot)) ||
         (type >= static_cast<std::uint16_t>(MessageType::Welcome) &&
          type <= static_cast<std::uint16_t>(MessageType::Status));
}

std::string to_string(DeviceState state) {
  switch (state) {
    case DeviceState::Closed: return "closed";
    case DeviceState::Idle: return "idle";
    case DeviceState::Streaming: return "streaming";
    case DeviceState::Lost: return "lost";
    case DeviceState::Ended: return "ended";
  }
  return "unknown";
}

Packet encode(MessageType type, std::uint32_t request_id) { return Writer(type, request_id).finish(); }

Packet encode(std::uint32_t request_id, const Welcome& m) {
  Writer w(MessageType::Welcome, request_id);
  w.put_u32(m.client_id);
  w.put_u32(m.max_held_slots);
  w.put_bool(m.ring.has_value());
  if (m.ring) put_ring(w, *m.ring);
  return w.finish();
}

Packet encode_ring_changed(const RingInfo& m) {
  Writer w(MessageType::RingChanged, 0);
  put_ring(w, m);
  return w.finish();
}

Packet encode(const FrameReady& m) {
  Writer w(MessageType::FrameReady, 0);
  w.put_u32(m.generation);
  w.put_u32(m.slot);
  w.put_u64(m.bytes_used);
  put_format(w, m.format);
  put_metadata(w, m.metadata);
  return w.finish();
}

Packet encode(std::uint32_t request_id, const ReleaseSlot& m) {
  Writer w(MessageType::ReleaseSlot, request_id);
  w.put_u32(m.generation);
  w.put_u32(m.slot);
  return w.finish();
}

Packet encode(const Event& m) {
  Writer w(MessageType::Event, 0);
  w.put_u8(static_cast<std::uint8_t>(m.kind));
  w.put_string(m.message.substr(0, kMaxStringBytes));
  return w.finish();
}

Packet encode_error(std::uint32_t request_id, const std::string& message) {
  Writer w(MessageType::Error, request_id);
  w.put_string(message.substr(0, kMaxStringBytes));
  return w.finish();
}

Packet encode_camera_list(std::uint32_t request_id, const std::vector<CameraInfo>& cameras) {
  Writer w(MessageType::CameraList, request_id);
  w.put_count(cameras.size());
  for (const auto& c : cameras) put_camera(w, c);
  return w.finish();
}

Packet encode_info(std::uint32_t request_id, const CameraInfo& info) {
  Writer w(MessageType::Info, request_id);
  put_camera(w, info);
  return w.finish();
}

Packet encode_select_camera(std::uint32_t request_id, const std::string& id) {
  Writer w(MessageType::SelectCamera, request_id);
  w.put_string(id);
  return w.finish();
}

Packet encode_configure(std::uint32_t request_id, const StreamConfig& config) {
  Writer w(MessageType::Configure, request_id);
  put_config(w, config);
  return w.finish();
}

Packet encode(std::uint32_t request_id, const ConfigureReply& m) {
  Writer w(MessageType::ConfigureReply, request_id);
  w.put_u8(static_cast<std::uint8_t>(m.status));
  put_config(w, m.config);
  return w.finish();
}

Packet encode(std::uint32_t request_id, const CameraControls& m) {
  Writer w(MessageType::SetControls, request_id);
  w.put_opt_f64(m.exposure_us);
  w.put_opt_f64(m.analogue_gain);
  w.put_opt_f64(m.colour_gain_red);
  w.put_opt_f64(m.colour_gain_blue);
  w.put_opt_bool(m.auto_exposure);
  w.put_opt_bool(m.auto_white_balance);
  return w.finish();
}

Packet encode_controls_reply(std::uint32_t request_id, const std::vector<std::string>& not_applied) {
  Writer w(MessageType::ControlsReply, request_id);
  w.put_count(not_applied.size());
  for (const auto& s : not_applied) w.put_string(s);
  return w.finish();
}

Packet encode(std::uint32_t request_id, const CaptureStillRequest& m) {
  Writer w(MessageType::CaptureStill, request_id);
  w.put_bool(m.config.has_value());
  if (m.config) put_config(w, *m.config);
  w.put_u32(m.timeout_ms);
  return w.finish();
}

Packet encode(std::uint32_t request_id, const StillFrame& m) {
  Writer w(MessageType::StillFrame, request_id);
  w.put_u8(static_cast<std::uint8_t>(m.status));
  w.put_string(m.message.substr(0, kMaxStringBytes));
  w.put_u64(m.bytes_used);
  w.put_u64(m.memfd_bytes);
  put_format(w, m.format);
  put_metadata(w, m.metadata);
  return w.finish();
}

Packet encode(std::uint32_t request_id, const Status& m) {
  Writer w(MessageType::Status, request_id);
  w.put_string(m.camera_id);
  put_config(w, m.stream);
  w.put_u8(static_cast<std::uint8_t>(m.device_state));
  w.put_f64(m.fps);
  w.put_u64(m.frames_captured);
  w.put_u64(m.frames_unplaced);
  w.put_u64(m.device_lost_count);
  w.put_u32(m.you);
  w.put_count(m.clients.size());
  for (const auto& c : m.clients) {
    w.put_u32(c.client_id);
    w.put_u64(c.frames_sent);
    w.put_u64(c.frames_dropped);
    w.put_u32(c.slots_held);
    w.put_bool(c.viewfinder);
  }
  return w.finish();
}

Header decode_header(const std::uint8_t* data, std::size_t size) {
  if (size < kHeaderBytes) throw ProtocolError("message shorter than its header");
  if (size > kMaxMessageBytes) throw ProtocolError("message too large");
  Reader r(Payload{data, kHeaderBytes});
  Header h;
  h.magic = r.u32();
  if (h.magic != kMagic) throw ProtocolError("bad magic");
  h.version = r.u16();
  if (h.version != kVersion) throw ProtocolError("unsupported protocol version " + std::to_string(h.version));
  const std::uint16_t type = r.u16();
  if (!valid_message_type(type)) throw ProtocolError("unknown message type " + std::to_string(type));
  h.type = static_cast<MessageType>(type);
  h.payload_bytes = r.u32();
  h.request_id = r.u32();
  if (h.payload_bytes != size - kHeaderBytes) throw ProtocolError("payload size does not match the packet");
  return h;
}

Payload payload_of(const std::uint8_t* data, std::size_t size) {
  return Payload{data + kHeaderBytes, size - kHeaderBytes};
}

Welcome decode_welcome(Payload p) {
  return decode_with(p, [](Reader& r) {
    Welcome m;
    m.client_id = r.u32();
    m.max_held_slots = r.u32();
    if (r.boolean()) m.ring = get_ring(r);
    return m;
  });
}

RingInfo decode_ring_info(Payload p) {
  return decode_with(p, [](Reader& r) { return get_ring(r); });
}

FrameReady decode_frame_ready(Payload p) {
  return decode_with(p, [](Reader& r) {
    FrameReady m;
    m.generation = r.u32();
    m.slot = r.u32();
    m.bytes_used = r.u64();
    m.format = get_format(r);
    m.metadata = get_metadata(r);
    return m;
  });
}

ReleaseSlot decode_release_slot(Payload p) {
  return decode_with(p, [](Reader& r) {
    ReleaseSlot m;
    m.generation = r.u32();
    m.slot = r.u32();
    return m;
  });
}

Event decode_event(Payload p) {
  return decode_with(p, [](Reader& r) {
    Event m;
    m.kind = r.enumeration<EventKind>(static_cast<std::uint8_t>(EventKind::EndOfStream));
    m.message = r.string();
    return m;
  });
}

std::string decode_error(Payload p) {
  return decode_with(p, [](Reader& r) { return r.string(); });
}

std::vector<CameraInfo> decode_camera_list(Payload p) {
  return decode_with(p, [](Reader& r) {
    std::vector<CameraInfo> cameras;
    const std::size_t n = r.count();
    for (std::size_t i = 0; i < n; ++i) cameras.push_back(get_camera(r));
    return cameras;
  });
}

CameraInfo decode_info(Payload p) {
  return decode_with(p, [](Reader& r) { return get_camera(r); });
}

std::string decode_select_camera(Payload p) {
  return decode_with(p, [](Reader& r) {
    std::string id = r.string();
    if (id.empty()) throw ProtocolError("empty camera id");
    return id;
  });
}

StreamConfig decode_configure(Payload p) {
  return decode_with(p, [](Reader& r) { return get_config(r); });
}

ConfigureReply decode_configure_reply(Payload p) {
  return decode_with(p, [](Reader& r) {
    ConfigureReply m;
    m.status = r.enumeration<ConfigStatus>(static_cast<std::uint8_t>(ConfigStatus::Invalid));
    m.config = get_config(r);
    return m;
  });
}

CameraControls decode_controls(Payload p) {
  return decode_with(p, [](Reader& r) {
    CameraControls m;
    m.exposure_us = r.opt_f64();
    m.analogue_gain = r.opt_f64();
    m.colour_gain_red = r.opt_f64();
    m.colour_gain_blue = r.opt_f64();
    m.auto_exposure = r.opt_bool();
    m.auto_white_balance = r.opt_bool();
    return m;
  });
}

std::vector<std::string> decode_controls_reply(Payload p) {
  return decode_with(p, [](Reader& r) {
    std::vector<std::string> names;
    const std::size_t n = r.count();
    for (std::size_t i = 0; i < n; ++i) names.push_back(r.string());
    return names;
  });
}

CaptureStillRequest decode_capture_still(Payload p) {
  return decode_with(p, [](Reader& r) {
    CaptureStillRequest m;
    if (r.boolean()) m.config = get_config(r);
    m.timeout_ms = r.u32();
    if (m.timeout_ms > 60000) throw ProtocolError("still timeout above 60 s");
    return m;
  });
}

StillFrame decode_still_frame(Payload p) {
  return decode_with(p, [](Reader& r) {
    StillFrame m;
    m.status = r.enumeration<CaptureStatus>(static_cast<std::uint8_t>(CaptureStatus::EndOfStream));
    m.message = r.string();
    m.bytes_used = r.u64();
    m.memfd_bytes = r.u64();
    if (m.bytes_used > m.memfd_bytes || m.memfd_bytes > (std::uint64_t{1} << 32))
      throw ProtocolError("bad still size");
    m.format = get_format(r);
    m.metadata = get_metadata(r);
    return m;
  });
}

Status decode_status(Payload p) {
  return decode_with(p, [](Reader& r) {
    Status m;
    m.camera_id = r.string();
    m.stream = get_config(r);
    m.device_state = r.enumeration<DeviceState>(static_cast<std::uint8_t>(DeviceState::Ended));
    m.fps = r.f64();
    m.frames_captured = r.u64();
    m.frames_unplaced = r.u64();
    m.device_lost_count = r.u64();
    m.you = r.u32();
    const std::size_t n = r.count();
    for (std::size_t i = 0; i < n; ++i) {
      ClientStatus c;
      c.client_id = r.u32();
      c.frames_sent = r.u64();
      c.frames_dropped = r.u64();
      c.slots_held = r.u32();
      c.viewfinder = r.boolean();
      m.clients.push_back(c);
    }
    return m;
  });
}

void decode_empty(Payload p) {
  Reader(p).finish();
}

}  // namespace propcam::capture::protocol
