// DrmDisplay: a DRM/KMS card driven with dumb buffers (libdrm's legacy modesetting
// API), for boards whose kernel has no fbdev emulation.
#include <fcntl.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xf86drm.h>
#include <xf86drmMode.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "propcam/ui_fb/display.h"

namespace propcam::ui_fb {

namespace {

constexpr int kMaxBuffers = 2;

std::string errno_text(int error) { return std::strerror(error); }

// --- owners of libdrm allocations ---------------------------------------------

struct FreeResources {
  void operator()(drmModeRes* p) const { drmModeFreeResources(p); }
};
struct FreeConnector {
  void operator()(drmModeConnector* p) const { drmModeFreeConnector(p); }
};
struct FreeEncoder {
  void operator()(drmModeEncoder* p) const { drmModeFreeEncoder(p); }
};
struct FreeCrtc {
  void operator()(drmModeCrtc* p) const { drmModeFreeCrtc(p); }
};
struct FreeVersion {
  void operator()(drmVersion* p) const { drmFreeVersion(p); }
};
using Resources = std::unique_ptr<drmModeRes, FreeResources>;
using Connector = std::unique_ptr<drmModeConnector, FreeConnector>;
using Encoder = std::unique_ptr<drmModeEncoder, FreeEncoder>;
using SavedCrtc = std::unique_ptr<drmModeCrtc, FreeCrtc>;
using Version = std::unique_ptr<drmVersion, FreeVersion>;

// --- owners of kernel objects -------------------------------------------------

class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  ~UniqueFd() {
    if (fd_ >= 0) ::close(fd_);
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(UniqueFd&& other) noexcept {
    std::swap(fd_, other.fd_);
    return *this;
  }
  int get() const { return fd_; }

 private:
  int fd_ = -1;
};

// Holds DRM master for as long as it lives.
class MasterHold {
 public:
  MasterHold() = default;
  explicit MasterHold(int fd) : fd_(fd) {}
  ~MasterHold() {
    if (fd_ >= 0) drmDropMaster(fd_);
  }
  MasterHold(const MasterHold&) = delete;
  MasterHold& operator=(MasterHold&& other) noexcept {
    std::swap(fd_, other.fd_);
    return *this;
  }

 private:
  int fd_ = -1;
};

class DumbHandle {
 public:
  DumbHandle(int fd, std::uint32_t handle) : fd_(fd), handle_(handle) {}
  ~DumbHandle() {
    if (handle_ == 0) return;
    drm_mode_destroy_dumb destroy{};
    destroy.handle = handle_;
    drmIoctl(fd_, DRM_IOCTL_MODE_DESTROY_DUMB, &destroy);
  }
  DumbHandle(DumbHandle&& other) noexcept
      : fd_(other.fd_), handle_(std::exchange(other.handle_, 0)) {}
  DumbHandle(const DumbHandle&) = delete;
  DumbHandle& operator=(const DumbHandle&) = delete;
  std::uint32_t get() const { return handle_; }

 private:
  int fd_;
  std::uint32_t handle_;
};

class Mapping {
 public:
  Mapping(void* address, std::size_t length)
      : address_(static_cast<std::uint8_t*>(address)), length_(length) {}
  ~Mapping() {
    if (address_ != nullptr) ::munmap(address_, length_);
  }
  Mapping(Mapping&& other) noexcept
      : address_(std::exchange(other.address_, nullptr)), length_(other.length_) {}
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  std::span<std::uint8_t> bytes() const { return {address_, length_}; }

 private:
  std::uint8_t* address_;
  std::size_t length_;
};

class FramebufferId {
 public:
  FramebufferId(int fd, std::uint32_t id) : fd_(fd), id_(id) {}
  ~FramebufferId() {
    if (id_ != 0) drmModeRmFB(fd_, id_);
  }
  FramebufferId(FramebufferId&& other) noexcept : fd_(other.fd_), id_(std::exchange(other.id_, 0)) {}
  FramebufferId(const FramebufferId&) = delete;
  FramebufferId& operator=(const FramebufferId&) = delete;
  std::uint32_t get() const { return id_; }

