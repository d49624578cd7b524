#include <gtest/gtest.h>

#include <chrono>
#include <iostream>
#include <string>

#include "propcam/capture/libcamera_source.h"

namespace propcam::capture {
namespace {

using namespace std::chrono_literals;

// DRM fourcc codes as drm_fourcc.h spells them, written out so the table is
// checked against the standard rather than against itself.
constexpr std::uint32_t fcc(char a, char b, char c, char d) {
  return std::uint32_t(std::uint8_t(a)) | std::uint32_t(std::uint8_t(b)) << 8 |
         std::uint32_t(std::uint8_t(c)) << 16 | std::uint32_t(std::uint8_t(d)) << 24;
}

constexpr PixelFormat kAll[] = {PixelFormat::RGB24, PixelFormat::BGR24, PixelFormat::YUYV, PixelFormat::UYVY,
                                PixelFormat::NV12,  PixelFormat::MJPEG, PixelFormat::GREY};

TEST(LibcameraFormats, DrmRgbOrderIsReversedInMemory) {
  // DRM_FORMAT_RGB888 'RG24' is [23:0] R:G:B little endian: B, G, R bytes.
  EXPECT_EQ(libcamera_map::to_pixel_format(fcc('R', 'G', '2', '4')), PixelFormat::BGR24);
  EXPECT_EQ(libcamera_map::to_pixel_format(fcc('B', 'G', '2', '4')), PixelFormat::RGB24);
  EXPECT_EQ(libcamera_map::to_drm_fourcc(PixelFormat::RGB24), fcc('B', 'G', '2', '4'));
  EXPECT_EQ(libcamera_map::to_drm_fourcc(PixelFormat::BGR24), fcc('R', 'G', '2', '4'));
}

TEST(LibcameraFormats, YuvJpegAndGreyMapAndRoundTrip) {
  EXPECT_EQ(libcamera_map::to_drm_fourcc(PixelFormat::YUYV), fcc('Y', 'U', 'Y', 'V'));
  EXPECT_EQ(libcamera_map::to_drm_fourcc(PixelFormat::UYVY), fcc('U', 'Y', 'V', 'Y'));
  EXPECT_EQ(libcamera_map::to_drm_fourcc(PixelFormat::NV12), fcc('N', 'V', '1', '2'));
  EXPECT_EQ(libcamera_map::to_drm_fourcc(PixelFormat::MJPEG), fcc('M', 'J', 'P', 'G'));
  EXPECT_EQ(libcamera_map::to_drm_fourcc(PixelFormat::GREY), fcc('R', '8', ' ', ' '));
  for (PixelFormat f : kAll) {
    const auto code = libcamera_map::to_drm_fourcc(f);
    ASSERT_TRUE(code);
    EXPECT_EQ(libcamera_map::to_pixel_format(*code), f);
  }
  EXPECT_FALSE(libcamera_map::to_pixel_format(fcc('X', 'R', '2', '4')));  // XRGB8888: 4 bytes a pixel
  EXPECT_FALSE(libcamera_map::to_pixel_format(fcc('Y', 'U', '1', '2')));  // YUV420 planar
  EXPECT_FALSE(libcamera_map::to_pixel_format(0));
}

TEST(LibcameraColour, ColourSpaceFieldsMap) {
  // ColorSpace::YcbcrEncoding: None 0, Rec601 1, Rec709 2, Rec2020 3; Range: Full 0, Limited 1.
  auto c = libcamera_map::colour_from_libcamera(1, 1, PixelFormat::YUYV);  // Smpte170m
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt601);
  EXPECT_EQ(c.range, QuantisationRange::Limited);
  c = libcamera_map::colour_from_libcamera(2, 1, PixelFormat::NV12);  // Rec709
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt709);
  EXPECT_EQ(c.range, QuantisationRange::Limited);
  c = libcamera_map::colour_from_libcamera(1, 0, PixelFormat::MJPEG);  // Sycc
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt601);
  EXPECT_EQ(c.range, QuantisationRange::Full);
  c = libcamera_map::colour_from_libcamera(3, 1, PixelFormat::YUYV);  // Rec2020: nearest is 709
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt709);
}

TEST(LibcameraColour, NoColourSpaceDefaultsByFormat) {
  auto c = libcamera_map::colour_from_libcamera(std::nullopt, std::nullopt, PixelFormat::YUYV);
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt601);
  EXPECT_EQ(c.range, QuantisationRange::Limited);
  EXPECT_EQ(libcamera_map::colour_from_libcamera(std::nullopt, std::nullopt, PixelFormat::BGR24).range,
            QuantisationRange::Full);
  EXPECT_EQ(libcamera_map::colour_from_libcamera(std::nullopt, std::nullopt, PixelFormat::MJPEG).range,
            QuantisationRange::Full);
  EXPECT_EQ(libcamera_map::colour_from_libcamera(0, 0, PixelFormat::RGB24).encoding, YcbcrEncoding::Bt601);
}

TEST(LibcameraFrameRate, DurationClampsToTheCameraLimits) {
  EXPECT_EQ(libcamera_map::frame_duration_us(30, 0, 0), 33333);
  EXPECT_EQ(libcamera_map::frame_duration_us(30, 50000, 1000000), 50000);   // 20 fps at most
  EXPECT_EQ(libcamera_map::frame_duration_us(0.5, 10000, 1000000), 1000000);
  EXPECT_EQ(libcamera_map::frame_duration_us(0, 10000, 1000000), 0);
  EXPECT_EQ(libcamera_map::frame_duration_us(-5, 0, 0), 0);
}

TEST(LibcameraList, ListingThisMachineReturns) {
  const auto cameras = list_libcamera_cameras();
  for (const auto& c : cameras) {
    EXPECT_EQ(c.backend, "libcamera");
    EXPECT_EQ(c.id.rfind("libcamera:", 0), 0u) << c.id;
  }
  // A second listing shares the started manager.
  EXPECT_EQ(list_libcamera_cameras().size(), cameras.size());
}

TEST(LibcameraOpen, UnknownCameraNamesTheId) {
  try {
    LibcameraSource source("propcam-no-such-camera");
    FAIL() << "opened a camera that does not exist";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("propcam-no-such-camera"), std::string::npos) << e.what();
  }
}

// Needs a camera libcamera can drive (a Pi camera, a UVC webcam).
TEST(LibcameraDevice, StreamsFramesAndTakesAStill) {
  const auto cameras = list_libcamera_cameras();
  if (cameras.empty()) GTEST_SKIP() << "no camera visible to libcamera on this machine";
  LibcameraSource source(cameras.front().id.substr(std::string("libcamera:").size()));
  std::cout << source.info().id << ": " << source.info().description << "\n";
  StreamConfig config = source.configuration();
  ASSERT_NE(source.configure(config), ConfigStatus::Invalid);
  EXPECT_THROW(source.next_frame(100ms), std::logic_error);
  source.start();
  for (int i = 0; i < 5; ++i) {
    const CaptureResult r = source.next_frame(3000ms);
    ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
    EXPECT_EQ(r.frame->format.width, config.width);
    EXPECT_GT(r.frame->bytes_used, 0u);
  }
  source.set_controls(CameraControls{10000.0, 2.0, std::nullopt, std::nullopt, std::nullopt, std::nullopt});
  const CaptureResult still = source.capture_still(std::nullopt, 5000ms);
  ASSERT_EQ(still.status, CaptureStatus::Ok) << still.message;
  EXPECT_TRUE(source.running());
  EXPECT_EQ(source.next_frame(3000ms).status, CaptureStatus::Ok);
  source.stop();
}

}  // namespace
}  // namespace propcam::capture
