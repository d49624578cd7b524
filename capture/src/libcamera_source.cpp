// libcamera backend, against libcamera 0.0.3 (Debian bookworm). What that
// version asks for: ControlList::get() returns std::optional; merge() never
// overwrites (so controls are copied one by one with set(id, value));
// generateConfiguration takes a StreamRoles vector; Request::reuse() clears
// the request's controls; there is one CameraManager per process.
#include "propcam/capture/libcamera_source.h"

#include <sys/mman.h>
#include <sys/stat.h>

#include <libcamera/camera.h>
#include <libcamera/camera_manager.h>
#include <libcamera/control_ids.h>
#include <libcamera/formats.h>
#include <libcamera/framebuffer_allocator.h>
#include <libcamera/property_ids.h>
#include <libcamera/request.h>
#include <libcamera/stream.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <utility>

namespace propcam::capture {
namespace lc = libcamera;
namespace {

// Private to this backend: frame.cpp owns the public fourcc() mapping.
struct LibcameraFormatEntry {
  PixelFormat format;
  std::uint32_t drm;
};
const LibcameraFormatEntry kLibcameraFormats[] = {
    {PixelFormat::YUYV, lc::formats::YUYV.fourcc()},    {PixelFormat::UYVY, lc::formats::UYVY.fourcc()},
    {PixelFormat::NV12, lc::formats::NV12.fourcc()},    {PixelFormat::MJPEG, lc::formats::MJPEG.fourcc()},
    {PixelFormat::GREY, lc::formats::R8.fourcc()},
    // DRM order: RGB888 is B, G, R in memory.
    {PixelFormat::BGR24, lc::formats::RGB888.fourcc()}, {PixelFormat::RGB24, lc::formats::BGR888.fourcc()},
};
// The viewfinder format picked when the camera's default cannot be converted.
constexpr PixelFormat kPreferred[] = {PixelFormat::YUYV, PixelFormat::NV12,  PixelFormat::BGR24,
                                      PixelFormat::RGB24, PixelFormat::UYVY, PixelFormat::MJPEG,
                                      PixelFormat::GREY};

static_assert(static_cast<int>(lc::ColorSpace::YcbcrEncoding::Rec709) == 2 &&
              static_cast<int>(lc::ColorSpace::Range::Limited) == 1);

constexpr int kStillSettleFrames = 2;  // frames dropped after the still reconfigure

std::string errno_text(int err) { return std::error_code(err, std::generic_category()).message(); }

std::mutex g_manager_mutex;
std::shared_ptr<lc::CameraManager> g_manager;

// One started CameraManager for the process (libcamera allows only one).
// Its log levels are libcamera's (LIBCAMERA_LOG_LEVELS): its categories are
// created lazily, so logSetLevel() before start() would not reach them. Left
// unset, warnings and errors only: its INFO lines would bury the CLI's output.
std::shared_ptr<lc::CameraManager> camera_manager() {
  std::lock_guard lock(g_manager_mutex);
  if (g_manager) return g_manager;
  ::setenv("LIBCAMERA_LOG_LEVELS", "*:WARN", /*overwrite=*/0);
  auto manager = std::make_shared<lc::CameraManager>();
  if (const int ret = manager->start())
    throw std::runtime_error("libcamera: CameraManager::start: " + errno_text(-ret));
  g_manager = std::move(manager);
  return g_manager;
}

std::string camera_description(const lc::Camera& camera) {
  std::string text = camera.properties().get(lc::properties::Model).value_or("camera");
  if (const auto location = camera.properties().get(lc::properties::Location)) {
    switch (*location) {
      case lc::properties::CameraLocationFront: text += " (front)"; break;
      case lc::properties::CameraLocationBack: text += " (back)"; break;
      case lc::properties::CameraLocationExternal: text += " (external)"; break;
      default: break;
    }
  }
  return text;
}

void add_sizes(FormatSizes& entry, const std::vector<lc::Size>& sizes) {
  for (const auto& s : sizes) {
    const FormatSizes::Size size{static_cast<int>(s.width), static_cast<int>(s.height)};
    const bool known = std::any_of(entry.sizes.begin(), entry.sizes.end(), [&](const auto& e) {
      return e.width == size.width && e.height == size.height;
    });
    if (!known) entry.sizes.push_back(size);
  }
}

// The convertible formats of the viewfinder and still roles, sizes merged.
std::vector<FormatSizes> camera_formats(lc::Camera& camera) {
  std::vector<FormatSizes> formats;
  for (const auto role : {lc::StreamRole::Viewfinder, lc::StreamRole::StillCapture}) {
    const auto config = camera.generateConfiguration({role});
    if (!config || config->empty()) continue;
    const lc::StreamFormats& offered = config->at(0).formats();
    for (const lc::PixelFormat& pf : offered.pixelformats()) {
      const auto format = libcamera_map::to_pixel_format(pf.fourcc());
      if (!format || pf.modifier() != 0) continue;
      auto it = std::find_if(formats.begin(), formats.end(),
                             [&](const FormatSizes& f) { return f.pixel_format == *format; });
      if (it == formats.end()) it = formats.insert(formats.end(), FormatSizes{*format, {}});
      add_sizes(*it, offered.sizes(pf));
    }
  }
  for (auto& f : formats)
    std::sort(f.sizes.begin(), f.sizes.end(), [](const auto& a, const auto& b) {
      return std::int64_t{a.width} * a.height < std::int64_t{b.width} * b.height;
    });
  return formats;
}

template <typename T>
T clamp_to(const lc::ControlInfo& info, T value) {
  constexpr auto type = lc::details::control_type<T>::value;
  if (info.min().type() == type && !info.min().isArray()) value = std::max(value, info.min().get<T>());
  if (info.max().type() == type && !info.max().isArray()) value = std::min(value, info.max().get<T>());
  return value;
}

std::optional<std::int64_t> int64_bound(const lc::ControlValue& v) {
  if (v.type() != lc::ControlTypeInteger64 || v.isArray()) return std::nullopt;
  return v.get<std::int64_t>();
}

// A dmabuf mapped once for all its planes.
class DmabufMapping {
 public:
  DmabufMapping(int fd, std::size_t length) : length_(length) {
    addr_ = ::mmap(nullptr, length, PROT_READ, MAP_SHARED, fd, 0);
  }
  ~DmabufMapping() {
    if (addr_ != MAP_FAILED) ::munmap(addr_, length_);
  }
  DmabufMapping(const DmabufMapping&) = delete;
  DmabufMapping& operator=(const DmabufMapping&) = delete;
  bool ok() const { return addr_ != MAP_FAILED; }
  const std::uint8_t* data() const { return static_cast<const std::uint8_t*>(addr_); }