 private:
  int fd_;
  std::uint32_t id_;
};

// A dumb buffer, its CPU mapping and the framebuffer that scans it out. Members are
// released in reverse order: framebuffer, mapping, buffer.
struct ScanoutBuffer {
  DumbHandle handle;
  std::size_t pitch;
  Mapping mapping;
  FramebufferId framebuffer;
};

// Puts the CRTC back the way it was found (the console, another program's last
// frame, or off) before our framebuffers go away.
class CrtcRestorer {
 public:
  CrtcRestorer() = default;
  CrtcRestorer(int fd, std::uint32_t connector_id, SavedCrtc saved)
      : fd_(fd), connector_id_(connector_id), saved_(std::move(saved)) {}
  ~CrtcRestorer() {
    if (!saved_) return;
    drmModeCrtc& crtc = *saved_;
    if (crtc.mode_valid && crtc.buffer_id != 0) {
      drmModeSetCrtc(fd_, crtc.crtc_id, crtc.buffer_id, crtc.x, crtc.y, &connector_id_, 1,
                     &crtc.mode);
    } else {
      drmModeSetCrtc(fd_, crtc.crtc_id, 0, 0, 0, nullptr, 0, nullptr);
    }
  }
  CrtcRestorer(const CrtcRestorer&) = delete;
  CrtcRestorer& operator=(CrtcRestorer&& other) noexcept {
    std::swap(fd_, other.fd_);
    std::swap(connector_id_, other.connector_id_);
    std::swap(saved_, other.saved_);
    return *this;
  }

 private:
  int fd_ = -1;
  std::uint32_t connector_id_ = 0;
  SavedCrtc saved_;
};

// A pixel layout the legacy drmModeAddFB call can ask for by depth and bpp.
struct ScanoutFormat {
  FramebufferFormat format;
  std::uint32_t depth;
  std::uint32_t bits_per_pixel;
  const char* fourcc_name;
};

// XRGB8888 is what every KMS driver scans out; RGB565 is for small panels that
// take nothing else.
constexpr std::array kScanoutFormats{
    ScanoutFormat{FramebufferFormat::xrgb8888(), 24, 32, "XRGB8888"},
    ScanoutFormat{FramebufferFormat::rgb565(), 16, 16, "RGB565"},
};

std::string connector_name(const drmModeConnector& connector) {
  const char* type = drmModeGetConnectorTypeName(connector.connector_type);
  return std::string(type != nullptr ? type : "Unknown") + "-" +
         std::to_string(connector.connector_type_id);
}

const drmModeModeInfo& preferred_mode(const drmModeConnector& connector) {
  for (int i = 0; i < connector.count_modes; ++i) {
    if (connector.modes[i].type & DRM_MODE_TYPE_PREFERRED) return connector.modes[i];
  }
  return connector.modes[0];  // drivers list the best mode first
}

bool usable(const drmModeConnector& connector) {
  return connector.connection == DRM_MODE_CONNECTED && connector.count_modes > 0;
}

void on_page_flip(int /*fd*/, unsigned /*frame*/, unsigned /*sec*/, unsigned /*usec*/, void* data) {
  *static_cast<bool*>(data) = false;  // the flip_pending flag of the display that asked
}

}  // namespace

struct DrmDisplay::Impl {
  explicit Impl(DrmDisplayOptions options_in);
  void present(const Canvas& canvas);

  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error("ui_fb: DRM card " + card + ": " + what);
  }
  void open_card();
  void become_master();
  Connector choose_connector(const drmModeRes& resources);
  std::uint32_t choose_crtc(const drmModeRes& resources, const drmModeConnector& connector);
  void allocate_buffers();
  std::optional<ScanoutBuffer> make_buffer(const ScanoutFormat& scanout, std::string& refusal);
  void show_first_frame();
  void show(std::size_t index);
  void wait_for_flip();
  void describe();

  DrmDisplayOptions options;
  std::string card;
  // Declared so that destruction restores the CRTC first, then frees the buffers,
  // drops master and closes the card.
  UniqueFd fd;
  MasterHold master;
  std::string driver;
  std::uint32_t connector_id = 0;
  std::string connector_label;
  std::uint32_t crtc_id = 0;
  drmModeModeInfo mode{};
  Size size;
  PixelPacker packer{FramebufferFormat::xrgb8888()};
  std::vector<ScanoutBuffer> buffers;
  CrtcRestorer restorer;
  std::size_t shown = 0;  // the buffer being scanned out (or about to be, mid-flip)
  bool page_flips = false;
  bool flip_pending = false;
  std::string name;
};

