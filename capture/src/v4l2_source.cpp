// V4L2 backend: plain ioctl(2) on the node, not libv4l2. libv4l2's value is
// its format emulation (vendor formats converted to RGB in user space),
// which would hide the camera's real format from the one conversion path
// (pixel_format.h) and cost CPU; plain ioctl also keeps errno exact for the
// DeviceLost decisions.
#include "propcam/capture/v4l2_source.h"

#include "capture_socket.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <utility>

namespace propcam::capture {
namespace {

// Private to this backend: frame.cpp owns the public fourcc() mapping.
struct V4l2FormatEntry {
  PixelFormat format;
  std::uint32_t code;
};
constexpr V4l2FormatEntry kV4l2Formats[] = {
    {PixelFormat::RGB24, V4L2_PIX_FMT_RGB24}, {PixelFormat::BGR24, V4L2_PIX_FMT_BGR24},
    {PixelFormat::YUYV, V4L2_PIX_FMT_YUYV},   {PixelFormat::UYVY, V4L2_PIX_FMT_UYVY},
    {PixelFormat::NV12, V4L2_PIX_FMT_NV12},   {PixelFormat::MJPEG, V4L2_PIX_FMT_MJPEG},
    {PixelFormat::GREY, V4L2_PIX_FMT_GREY},
};

constexpr unsigned kBufferCount = 4;     // enough to keep the driver fed while we copy
constexpr int kStillSettleFrames = 2;    // frames dropped after a still reconfigure

std::string errno_text(int err) { return std::error_code(err, std::generic_category()).message(); }

std::string fourcc_text(std::uint32_t code) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((code >> (8 * i)) & 0xff);
    s += (c >= 32 && c < 127) ? c : '?';
  }
  return s;
}

// ioctl, retried on EINTR; returns the errno (0 on success).
int xioctl(int fd, unsigned long request, void* arg) {
  for (;;) {
    if (::ioctl(fd, request, arg) == 0) return 0;
    if (errno != EINTR) return errno;
  }
}


[[noreturn]] void fail(const std::string& path, const char* step, int err) {
  throw std::runtime_error("V4L2 " + path + ": " + step + ": " + errno_text(err));
}

// The module's fd owner and clock (capture_socket.h).
using Fd = detail::UniqueFd;
using detail::monotonic_ns;

class Mapping {
 public:
  Mapping(void* addr, std::size_t length) : addr_(addr), length_(length) {}
  ~Mapping() {
    if (addr_ != MAP_FAILED) ::munmap(addr_, length_);
  }
  Mapping(Mapping&& other) noexcept
      : addr_(std::exchange(other.addr_, MAP_FAILED)), length_(other.length_) {}
  Mapping& operator=(Mapping&&) = delete;
  const std::uint8_t* data() const { return static_cast<const std::uint8_t*>(addr_); }
  std::size_t size() const { return length_; }

 private:
  void* addr_ = MAP_FAILED;
  std::size_t length_ = 0;
};

// Opens the node and checks it is a single-planar streaming capture device.
Fd open_capture_node(const std::string& path, v4l2_capability& cap) {
  Fd fd(::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC));
  if (fd.get() < 0) fail(path, "cannot open", errno);
  struct stat st{};
  if (::fstat(fd.get(), &st) != 0) fail(path, "fstat", errno);
  if (!S_ISCHR(st.st_mode))
    throw std::runtime_error("V4L2 " + path + ": not a V4L2 device (not a character device)");
  cap = v4l2_capability{};
  if (const int err = xioctl(fd.get(), VIDIOC_QUERYCAP, &cap)) {
    if (err == ENOTTY || err == EINVAL)
      throw std::runtime_error("V4L2 " + path + ": not a V4L2 device (VIDIOC_QUERYCAP: " +
                               errno_text(err) + ")");
    fail(path, "VIDIOC_QUERYCAP", err);
  }
  const std::uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
    std::string what = "not a video capture node";
    if (caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE)
      what = "a multiplanar capture node, which PropCam does not support";
    else if (caps & V4L2_CAP_META_CAPTURE)
      what = "a metadata capture node";
    else if (caps & V4L2_CAP_META_OUTPUT)
      what = "a metadata output node";
    else if (caps & (V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_VIDEO_OUTPUT_MPLANE))
      what = "a video output node";
    throw std::runtime_error("V4L2 " + path + ": " + what);
  }
  if (!(caps & V4L2_CAP_STREAMING))
    throw std::runtime_error("V4L2 " + path + ": capture node without streaming I/O");
  return fd;
}