 private:
  void* addr_ = MAP_FAILED;
  std::size_t length_;
};

}  // namespace

// --- pure parts --------------------------------------------------------

namespace libcamera_map {

std::optional<PixelFormat> to_pixel_format(std::uint32_t drm_fourcc) {
  for (const auto& e : kLibcameraFormats)
    if (e.drm == drm_fourcc) return e.format;
  return std::nullopt;
}

std::optional<std::uint32_t> to_drm_fourcc(PixelFormat format) {
  for (const auto& e : kLibcameraFormats)
    if (e.format == format) return e.drm;
  return std::nullopt;
}

Colour colour_from_libcamera(std::optional<int> ycbcr_encoding, std::optional<int> range,
                             PixelFormat format) {
  using E = lc::ColorSpace::YcbcrEncoding;
  Colour c;
  if (ycbcr_encoding == static_cast<int>(E::Rec709) || ycbcr_encoding == static_cast<int>(E::Rec2020))
    c.encoding = YcbcrEncoding::Bt709;
  const bool full_by_default =
      format == PixelFormat::RGB24 || format == PixelFormat::BGR24 || format == PixelFormat::MJPEG;
  if (range)
    c.range = *range == static_cast<int>(lc::ColorSpace::Range::Full) ? QuantisationRange::Full
                                                                        : QuantisationRange::Limited;
  else
    c.range = full_by_default ? QuantisationRange::Full : QuantisationRange::Limited;
  return c;
}

std::int64_t frame_duration_us(double fps, std::int64_t min_us, std::int64_t max_us) {
  if (!(fps > 0)) return 0;
  std::int64_t d = std::llround(1e6 / fps);
  if (min_us > 0) d = std::max(d, min_us);
  if (max_us > 0) d = std::min(d, max_us);
  return d;
}

}  // namespace libcamera_map

// --- the source --------------------------------------------------------

struct LibcameraSource::Impl {
  std::string id;
  std::shared_ptr<lc::CameraManager> manager;
  std::shared_ptr<lc::Camera> camera;
  bool acquired = false;
  std::vector<FormatSizes> formats;