DrmDisplay::Impl::Impl(DrmDisplayOptions options_in)
    : options(std::move(options_in)), card(options.card.string()) {
  if (options.buffer_count < 1 || options.buffer_count > kMaxBuffers) {
    throw std::invalid_argument("ui_fb: DrmDisplay buffer count " +
                                std::to_string(options.buffer_count) + " (expected 1 or 2)");
  }
  open_card();
  become_master();

  std::uint64_t has_dumb = 0;
  if (drmGetCap(fd.get(), DRM_CAP_DUMB_BUFFER, &has_dumb) != 0 || has_dumb == 0) {
    fail("driver " + driver + " has no dumb buffers");
  }
  const Resources resources(drmModeGetResources(fd.get()));
  if (!resources) {
    fail("has no modesetting resources (" + errno_text(errno) +
         "; a render node, or a GPU without a display?)");
  }
  const Connector connector = choose_connector(*resources);
  connector_id = connector->connector_id;
  connector_label = connector_name(*connector);
  mode = preferred_mode(*connector);
  size = {mode.hdisplay, mode.vdisplay};
  crtc_id = choose_crtc(*resources, *connector);

  allocate_buffers();
  show_first_frame();
  page_flips = buffers.size() > 1;
  describe();
}

void DrmDisplay::Impl::open_card() {
  fd = UniqueFd(::open(card.c_str(), O_RDWR | O_CLOEXEC));
  if (fd.get() < 0) fail("cannot open (" + errno_text(errno) + ")");
  struct stat status {};
  if (::fstat(fd.get(), &status) != 0) fail("cannot stat (" + errno_text(errno) + ")");
  if (!S_ISCHR(status.st_mode)) fail("not a DRM device (not a character device)");
  const Version version(drmGetVersion(fd.get()));
  if (!version) fail("not a DRM device (DRM_IOCTL_VERSION failed: " + errno_text(errno) + ")");
  driver.assign(version->name, static_cast<std::size_t>(std::max(version->name_len, 0)));
}

void DrmDisplay::Impl::become_master() {
  // The first opener is master already; setting it again is then a no-op.
  if (drmSetMaster(fd.get()) == 0) {
    master = MasterHold(fd.get());
    return;
  }
  const int error = errno;
  // EBUSY: someone holds master. EACCES/EPERM (unprivileged) or EINVAL (old
  // kernels): we did not get master on open because someone held it then.
  if (error == EBUSY || error == EACCES || error == EPERM || error == EINVAL) {
    throw DrmDisplayUnavailable(
        DrmDisplayUnavailable::Reason::OwnedByAnotherProcess,
        "ui_fb: DRM card " + card + ": another process owns the display (it is DRM master: "
        "a compositor, an X server or another propcam?); cannot become master (" +
            errno_text(error) + ")");
  }
  fail("cannot become DRM master (" + errno_text(error) + ")");
}

Connector DrmDisplay::Impl::choose_connector(const drmModeRes& resources) {
  std::string seen;
  for (int i = 0; i < resources.count_connectors; ++i) {
    Connector connector(drmModeGetConnector(fd.get(), resources.connectors[i]));
    if (!connector) continue;
    const bool wanted = !options.connector_id || *options.connector_id == connector->connector_id;
    if (wanted && usable(*connector)) return connector;
    if (wanted && options.connector_id) {
      throw DrmDisplayUnavailable(DrmDisplayUnavailable::Reason::NoConnectedConnector,
                                  "ui_fb: DRM card " + card + ": connector " +
                                      std::to_string(connector->connector_id) + " " +
                                      connector_name(*connector) + " is not connected");
    }
    seen += (seen.empty() ? "" : ", ") + std::to_string(connector->connector_id) + " " +
            connector_name(*connector) +
            (connector->connection == DRM_MODE_CONNECTED ? " (no modes)" : " (disconnected)");
  }
  if (options.connector_id) {
    fail("has no connector " + std::to_string(*options.connector_id) + " (connectors: " +
         (seen.empty() ? "none" : seen) + ")");
  }
  throw DrmDisplayUnavailable(DrmDisplayUnavailable::Reason::NoConnectedConnector,
                              "ui_fb: DRM card " + card + ": no connected connector (" +
                                  (seen.empty() ? "it has none" : "connectors: " + seen) + ")");
}

