#include "propcam/capture/frame.h"

#include <linux/videodev2.h>

#include <array>
#include <cctype>
#include <stdexcept>

#include "propcam/capture/frame_source.h"

namespace propcam::capture {
namespace {

struct FormatName {
  PixelFormat format;
  const char* name;
  std::uint32_t fourcc;
};

constexpr std::array<FormatName, 7> kFormats{{
    {PixelFormat::RGB24, "RGB24", V4L2_PIX_FMT_RGB24},
    {PixelFormat::BGR24, "BGR24", V4L2_PIX_FMT_BGR24},
    {PixelFormat::YUYV, "YUYV", V4L2_PIX_FMT_YUYV},
    {PixelFormat::UYVY, "UYVY", V4L2_PIX_FMT_UYVY},
    {PixelFormat::NV12, "NV12", V4L2_PIX_FMT_NV12},
    {PixelFormat::MJPEG, "MJPEG", V4L2_PIX_FMT_MJPEG},
    {PixelFormat::GREY, "GREY", V4L2_PIX_FMT_GREY},
}};

const FormatName& entry(PixelFormat format) {
  for (const auto& f : kFormats)
    if (f.format == format) return f;
  throw std::runtime_error("unknown pixel format value " + std::to_string(static_cast<int>(format)));
}

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

bool is_subsampled(PixelFormat f) {
  return f == PixelFormat::YUYV || f == PixelFormat::UYVY || f == PixelFormat::NV12;
}

std::string describe(const FrameFormat& f) {
  return to_string(f.pixel_format) + " " + std::to_string(f.width) + "x" + std::to_string(f.height);
}

}  // namespace

std::string to_string(PixelFormat format) { return entry(format).name; }

std::optional<PixelFormat> pixel_format_from_string(const std::string& name) {
  const std::string u = upper(name);
  if (u == "MJPG") return PixelFormat::MJPEG;  // V4L2's own spelling
  for (const auto& f : kFormats)
    if (u == f.name) return f.format;
  return std::nullopt;
}

std::uint32_t fourcc(PixelFormat format) { return entry(format).fourcc; }

std::optional<PixelFormat> pixel_format_from_fourcc(std::uint32_t code) {
  if (code == V4L2_PIX_FMT_JPEG) return PixelFormat::MJPEG;  // some UVC drivers name it so; same bytes
  for (const auto& f : kFormats)
    if (f.fourcc == code) return f.format;
  return std::nullopt;
}

int minimum_stride(PixelFormat format, int width) {
  if (width < 0 || width > kMaxFrameDimension)
    throw std::runtime_error(to_string(format) + ": width " + std::to_string(width) + " outside 0.." +
                             std::to_string(kMaxFrameDimension));
  const int pairs = (width + 1) / 2;  // 4:2:x chroma is sampled per pair of pixels
  switch (format) {
    case PixelFormat::RGB24:
    case PixelFormat::BGR24: return 3 * width;
    case PixelFormat::YUYV:
    case PixelFormat::UYVY: return 4 * pairs;
    case PixelFormat::NV12: return 2 * pairs;  // the interleaved U V row is the wider one
    case PixelFormat::GREY: return width;
    case PixelFormat::MJPEG: return 0;
  }
  throw std::runtime_error("unknown pixel format value " + std::to_string(static_cast<int>(format)));
}

void validate_frame_format(const FrameFormat& f) {
  const std::string name = to_string(f.pixel_format);  // throws on a bad enum value
  for (const auto& [what, value] : {std::pair{"width", f.width}, std::pair{"height", f.height}})
    if (value < 1 || value > kMaxFrameDimension)
      throw std::runtime_error(name + ": " + what + " " + std::to_string(value) + " outside 1.." +
                               std::to_string(kMaxFrameDimension));
  if (is_subsampled(f.pixel_format) && f.width % 2 != 0)
    throw std::runtime_error(describe(f) + ": the width must be even (chroma is shared by pixel pairs)");
  if (f.pixel_format == PixelFormat::NV12 && f.height % 2 != 0)
    throw std::runtime_error(describe(f) + ": the height must be even (NV12 chroma is shared by row pairs)");
  if (f.pixel_format == PixelFormat::MJPEG) return;  // no rows to speak of
  const int min_stride = minimum_stride(f.pixel_format, f.width);
  if (f.stride != 0 && (f.stride < min_stride || f.stride > 4 * min_stride + 4096))
    throw std::runtime_error(describe(f) + ": stride " + std::to_string(f.stride) + " outside " +
                             std::to_string(min_stride) + ".." + std::to_string(4 * min_stride + 4096));
}

std::size_t frame_bytes(const FrameFormat& f) {
  validate_frame_format(f);
  const auto w = static_cast<std::size_t>(f.width);
  const auto h = static_cast<std::size_t>(f.height);
  if (f.pixel_format == PixelFormat::MJPEG) {
    // Worst case of a 4:4:4 JPEG of noise, in whole 16x16 blocks, plus room for
    // headers and an APP segment or two; cameras size their buffers likewise.
    const std::size_t pw = (w + 15) / 16 * 16, ph = (h + 15) / 16 * 16;
    return pw * ph * 6 + 128 * 1024;
  }
  const auto stride = static_cast<std::size_t>(f.stride ? f.stride : minimum_stride(f.pixel_format, f.width));
  if (f.pixel_format == PixelFormat::NV12) return stride * h + stride * (h / 2);
  return stride * h;
}

std::string to_string(CaptureStatus status) {
  switch (status) {
    case CaptureStatus::Ok: return "Ok";
    case CaptureStatus::Timeout: return "Timeout";
    case CaptureStatus::DeviceLost: return "DeviceLost";
    case CaptureStatus::EndOfStream: return "EndOfStream";
  }
  return "CaptureStatus(" + std::to_string(static_cast<int>(status)) + ")";
}

}  // namespace propcam::capture