std::vector<FormatSizes::Size> enumerate_sizes(int fd, std::uint32_t code) {
  std::vector<FormatSizes::Size> sizes;
  for (std::uint32_t index = 0;; ++index) {
    v4l2_frmsizeenum fs{};
    fs.index = index;
    fs.pixel_format = code;
    if (xioctl(fd, VIDIOC_ENUM_FRAMESIZES, &fs) != 0) break;
    if (fs.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
      sizes.push_back({static_cast<int>(fs.discrete.width), static_cast<int>(fs.discrete.height)});
      continue;
    }
    const auto& sw = fs.stepwise;  // stepwise and continuous come as one entry
    return v4l2::stepwise_sizes(sw.min_width, sw.max_width, sw.step_width, sw.min_height,
                                sw.max_height, sw.step_height);
  }
  return sizes;
}

// The formats PropCam can convert, each with its sizes; also the fourccs of
// the others (for an error message).
std::vector<FormatSizes> enumerate_formats(int fd, std::vector<std::uint32_t>* others = nullptr) {
  std::vector<FormatSizes> formats;
  for (std::uint32_t index = 0;; ++index) {
    v4l2_fmtdesc desc{};
    desc.index = index;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd, VIDIOC_ENUM_FMT, &desc) != 0) break;
    const auto format = v4l2::to_pixel_format(desc.pixelformat);
    if (!format) {
      if (others) others->push_back(desc.pixelformat);
      continue;
    }
    FormatSizes entry;
    entry.pixel_format = *format;
    entry.sizes = enumerate_sizes(fd, desc.pixelformat);
    formats.push_back(std::move(entry));
  }
  return formats;
}

std::string description(const v4l2_capability& cap) {
  auto text = [](const __u8* s, std::size_t n) {
    return std::string(reinterpret_cast<const char*>(s), strnlen(reinterpret_cast<const char*>(s), n));
  };
  return text(cap.card, sizeof cap.card) + " (" + text(cap.driver, sizeof cap.driver) + ", " +
         text(cap.bus_info, sizeof cap.bus_info) + ")";
}

std::string config_text(const StreamConfig& c) {
  std::uint32_t code = 0;
  for (const auto& e : kV4l2Formats)
    if (e.format == c.pixel_format) code = e.code;
  return fourcc_text(code) + " " + std::to_string(c.width) + "x" + std::to_string(c.height);
}

std::int64_t snap(std::int64_t value, std::int64_t minimum, std::int64_t maximum, std::int64_t step) {
  value = std::clamp(value, minimum, maximum);
  if (step > 1) {
    value = minimum + (value - minimum + step / 2) / step * step;
    while (value > maximum) value -= step;
  }
  return value;
}

}  // namespace

// --- pure parts --------------------------------------------------------