std::uint32_t DrmDisplay::Impl::choose_crtc(const drmModeRes& resources,
                                            const drmModeConnector& connector) {
  // Keep the CRTC already driving this connector (the console's), if any.
  if (connector.encoder_id != 0) {
    const Encoder encoder(drmModeGetEncoder(fd.get(), connector.encoder_id));
    if (encoder && encoder->crtc_id != 0) return encoder->crtc_id;
  }
  for (int e = 0; e < connector.count_encoders; ++e) {
    const Encoder encoder(drmModeGetEncoder(fd.get(), connector.encoders[e]));
    if (!encoder) continue;
    for (int c = 0; c < resources.count_crtcs; ++c) {
      if (encoder->possible_crtcs & (1u << c)) return resources.crtcs[c];
    }
  }
  fail("no CRTC can drive connector " + std::to_string(connector.connector_id) + " " +
       connector_name(connector));
}

// A dumb buffer of the display's size, mapped and wrapped in a framebuffer; nullopt
// (and the reason in `refusal`) if the driver does not take the format.
std::optional<ScanoutBuffer> DrmDisplay::Impl::make_buffer(const ScanoutFormat& scanout,
                                                           std::string& refusal) {
  drm_mode_create_dumb create{};
  create.width = static_cast<std::uint32_t>(size.width);
  create.height = static_cast<std::uint32_t>(size.height);
  create.bpp = scanout.bits_per_pixel;
  if (drmIoctl(fd.get(), DRM_IOCTL_MODE_CREATE_DUMB, &create) != 0) {
    refusal = std::string(scanout.fourcc_name) + ": cannot create a dumb buffer (" +
              errno_text(errno) + ")";
    return std::nullopt;
  }
  DumbHandle handle(fd.get(), create.handle);
  const std::size_t row_bytes = static_cast<std::size_t>(size.width) * scanout.bits_per_pixel / 8;
  if (create.pitch < row_bytes || create.size < std::size_t{create.pitch} * size.height) {
    fail("dumb buffer of " + std::to_string(create.size) + " bytes, pitch " +
         std::to_string(create.pitch) + ", is too small");
  }

  drm_mode_map_dumb map{};
  map.handle = handle.get();
  if (drmIoctl(fd.get(), DRM_IOCTL_MODE_MAP_DUMB, &map) != 0) {
    fail("cannot map a dumb buffer (" + errno_text(errno) + ")");
  }
  void* address = ::mmap(nullptr, create.size, PROT_READ | PROT_WRITE, MAP_SHARED, fd.get(),
                         static_cast<off_t>(map.offset));
  if (address == MAP_FAILED) {
    fail("mmap of a " + std::to_string(create.size) + "-byte dumb buffer failed (" +
         errno_text(errno) + ")");
  }
  Mapping mapping(address, create.size);
  std::fill(mapping.bytes().begin(), mapping.bytes().end(), std::uint8_t{0});  // black

  std::uint32_t framebuffer_id = 0;
  if (drmModeAddFB(fd.get(), create.width, create.height, static_cast<std::uint8_t>(scanout.depth),
                   static_cast<std::uint8_t>(scanout.bits_per_pixel), create.pitch, handle.get(),
                   &framebuffer_id) != 0) {
    refusal = std::string(scanout.fourcc_name) + ": drmModeAddFB refused (" + errno_text(errno) + ")";
    return std::nullopt;
  }
  return ScanoutBuffer{std::move(handle), create.pitch, std::move(mapping),
                       FramebufferId(fd.get(), framebuffer_id)};
}

void DrmDisplay::Impl::allocate_buffers() {
  std::string refusals;
  for (const ScanoutFormat& scanout : kScanoutFormats) {
    buffers.clear();
    std::string refusal;
    while (static_cast<int>(buffers.size()) < options.buffer_count) {
      auto buffer = make_buffer(scanout, refusal);
      if (!buffer) break;
      buffers.push_back(std::move(*buffer));
    }
    if (refusal.empty()) {
      packer = PixelPacker(scanout.format);
      return;
    }
    refusals += (refusals.empty() ? "" : "; ") + refusal;
  }
  buffers.clear();
  fail("no framebuffer format works: " + refusals);
}

void DrmDisplay::Impl::show_first_frame() {
  SavedCrtc saved(drmModeGetCrtc(fd.get(), crtc_id));
  if (drmModeSetCrtc(fd.get(), crtc_id, buffers[0].framebuffer.get(), 0, 0, &connector_id, 1,
                     &mode) != 0) {
    fail("cannot set mode " + std::string(mode.name) + " on CRTC " + std::to_string(crtc_id) +
         " for " + connector_label + " (" + errno_text(errno) + ")");
  }
  restorer = CrtcRestorer(fd.get(), connector_id, std::move(saved));
  shown = 0;
}

