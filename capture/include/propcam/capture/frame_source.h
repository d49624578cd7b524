// One interface for every camera: libcamera, V4L2 and the replay of a
// recording. A source is opened by id (camera_registry.h), configured,
// started, and then hands out frames until it is stopped. Expected
// conditions (a timeout, the camera unplugged, the end of a recording) are
// values in CaptureResult; broken calls (next_frame before start) throw.
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "propcam/capture/frame.h"

namespace propcam::capture {

struct StreamConfig {
  PixelFormat pixel_format = PixelFormat::YUYV;
  int width = 640;
  int height = 480;
  double fps = 30;  // 0: the camera's default
};

// As libcamera answers a configuration: accepted as asked, adjusted to the
// nearest the camera supports (the config is rewritten), or impossible.
enum class ConfigStatus { Valid, Adjusted, Invalid };

// What a camera offers: each pixel format with its frame sizes.
struct FormatSizes {
  PixelFormat pixel_format = PixelFormat::YUYV;
  struct Size {
    int width = 0;
    int height = 0;
  };
  std::vector<Size> sizes;
};

struct CameraInfo {
  std::string id;           // "v4l2:/dev/video0", "libcamera:<name>", "replay:<folder>"
  std::string backend;      // "v4l2", "libcamera", "replay"
  std::string description;  // the driver's card name, the sensor model, ...
  std::vector<FormatSizes> formats;
};

// Controls a client may set; unset fields are left as they are.
struct CameraControls {
  std::optional<double> exposure_us;      // manual exposure (turns auto-exposure off)
  std::optional<double> analogue_gain;
  std::optional<double> colour_gain_red;  // manual white balance
  std::optional<double> colour_gain_blue;
  std::optional<bool> auto_exposure;      // false locks exposure and gain where they are
  std::optional<bool> auto_white_balance;
};

enum class CaptureStatus {
  Ok,          // frame holds a frame
  Timeout,     // nothing arrived in time; the source is still usable
  DeviceLost,  // the camera went away; reopen it (the daemon retries)
  EndOfStream, // a recording played to its end without looping
};
std::string to_string(CaptureStatus status);

struct CaptureResult {
  CaptureStatus status = CaptureStatus::Timeout;
  std::optional<Frame> frame;
  std::string message;  // why, when status is not Ok
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;

  virtual CameraInfo info() const = 0;
  // Checks and adjusts the viewfinder stream; Invalid leaves the source as it was.
  virtual ConfigStatus configure(StreamConfig& config) = 0;
  virtual StreamConfig configuration() const = 0;
  virtual void start() = 0;
  virtual void stop() = 0;
  virtual bool running() const = 0;

  // The next viewfinder frame, waiting at most `timeout`.
  virtual CaptureResult next_frame(std::chrono::milliseconds timeout) = 0;
  // One frame of the still stream (the highest resolution the camera offers
  // when `still` is nullopt), taken with the current controls; the viewfinder
  // is resumed afterwards if it was running.
  virtual CaptureResult capture_still(const std::optional<StreamConfig>& still,
                                      std::chrono::milliseconds timeout) = 0;

  // Applies what the camera supports; returns the controls it could not
  // apply, named, so the caller can tell the user.
  virtual std::vector<std::string> set_controls(const CameraControls& controls) = 0;
};

}  // namespace propcam::capture
