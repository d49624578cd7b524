// A camera frame as it leaves a backend: the raw bytes in the camera's own
// pixel format, with the format and the metadata the camera reported. The
// conversion to RGB (pixel_format.h) is the same for live and replayed
// frames, so a recording exercises the exact code a live camera does.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace propcam::capture {

// Byte layouts as V4L2 defines them (videodev2.h), named after their fourcc.
enum class PixelFormat {
  RGB24,  // R, G, B bytes per pixel
  BGR24,  // B, G, R
  YUYV,   // 4:2:2 packed Y0 U Y1 V
  UYVY,   // 4:2:2 packed U Y0 V Y1
  NV12,   // 4:2:0, a Y plane then an interleaved U V plane
  MJPEG,  // one JPEG per frame (bytes_used is the JPEG's length)
  GREY,   // 8-bit luma
};

// "YUYV", "NV12", ... and back (nullopt for an unknown name).
std::string to_string(PixelFormat format);
std::optional<PixelFormat> pixel_format_from_string(const std::string& name);
// The V4L2 / DRM fourcc code of the format, and back.
std::uint32_t fourcc(PixelFormat format);
std::optional<PixelFormat> pixel_format_from_fourcc(std::uint32_t code);

// Y'CbCr encoding and range of the YUV formats (V4L2's colorspace fields).
enum class YcbcrEncoding { Bt601, Bt709 };
enum class QuantisationRange { Limited, Full };

struct FrameFormat {
  PixelFormat pixel_format = PixelFormat::RGB24;
  int width = 0;
  int height = 0;
  // Bytes per row of the first plane (0 for MJPEG). NV12's chroma plane has
  // the same stride and follows the luma plane after stride * height bytes.
  int stride = 0;
  YcbcrEncoding encoding = YcbcrEncoding::Bt601;
  QuantisationRange range = QuantisationRange::Limited;
};

// The smallest stride the format allows at this width, and the bytes a frame
// of that format needs (the maximum for MJPEG: an upper bound, not a size).
// A stride of 0 means rows packed at the minimum stride. Both throw
// std::runtime_error on a format validate_frame_format rejects.
int minimum_stride(PixelFormat format, int width);
std::size_t frame_bytes(const FrameFormat& format);

// Frames larger than this on either side are refused as implausible.
inline constexpr int kMaxFrameDimension = 16384;

// Throws std::runtime_error saying what is wrong: a width or height outside
// 1..kMaxFrameDimension, a stride below the minimum (0 is packed) or above
// 4 x minimum + 4096 (implausible padding), an odd width for YUYV/UYVY/NV12
// or an odd height for NV12. MJPEG's stride is not looked at.
void validate_frame_format(const FrameFormat& format);

struct FrameMetadata {
  std::int64_t timestamp_ns = 0;  // CLOCK_MONOTONIC, when the sensor finished the frame
  std::uint64_t sequence = 0;     // the camera's frame counter
  std::optional<double> exposure_us;
  std::optional<double> analogue_gain;
  std::optional<double> colour_gain_red;   // white balance: gain applied to red
  std::optional<double> colour_gain_blue;  // and to blue (green is 1)
  std::optional<double> colour_temperature_k;
};

// Owns a frame's bytes: a vector, a mapped memfd shared with the daemon, a
// dequeued driver buffer that goes back to the queue when released, ...
class FrameBuffer {
 public:
  virtual ~FrameBuffer() = default;
  virtual std::span<const std::uint8_t> bytes() const = 0;
};

// The simplest owner: bytes held in memory.
class VectorFrameBuffer final : public FrameBuffer {
 public:
  explicit VectorFrameBuffer(std::vector<std::uint8_t> bytes) : bytes_(std::move(bytes)) {}
  std::span<const std::uint8_t> bytes() const override { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
};

struct Frame {
  FrameFormat format;
  std::shared_ptr<const FrameBuffer> buffer;
  std::size_t bytes_used = 0;  // of buffer->bytes()
  FrameMetadata metadata;

  // The frame's bytes (the first bytes_used of the buffer; empty without one).
  std::span<const std::uint8_t> data() const {
    if (!buffer) return {};
    return buffer->bytes().first(std::min(bytes_used, buffer->bytes().size()));
  }
};

// A frame that owns `bytes`, all of them used.
inline Frame frame_from_bytes(const FrameFormat& format, std::vector<std::uint8_t> bytes,
                              const FrameMetadata& metadata = {}) {
  Frame frame;
  frame.format = format;
  frame.bytes_used = bytes.size();
  frame.buffer = std::make_shared<VectorFrameBuffer>(std::move(bytes));
  frame.metadata = metadata;
  return frame;
}

}  // namespace propcam::capture