  std::unique_ptr<lc::CameraConfiguration> camera_config;
  lc::Stream* stream = nullptr;
  StreamConfig config;
  FrameFormat format;
  std::int64_t frame_duration = 0;  // µs, 0: the camera's own

  std::unique_ptr<lc::FrameBufferAllocator> allocator;
  std::vector<std::unique_ptr<lc::Request>> requests;
  std::map<int, std::unique_ptr<DmabufMapping>> mappings;  // by dmabuf fd
  bool streaming = false;

  // Shared with libcamera's thread.
  std::mutex mutex;
  std::condition_variable completed_cv;
  std::deque<lc::Request*> completed;
  bool lost = false;
  std::string lost_message;

  // Controls set by the client: all of them (given to start) and the ones
  // not yet sent (merged into the next re-queued request).
  std::mutex controls_mutex;
  lc::ControlList sticky_controls;
  lc::ControlList pending_controls;
  std::optional<std::pair<float, float>> last_colour_gains;

  void open(const std::string& camera_id);
  void close();
  [[noreturn]] void fail(const char* step, int ret) const {
    throw std::runtime_error("libcamera " + id + ": " + step + ": " + errno_text(-ret));
  }

  // libcamera thread
  void on_request_completed(lc::Request* request);
  void on_camera_removed(std::shared_ptr<lc::Camera> removed);
  void on_disconnected();
  void mark_lost(const std::string& why);

