#include <gtest/gtest.h>

#include <linux/videodev2.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <string>

#include "propcam/capture/v4l2_source.h"

namespace propcam::capture {
namespace {

using namespace std::chrono_literals;

constexpr std::uint32_t fcc(char a, char b, char c, char d) {
  return std::uint32_t(std::uint8_t(a)) | std::uint32_t(std::uint8_t(b)) << 8 |
         std::uint32_t(std::uint8_t(c)) << 16 | std::uint32_t(std::uint8_t(d)) << 24;
}

constexpr PixelFormat kAll[] = {PixelFormat::RGB24, PixelFormat::BGR24, PixelFormat::YUYV, PixelFormat::UYVY,
                                PixelFormat::NV12,  PixelFormat::MJPEG, PixelFormat::GREY};

template <typename Fn>
std::string thrown_message(Fn fn) {
  try {
    fn();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(nothing thrown)";
}

TEST(V4l2Formats, FourccTableMatchesVideodev2AndRoundTrips) {
  EXPECT_EQ(v4l2::to_v4l2_fourcc(PixelFormat::RGB24), fcc('R', 'G', 'B', '3'));
  EXPECT_EQ(v4l2::to_v4l2_fourcc(PixelFormat::BGR24), fcc('B', 'G', 'R', '3'));
  EXPECT_EQ(v4l2::to_v4l2_fourcc(PixelFormat::YUYV), fcc('Y', 'U', 'Y', 'V'));
  EXPECT_EQ(v4l2::to_v4l2_fourcc(PixelFormat::UYVY), fcc('U', 'Y', 'V', 'Y'));
  EXPECT_EQ(v4l2::to_v4l2_fourcc(PixelFormat::NV12), fcc('N', 'V', '1', '2'));
  EXPECT_EQ(v4l2::to_v4l2_fourcc(PixelFormat::MJPEG), fcc('M', 'J', 'P', 'G'));
  EXPECT_EQ(v4l2::to_v4l2_fourcc(PixelFormat::GREY), fcc('G', 'R', 'E', 'Y'));
  for (PixelFormat f : kAll) {
    const auto code = v4l2::to_v4l2_fourcc(f);
    ASSERT_TRUE(code);
    EXPECT_EQ(v4l2::to_pixel_format(*code), f);
  }
  EXPECT_FALSE(v4l2::to_pixel_format(V4L2_PIX_FMT_H264));
  EXPECT_FALSE(v4l2::to_pixel_format(V4L2_PIX_FMT_YUV420));
  EXPECT_FALSE(v4l2::to_pixel_format(0));
}

TEST(V4l2Colour, DefaultsResolveAsTheKernelDoes) {
  // A webcam's YUYV in sRGB: BT.601, limited.
  auto c = v4l2::colour_from_v4l2(V4L2_COLORSPACE_SRGB, V4L2_YCBCR_ENC_DEFAULT, V4L2_QUANTIZATION_DEFAULT,
                                  PixelFormat::YUYV);
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt601);
  EXPECT_EQ(c.range, QuantisationRange::Limited);
  // HD video: BT.709 limited.
  c = v4l2::colour_from_v4l2(V4L2_COLORSPACE_REC709, V4L2_YCBCR_ENC_DEFAULT, V4L2_QUANTIZATION_DEFAULT,
                             PixelFormat::NV12);
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt709);
  EXPECT_EQ(c.range, QuantisationRange::Limited);
  // JPEG: BT.601 full range, also when the driver leaves the colorspace DEFAULT.
  for (std::uint32_t cs : {std::uint32_t{V4L2_COLORSPACE_JPEG}, std::uint32_t{V4L2_COLORSPACE_DEFAULT}}) {
    c = v4l2::colour_from_v4l2(cs, V4L2_YCBCR_ENC_DEFAULT, V4L2_QUANTIZATION_DEFAULT, PixelFormat::MJPEG);
    EXPECT_EQ(c.encoding, YcbcrEncoding::Bt601);
    EXPECT_EQ(c.range, QuantisationRange::Full);
  }
  // RGB defaults to full range.
  c = v4l2::colour_from_v4l2(V4L2_COLORSPACE_SRGB, V4L2_YCBCR_ENC_DEFAULT, V4L2_QUANTIZATION_DEFAULT,
                             PixelFormat::RGB24);
  EXPECT_EQ(c.range, QuantisationRange::Full);
}

TEST(V4l2Colour, ExplicitFieldsWinAndWideGamutsMapToBt709) {
  auto c = v4l2::colour_from_v4l2(V4L2_COLORSPACE_SRGB, V4L2_YCBCR_ENC_709, V4L2_QUANTIZATION_FULL_RANGE,
                                  PixelFormat::YUYV);
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt709);
  EXPECT_EQ(c.range, QuantisationRange::Full);
  c = v4l2::colour_from_v4l2(V4L2_COLORSPACE_BT2020, V4L2_YCBCR_ENC_DEFAULT, V4L2_QUANTIZATION_DEFAULT,
                             PixelFormat::YUYV);
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt709);
  c = v4l2::colour_from_v4l2(V4L2_COLORSPACE_REC709, V4L2_YCBCR_ENC_XV601, V4L2_QUANTIZATION_LIM_RANGE,
                             PixelFormat::UYVY);
  EXPECT_EQ(c.encoding, YcbcrEncoding::Bt601);
  EXPECT_EQ(c.range, QuantisationRange::Limited);
}