namespace v4l2 {

std::optional<PixelFormat> to_pixel_format(std::uint32_t v4l2_fourcc) {
  for (const auto& e : kV4l2Formats)
    if (e.code == v4l2_fourcc) return e.format;
  return std::nullopt;
}

std::optional<std::uint32_t> to_v4l2_fourcc(PixelFormat format) {
  for (const auto& e : kV4l2Formats)
    if (e.format == format) return e.code;
  return std::nullopt;
}

Colour colour_from_v4l2(std::uint32_t colorspace, std::uint32_t ycbcr_enc,
                        std::uint32_t quantization, PixelFormat format) {
  // A capture driver should not answer DEFAULT; webcams mean sRGB (JPEG for MJPEG).
  if (colorspace == V4L2_COLORSPACE_DEFAULT)
    colorspace = format == PixelFormat::MJPEG ? V4L2_COLORSPACE_JPEG : V4L2_COLORSPACE_SRGB;
  if (ycbcr_enc == V4L2_YCBCR_ENC_DEFAULT) ycbcr_enc = V4L2_MAP_YCBCR_ENC_DEFAULT(colorspace);
  const bool rgb = format == PixelFormat::RGB24 || format == PixelFormat::BGR24;
  if (quantization == V4L2_QUANTIZATION_DEFAULT)
    quantization = V4L2_MAP_QUANTIZATION_DEFAULT(rgb, colorspace, ycbcr_enc);
  Colour c;
  switch (ycbcr_enc) {
    case V4L2_YCBCR_ENC_709:
    case V4L2_YCBCR_ENC_XV709:
    case V4L2_YCBCR_ENC_BT2020:
    case V4L2_YCBCR_ENC_BT2020_CONST_LUM:
    case V4L2_YCBCR_ENC_SMPTE240M:
      c.encoding = YcbcrEncoding::Bt709;
      break;
    default:
      c.encoding = YcbcrEncoding::Bt601;
  }
  c.range = quantization == V4L2_QUANTIZATION_FULL_RANGE ? QuantisationRange::Full
                                                         : QuantisationRange::Limited;
  return c;
}

std::vector<FormatSizes::Size> stepwise_sizes(int min_width, int max_width, int step_width,
                                              int min_height, int max_height, int step_height) {
  static constexpr FormatSizes::Size kCommon[] = {
      {160, 120},   {176, 144},   {320, 240},   {352, 288},   {640, 360},
      {640, 480},   {800, 600},   {1024, 768},  {1280, 720},  {1280, 960},
      {1600, 1200}, {1920, 1080}, {2048, 1536}, {2592, 1944}, {3840, 2160}, {4056, 3040}};
  std::vector<FormatSizes::Size> sizes;
  if (min_width <= 0 || min_height <= 0 || max_width < min_width || max_height < min_height)
    return sizes;
  step_width = std::max(step_width, 1);
  step_height = std::max(step_height, 1);
  auto fits = [&](FormatSizes::Size s) {
    return s.width >= min_width && s.width <= max_width && s.height >= min_height &&
           s.height <= max_height && (s.width - min_width) % step_width == 0 &&
           (s.height - min_height) % step_height == 0;
  };
  sizes.push_back({min_width, min_height});
  for (const auto& s : kCommon)
    if (fits(s)) sizes.push_back(s);
  // The maximum, aligned down to the steps.
  sizes.push_back({max_width - (max_width - min_width) % step_width,
                   max_height - (max_height - min_height) % step_height});
  auto area = [](FormatSizes::Size s) { return std::int64_t{s.width} * s.height; };
  std::sort(sizes.begin(), sizes.end(), [&](auto a, auto b) {
    return area(a) != area(b) ? area(a) < area(b) : a.width < b.width;
  });
  sizes.erase(std::unique(sizes.begin(), sizes.end(),
                          [](auto a, auto b) { return a.width == b.width && a.height == b.height; }),
              sizes.end());
  return sizes;
}

std::optional<FormatSizes::Size> largest_size(const std::vector<FormatSizes::Size>& sizes) {
  if (sizes.empty()) return std::nullopt;
  return *std::max_element(sizes.begin(), sizes.end(), [](auto a, auto b) {
    const auto aa = std::int64_t{a.width} * a.height, ba = std::int64_t{b.width} * b.height;
    return aa != ba ? aa < ba : a.width < b.width;
  });
}

ConfigStatus negotiation_status(const StreamConfig& asked, std::uint32_t granted_fourcc,
                                int granted_width, int granted_height, double granted_fps) {
  const auto format = to_pixel_format(granted_fourcc);
  if (!format || granted_width <= 0 || granted_height <= 0) return ConfigStatus::Invalid;
  bool adjusted = *format != asked.pixel_format || granted_width != asked.width ||
                  granted_height != asked.height;
  if (asked.fps > 0 && !(granted_fps > 0 && std::abs(granted_fps - asked.fps) <= 0.01 * asked.fps))
    adjusted = true;
  return adjusted ? ConfigStatus::Adjusted : ConfigStatus::Valid;
}

std::int64_t buffer_timestamp_ns(std::uint32_t buffer_flags, std::int64_t tv_sec,
                                 std::int64_t tv_usec, std::int64_t now_ns) {
  if ((buffer_flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC)
    return now_ns;
  return tv_sec * 1'000'000'000 + tv_usec * 1'000;
}

std::int64_t gain_to_control(double gain, std::int64_t minimum, std::int64_t maximum,
                             std::int64_t step, std::int64_t default_value) {
  const double unity = default_value > 0 ? static_cast<double>(default_value) : 1.0;
  const double scaled = std::clamp(gain * unity, static_cast<double>(minimum), static_cast<double>(maximum));
  return snap(std::llround(scaled), minimum, maximum, step);
}

}  // namespace v4l2

// --- the source --------------------------------------------------------

struct V4l2Source::Impl {
  std::string path;
  Fd fd;
  v4l2_capability cap{};
  std::vector<FormatSizes> formats;
  StreamConfig config;
  FrameFormat format;
  std::vector<Mapping> buffers;
  bool streaming = false;
  bool lost = false;
  std::string lost_message;

