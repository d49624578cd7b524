// A libcamera camera (Raspberry Pi CSI sensors, UVC through libcamera's
// uvcvideo pipeline), written against libcamera 0.0.3 as Debian bookworm
// ships it. One CameraManager serves the whole process. Completed requests
// are only queued by libcamera's thread; next_frame copies the newest one
// and gives every request straight back to the camera.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "propcam/capture/frame_source.h"

namespace propcam::capture {

class LibcameraSource final : public FrameSource {
 public:
  // `camera_id` is libcamera's id (without the "libcamera:" prefix). Acquires
  // the camera and configures the viewfinder role with its defaults (a
  // convertible pixel format preferred). Throws std::runtime_error naming the
  // camera and the reason (manager not started, no such camera, busy).
  explicit LibcameraSource(const std::string& camera_id);
  ~LibcameraSource() override;
  LibcameraSource(const LibcameraSource&) = delete;
  LibcameraSource& operator=(const LibcameraSource&) = delete;

  CameraInfo info() const override;
  // Throws std::logic_error while running (stop first).
  ConfigStatus configure(StreamConfig& config) override;
  StreamConfig configuration() const override;
  FrameFormat frame_format() const;
  void start() override;
  void stop() override;
  bool running() const override;
  // The newest completed frame; older completed ones are dropped (and their
  // requests re-queued), metadata.sequence shows the gap.
  CaptureResult next_frame(std::chrono::milliseconds timeout) override;
  CaptureResult capture_still(const std::optional<StreamConfig>& still,
                              std::chrono::milliseconds timeout) override;
  std::vector<std::string> set_controls(const CameraControls& controls) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Every camera libcamera sees (empty when the manager cannot start).
std::vector<CameraInfo> list_libcamera_cameras();

// True when a libcamera camera is built on this V4L2 device node (a UVC
// webcam is both), so the registry lists it once, as the libcamera camera.
// False when the manager cannot start or the path is not a device.
bool libcamera_owns_device(const std::string& device_path);

// The pure parts of the backend, exposed for tests.
namespace libcamera_map {

// libcamera (DRM) fourcc <-> PixelFormat. DRM names the bytes of a
// little-endian word from the high end: libcamera's RGB888 ('RG24') is
// B, G, R in memory (PixelFormat::BGR24) and BGR888 ('BG24') is R, G, B.
std::optional<PixelFormat> to_pixel_format(std::uint32_t drm_fourcc);
std::optional<std::uint32_t> to_drm_fourcc(PixelFormat format);

// libcamera::ColorSpace's ycbcrEncoding / range as their enum values
// (ColorSpace::YcbcrEncoding: None 0, Rec601 1, Rec709 2, Rec2020 3;
// Range: Full 0, Limited 1), nullopt when the stream has no colour space.
// Rec2020 maps to BT.709 (the nearest PropCam converts); None (RGB, raw)
// and an unknown space to BT.601. The range defaults by format: full for
// RGB and MJPEG, limited for YUV.
struct Colour {
  YcbcrEncoding encoding = YcbcrEncoding::Bt601;
  QuantisationRange range = QuantisationRange::Limited;
};
Colour colour_from_libcamera(std::optional<int> ycbcr_encoding, std::optional<int> range,
                             PixelFormat format);

// The frame duration limits (µs) that ask for `fps`, clamped to what the
// camera allows ([min_us, max_us]; 0 for an unknown bound).
std::int64_t frame_duration_us(double fps, std::int64_t min_us, std::int64_t max_us);

}  // namespace libcamera_map
}  // namespace propcam::capture
