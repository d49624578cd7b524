// A client of propcamd (capture_server.h). Frames arrive as views into the
// daemon's shared-memory ring: no copy; the slot goes back to the daemon
// when the last reference to the frame's buffer goes (from any thread).
// Holding more frames than the daemon allows (Welcome::max_held_slots, 2 by
// default) makes the client miss frames, not stall the camera.
//
// One thread at a time calls a CaptureClient's methods; frames may be
// released from any thread. Commands throw CaptureClientError when the
// daemon refuses them, does not answer in time, or the connection is gone.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "propcam/capture/capture_protocol.h"
#include "propcam/capture/frame_source.h"

namespace propcam::capture {

class CaptureClientError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CaptureClient {
 public:
  // Connects and maps the ring; throws CaptureClientError.
  explicit CaptureClient(const std::string& socket_path,
                         std::chrono::milliseconds command_timeout = std::chrono::seconds(10));
  ~CaptureClient();
  CaptureClient(const CaptureClient&) = delete;
  CaptureClient& operator=(const CaptureClient&) = delete;

  std::uint32_t client_id() const;
  std::uint32_t max_held_slots() const;

  std::vector<CameraInfo> list_cameras();
  CameraInfo info();
  void select_camera(const std::string& id);
  // As FrameSource::configure: `config` is rewritten to what the camera took.
  ConfigStatus configure(StreamConfig& config);
  void start_viewfinder();
  void stop_viewfinder();
  // The controls the camera could not apply.
  std::vector<std::string> set_controls(const CameraControls& controls);
  // The still arrives in its own memfd; the frame's buffer maps it.
  CaptureResult capture_still(const std::optional<StreamConfig>& still, std::chrono::milliseconds timeout);
  protocol::Status status();

  // The next viewfinder frame (after start_viewfinder), or the daemon's
  // DeviceLost / EndOfStream events in the order they came, or Timeout.
  // A lost connection to the daemon is reported as DeviceLost.
  CaptureResult next_frame(std::chrono::milliseconds timeout);
  // Every event received so far (DeviceLost, Resumed, EndOfStream), oldest first.
  std::vector<protocol::Event> take_events();
  // The device's state as far as the events tell (Lost after DeviceLost,
  // Streaming after Resumed, Ended after EndOfStream).
  protocol::DeviceState device_state() const;
  bool connected() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The daemon as a FrameSource, so the appliance uses it like a local camera.
// start()/stop() are the viewfinder; DeviceLost needs no reopen: the daemon
// reopens the camera and frames come back by themselves.
class DaemonFrameSource final : public FrameSource {
 public:
  explicit DaemonFrameSource(const std::string& socket_path,
                             const std::optional<std::string>& camera_id = std::nullopt);

  CameraInfo info() const override;
  ConfigStatus configure(StreamConfig& config) override;
  StreamConfig configuration() const override;
  void start() override;
  void stop() override;
  bool running() const override;
  CaptureResult next_frame(std::chrono::milliseconds timeout) override;
  CaptureResult capture_still(const std::optional<StreamConfig>& still,
                              std::chrono::milliseconds timeout) override;
  std::vector<std::string> set_controls(const CameraControls& controls) override;

  CaptureClient& client() { return *client_; }

 private:
  std::unique_ptr<CaptureClient> client_;
  bool running_ = false;
};

}  // namespace propcam::capture