  // --- negotiation ---
  std::optional<v4l2_format> negotiate(unsigned long request, const StreamConfig& asked);
  double apply_frame_rate(double fps);
  ConfigStatus configure(StreamConfig& asked);
  void adopt_current_format();
  std::optional<FormatSizes::Size> largest_for(PixelFormat pf);

  // --- streaming ---
  void start();
  void stop();
  void release_buffers();
  void mark_lost(const char* step, int err);
  bool requeue(const v4l2_buffer& buffer);
  std::optional<Frame> dequeue_newest(bool& drained_all);
  CaptureResult next_frame(std::chrono::milliseconds timeout);
  CaptureResult lost_result() const { return {CaptureStatus::DeviceLost, std::nullopt, lost_message}; }

  // --- controls ---
  std::optional<v4l2_queryctrl> query(std::uint32_t id);
  bool menu_has(std::uint32_t id, std::uint32_t index);
  bool set_control(std::uint32_t id, std::int64_t value);
  bool set_auto_exposure(bool on);
};

std::optional<v4l2_format> V4l2Source::Impl::negotiate(unsigned long request,
                                                       const StreamConfig& asked) {
  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const auto code = v4l2::to_v4l2_fourcc(asked.pixel_format);
  if (!code) return std::nullopt;
  f.fmt.pix.pixelformat = *code;
  f.fmt.pix.width = static_cast<std::uint32_t>(std::max(asked.width, 0));
  f.fmt.pix.height = static_cast<std::uint32_t>(std::max(asked.height, 0));
  f.fmt.pix.field = V4L2_FIELD_NONE;
  const char* name = request == VIDIOC_TRY_FMT ? "VIDIOC_TRY_FMT" : "VIDIOC_S_FMT";
  if (const int err = xioctl(fd.get(), request, &f)) {
    if (err == EINVAL) return std::nullopt;
    if (err == ENOTTY && request == VIDIOC_TRY_FMT) return f;  // optional ioctl: S_FMT decides
    fail(path, name, err);
  }
  return f;
}

// Sets the frame interval when the driver allows it; returns the rate in
// force (0 when the driver does not say).
double V4l2Source::Impl::apply_frame_rate(double fps) {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd.get(), VIDIOC_G_PARM, &parm) != 0) return 0;
  auto& tpf = parm.parm.capture.timeperframe;
  if (fps > 0 && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
    tpf.numerator = 1000;
    tpf.denominator = static_cast<std::uint32_t>(std::lround(fps * 1000));
    if (const int err = xioctl(fd.get(), VIDIOC_S_PARM, &parm); err && err != EINVAL && err != ENOTTY)
      fail(path, "VIDIOC_S_PARM", err);
  }
  return tpf.numerator && tpf.denominator ? static_cast<double>(tpf.denominator) / tpf.numerator : 0.0;
}