void DrmDisplay::Impl::describe() {
  const std::size_t pitch = buffers[0].pitch;
  name = "drm " + card + " (" + driver + ") " + connector_label + " (connector " +
         std::to_string(connector_id) + ", CRTC " + std::to_string(crtc_id) + ") " +
         std::to_string(size.width) + "x" + std::to_string(size.height) + "@" +
         std::to_string(mode.vrefresh) + "Hz " + packer.format().describe() + " pitch " +
         std::to_string(pitch) + ", " + std::to_string(buffers.size()) +
         (buffers.size() > 1 ? " buffers" : " buffer");
}

// Waits, at most flip_timeout, for the page-flip event of the last flip.
void DrmDisplay::Impl::wait_for_flip() {
  const auto deadline = std::chrono::steady_clock::now() + options.flip_timeout;
  while (flip_pending) {
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return;
    pollfd ready{fd.get(), POLLIN, 0};
    const int polled = ::poll(&ready, 1, static_cast<int>(left.count()));
    if (polled < 0 && errno == EINTR) continue;
    if (polled < 0) fail("poll for the page-flip event failed (" + errno_text(errno) + ")");
    if (polled == 0) return;
    drmEventContext context{};
    context.version = 2;  // page_flip_handler
    context.page_flip_handler = on_page_flip;
    if (drmHandleEvent(fd.get(), &context) != 0) {
      fail("reading the page-flip event failed (" + errno_text(errno) + ")");
    }
  }
}

void DrmDisplay::Impl::show(std::size_t index) {
  const std::uint32_t framebuffer_id = buffers[index].framebuffer.get();
  if (page_flips) {
    const int result = drmModePageFlip(fd.get(), crtc_id, framebuffer_id, DRM_MODE_PAGE_FLIP_EVENT,
                                       &flip_pending);
    if (result == 0) {
      flip_pending = true;
      shown = index;
      wait_for_flip();  // if it times out, the next present() waits again
      return;
    }
    if (result == -EBUSY) fail("page flip refused: a flip is still pending (EBUSY)");
    page_flips = false;  // the driver cannot flip: set the CRTC instead from now on
  }
  if (drmModeSetCrtc(fd.get(), crtc_id, framebuffer_id, 0, 0, &connector_id, 1, &mode) != 0) {
    fail("cannot show the frame on CRTC " + std::to_string(crtc_id) + " (" + errno_text(errno) +
         ")");
  }
  shown = index;
}

void DrmDisplay::Impl::present(const Canvas& canvas) {
  if (flip_pending) {
    wait_for_flip();
    if (flip_pending) {
      fail("the previous page flip did not complete within " +
           std::to_string(2 * options.flip_timeout.count()) + " ms");
    }
  }
  const std::size_t target = buffers.size() > 1 ? 1 - shown : shown;
  ScanoutBuffer& buffer = buffers[target];
  packer.pack(canvas, canvas.bounds(), buffer.mapping.bytes(), buffer.pitch);
  if (target != shown) {
    show(target);
    return;
  }
  // Single-buffered: the frame is on screen already, except on drivers that copy
  // to the panel only when told (USB and SPI displays). Others answer ENOSYS.
  drmModeDirtyFB(fd.get(), buffer.framebuffer.get(), nullptr, 0);
}

// --- DrmDisplay -----------------------------------------------------------------

DrmDisplay::DrmDisplay(DrmDisplayOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

DrmDisplay::~DrmDisplay() = default;

Size DrmDisplay::size() const { return impl_->size; }

void DrmDisplay::present(const Canvas& canvas) {
  require_canvas_size(canvas);
  impl_->present(canvas);
}

std::string DrmDisplay::name() const {
  if (impl_->buffers.size() < 2) return impl_->name;
  return impl_->name + (impl_->page_flips ? " page-flip" : " set-crtc");
}

const FramebufferFormat& DrmDisplay::format() const { return impl_->packer.format(); }
std::size_t DrmDisplay::line_length() const { return impl_->buffers[0].pitch; }
std::uint32_t DrmDisplay::connector_id() const { return impl_->connector_id; }
std::uint32_t DrmDisplay::crtc_id() const { return impl_->crtc_id; }
int DrmDisplay::buffer_count() const { return static_cast<int>(impl_->buffers.size()); }
bool DrmDisplay::page_flips() const { return impl_->page_flips; }

}  // namespace propcam::ui_fb