bool contains(const std::vector<FormatSizes::Size>& sizes, int w, int h) {
  for (const auto& s : sizes)
    if (s.width == w && s.height == h) return true;
  return false;
}

TEST(V4l2Sizes, StepwiseRangeGivesCommonSizesAlignedAndAscending) {
  const auto sizes = v4l2::stepwise_sizes(16, 1920, 8, 16, 1080, 8);
  EXPECT_TRUE(contains(sizes, 16, 16));
  EXPECT_TRUE(contains(sizes, 640, 480));
  EXPECT_TRUE(contains(sizes, 1280, 720));
  EXPECT_TRUE(contains(sizes, 1920, 1080));
  EXPECT_FALSE(contains(sizes, 2592, 1944));  // outside the range
  EXPECT_TRUE(contains(sizes, 176, 144));
  for (std::size_t i = 1; i < sizes.size(); ++i)
    EXPECT_LT(std::int64_t{sizes[i - 1].width} * sizes[i - 1].height,
              std::int64_t{sizes[i].width} * sizes[i].height + 1);
  for (const auto& s : sizes) {
    EXPECT_EQ((s.width - 16) % 8, 0);
    EXPECT_EQ((s.height - 16) % 8, 0);
  }
}

TEST(V4l2Sizes, StepsExcludeMisalignedSizesAndTheMaximumAlignsDown) {
  // (1080 - 16) is not a multiple of 16: 1920x1080 is out, 1920x1072 is the top.
  const auto sizes = v4l2::stepwise_sizes(16, 1920, 16, 16, 1080, 16);
  EXPECT_FALSE(contains(sizes, 1920, 1080));
  EXPECT_TRUE(contains(sizes, 1920, 1072));
  EXPECT_TRUE(contains(sizes, 640, 480));
  const auto top = v4l2::largest_size(sizes);
  ASSERT_TRUE(top);
  EXPECT_EQ(top->width, 1920);
  EXPECT_EQ(top->height, 1072);
}