ConfigStatus V4l2Source::Impl::configure(StreamConfig& asked) {
  if (streaming) throw std::logic_error("V4L2 " + path + ": configure while running (stop first)");
  const auto tried = negotiate(VIDIOC_TRY_FMT, asked);
  if (!tried || !v4l2::to_pixel_format(tried->fmt.pix.pixelformat)) return ConfigStatus::Invalid;
  StreamConfig request = asked;
  request.pixel_format = *v4l2::to_pixel_format(tried->fmt.pix.pixelformat);
  if (tried->fmt.pix.width && tried->fmt.pix.height) {
    request.width = static_cast<int>(tried->fmt.pix.width);
    request.height = static_cast<int>(tried->fmt.pix.height);
  }
  const auto set = negotiate(VIDIOC_S_FMT, request);
  if (!set || !v4l2::to_pixel_format(set->fmt.pix.pixelformat)) return ConfigStatus::Invalid;
  const auto& pix = set->fmt.pix;
  const double fps = apply_frame_rate(asked.fps);
  const ConfigStatus status = v4l2::negotiation_status(asked, pix.pixelformat, static_cast<int>(pix.width),
                                                       static_cast<int>(pix.height), fps);
  config = StreamConfig{*v4l2::to_pixel_format(pix.pixelformat), static_cast<int>(pix.width),
                        static_cast<int>(pix.height), fps};
  const auto colour = v4l2::colour_from_v4l2(pix.colorspace, pix.ycbcr_enc, pix.quantization,
                                             config.pixel_format);
  format = FrameFormat{config.pixel_format, config.width, config.height,
                       config.pixel_format == PixelFormat::MJPEG ? 0 : static_cast<int>(pix.bytesperline),
                       colour.encoding, colour.range};
  asked = config;
  return status;
}

// Keeps the driver's format when PropCam can convert it (another program
// may have chosen it on purpose); otherwise the first convertible one.
void V4l2Source::Impl::adopt_current_format() {
  std::vector<std::uint32_t> others;
  formats = enumerate_formats(fd.get(), &others);
  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (const int err = xioctl(fd.get(), VIDIOC_G_FMT, &f)) fail(path, "VIDIOC_G_FMT", err);
  StreamConfig wanted;
  if (const auto pf = v4l2::to_pixel_format(f.fmt.pix.pixelformat)) {
    wanted = StreamConfig{*pf, static_cast<int>(f.fmt.pix.width), static_cast<int>(f.fmt.pix.height), 0};
  } else if (!formats.empty()) {
    wanted.pixel_format = formats.front().pixel_format;
  } else {
    std::string offered;
    for (auto code : others) offered += (offered.empty() ? "" : ", ") + fourcc_text(code);
    throw std::runtime_error("V4L2 " + path + ": no pixel format PropCam can convert (offers: " +
                             (offered.empty() ? "none" : offered) + ")");
  }
  if (configure(wanted) == ConfigStatus::Invalid)
    throw std::runtime_error("V4L2 " + path + ": the driver refused " + config_text(wanted));
}

std::optional<FormatSizes::Size> V4l2Source::Impl::largest_for(PixelFormat pf) {
  for (const auto& f : formats)
    if (f.pixel_format == pf)
      if (auto s = v4l2::largest_size(f.sizes)) return s;
  // No size list: the driver clamps an oversized request to its maximum.
  StreamConfig huge{pf, 1 << 14, 1 << 14, 0};
  if (const auto f = negotiate(VIDIOC_TRY_FMT, huge); f && f->fmt.pix.width && f->fmt.pix.height)
    return FormatSizes::Size{static_cast<int>(f->fmt.pix.width), static_cast<int>(f->fmt.pix.height)};
  return std::nullopt;
}

void V4l2Source::Impl::release_buffers() {
  buffers.clear();  // unmap first: vb2 refuses to free mapped buffers
  v4l2_requestbuffers req{};
  req.count = 0;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  xioctl(fd.get(), VIDIOC_REQBUFS, &req);
}

void V4l2Source::Impl::start() {
  if (streaming) return;
  if (lost) throw std::runtime_error(lost_message);
  v4l2_requestbuffers req{};
  req.count = kBufferCount;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (const int err = xioctl(fd.get(), VIDIOC_REQBUFS, &req)) fail(path, "VIDIOC_REQBUFS", err);
  try {
    if (req.count < 2)
      throw std::runtime_error("V4L2 " + path + ": VIDIOC_REQBUFS: only " + std::to_string(req.count) +
                               " buffer(s)");
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      b.memory = V4L2_MEMORY_MMAP;
      b.index = i;
      if (const int err = xioctl(fd.get(), VIDIOC_QUERYBUF, &b)) fail(path, "VIDIOC_QUERYBUF", err);
      void* addr = ::mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd.get(), b.m.offset);
      if (addr == MAP_FAILED) fail(path, "mmap", errno);
      buffers.emplace_back(addr, b.length);
    }
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      b.memory = V4L2_MEMORY_MMAP;
      b.index = i;
      if (const int err = xioctl(fd.get(), VIDIOC_QBUF, &b)) fail(path, "VIDIOC_QBUF", err);
    }
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (const int err = xioctl(fd.get(), VIDIOC_STREAMON, &type)) fail(path, "VIDIOC_STREAMON", err);
  } catch (...) {
    release_buffers();
    throw;
  }
  streaming = true;
}

