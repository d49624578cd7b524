// Where a finished Canvas goes: a Linux framebuffer device or a DRM/KMS card on the
// appliance, or a file-backed framebuffer that leaves PNG snapshots (development, CI,
// demos).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "propcam/ui_fb/canvas.h"
#include "propcam/ui_fb/pixel_format.h"

namespace propcam::ui_fb {

class Display {
 public:
  virtual ~Display() = default;
  // The visible resolution; present() expects a Canvas of exactly this size.
  virtual Size size() const = 0;
  // Shows the canvas. Throws std::invalid_argument if its size differs from size().
  virtual void present(const Canvas& canvas) = 0;
  // Human-readable identity for logs, e.g. "fbdev /dev/fb0 (vc4drmfb) 800x480 ...".
  virtual std::string name() const = 0;

 protected:
  // Throws the std::invalid_argument that present() promises for a wrong-sized canvas.
  void require_canvas_size(const Canvas& canvas) const {
    const Size expected = size();
    if (canvas.size() == expected) return;
    throw std::invalid_argument("ui_fb: " + name() + " expects a " +
                                std::to_string(expected.width) + "x" +
                                std::to_string(expected.height) + " canvas, got " +
                                std::to_string(canvas.width()) + "x" +
                                std::to_string(canvas.height()));
  }
};

struct FileDisplayOptions {
  Size size{800, 480};
  FramebufferFormat format = FramebufferFormat::xrgb8888();
  int line_length = 0;  // bytes per framebuffer row; 0 means tightly packed
  // Where snapshots go; the folder is created if missing. With `numbered`, frame N is
  // written next to it as <stem>_NNNNNN<ext> (N from 1) instead of overwriting it.
  std::filesystem::path snapshot_path = "screen.png";
  bool numbered = false;
};

// A framebuffer held in memory: present() packs the canvas into it with the same
// code as the device backend, then decodes it and saves the result as a PNG, so a
// snapshot shows exactly what the screen would (RGB565 banding included). Each
// snapshot is written under a temporary name in the same folder and renamed into
// place, so a reader never sees a partial file.
class FileDisplay : public Display {
 public:
  explicit FileDisplay(FileDisplayOptions options);

  Size size() const override { return options_.size; }
  void present(const Canvas& canvas) override;
  std::string name() const override;

  const FramebufferFormat& format() const { return packer_.format(); }
  std::size_t line_length() const { return line_length_; }
  // The packed framebuffer bytes after the last present().
  const std::vector<std::uint8_t>& framebuffer() const { return framebuffer_; }
  // What the screen shows: the framebuffer decoded back to RGB8.
  Canvas screen_contents() const;
  int frames_presented() const { return frames_presented_; }
  // The file written by the last present(); empty before the first.
  const std::filesystem::path& last_snapshot() const { return last_snapshot_; }

 private:
  std::filesystem::path snapshot_path_for_frame(int frame_number) const;

  FileDisplayOptions options_;
  PixelPacker packer_;
  std::size_t line_length_;
  std::vector<std::uint8_t> framebuffer_;
  int frames_presented_ = 0;
  std::filesystem::path last_snapshot_;
};

// A Linux fbdev device (/dev/fbN), memory-mapped. When the virtual resolution holds
// two screens, present() draws into the hidden one and pans to it (FBIOPAN_DISPLAY)
// so a frame never appears half drawn; otherwise it draws into the visible screen.
// Only packed-pixel true/direct-colour modes of 16, 24 or 32 bpp are supported.
class FbdevDisplay : public Display {
 public:
  // Throws std::runtime_error saying what went wrong: cannot open, not a
  // framebuffer, unsupported pixel layout, mmap failure.
  explicit FbdevDisplay(const std::filesystem::path& device = "/dev/fb0");
  ~FbdevDisplay() override;
  FbdevDisplay(const FbdevDisplay&) = delete;
  FbdevDisplay& operator=(const FbdevDisplay&) = delete;