TEST(V4l2Sizes, ContinuousAndDegenerateRanges) {
  EXPECT_TRUE(contains(v4l2::stepwise_sizes(1, 4096, 1, 1, 4096, 1), 4096, 4096));
  EXPECT_TRUE(contains(v4l2::stepwise_sizes(1, 4096, 0, 1, 4096, 0), 1280, 720));  // step 0 read as 1
  EXPECT_TRUE(v4l2::stepwise_sizes(640, 320, 1, 480, 240, 1).empty());
  EXPECT_TRUE(v4l2::stepwise_sizes(0, 0, 1, 0, 0, 1).empty());
  const auto one = v4l2::stepwise_sizes(640, 640, 1, 480, 480, 1);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].width, 640);
}

TEST(V4l2Sizes, LargestSizeIsTheMostPixels) {
  EXPECT_FALSE(v4l2::largest_size({}));
  const auto top = v4l2::largest_size({{640, 480}, {2592, 1944}, {1920, 1080}, {320, 240}});
  ASSERT_TRUE(top);
  EXPECT_EQ(top->width, 2592);
  EXPECT_EQ(top->height, 1944);
}

TEST(V4l2Negotiation, StatusFollowsWhatTheDriverGranted) {
  const StreamConfig asked{PixelFormat::YUYV, 640, 480, 30};
  const auto yuyv = fcc('Y', 'U', 'Y', 'V');
  EXPECT_EQ(v4l2::negotiation_status(asked, yuyv, 640, 480, 30), ConfigStatus::Valid);
  EXPECT_EQ(v4l2::negotiation_status(asked, yuyv, 640, 480, 29.97), ConfigStatus::Valid);
  EXPECT_EQ(v4l2::negotiation_status(asked, yuyv, 640, 360, 30), ConfigStatus::Adjusted);
  EXPECT_EQ(v4l2::negotiation_status(asked, yuyv, 640, 480, 15), ConfigStatus::Adjusted);
  EXPECT_EQ(v4l2::negotiation_status(asked, yuyv, 640, 480, 0), ConfigStatus::Adjusted);  // rate unknown
  EXPECT_EQ(v4l2::negotiation_status(asked, fcc('M', 'J', 'P', 'G'), 640, 480, 30), ConfigStatus::Adjusted);
  EXPECT_EQ(v4l2::negotiation_status(asked, V4L2_PIX_FMT_H264, 640, 480, 30), ConfigStatus::Invalid);
  EXPECT_EQ(v4l2::negotiation_status(asked, yuyv, 0, 480, 30), ConfigStatus::Invalid);
  const StreamConfig any_rate{PixelFormat::YUYV, 640, 480, 0};
  EXPECT_EQ(v4l2::negotiation_status(any_rate, yuyv, 640, 480, 0), ConfigStatus::Valid);
}