void V4l2Source::Impl::stop() {
  if (!streaming) return;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  xioctl(fd.get(), VIDIOC_STREAMOFF, &type);  // fails only when the device is gone
  release_buffers();
  streaming = false;
}

void V4l2Source::Impl::mark_lost(const char* step, int err) {
  lost = true;
  lost_message = "V4L2 " + path + ": " + step + ": " + errno_text(err);
}

// A driver that refuses a buffer back has failed (a buffer short, for
// good): DeviceLost, so the daemon reopens it, whatever the errno.
bool V4l2Source::Impl::requeue(const v4l2_buffer& buffer) {
  v4l2_buffer b{};
  b.type = buffer.type;
  b.memory = buffer.memory;
  b.index = buffer.index;
  if (const int err = xioctl(fd.get(), VIDIOC_QBUF, &b)) {
    mark_lost("VIDIOC_QBUF", err);
    return false;
  }
  return true;
}

// Dequeues every buffer ready, re-queues all but the newest, copies the
// newest and re-queues it too. nullopt when none was ready (or it was
// flagged corrupt, or the device went away: see `lost`).
std::optional<Frame> V4l2Source::Impl::dequeue_newest(bool& drained_all) {
  std::optional<v4l2_buffer> newest;
  std::size_t count = 0;
  for (;;) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (const int err = xioctl(fd.get(), VIDIOC_DQBUF, &b)) {
      if (err == EAGAIN || err == EPIPE) break;
      mark_lost("VIDIOC_DQBUF", err);  // ENODEV, EIO: unplugged or failed
      return std::nullopt;
    }
    if (newest && !requeue(*newest)) return std::nullopt;
    newest = b;
    ++count;
  }
  drained_all = count >= buffers.size();
  if (!newest) return std::nullopt;
  if (newest->index >= buffers.size()) {
    mark_lost("VIDIOC_DQBUF (buffer index out of range)", EINVAL);
    return std::nullopt;
  }
  if (newest->flags & V4L2_BUF_FLAG_ERROR) {
    requeue(*newest);
    return std::nullopt;
  }
  const Mapping& m = buffers[newest->index];
  std::size_t used = newest->bytesused ? std::min<std::size_t>(newest->bytesused, m.size()) : m.size();
  Frame frame;
  frame.format = format;
  frame.buffer = std::make_shared<VectorFrameBuffer>(std::vector<std::uint8_t>(m.data(), m.data() + used));
  frame.bytes_used = used;
  frame.metadata.sequence = newest->sequence;
  frame.metadata.timestamp_ns = v4l2::buffer_timestamp_ns(
      newest->flags, newest->timestamp.tv_sec, newest->timestamp.tv_usec, monotonic_ns());
  requeue(*newest);  // a lost device shows on the next call
  return frame;
}

CaptureResult V4l2Source::Impl::next_frame(std::chrono::milliseconds timeout) {
  if (lost) return lost_result();
  if (!streaming) throw std::logic_error("V4L2 " + path + ": next_frame before start");
  using clock = std::chrono::steady_clock;
  const auto deadline = clock::now() + timeout;
  std::optional<Frame> stale;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - clock::now());
    pollfd p{fd.get(), POLLIN, 0};
    const int r = ::poll(&p, 1, static_cast<int>(std::max<std::int64_t>(left.count(), 0)));
    if (r < 0) {
      if (errno == EINTR) continue;
      mark_lost("poll", errno);
      return lost_result();
    }
    if (r == 0 && stale) return {CaptureStatus::Ok, std::move(stale), {}};
    if (r == 0)
      return {CaptureStatus::Timeout, std::nullopt,
              "V4L2 " + path + ": no frame within " + std::to_string(timeout.count()) + " ms"};
    if (p.revents & (POLLERR | POLLHUP | POLLNVAL)) {
      lost = true;
      lost_message = "V4L2 " + path + ": poll reported an error (device unplugged or failed)";
      return lost_result();
    }
    bool drained_all = false;
    auto frame = dequeue_newest(drained_all);
    if (lost) return lost_result();
    if (!frame) continue;
    // Every buffer full: the driver ran dry while the client was away and
    // the newest is as old as that. Wait once for a fresh one (the stale
    // one is the answer if none comes in time).
    if (drained_all && !stale) {
      stale = std::move(frame);
      continue;
    }
    return {CaptureStatus::Ok, std::move(frame), {}};
  }
}

