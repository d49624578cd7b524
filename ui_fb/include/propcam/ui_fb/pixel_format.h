// Framebuffer pixel formats and the one packing routine every Display uses to
// turn the RGB8 Canvas into the bytes a framebuffer expects.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "propcam/ui_fb/canvas.h"

namespace propcam::ui_fb {

// Mirrors Linux's struct fb_bitfield: the channel occupies bits
// [offset, offset + length) of the pixel word. length 0 means "absent".
struct BitField {
  int offset = 0;
  int length = 0;
  friend bool operator==(const BitField&, const BitField&) = default;
};

// Mirrors the colour part of Linux's struct fb_var_screeninfo. A pixel is a
// bits_per_pixel/8-byte little-endian word. Preset names follow the DRM fourcc
// convention: channels listed from the most significant bit of the word down, so
// xrgb8888 is the bytes B,G,R,X in memory and bgr888 is R,G,B.
struct FramebufferFormat {
  int bits_per_pixel = 32;
  BitField red;
  BitField green;
  BitField blue;
  BitField alpha;  // written fully opaque when present

  int bytes_per_pixel() const { return bits_per_pixel / 8; }
  // Throws std::invalid_argument unless bits_per_pixel is 16, 24 or 32, red, green
  // and blue are 1..16 bits, alpha is 0..16 bits, and no fields overlap or spill
  // out of the word.
  void validate() const;
  // e.g. "32bpp r16:8 g8:8 b0:8" (offset:length), for logs and error messages.
  std::string describe() const;
  friend bool operator==(const FramebufferFormat&, const FramebufferFormat&) = default;

  static constexpr FramebufferFormat rgb565() { return {16, {11, 5}, {5, 6}, {0, 5}, {}}; }
  static constexpr FramebufferFormat rgb888() { return {24, {16, 8}, {8, 8}, {0, 8}, {}}; }
  static constexpr FramebufferFormat bgr888() { return {24, {0, 8}, {8, 8}, {16, 8}, {}}; }
  static constexpr FramebufferFormat xrgb8888() { return {32, {16, 8}, {8, 8}, {0, 8}, {}}; }
  static constexpr FramebufferFormat argb8888() { return {32, {16, 8}, {8, 8}, {0, 8}, {24, 8}}; }
  static constexpr FramebufferFormat xbgr8888() { return {32, {0, 8}, {8, 8}, {16, 8}, {}}; }
};

// Converts between Rgb and pixel words of one format. Channels are rescaled with
// rounding (8 -> 5 bits is round(v * 31 / 255)); unpacking expands back to 8 bits
// the same way. Building one precomputes per-channel tables, so keep it around.
class PixelPacker {
 public:
  explicit PixelPacker(const FramebufferFormat& format);  // validates the format

  const FramebufferFormat& format() const { return format_; }
  int bytes_per_pixel() const { return bytes_per_pixel_; }

  std::uint32_t pack(Rgb colour) const;
  Rgb unpack(std::uint32_t word) const;

  // `rgb` holds pixel_count R,G,B triples; `dest` receives pixel_count words.
  void pack_row(const std::uint8_t* rgb, int pixel_count, std::uint8_t* dest) const;
  void unpack_row(const std::uint8_t* src, int pixel_count, std::uint8_t* rgb) const;

  // Packs the canvas pixels inside `region` (clipped to the canvas) into `frame`,
  // laid out like the screen: pixel (x, y) starts at byte y * line_stride +
  // x * bytes_per_pixel(). Bytes outside the region are left alone. Throws
  // std::invalid_argument if the stride is shorter than a row or `frame` is too
  // small for the canvas.
  void pack(const Canvas& canvas, const Rect& region, std::span<std::uint8_t> frame,
            std::size_t line_stride) const;
  // The inverse: decodes a whole frame of canvas.size() into `canvas`.
  void unpack(std::span<const std::uint8_t> frame, std::size_t line_stride, Canvas& canvas) const;

 private:
  void check_frame(Size size, std::size_t frame_bytes, std::size_t line_stride) const;

  FramebufferFormat format_;
  int bytes_per_pixel_;
  std::array<std::uint32_t, 256> red_bits_{};    // 8-bit value -> field bits in place
  std::array<std::uint32_t, 256> green_bits_{};
  std::array<std::uint32_t, 256> blue_bits_{};
  std::uint32_t opaque_alpha_bits_ = 0;
};

// One-shot form of PixelPacker(format).pack(...).
void pack_pixels(const Canvas& canvas, const Rect& region, const FramebufferFormat& format,
                 std::span<std::uint8_t> frame, std::size_t line_stride);

}  // namespace propcam::ui_fb
