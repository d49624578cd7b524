#include <fcntl.h>
#include <linux/fb.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

#include "propcam/ui_fb/display.h"

namespace propcam::ui_fb {

namespace {

std::string errno_text() { return std::strerror(errno); }

BitField to_bitfield(const fb_bitfield& field) {
  return {static_cast<int>(field.offset), static_cast<int>(field.length)};
}

}  // namespace

FbdevDisplay::FbdevDisplay(const std::filesystem::path& device) : device_(device) {
  try {
    open_and_map();
  } catch (...) {
    release();  // the destructor does not run for a constructor that throws
    throw;
  }
}

FbdevDisplay::~FbdevDisplay() { release(); }

void FbdevDisplay::release() noexcept {
  if (mapping_ != nullptr) ::munmap(mapping_, mapping_length_);
  mapping_ = nullptr;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void FbdevDisplay::open_and_map() {
  const std::string path = device_.string();
  auto fail = [&path](const std::string& what) {
    throw std::runtime_error("ui_fb: framebuffer " + path + ": " + what);
  };

  fd_ = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) fail("cannot open (" + errno_text() + ")");
  struct stat status {};
  if (::fstat(fd_, &status) != 0) fail("cannot stat (" + errno_text() + ")");
  if (!S_ISCHR(status.st_mode)) fail("not a framebuffer device (not a character device)");

  fb_fix_screeninfo fixed{};
  fb_var_screeninfo variable{};
  if (::ioctl(fd_, FBIOGET_FSCREENINFO, &fixed) != 0) {
    fail("not a framebuffer device (FBIOGET_FSCREENINFO failed: " + errno_text() + ")");
  }
  if (::ioctl(fd_, FBIOGET_VSCREENINFO, &variable) != 0) {
    fail("FBIOGET_VSCREENINFO failed (" + errno_text() + ")");
  }

  if (fixed.type != FB_TYPE_PACKED_PIXELS) {
    fail("unsupported memory layout (fb type " + std::to_string(fixed.type) +
         "; only packed pixels are supported)");
  }
  // Direct colour passes pixel values through the driver's colour map, which is
  // the identity unless someone changed it, so it is treated like true colour.
  if (fixed.visual != FB_VISUAL_TRUECOLOR && fixed.visual != FB_VISUAL_DIRECTCOLOR) {
    fail("unsupported visual " + std::to_string(fixed.visual) +
         " (palette and monochrome modes are not supported)");
  }
  if (variable.grayscale != 0 || variable.nonstd != 0) {
    fail("unsupported greyscale, FOURCC or non-standard pixel format");
  }
  if (variable.red.msb_right || variable.green.msb_right || variable.blue.msb_right) {
    fail("unsupported bit order (msb_right colour fields)");
  }

  const FramebufferFormat format{static_cast<int>(variable.bits_per_pixel),
                                 to_bitfield(variable.red), to_bitfield(variable.green),
                                 to_bitfield(variable.blue), to_bitfield(variable.transp)};
  try {
    packer_ = PixelPacker(format);
  } catch (const std::invalid_argument& error) {
    fail(std::string("unsupported pixel format: ") + error.what());
  }

  size_ = {static_cast<int>(variable.xres), static_cast<int>(variable.yres)};
  x_offset_ = static_cast<int>(variable.xoffset);
  y_offset_ = static_cast<int>(variable.yoffset);
  const std::size_t bytes_per_pixel = static_cast<std::size_t>(packer_.bytes_per_pixel());
  line_length_ = fixed.line_length != 0 ? fixed.line_length
                                        : static_cast<std::size_t>(variable.xres_virtual) * bytes_per_pixel;
  if (size_.width <= 0 || size_.height <= 0) fail("reports an empty resolution");
  if ((static_cast<std::size_t>(x_offset_) + size_.width) * bytes_per_pixel > line_length_) {
    fail("visible width does not fit its line length of " + std::to_string(line_length_) +
         " bytes");
  }

  mapping_length_ = fixed.smem_len;
  const std::size_t page_bytes = line_length_ * static_cast<std::size_t>(size_.height);
  if (mapping_length_ < (static_cast<std::size_t>(y_offset_) * line_length_) + page_bytes) {
    fail("framebuffer memory of " + std::to_string(mapping_length_) +
         " bytes is smaller than the visible screen");
  }
  void* mapped = ::mmap(nullptr, mapping_length_, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, 0);
  if (mapped == MAP_FAILED) fail("mmap of " + std::to_string(mapping_length_) +
                                 " bytes failed (" + errno_text() + ")");
  mapping_ = static_cast<std::uint8_t*>(mapped);

  // Two screens stacked vertically in the virtual resolution, and a driver that can
  // pan by whole screens, allow drawing off-screen and flipping.
  double_buffered_ = variable.yres_virtual >= 2 * variable.yres && fixed.ypanstep != 0 &&
                     variable.yres % fixed.ypanstep == 0 && mapping_length_ >= 2 * page_bytes;
  visible_page_ = double_buffered_ && variable.yoffset >= variable.yres ? 1 : 0;

  const std::string id(fixed.id, strnlen(fixed.id, sizeof fixed.id));
  name_ = "fbdev " + path + " (" + id + ") " + std::to_string(size_.width) + "x" +
          std::to_string(size_.height) + " " + format.describe() + " stride " +
          std::to_string(line_length_);
}

std::span<std::uint8_t> FbdevDisplay::page_pixels(int page) const {
  const std::size_t first_row =
      double_buffered_ ? static_cast<std::size_t>(page) * size_.height : y_offset_;
  const std::size_t start = first_row * line_length_ +
                            static_cast<std::size_t>(x_offset_) * packer_.bytes_per_pixel();
  return {mapping_ + start, mapping_length_ - start};
}

bool FbdevDisplay::pan_to(int page) {
  fb_var_screeninfo variable{};
  if (::ioctl(fd_, FBIOGET_VSCREENINFO, &variable) != 0) return false;
  variable.xoffset = static_cast<std::uint32_t>(x_offset_);
  variable.yoffset = static_cast<std::uint32_t>(page * size_.height);
  return ::ioctl(fd_, FBIOPAN_DISPLAY, &variable) == 0;
}

void FbdevDisplay::present(const Canvas& canvas) {
  require_canvas_size(canvas);
  if (double_buffered_) {
    const int hidden_page = 1 - visible_page_;
    packer_.pack(canvas, canvas.bounds(), page_pixels(hidden_page), line_length_);
    if (pan_to(hidden_page)) {
      visible_page_ = hidden_page;
      return;
    }
    // Some drivers advertise a tall virtual screen but refuse to pan: draw into
    // whatever is shown from now on.
    double_buffered_ = false;
    y_offset_ = visible_page_ * size_.height;
  }
  packer_.pack(canvas, canvas.bounds(), page_pixels(0), line_length_);
}

}  // namespace propcam::ui_fb