std::optional<v4l2_queryctrl> V4l2Source::Impl::query(std::uint32_t id) {
  v4l2_queryctrl q{};
  q.id = id;
  if (xioctl(fd.get(), VIDIOC_QUERYCTRL, &q) != 0) return std::nullopt;
  if (q.flags & (V4L2_CTRL_FLAG_DISABLED | V4L2_CTRL_FLAG_READ_ONLY)) return std::nullopt;
  return q;
}

bool V4l2Source::Impl::menu_has(std::uint32_t id, std::uint32_t index) {
  v4l2_querymenu m{};
  m.id = id;
  m.index = index;
  return xioctl(fd.get(), VIDIOC_QUERYMENU, &m) == 0;
}

bool V4l2Source::Impl::set_control(std::uint32_t id, std::int64_t value) {
  const auto q = query(id);
  if (!q) return false;
  v4l2_control c{};
  c.id = id;
  c.value = static_cast<std::int32_t>(snap(value, q->minimum, q->maximum, q->step));
  return xioctl(fd.get(), VIDIOC_S_CTRL, &c) == 0;
}

// UVC cameras often offer only manual and aperture priority (auto exposure
// at a fixed iris), so "auto" falls back to that.
bool V4l2Source::Impl::set_auto_exposure(bool on) {
  if (!query(V4L2_CID_EXPOSURE_AUTO)) return false;
  if (!on) return set_control(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL);
  for (std::uint32_t mode : {V4L2_EXPOSURE_AUTO, V4L2_EXPOSURE_APERTURE_PRIORITY})
    if (menu_has(V4L2_CID_EXPOSURE_AUTO, mode) && set_control(V4L2_CID_EXPOSURE_AUTO, mode)) return true;
  return false;
}

// --- public methods ------------------------------------------------------

V4l2Source::V4l2Source(const std::string& device_path) : impl_(std::make_unique<Impl>()) {
  impl_->path = device_path;
  impl_->fd = open_capture_node(device_path, impl_->cap);
  impl_->adopt_current_format();
}

V4l2Source::~V4l2Source() {
  try {
    impl_->stop();
  } catch (...) {  // a destructor must not throw; the fd closes regardless
  }
}

CameraInfo V4l2Source::info() const {
  return CameraInfo{"v4l2:" + impl_->path, "v4l2", description(impl_->cap), impl_->formats};
}

ConfigStatus V4l2Source::configure(StreamConfig& config) { return impl_->configure(config); }
StreamConfig V4l2Source::configuration() const { return impl_->config; }
FrameFormat V4l2Source::frame_format() const { return impl_->format; }
void V4l2Source::start() { impl_->start(); }
void V4l2Source::stop() { impl_->stop(); }
bool V4l2Source::running() const { return impl_->streaming; }

CaptureResult V4l2Source::next_frame(std::chrono::milliseconds timeout) {
  return impl_->next_frame(timeout);
}

CaptureResult V4l2Source::capture_still(const std::optional<StreamConfig>& still,
                                        std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (d.lost) return d.lost_result();
  const StreamConfig viewfinder = d.config;
  const bool was_running = d.streaming;
  StreamConfig target = viewfinder;
  target.fps = 0;
  if (still) {
    target = *still;
  } else if (const auto size = d.largest_for(viewfinder.pixel_format)) {
    target.width = size->width;
    target.height = size->height;
  }
  d.stop();
  auto restore = [&](bool quiet) {
    try {
      d.stop();
      StreamConfig back = viewfinder;
      d.configure(back);
      if (was_running) d.start();
    } catch (...) {
      if (!quiet) throw;
    }
  };
  if (d.configure(target) == ConfigStatus::Invalid) {
    restore(false);
    throw std::invalid_argument("V4L2 " + d.path + ": the still configuration was refused");
  }
  CaptureResult result;
  try {
    d.start();
    for (int i = 0; i <= kStillSettleFrames; ++i) {
      result = d.next_frame(timeout);  // the last one is kept
      if (result.status != CaptureStatus::Ok) break;
    }
  } catch (...) {
    restore(true);
    throw;
  }
  restore(result.status == CaptureStatus::DeviceLost || d.lost);
  return result;
}