  ConfigStatus configure(lc::StreamRole role, StreamConfig& asked);
  StreamConfig default_viewfinder();
  StreamConfig largest_still();
  void map_buffer(const lc::FrameBuffer& buffer);
  void start();
  void stop();
  bool requeue(lc::Request* request);
  Frame copy_frame(lc::Request& request, const lc::FrameBuffer& buffer);
  CaptureResult next_frame(std::chrono::milliseconds timeout);
  CaptureResult lost_result() {
    std::lock_guard lock(mutex);
    return {CaptureStatus::DeviceLost, std::nullopt, lost_message};
  }
  bool is_lost() {
    std::lock_guard lock(mutex);
    return lost;
  }
};

void LibcameraSource::Impl::open(const std::string& camera_id) {
  id = camera_id;
  manager = camera_manager();
  camera = manager->get(camera_id);
  if (!camera) {
    std::string known;
    for (const auto& c : manager->cameras()) known += (known.empty() ? "" : ", ") + c->id();
    throw std::runtime_error("libcamera: no camera '" + camera_id + "' (cameras: " +
                             (known.empty() ? "none" : known) + ")");
  }
  if (const int ret = camera->acquire()) {
    camera.reset();
    if (ret == -EBUSY) throw std::runtime_error("libcamera " + camera_id + ": in use by another client");
    fail("Camera::acquire", ret);
  }
  acquired = true;
  camera->requestCompleted.connect(this, &Impl::on_request_completed);
  camera->disconnected.connect(this, &Impl::on_disconnected);
  manager->cameraRemoved.connect(this, &Impl::on_camera_removed);
  sticky_controls = lc::ControlList(camera->controls());
  pending_controls = lc::ControlList(camera->controls());
  formats = camera_formats(*camera);
  StreamConfig wanted = default_viewfinder();
  if (configure(lc::StreamRole::Viewfinder, wanted) == ConfigStatus::Invalid)
    throw std::runtime_error("libcamera " + camera_id + ": no viewfinder configuration PropCam can convert");
}

void LibcameraSource::Impl::close() {
  if (!camera) return;
  try {
    stop();
  } catch (...) {  // closing regardless
  }
  camera->requestCompleted.disconnect(this);
  camera->disconnected.disconnect(this);
  if (manager) manager->cameraRemoved.disconnect(this);
  camera_config.reset();
  if (acquired) camera->release();
  camera.reset();
}

void LibcameraSource::Impl::on_request_completed(lc::Request* request) {
  {
    std::lock_guard lock(mutex);
    completed.push_back(request);
  }
  completed_cv.notify_one();
}

void LibcameraSource::Impl::mark_lost(const std::string& why) {
  {
    std::lock_guard lock(mutex);
    if (lost) return;
    lost = true;
    lost_message = "libcamera " + id + ": " + why;
  }
  completed_cv.notify_all();
}

void LibcameraSource::Impl::on_camera_removed(std::shared_ptr<lc::Camera> removed) {
  if (removed == camera) mark_lost("camera removed");
}

void LibcameraSource::Impl::on_disconnected() { mark_lost("camera disconnected"); }

StreamConfig LibcameraSource::Impl::default_viewfinder() {
  StreamConfig wanted;
  wanted.fps = 0;
  const auto generated = camera->generateConfiguration({lc::StreamRole::Viewfinder});
  if (!generated || generated->empty()) return wanted;
  const lc::StreamConfiguration& sc = generated->at(0);
  wanted.width = static_cast<int>(sc.size.width);
  wanted.height = static_cast<int>(sc.size.height);
  if (const auto pf = libcamera_map::to_pixel_format(sc.pixelFormat.fourcc())) {
    wanted.pixel_format = *pf;
    return wanted;
  }
  const auto offered = sc.formats().pixelformats();
  for (PixelFormat pf : kPreferred) {
    const auto drm = libcamera_map::to_drm_fourcc(pf);
    if (std::any_of(offered.begin(), offered.end(), [&](const lc::PixelFormat& o) { return o.fourcc() == *drm; })) {
      wanted.pixel_format = pf;
      break;
    }
  }
  return wanted;
}

// The still role at the most pixels it offers in the viewfinder's format
// (the role's own default when it does not offer that format).
StreamConfig LibcameraSource::Impl::largest_still() {
  StreamConfig still = config;
  still.fps = 0;
  const auto generated = camera->generateConfiguration({lc::StreamRole::StillCapture});
  if (!generated || generated->empty()) return still;
  const lc::StreamConfiguration& sc = generated->at(0);
  const auto sizes = sc.formats().sizes(lc::PixelFormat(*libcamera_map::to_drm_fourcc(config.pixel_format)));
  const auto area = [](const lc::Size& s) { return std::uint64_t{s.width} * s.height; };
  const auto best = std::max_element(sizes.begin(), sizes.end(),
                                     [&](const auto& a, const auto& b) { return area(a) < area(b); });
  const lc::Size size = best != sizes.end() ? *best : sc.size;
  still.width = static_cast<int>(size.width);
  still.height = static_cast<int>(size.height);
  return still;
}

ConfigStatus LibcameraSource::Impl::configure(lc::StreamRole role, StreamConfig& asked) {
  if (streaming) throw std::logic_error("libcamera " + id + ": configure while running (stop first)");
  auto generated = camera->generateConfiguration({role});
  const auto drm = libcamera_map::to_drm_fourcc(asked.pixel_format);
  if (!generated || generated->empty() || !drm || asked.width <= 0 || asked.height <= 0)
    return ConfigStatus::Invalid;
  lc::StreamConfiguration& sc = generated->at(0);
  sc.pixelFormat = lc::PixelFormat(*drm);
  sc.size = lc::Size(static_cast<unsigned>(asked.width), static_cast<unsigned>(asked.height));
  const auto validated = generated->validate();
  const auto pf = libcamera_map::to_pixel_format(sc.pixelFormat.fourcc());
  if (validated == lc::CameraConfiguration::Invalid || !pf || sc.pixelFormat.modifier() != 0)
    return ConfigStatus::Invalid;
  bool adjusted = validated == lc::CameraConfiguration::Adjusted || *pf != asked.pixel_format ||
                  sc.size.width != static_cast<unsigned>(asked.width) ||
                  sc.size.height != static_cast<unsigned>(asked.height);

  std::int64_t duration = 0;
  double fps = 0;
  if (asked.fps > 0) {
    const auto& info = camera->controls();
    if (const auto it = info.find(lc::controls::FrameDurationLimits.id()); it != info.end()) {
      duration = libcamera_map::frame_duration_us(asked.fps, int64_bound(it->second.min()).value_or(0),
                                                  int64_bound(it->second.max()).value_or(0));
      fps = 1e6 / static_cast<double>(duration);
    }
    if (!(fps > 0 && std::abs(fps - asked.fps) <= 0.01 * asked.fps)) adjusted = true;
  }

  if (const int ret = camera->configure(generated.get())) fail("Camera::configure", ret);
  camera_config = std::move(generated);
  stream = camera_config->at(0).stream();
  frame_duration = duration;
  config = StreamConfig{*pf, static_cast<int>(sc.size.width), static_cast<int>(sc.size.height), fps};
  std::optional<int> encoding, range;
  if (sc.colorSpace) {
    encoding = static_cast<int>(sc.colorSpace->ycbcrEncoding);
    range = static_cast<int>(sc.colorSpace->range);
  }
  const auto colour = libcamera_map::colour_from_libcamera(encoding, range, *pf);
  format = FrameFormat{*pf, config.width, config.height,
                       *pf == PixelFormat::MJPEG ? 0 : static_cast<int>(sc.stride), colour.encoding,
                       colour.range};
  asked = config;
  return adjusted ? ConfigStatus::Adjusted : ConfigStatus::Valid;
}

// Maps each dmabuf of the buffer once (planes often share one fd).
void LibcameraSource::Impl::map_buffer(const lc::FrameBuffer& buffer) {
  std::map<int, std::size_t> lengths;
  for (const auto& plane : buffer.planes()) {
    const std::size_t offset = plane.offset == lc::FrameBuffer::Plane::kInvalidOffset ? 0 : plane.offset;
    auto& length = lengths[plane.fd.get()];
    length = std::max(length, offset + plane.length);
  }
  for (const auto& [fd, length] : lengths) {
    if (mappings.count(fd)) continue;
    auto mapping = std::make_unique<DmabufMapping>(fd, length);
    if (!mapping->ok()) fail("mmap of a frame buffer", -errno);
    mappings.emplace(fd, std::move(mapping));
  }
}

void LibcameraSource::Impl::start() {
  if (streaming) return;
  if (is_lost()) throw std::runtime_error(lost_result().message);
  allocator = std::make_unique<lc::FrameBufferAllocator>(camera);
  try {
    if (const int ret = allocator->allocate(stream); ret < 0) fail("FrameBufferAllocator::allocate", ret);
    for (const auto& buffer : allocator->buffers(stream)) {
      map_buffer(*buffer);
      auto request = camera->createRequest();
      if (!request) throw std::runtime_error("libcamera " + id + ": Camera::createRequest failed");
      if (const int ret = request->addBuffer(stream, buffer.get())) fail("Request::addBuffer", ret);
      requests.push_back(std::move(request));
    }
    lc::ControlList start_controls(camera->controls());
    {
      std::lock_guard lock(controls_mutex);
      for (const auto& [cid, value] : sticky_controls) start_controls.set(cid, value);
      pending_controls.clear();
    }
    if (frame_duration > 0) start_controls.set(lc::controls::FrameDurationLimits, {frame_duration, frame_duration});
    {
      std::lock_guard lock(mutex);
      completed.clear();
    }
    if (const int ret = camera->start(&start_controls)) fail("Camera::start", ret);
    streaming = true;
    for (const auto& request : requests)
      if (const int ret = camera->queueRequest(request.get())) fail("Camera::queueRequest", ret);
  } catch (...) {
    stop();
    throw;
  }
}

void LibcameraSource::Impl::stop() {
  if (streaming) camera->stop();  // cancels the queued requests; fails only once the camera is gone
  streaming = false;
  {
    std::lock_guard lock(mutex);
    completed.clear();
  }
  requests.clear();  // before their buffers are freed
  mappings.clear();
  if (allocator && stream) allocator->free(stream);
  allocator.reset();
}

bool LibcameraSource::Impl::requeue(lc::Request* request) {
  request->reuse(lc::Request::ReuseBuffers);
  {
    std::lock_guard lock(controls_mutex);
    for (const auto& [cid, value] : pending_controls) request->controls().set(cid, value);
    pending_controls.clear();
  }
  if (const int ret = camera->queueRequest(request)) {
    mark_lost("Camera::queueRequest: " + errno_text(-ret));
    return false;
  }
  return true;
}

Frame LibcameraSource::Impl::copy_frame(lc::Request& request, const lc::FrameBuffer& buffer) {
  const auto& planes = buffer.planes();
  const auto& used = buffer.metadata().planes();
  std::vector<std::uint8_t> bytes;
  for (std::size_t i = 0; i < planes.size(); ++i) {
    const auto& plane = planes[i];
    const std::size_t offset = plane.offset == lc::FrameBuffer::Plane::kInvalidOffset ? 0 : plane.offset;
    std::size_t n = i < used.size() && used[i].bytesused ? std::min<std::size_t>(used[i].bytesused, plane.length)
                                                          : plane.length;
    // NV12's chroma must start right after stride * height luma bytes.
    if (format.pixel_format == PixelFormat::NV12 && planes.size() > 1)
      n = std::min<std::size_t>(plane.length, static_cast<std::size_t>(format.stride) *
                                                  (i == 0 ? format.height : (format.height + 1) / 2));
    const std::uint8_t* base = mappings.at(plane.fd.get())->data() + offset;
    bytes.insert(bytes.end(), base, base + n);
  }
  Frame frame = frame_from_bytes(format, std::move(bytes));

  const lc::ControlList& md = request.metadata();
  frame.metadata.sequence = buffer.metadata().sequence;
  frame.metadata.timestamp_ns = md.get(lc::controls::SensorTimestamp)
                                    .value_or(static_cast<std::int64_t>(buffer.metadata().timestamp));
  if (const auto v = md.get(lc::controls::ExposureTime)) frame.metadata.exposure_us = *v;
  if (const auto v = md.get(lc::controls::AnalogueGain)) frame.metadata.analogue_gain = *v;
  if (const auto v = md.get(lc::controls::ColourGains)) {
    frame.metadata.colour_gain_red = (*v)[0];
    frame.metadata.colour_gain_blue = (*v)[1];
    std::lock_guard lock(controls_mutex);
    last_colour_gains = std::pair{(*v)[0], (*v)[1]};
  }
  if (const auto v = md.get(lc::controls::ColourTemperature)) frame.metadata.colour_temperature_k = *v;
  return frame;
}

CaptureResult LibcameraSource::Impl::next_frame(std::chrono::milliseconds timeout) {
  if (is_lost()) return lost_result();
  if (!streaming) throw std::logic_error("libcamera " + id + ": next_frame before start");
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::optional<Frame> stale;
  for (;;) {
    std::deque<lc::Request*> ready;
    {
      std::unique_lock lock(mutex);
      completed_cv.wait_until(lock, deadline, [&] { return lost || !completed.empty(); });
      if (lost) return {CaptureStatus::DeviceLost, std::nullopt, lost_message};
      if (completed.empty() && stale) return {CaptureStatus::Ok, std::move(stale), {}};
      if (completed.empty())
        return {CaptureStatus::Timeout, std::nullopt,
                "libcamera " + id + ": no frame within " + std::to_string(timeout.count()) + " ms"};
      ready.swap(completed);
    }
    const bool drained_all = ready.size() >= requests.size();
    lc::Request* newest = ready.back();
    ready.pop_back();
    for (lc::Request* stale : ready)
      if (!requeue(stale)) return lost_result();
    // A request cancelled while streaming means the pipeline failed.
    if (newest->status() == lc::Request::RequestCancelled) {
      mark_lost("request cancelled (camera failed)");
      return lost_result();
    }
    const lc::FrameBuffer* buffer = newest->findBuffer(stream);
    std::optional<Frame> frame;
    if (buffer && buffer->metadata().status == lc::FrameMetadata::FrameSuccess)
      frame = copy_frame(*newest, *buffer);
    if (!requeue(newest)) return lost_result();
    // Every request done: the camera ran dry while the client was away and
    // the newest is as old as that. Wait once for a fresh one (the stale
    // one is the answer if none comes in time).
    if (frame && drained_all && !stale) {
      stale = std::move(frame);
      continue;
    }
    if (frame) return {CaptureStatus::Ok, std::move(frame), {}};
    // A frame error: wait for the next one within the same deadline.
  }
}

// --- public methods ------------------------------------------------------

LibcameraSource::LibcameraSource(const std::string& camera_id) : impl_(std::make_unique<Impl>()) {
  try {
    impl_->open(camera_id);
  } catch (...) {
    impl_->close();
    throw;
  }
}

LibcameraSource::~LibcameraSource() { impl_->close(); }

CameraInfo LibcameraSource::info() const {
  return CameraInfo{"libcamera:" + impl_->id, "libcamera", camera_description(*impl_->camera), impl_->formats};
}

ConfigStatus LibcameraSource::configure(StreamConfig& config) {
  return impl_->configure(lc::StreamRole::Viewfinder, config);
}

StreamConfig LibcameraSource::configuration() const { return impl_->config; }
FrameFormat LibcameraSource::frame_format() const { return impl_->format; }
void LibcameraSource::start() { impl_->start(); }
void LibcameraSource::stop() { impl_->stop(); }
bool LibcameraSource::running() const { return impl_->streaming; }

CaptureResult LibcameraSource::next_frame(std::chrono::milliseconds timeout) {
  return impl_->next_frame(timeout);
}

CaptureResult LibcameraSource::capture_still(const std::optional<StreamConfig>& still,
                                             std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (d.is_lost()) return d.lost_result();
  const StreamConfig viewfinder = d.config;
  const bool was_running = d.streaming;
  d.stop();
  auto restore = [&](bool quiet) {
    try {
      d.stop();
      StreamConfig back = viewfinder;
      d.configure(lc::StreamRole::Viewfinder, back);
      if (was_running) d.start();
    } catch (...) {
      if (!quiet) throw;
    }
  };
  StreamConfig target = still ? *still : d.largest_still();
  if (d.configure(lc::StreamRole::StillCapture, target) == ConfigStatus::Invalid) {
    restore(false);
    throw std::invalid_argument("libcamera " + d.id + ": the still configuration was refused");
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
  restore(result.status == CaptureStatus::DeviceLost || d.is_lost());
  return result;
}

std::vector<std::string> LibcameraSource::set_controls(const CameraControls& controls) {
  Impl& d = *impl_;
  const lc::ControlInfoMap& info = d.camera->controls();
  auto find = [&](const lc::ControlId& cid) -> const lc::ControlInfo* {
    const auto it = info.find(cid.id());
    return it == info.end() ? nullptr : &it->second;
  };
  lc::ControlList set(info);
  std::vector<std::string> unsupported;
  if (controls.auto_exposure) {
    if (find(lc::controls::AeEnable)) set.set(lc::controls::AeEnable, *controls.auto_exposure);
    else unsupported.push_back("auto_exposure");
  }
  if (controls.exposure_us) {
    if (const auto* ci = find(lc::controls::ExposureTime)) {
      if (find(lc::controls::AeEnable)) set.set(lc::controls::AeEnable, false);
      const double us = std::clamp(*controls.exposure_us, 0.0, 2.0e9);
      set.set(lc::controls::ExposureTime, clamp_to<std::int32_t>(*ci, static_cast<std::int32_t>(std::lround(us))));
    } else {
      unsupported.push_back("exposure_us");
    }
  }
  if (controls.analogue_gain) {
    if (const auto* ci = find(lc::controls::AnalogueGain))
      set.set(lc::controls::AnalogueGain, clamp_to<float>(*ci, static_cast<float>(*controls.analogue_gain)));
    else
      unsupported.push_back("analogue_gain");
  }
  if (controls.auto_white_balance) {
    if (find(lc::controls::AwbEnable)) set.set(lc::controls::AwbEnable, *controls.auto_white_balance);
    else unsupported.push_back("auto_white_balance");
  }
  if (controls.colour_gain_red || controls.colour_gain_blue) {
    if (find(lc::controls::ColourGains)) {
      // Both gains go together: the one not given stays as last reported.
      std::pair<float, float> gains{1.0f, 1.0f};
      {
        std::lock_guard lock(d.controls_mutex);
        if (d.last_colour_gains) gains = *d.last_colour_gains;
      }
      if (controls.colour_gain_red) gains.first = static_cast<float>(*controls.colour_gain_red);
      if (controls.colour_gain_blue) gains.second = static_cast<float>(*controls.colour_gain_blue);
      if (find(lc::controls::AwbEnable)) set.set(lc::controls::AwbEnable, false);
      set.set(lc::controls::ColourGains, {gains.first, gains.second});
    } else {
      if (controls.colour_gain_red) unsupported.push_back("colour_gain_red");
      if (controls.colour_gain_blue) unsupported.push_back("colour_gain_blue");
    }
  }
  std::lock_guard lock(d.controls_mutex);
  for (const auto& [cid, value] : set) {
    d.sticky_controls.set(cid, value);
    d.pending_controls.set(cid, value);
  }
  return unsupported;
}

std::vector<CameraInfo> list_libcamera_cameras() {
  std::shared_ptr<lc::CameraManager> manager;
  try {
    manager = camera_manager();
  } catch (const std::exception&) {
    return {};
  }
  std::vector<CameraInfo> cameras;
  for (const auto& camera : manager->cameras())
    cameras.push_back(CameraInfo{"libcamera:" + camera->id(), "libcamera", camera_description(*camera),
                                 camera_formats(*camera)});
  return cameras;
}

bool libcamera_owns_device(const std::string& device_path) {
  struct stat st {};
  if (::stat(device_path.c_str(), &st) != 0 || !S_ISCHR(st.st_mode)) return false;
  try {
    return camera_manager()->get(st.st_rdev) != nullptr;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace propcam::capture
