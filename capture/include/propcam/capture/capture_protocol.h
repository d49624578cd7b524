// The wire protocol between propcamd (capture_server.h) and its clients
// (capture_client.h), over a UNIX SOCK_SEQPACKET socket: one message per
// packet, a fixed header then a small length-prefixed little-endian payload.
// Frames themselves never cross the socket: they sit in a shared-memory ring
// (a memfd passed with SCM_RIGHTS) and a FrameReady message names the slot.
// Every decoder validates sizes, enum ranges and counts and throws
// ProtocolError, so a garbled packet can never crash the reader.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "propcam/capture/frame.h"
#include "propcam/capture/frame_source.h"

namespace propcam::capture::protocol {

inline constexpr std::uint32_t kMagic = 0x4d435050;  // "PPCM" little-endian
inline constexpr std::uint16_t kVersion = 1;
inline constexpr std::size_t kHeaderBytes = 16;
// Largest packet either side sends or accepts (the camera list is the biggest).
inline constexpr std::size_t kMaxMessageBytes = 64 * 1024;
inline constexpr std::size_t kMaxStringBytes = 4096;
inline constexpr std::size_t kMaxListItems = 256;
inline constexpr int kMaxDimension = 16384;

class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class MessageType : std::uint16_t {
  // client -> server (each but ReleaseSlot answered with its reply or Error)
  ListCameras = 1,
  GetInfo = 2,
  SelectCamera = 3,
  Configure = 4,
  StartViewfinder = 5,
  StopViewfinder = 6,
  SetControls = 7,
  CaptureStill = 8,
  GetStatus = 9,
  ReleaseSlot = 10,
  // server -> client
  Welcome = 100,      // first message; carries the ring fd when there is a ring
  RingChanged = 101,  // a new ring (fd attached); frames of older rings are not released
  FrameReady = 102,
  Event = 103,
  Ok = 104,
  Error = 105,
  CameraList = 106,
  Info = 107,
  ConfigureReply = 108,
  ControlsReply = 109,
  StillFrame = 110,   // the still's own memfd attached
  Status = 111,
};
inline constexpr std::uint16_t kFirstServerType = 100;
bool valid_message_type(std::uint16_t type);

struct Header {
  std::uint32_t magic = kMagic;
  std::uint16_t version = kVersion;
  MessageType type = MessageType::Error;
  std::uint32_t payload_bytes = 0;
  std::uint32_t request_id = 0;  // echoed in the reply; 0 for unsolicited messages
};

// ---- payloads ---------------------------------------------------------------

struct RingInfo {
  std::uint32_t generation = 0;  // increases with every new ring
  std::uint32_t slot_count = 0;
  std::uint64_t slot_bytes = 0;  // slot i starts at i * slot_bytes
};

struct Welcome {
  std::uint32_t client_id = 0;
  std::uint32_t max_held_slots = 0;  // frames a client may hold before it misses frames
  std::optional<RingInfo> ring;      // none until a camera has been opened
};

struct FrameReady {
  std::uint32_t generation = 0;
  std::uint32_t slot = 0;
  std::uint64_t bytes_used = 0;
  FrameFormat format;
  FrameMetadata metadata;
};

struct ReleaseSlot {
  std::uint32_t generation = 0;
  std::uint32_t slot = 0;
};

enum class EventKind : std::uint8_t { DeviceLost = 0, Resumed = 1, EndOfStream = 2 };
struct Event {
  EventKind kind = EventKind::DeviceLost;
  std::string message;
};

// The device's state as the server sees it.
enum class DeviceState : std::uint8_t {
  Closed = 0,     // no camera open yet
  Idle = 1,       // open, not streaming (no client wants the viewfinder)
  Streaming = 2,
  Lost = 3,       // unplugged; reopening with backoff
  Ended = 4,      // the recording ended
};
std::string to_string(DeviceState state);

struct ClientStatus {
  std::uint32_t client_id = 0;
  std::uint64_t frames_sent = 0;
  std::uint64_t frames_dropped = 0;  // missed: all its slots held, or its socket full
  std::uint32_t slots_held = 0;
  bool viewfinder = false;
};

struct Status {
  std::string camera_id;
  StreamConfig stream;               // the viewfinder configuration in use
  DeviceState device_state = DeviceState::Closed;
  double fps = 0;                    // frames from the camera over the last second or so
  std::uint64_t frames_captured = 0;
  std::uint64_t frames_unplaced = 0;  // no free ring slot: nobody got the frame
  std::uint64_t device_lost_count = 0;
  std::uint32_t you = 0;             // the asking client's id
  std::vector<ClientStatus> clients;
};

// Ok: the still's memfd is attached; otherwise why there is no still.
struct StillFrame {
  CaptureStatus status = CaptureStatus::Ok;
  std::string message;
  std::uint64_t bytes_used = 0;
  std::uint64_t memfd_bytes = 0;
  FrameFormat format;
  FrameMetadata metadata;
};

struct CaptureStillRequest {
  std::optional<StreamConfig> config;
  std::uint32_t timeout_ms = 0;
};

struct ConfigureReply {
  ConfigStatus status = ConfigStatus::Invalid;
  StreamConfig config;
};

// ---- encoding ---------------------------------------------------------------

// A packet: the header followed by the payload.
using Packet = std::vector<std::uint8_t>;

Packet encode(MessageType type, std::uint32_t request_id);  // no payload
Packet encode(std::uint32_t request_id, const Welcome& m);
Packet encode_ring_changed(const RingInfo& m);
Packet encode(const FrameReady& m);
Packet encode(std::uint32_t request_id, const ReleaseSlot& m);
Packet encode(const Event& m);
Packet encode_error(std::uint32_t request_id, const std::string& message);
Packet encode_camera_list(std::uint32_t request_id, const std::vector<CameraInfo>& cameras);
Packet encode_info(std::uint32_t request_id, const CameraInfo& info);
Packet encode_select_camera(std::uint32_t request_id, const std::string& id);
Packet encode_configure(std::uint32_t request_id, const StreamConfig& config);
Packet encode(std::uint32_t request_id, const ConfigureReply& m);
Packet encode(std::uint32_t request_id, const CameraControls& m);
Packet encode_controls_reply(std::uint32_t request_id, const std::vector<std::string>& not_applied);
Packet encode(std::uint32_t request_id, const CaptureStillRequest& m);
Packet encode(std::uint32_t request_id, const StillFrame& m);
Packet encode(std::uint32_t request_id, const Status& m);

// Checks magic, version, type and that the payload size matches the packet.
Header decode_header(const std::uint8_t* data, std::size_t size);

// Each decoder takes the payload (the bytes after the header) and requires
// it to be consumed exactly.
struct Payload {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};
Payload payload_of(const std::uint8_t* data, std::size_t size);  // after decode_header

Welcome decode_welcome(Payload p);
RingInfo decode_ring_info(Payload p);
FrameReady decode_frame_ready(Payload p);
ReleaseSlot decode_release_slot(Payload p);
Event decode_event(Payload p);
std::string decode_error(Payload p);
std::vector<CameraInfo> decode_camera_list(Payload p);
CameraInfo decode_info(Payload p);
std::string decode_select_camera(Payload p);
StreamConfig decode_configure(Payload p);
ConfigureReply decode_configure_reply(Payload p);
CameraControls decode_controls(Payload p);
std::vector<std::string> decode_controls_reply(Payload p);
CaptureStillRequest decode_capture_still(Payload p);
StillFrame decode_still_frame(Payload p);
Status decode_status(Payload p);
void decode_empty(Payload p);

}  // namespace propcam::capture::protocol
