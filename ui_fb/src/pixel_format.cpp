#include "propcam/ui_fb/pixel_format.h"

#include <stdexcept>
#include <string>

namespace propcam::ui_fb {

namespace {

std::uint32_t field_max(const BitField& field) {
  return field.length == 0 ? 0u : static_cast<std::uint32_t>((1ull << field.length) - 1);
}

void check_field(const char* channel, const BitField& field, int bits_per_pixel,
                 int min_length) {
  if (field.length < min_length || field.length > 16 || field.offset < 0 ||
      (field.length > 0 && field.offset + field.length > bits_per_pixel)) {
    throw std::invalid_argument("ui_fb: framebuffer " + std::string(channel) +
                                " field at bit " + std::to_string(field.offset) + " length " +
                                std::to_string(field.length) + " does not fit a " +
                                std::to_string(bits_per_pixel) + "-bit pixel");
  }
}

std::uint64_t field_mask(const BitField& field) {
  return static_cast<std::uint64_t>(field_max(field)) << field.offset;
}

// Stores the low `Bytes` bytes of each word, least significant first: fbdev pixels
// are little-endian words regardless of how this code is compiled.
template <int Bytes>
void pack_row_words(const std::uint8_t* rgb, int pixel_count, std::uint8_t* dest,
                    const std::array<std::uint32_t, 256>& red,
                    const std::array<std::uint32_t, 256>& green,
                    const std::array<std::uint32_t, 256>& blue, std::uint32_t alpha) {
  for (int i = 0; i < pixel_count; ++i, rgb += 3, dest += Bytes) {
    const std::uint32_t word = red[rgb[0]] | green[rgb[1]] | blue[rgb[2]] | alpha;
    dest[0] = static_cast<std::uint8_t>(word);
    dest[1] = static_cast<std::uint8_t>(word >> 8);
    if constexpr (Bytes >= 3) dest[2] = static_cast<std::uint8_t>(word >> 16);
    if constexpr (Bytes >= 4) dest[3] = static_cast<std::uint8_t>(word >> 24);
  }
}

}  // namespace

void FramebufferFormat::validate() const {
  if (bits_per_pixel != 16 && bits_per_pixel != 24 && bits_per_pixel != 32) {
    throw std::invalid_argument("ui_fb: unsupported framebuffer depth of " +
                                std::to_string(bits_per_pixel) +
                                " bits per pixel (16, 24 or 32 supported)");
  }
  check_field("red", red, bits_per_pixel, 1);
  check_field("green", green, bits_per_pixel, 1);
  check_field("blue", blue, bits_per_pixel, 1);
  check_field("alpha", alpha, bits_per_pixel, 0);
  const std::uint64_t masks[] = {field_mask(red), field_mask(green), field_mask(blue),
                                 field_mask(alpha)};
  std::uint64_t used = 0;
  for (std::uint64_t mask : masks) {
    if ((used & mask) != 0) {
      throw std::invalid_argument("ui_fb: overlapping colour fields in framebuffer format " +
                                  describe());
    }
    used |= mask;
  }
}

std::string FramebufferFormat::describe() const {
  auto field = [](char name, const BitField& f) {
    return std::string(" ") + name + std::to_string(f.offset) + ":" + std::to_string(f.length);
  };
  std::string text = std::to_string(bits_per_pixel) + "bpp" + field('r', red) +
                     field('g', green) + field('b', blue);
  if (alpha.length > 0) text += field('a', alpha);
  return text;
}

PixelPacker::PixelPacker(const FramebufferFormat& format)
    : format_(format), bytes_per_pixel_(format.bytes_per_pixel()) {
  format_.validate();
  auto fill_table = [](std::array<std::uint32_t, 256>& table, const BitField& field) {
    const std::uint32_t max = field_max(field);
    for (std::uint32_t value = 0; value < 256; ++value) {
      table[value] = ((value * max + 127) / 255) << field.offset;
    }
  };
  fill_table(red_bits_, format_.red);
  fill_table(green_bits_, format_.green);
  fill_table(blue_bits_, format_.blue);
  opaque_alpha_bits_ = field_max(format_.alpha) << format_.alpha.offset;
}

std::uint32_t PixelPacker::pack(Rgb colour) const {
  return red_bits_[colour.r] | green_bits_[colour.g] | blue_bits_[colour.b] | opaque_alpha_bits_;
}

Rgb PixelPacker::unpack(std::uint32_t word) const {
  auto expand = [word](const BitField& field) {
    const std::uint32_t max = field_max(field);
    const std::uint32_t value = (word >> field.offset) & max;
    return static_cast<std::uint8_t>((value * 255 + max / 2) / max);
  };
  return {expand(format_.red), expand(format_.green), expand(format_.blue)};
}

void PixelPacker::pack_row(const std::uint8_t* rgb, int pixel_count, std::uint8_t* dest) const {
  switch (bytes_per_pixel_) {
    case 2:
      pack_row_words<2>(rgb, pixel_count, dest, red_bits_, green_bits_, blue_bits_,
                        opaque_alpha_bits_);
      break;
    case 3:
      pack_row_words<3>(rgb, pixel_count, dest, red_bits_, green_bits_, blue_bits_,
                        opaque_alpha_bits_);
      break;
    default:
      pack_row_words<4>(rgb, pixel_count, dest, red_bits_, green_bits_, blue_bits_,
                        opaque_alpha_bits_);
      break;
  }
}

void PixelPacker::unpack_row(const std::uint8_t* src, int pixel_count, std::uint8_t* rgb) const {
  for (int i = 0; i < pixel_count; ++i, src += bytes_per_pixel_, rgb += 3) {
    std::uint32_t word = 0;
    for (int byte = bytes_per_pixel_ - 1; byte >= 0; --byte) word = (word << 8) | src[byte];
    const Rgb colour = unpack(word);
    rgb[0] = colour.r;
    rgb[1] = colour.g;
    rgb[2] = colour.b;
  }
}

void PixelPacker::check_frame(Size size, std::size_t frame_bytes, std::size_t line_stride) const {
  const std::size_t row_bytes = static_cast<std::size_t>(size.width) * bytes_per_pixel_;
  if (line_stride < row_bytes) {
    throw std::invalid_argument("ui_fb: line stride of " + std::to_string(line_stride) +
                                " bytes is shorter than a " + std::to_string(size.width) +
                                "-pixel row of " + std::to_string(row_bytes) + " bytes");
  }
  const std::size_t needed = (static_cast<std::size_t>(size.height) - 1) * line_stride + row_bytes;
  if (frame_bytes < needed) {
    throw std::invalid_argument("ui_fb: frame buffer of " + std::to_string(frame_bytes) +
                                " bytes cannot hold " + std::to_string(size.width) + "x" +
                                std::to_string(size.height) + " pixels at stride " +
                                std::to_string(line_stride) + " (needs " +
                                std::to_string(needed) + ")");
  }
}

void PixelPacker::pack(const Canvas& canvas, const Rect& region, std::span<std::uint8_t> frame,
                       std::size_t line_stride) const {
  check_frame(canvas.size(), frame.size(), line_stride);
  const Rect visible = intersect(region, canvas.bounds());
  for (int row = visible.y; row < visible.bottom(); ++row) {
    const std::uint8_t* rgb = canvas.pixels().ptr<std::uint8_t>(row) + 3 * visible.x;
    std::uint8_t* dest = frame.data() + static_cast<std::size_t>(row) * line_stride +
                         static_cast<std::size_t>(visible.x) * bytes_per_pixel_;
    pack_row(rgb, visible.width, dest);
  }
}

void PixelPacker::unpack(std::span<const std::uint8_t> frame, std::size_t line_stride,
                         Canvas& canvas) const {
  check_frame(canvas.size(), frame.size(), line_stride);
  for (int row = 0; row < canvas.height(); ++row) {
    unpack_row(frame.data() + static_cast<std::size_t>(row) * line_stride, canvas.width(),
               canvas.pixels().ptr<std::uint8_t>(row));
  }
}

void pack_pixels(const Canvas& canvas, const Rect& region, const FramebufferFormat& format,
                 std::span<std::uint8_t> frame, std::size_t line_stride) {
  PixelPacker(format).pack(canvas, region, frame, line_stride);
}

}  // namespace propcam::ui_fb