TEST(V4l2Timestamps, MonotonicStampsAreUsedOthersReplacedByNow) {
  EXPECT_EQ(v4l2::buffer_timestamp_ns(V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, 12, 345678, 99), 12'345'678'000);
  EXPECT_EQ(v4l2::buffer_timestamp_ns(V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_MAPPED, 1, 0, 99),
            1'000'000'000);
  EXPECT_EQ(v4l2::buffer_timestamp_ns(V4L2_BUF_FLAG_TIMESTAMP_COPY, 12, 0, 99), 99);
  EXPECT_EQ(v4l2::buffer_timestamp_ns(V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN, 12, 0, 99), 99);
}

TEST(V4l2Controls, GainScalesFromTheDefaultClampsAndSnaps) {
  EXPECT_EQ(v4l2::gain_to_control(2.0, 0, 255, 1, 16), 32);
  EXPECT_EQ(v4l2::gain_to_control(100.0, 0, 255, 1, 16), 255);
  EXPECT_EQ(v4l2::gain_to_control(0.0, 8, 255, 1, 16), 8);
  EXPECT_EQ(v4l2::gain_to_control(3.0, 0, 100, 1, 0), 3);   // no default: 1 is unity
  EXPECT_EQ(v4l2::gain_to_control(2.2, 0, 100, 4, 10), 24);  // 22 snapped to the step of 4
  EXPECT_EQ(v4l2::gain_to_control(9.9, 0, 98, 4, 10), 96);   // the top step inside the range
}

TEST(V4l2Open, MissingDeviceNamesThePathAndReason) {
  const std::string message = thrown_message([] { V4l2Source source("/dev/propcam-no-such-video"); });
  EXPECT_NE(message.find("/dev/propcam-no-such-video"), std::string::npos) << message;
  EXPECT_NE(message.find("No such file"), std::string::npos) << message;
}

TEST(V4l2Open, DevNullIsNotAV4l2Device) {
  const std::string message = thrown_message([] { V4l2Source source("/dev/null"); });
  EXPECT_NE(message.find("/dev/null"), std::string::npos) << message;
  EXPECT_NE(message.find("not a V4L2 device"), std::string::npos) << message;
  EXPECT_NE(message.find("VIDIOC_QUERYCAP"), std::string::npos) << message;
}

TEST(V4l2List, ListingThisMachineReturns) {
  const auto cameras = list_v4l2_cameras();
  for (const auto& c : cameras) {
    EXPECT_EQ(c.backend, "v4l2");
    EXPECT_EQ(c.id.rfind("v4l2:/dev/video", 0), 0u) << c.id;
  }
}

// Needs a real capture node (a webcam, or vivid in a VM).
TEST(V4l2Device, StreamsFramesAndTakesAStill) {
  const auto cameras = list_v4l2_cameras();
  if (cameras.empty()) GTEST_SKIP() << "no V4L2 capture node (/dev/video*) on this machine";
  const std::string path = cameras.front().id.substr(5);
  V4l2Source source(path);
  const CameraInfo info = source.info();
  ASSERT_FALSE(info.formats.empty());
  std::cout << path << ": " << info.description << "\n";
  StreamConfig config{PixelFormat::YUYV, 640, 480, 30};
  const ConfigStatus status = source.configure(config);
  ASSERT_NE(status, ConfigStatus::Invalid);
  std::cout << "configured " << config.width << "x" << config.height << " @ " << config.fps
            << " fps (status " << static_cast<int>(status) << ")\n";
  source.start();
  EXPECT_TRUE(source.running());
  std::uint64_t last_sequence = 0;
  std::int64_t last_time = 0;
  for (int i = 0; i < 5; ++i) {
    const CaptureResult r = source.next_frame(2000ms);
    ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
    ASSERT_TRUE(r.frame);
    EXPECT_EQ(r.frame->format.width, config.width);
    EXPECT_GT(r.frame->bytes_used, 0u);
    if (config.pixel_format != PixelFormat::MJPEG) {
      EXPECT_GE(r.frame->bytes_used, std::size_t(r.frame->format.stride) * config.height);
    }
    if (i > 0) {
      EXPECT_GT(r.frame->metadata.sequence, last_sequence);
      EXPECT_GT(r.frame->metadata.timestamp_ns, last_time);
    }
    last_sequence = r.frame->metadata.sequence;
    last_time = r.frame->metadata.timestamp_ns;
  }
  const auto unsupported = source.set_controls(CameraControls{1000.0, 2.0, std::nullopt, std::nullopt, std::nullopt, true});
  for (const auto& name : unsupported) std::cout << "unsupported control: " << name << "\n";
  const CaptureResult still = source.capture_still(std::nullopt, 3000ms);
  ASSERT_EQ(still.status, CaptureStatus::Ok) << still.message;
  std::cout << "still " << still.frame->format.width << "x" << still.frame->format.height << "\n";
  EXPECT_GE(still.frame->format.width * still.frame->format.height, config.width * config.height);
  EXPECT_TRUE(source.running());  // the viewfinder was resumed
  EXPECT_EQ(source.configuration().width, config.width);
  EXPECT_EQ(source.next_frame(2000ms).status, CaptureStatus::Ok);
  source.stop();
  EXPECT_FALSE(source.running());
}

}  // namespace
}  // namespace propcam::capture