std::vector<std::string> V4l2Source::set_controls(const CameraControls& controls) {
  Impl& d = *impl_;
  std::vector<std::string> unsupported;
  if (controls.auto_exposure) {
    const bool exposure = d.set_auto_exposure(*controls.auto_exposure);
    const bool gain = d.query(V4L2_CID_AUTOGAIN) && d.set_control(V4L2_CID_AUTOGAIN, *controls.auto_exposure);
    if (!exposure && !gain) unsupported.push_back("auto_exposure");
  }
  if (controls.exposure_us) {
    d.set_auto_exposure(false);
    // EXPOSURE_ABSOLUTE counts 100 us units.
    if (!d.set_control(V4L2_CID_EXPOSURE_ABSOLUTE, std::llround(*controls.exposure_us / 100.0)))
      unsupported.push_back("exposure_us");
  }
  if (controls.analogue_gain) {
    if (d.query(V4L2_CID_AUTOGAIN)) d.set_control(V4L2_CID_AUTOGAIN, 0);
    bool done = false;
    for (std::uint32_t id : {std::uint32_t{V4L2_CID_ANALOGUE_GAIN}, std::uint32_t{V4L2_CID_GAIN}}) {
      if (const auto q = d.query(id)) {
        done = d.set_control(id, v4l2::gain_to_control(*controls.analogue_gain, q->minimum, q->maximum,
                                                       q->step, q->default_value));
        break;
      }
    }
    if (!done) unsupported.push_back("analogue_gain");
  }
  if (controls.auto_white_balance &&
      !d.set_control(V4L2_CID_AUTO_WHITE_BALANCE, *controls.auto_white_balance ? 1 : 0))
    unsupported.push_back("auto_white_balance");
  const std::pair<const std::optional<double>*, std::pair<std::uint32_t, const char*>> balances[] = {
      {&controls.colour_gain_red, {V4L2_CID_RED_BALANCE, "colour_gain_red"}},
      {&controls.colour_gain_blue, {V4L2_CID_BLUE_BALANCE, "colour_gain_blue"}}};
  for (const auto& [value, control] : balances) {
    if (!*value) continue;
    if (d.query(V4L2_CID_AUTO_WHITE_BALANCE)) d.set_control(V4L2_CID_AUTO_WHITE_BALANCE, 0);
    const auto q = d.query(control.first);
    if (!q || !d.set_control(control.first, v4l2::gain_to_control(**value, q->minimum, q->maximum,
                                                                    q->step, q->default_value)))
      unsupported.push_back(control.second);
  }
  return unsupported;
}

std::vector<CameraInfo> list_v4l2_cameras(const std::string& dev_dir) {
  namespace fs = std::filesystem;
  std::vector<std::pair<int, std::string>> nodes;
  std::error_code ec;
  for (fs::directory_iterator it(dev_dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= 5 || name.compare(0, 5, "video") != 0) continue;
    if (!std::all_of(name.begin() + 5, name.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    if (name.size() > 12) continue;  // not a node number
    nodes.emplace_back(std::stoi(name.substr(5)), it->path().string());
  }
  std::sort(nodes.begin(), nodes.end());
  std::vector<CameraInfo> cameras;
  for (const auto& [number, path] : nodes) {
    try {
      v4l2_capability cap{};
      const Fd fd = open_capture_node(path, cap);
      cameras.push_back(CameraInfo{"v4l2:" + path, "v4l2", description(cap), enumerate_formats(fd.get())});
    } catch (const std::exception&) {
      // Not a capture node, gone, or not ours to open: not a camera to list.
    }
  }
  return cameras;
}

}  // namespace propcam::capture
