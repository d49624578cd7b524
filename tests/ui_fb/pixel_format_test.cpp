#include "propcam/ui_fb/pixel_format.h"

#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

namespace propcam::ui_fb {
namespace {

using Bytes = std::vector<std::uint8_t>;

// Packs one row of colours with the shared pack function and returns the bytes.
Bytes pack_colours(const std::vector<Rgb>& colours, const FramebufferFormat& format) {
  Canvas canvas(static_cast<int>(colours.size()), 1);
  for (std::size_t i = 0; i < colours.size(); ++i) canvas.set_pixel(static_cast<int>(i), 0, colours[i]);
  const std::size_t stride = colours.size() * static_cast<std::size_t>(format.bytes_per_pixel());
  Bytes frame(stride, 0xEE);
  pack_pixels(canvas, canvas.bounds(), format, frame, stride);
  return frame;
}

constexpr Rgb kRed{255, 0, 0};
constexpr Rgb kGreen{0, 255, 0};
constexpr Rgb kBlue{0, 0, 255};
constexpr Rgb kWhite{255, 255, 255};
constexpr Rgb kSample{0x12, 0x34, 0x56};

TEST(PixelFormat, Rgb565PacksLittleEndianWords) {
  // Mid grey 128 rounds to 16/31 and 32/63: word 0x8410. 250 rounds to 30, not 31.
  const Bytes bytes = pack_colours({kRed, kGreen, kBlue, kWhite, {128, 128, 128}, {250, 0, 0}},
                                   FramebufferFormat::rgb565());
  EXPECT_EQ(bytes, (Bytes{0x00, 0xF8, 0xE0, 0x07, 0x1F, 0x00, 0xFF, 0xFF, 0x10, 0x84, 0x00, 0xF0}));
}

TEST(PixelFormat, Bgr888And888ByteOrders) {
  // DRM naming: BGR888 has blue in the top byte of the word, so memory reads R,G,B.
  EXPECT_EQ(pack_colours({kSample, kRed}, FramebufferFormat::bgr888()),
            (Bytes{0x12, 0x34, 0x56, 0xFF, 0x00, 0x00}));
  // RGB888 (the usual fbdev 24 bpp layout: red at bit 16) reads B,G,R in memory.
  EXPECT_EQ(pack_colours({kSample, kRed}, FramebufferFormat::rgb888()),
            (Bytes{0x56, 0x34, 0x12, 0x00, 0x00, 0xFF}));
}

TEST(PixelFormat, Xrgb8888AndArgb8888) {
  EXPECT_EQ(pack_colours({kSample, kBlue}, FramebufferFormat::xrgb8888()),
            (Bytes{0x56, 0x34, 0x12, 0x00, 0xFF, 0x00, 0x00, 0x00}));
  // A present alpha field is written fully opaque.
  EXPECT_EQ(pack_colours({kSample}, FramebufferFormat::argb8888()),
            (Bytes{0x56, 0x34, 0x12, 0xFF}));
}

TEST(PixelFormat, OddLayouts) {
  // 10-bit channels with a 2-bit alpha at the bottom: R 22:10, G 12:10, B 2:10, A 0:2.
  const FramebufferFormat rgba1010102{32, {22, 10}, {12, 10}, {2, 10}, {0, 2}};
  // 128 -> round(128 * 1023 / 255) = 514; word 0xFFC00000 | 514 << 12 | 3 = 0xFFE02003.
  EXPECT_EQ(pack_colours({{255, 128, 0}}, rgba1010102), (Bytes{0x03, 0x20, 0xE0, 0xFF}));

  // 16 bpp ABGR1555: red in the low bits, 1-bit alpha at the top.
  const FramebufferFormat abgr1555{16, {0, 5}, {5, 5}, {10, 5}, {15, 1}};
  EXPECT_EQ(pack_colours({kRed, kBlue}, abgr1555), (Bytes{0x1F, 0x80, 0x00, 0xFC}));

  // 24 bpp with uneven fields and a gap: G 18:6, B 8:6, R 0:6 (bits 6-7 and 14-17 unused).
  const FramebufferFormat odd24{24, {0, 6}, {18, 6}, {8, 6}, {}};
  EXPECT_EQ(pack_colours({kWhite, kGreen}, odd24), (Bytes{0x3F, 0x3F, 0xFC, 0x00, 0x00, 0xFC}));
}

TEST(PixelFormat, RegionPackHonoursStrideAndLeavesOtherBytesAlone) {
  Canvas canvas(3, 2);
  canvas.fill(kWhite);
  constexpr std::size_t kStride = 8;  // 6 bytes of pixels + 2 bytes of padding per row
  Bytes frame(kStride * 2, 0xAA);
  // Region sticks out of the canvas on the right: only columns 1..2 are packed.
  pack_pixels(canvas, {1, 0, 5, 2}, FramebufferFormat::rgb565(), frame, kStride);
  const Bytes expected{0xAA, 0xAA, 0xFF, 0xFF, 0xFF, 0xFF, 0xAA, 0xAA,
                       0xAA, 0xAA, 0xFF, 0xFF, 0xFF, 0xFF, 0xAA, 0xAA};
  EXPECT_EQ(frame, expected);
}

TEST(PixelFormat, RejectsBadFormatsAndShortBuffers) {
  EXPECT_THROW(PixelPacker({8, {5, 3}, {2, 3}, {0, 2}, {}}), std::invalid_argument);
  EXPECT_THROW(PixelPacker({16, {8, 8}, {4, 8}, {0, 4}, {}}), std::invalid_argument);  // overlap
  EXPECT_THROW(PixelPacker({24, {20, 8}, {8, 8}, {0, 8}, {}}), std::invalid_argument);  // spills
  EXPECT_THROW(PixelPacker({32, {16, 8}, {8, 8}, {0, 0}, {}}), std::invalid_argument);  // no blue

  Canvas canvas(4, 4);
  Bytes small(4 * 4 * 4 - 1);
  EXPECT_THROW(pack_pixels(canvas, canvas.bounds(), FramebufferFormat::xrgb8888(), small, 16),
               std::invalid_argument);
  Bytes enough(4 * 4 * 4);
  EXPECT_THROW(pack_pixels(canvas, canvas.bounds(), FramebufferFormat::xrgb8888(), enough, 15),
               std::invalid_argument);
}

TEST(PixelFormat, UnpackInvertsPack) {
  const PixelPacker exact(FramebufferFormat::xrgb8888());
  const PixelPacker rgb565(FramebufferFormat::rgb565());
  for (int value = 0; value < 256; ++value) {
    const auto v = static_cast<std::uint8_t>(value);
    const Rgb colour{v, static_cast<std::uint8_t>(255 - v), v};
    EXPECT_EQ(exact.unpack(exact.pack(colour)), colour);
    const Rgb coarse = rgb565.unpack(rgb565.pack(colour));
    EXPECT_LE(std::abs(coarse.r - colour.r), 4);
    EXPECT_LE(std::abs(coarse.g - colour.g), 2);
  }
  EXPECT_EQ(rgb565.unpack(0xFFFF), kWhite);
}

TEST(PixelFormat, DescribeNamesTheFields) {
  EXPECT_EQ(FramebufferFormat::argb8888().describe(), "32bpp r16:8 g8:8 b0:8 a24:8");
  EXPECT_EQ(FramebufferFormat::rgb565().describe(), "16bpp r11:5 g5:6 b0:5");
}

}  // namespace
}  // namespace propcam::ui_fb
