// A V4L2 capture node (a UVC webcam, a CSI bridge driver, vivid) driven
// through the kernel API directly: single-planar capture, mmap streaming.
// Each dequeued buffer is copied into the Frame and re-queued at once, so
// a client that holds frames never takes buffers from the driver.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "propcam/capture/frame_source.h"

namespace propcam::capture {

class V4l2Source final : public FrameSource {
 public:
  // Opens and checks the node (a streaming video capture device). The
  // driver's current format is kept when PropCam can convert it, else the
  // first convertible format is configured near 640x480. Throws
  // std::runtime_error naming the path and the failed step.
  explicit V4l2Source(const std::string& device_path);
  ~V4l2Source() override;
  V4l2Source(const V4l2Source&) = delete;
  V4l2Source& operator=(const V4l2Source&) = delete;

  CameraInfo info() const override;
  // Throws std::logic_error while running (stop first).
  ConfigStatus configure(StreamConfig& config) override;
  StreamConfig configuration() const override;
  // The format the frames carry (stride, encoding and range as negotiated).
  FrameFormat frame_format() const;
  void start() override;
  void stop() override;
  bool running() const override;
  // Returns the newest frame waiting: older ones already dequeued are
  // dropped (metadata.sequence shows the gap).
  CaptureResult next_frame(std::chrono::milliseconds timeout) override;
  CaptureResult capture_still(const std::optional<StreamConfig>& still,
                              std::chrono::milliseconds timeout) override;
  std::vector<std::string> set_controls(const CameraControls& controls) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The capture nodes under `dev_dir` (video* entries; metadata, output and
// multiplanar-only nodes skipped; nodes that cannot be opened skipped).
std::vector<CameraInfo> list_v4l2_cameras(const std::string& dev_dir = "/dev");

// The pure parts of the backend, exposed for tests.
namespace v4l2 {

// V4L2 fourcc <-> PixelFormat for the formats PropCam converts.
std::optional<PixelFormat> to_pixel_format(std::uint32_t v4l2_fourcc);
std::optional<std::uint32_t> to_v4l2_fourcc(PixelFormat format);

struct Colour {
  YcbcrEncoding encoding = YcbcrEncoding::Bt601;
  QuantisationRange range = QuantisationRange::Limited;
};
// v4l2_pix_format's colorspace / ycbcr_enc / quantization, with the
// kernel's defaults resolved (videodev2.h V4L2_MAP_*_DEFAULT). BT.2020 and
// SMPTE 240M have no PixelFormat encoding: they map to BT.709, the nearest.
Colour colour_from_v4l2(std::uint32_t colorspace, std::uint32_t ycbcr_enc,
                        std::uint32_t quantization, PixelFormat format);

// A VIDIOC_ENUM_FRAMESIZES stepwise (or continuous, step 1) range as a list
// of sizes: the common resolutions inside it aligned to the steps, plus
// the range's minimum and maximum; ascending by area.
std::vector<FormatSizes::Size> stepwise_sizes(int min_width, int max_width, int step_width,
                                              int min_height, int max_height, int step_height);
// The size with most pixels (nullopt for none).
std::optional<FormatSizes::Size> largest_size(const std::vector<FormatSizes::Size>& sizes);

// What the driver answered to a request: Valid if it took it as asked,
// Adjusted if it changed something we can still use, Invalid if it gave a
// pixel format PropCam cannot convert. fps compares within 1 %.
ConfigStatus negotiation_status(const StreamConfig& asked, std::uint32_t granted_fourcc,
                                int granted_width, int granted_height,
                                double granted_fps);

// The frame's CLOCK_MONOTONIC time: the driver's stamp when the buffer
// flags say it is monotonic, else `now_ns` (the dequeue time).
std::int64_t buffer_timestamp_ns(std::uint32_t buffer_flags, std::int64_t tv_sec,
                                 std::int64_t tv_usec, std::int64_t now_ns);

// V4L2 gain-like controls have no unit: the control's default is taken as
// 1x (1 when the default is 0 or below) and the value scales linearly,
// clamped to [minimum, maximum] and snapped to the step.
std::int64_t gain_to_control(double gain, std::int64_t minimum, std::int64_t maximum,
                             std::int64_t step, std::int64_t default_value);

}  // namespace v4l2
}  // namespace propcam::capture