  Size size() const override { return size_; }
  void present(const Canvas& canvas) override;
  std::string name() const override {
    return name_ + (double_buffered_ ? " double-buffered" : "");
  }

  const FramebufferFormat& format() const { return packer_.format(); }
  std::size_t line_length() const { return line_length_; }
  // False from the start on single-screen modes, and after a refused pan.
  bool double_buffered() const { return double_buffered_; }

 private:
  void open_and_map();
  void release() noexcept;
  bool pan_to(int page);
  std::span<std::uint8_t> page_pixels(int page) const;

  std::filesystem::path device_;
  int fd_ = -1;
  std::uint8_t* mapping_ = nullptr;
  std::size_t mapping_length_ = 0;
  Size size_;
  std::size_t line_length_ = 0;
  int x_offset_ = 0;  // visible origin within the virtual screen
  int y_offset_ = 0;  // first visible row when single-buffered
  PixelPacker packer_{FramebufferFormat::xrgb8888()};
  bool double_buffered_ = false;
  int visible_page_ = 0;  // double-buffered: 0 shows rows [0, h), 1 shows [h, 2h)
  std::string name_;
};

struct DrmDisplayOptions {
  std::filesystem::path card = "/dev/dri/card0";
  // A connector id (as modetest lists them); nullopt takes the first connected one.
  std::optional<std::uint32_t> connector_id;
  // 2: draw into a hidden buffer and page-flip to it; 1: draw into the shown one.
  int buffer_count = 2;
  // How long present() waits for a page flip to complete (a few frames).
  std::chrono::milliseconds flip_timeout{100};
};

// Thrown when a DRM card works but cannot show the UI now: nothing is plugged in,
// or another process (a compositor, an X server) is DRM master.
class DrmDisplayUnavailable : public std::runtime_error {
 public:
  enum class Reason { NoConnectedConnector, OwnedByAnotherProcess };
  DrmDisplayUnavailable(Reason reason, const std::string& message)
      : std::runtime_error(message), reason_(reason) {}
  Reason reason() const { return reason_; }

 private:
  Reason reason_;
};

// A DRM/KMS card (/dev/dri/cardN) driven with dumb buffers, for boards without
// fbdev emulation. The constructor becomes DRM master, picks a connected connector,
// its preferred mode and a CRTC, allocates the buffers (XRGB8888, or RGB565 if the
// driver takes nothing else) and shows a black frame. present() packs the canvas
// with the same PixelPacker as the other displays into the hidden buffer and
// page-flips to it, waiting for the flip at most flip_timeout; a driver without
// page flips gets drmModeSetCrtc instead. The destructor restores the CRTC as it
// was (e.g. the console) and releases everything.
class DrmDisplay : public Display {
 public:
  // Throws std::runtime_error naming the card: cannot open, not a DRM device, no
  // modesetting or dumb buffers, no CRTC, allocation failures; DrmDisplayUnavailable
  // for no connected connector or another DRM master; std::invalid_argument for a
  // buffer_count other than 1 or 2.
  explicit DrmDisplay(DrmDisplayOptions options = {});
  ~DrmDisplay() override;
  DrmDisplay(const DrmDisplay&) = delete;
  DrmDisplay& operator=(const DrmDisplay&) = delete;

  Size size() const override;
  // Also throws std::runtime_error if the driver refuses the frame, or a page flip
  // is still pending a flip_timeout after the previous present().
  void present(const Canvas& canvas) override;
  // e.g. "drm /dev/dri/card0 (bochs-drm) connector 35 Virtual-1 1280x800@75 ..."
  std::string name() const override;

  const FramebufferFormat& format() const;
  std::size_t line_length() const;  // the dumb buffer's pitch
  std::uint32_t connector_id() const;
  std::uint32_t crtc_id() const;
  int buffer_count() const;
  // False with one buffer, or once the driver refused a page flip.
  bool page_flips() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace propcam::ui_fb
