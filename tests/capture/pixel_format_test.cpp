#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "propcam/capture/frame_source.h"
#include "propcam/capture/image_file.h"
#include "propcam/capture/pixel_format.h"

namespace propcam::capture {
namespace {

using Rgb = std::array<int, 3>;
using Yuv = std::array<int, 3>;

FrameFormat format_of(PixelFormat pf, int w, int h, YcbcrEncoding e = YcbcrEncoding::Bt601,
                      QuantisationRange r = QuantisationRange::Limited, int stride = 0) {
  FrameFormat f;
  f.pixel_format = pf;
  f.width = w;
  f.height = h;
  f.stride = stride;
  f.encoding = e;
  f.range = r;
  return f;
}

// A YUYV frame, one pixel pair per sample, both pixels of a pair the same colour.
Frame yuyv_pairs(const std::vector<Yuv>& samples, YcbcrEncoding e, QuantisationRange r) {
  std::vector<std::uint8_t> bytes;
  for (const Yuv& s : samples)
    for (int v : {s[0], s[1], s[0], s[2]}) bytes.push_back(static_cast<std::uint8_t>(v));
  return frame_from_bytes(format_of(PixelFormat::YUYV, 2 * static_cast<int>(samples.size()), 1, e, r), bytes);
}

Rgb pixel(const cv::Mat& rgb, int x, int y = 0) {
  const cv::Vec3b p = rgb.at<cv::Vec3b>(y, x);
  return {p[0], p[1], p[2]};
}

// The 75% colour bars (white, yellow, cyan, green, magenta, red, blue, black)
// as ITU-R BT.601 and BT.709 limited-range Y'CbCr.
const std::vector<Yuv> kBars601 = {{180, 128, 128}, {162, 44, 142}, {131, 156, 44}, {112, 72, 58},
                                   {84, 184, 198},  {65, 100, 212}, {35, 212, 114}, {16, 128, 128}};
const std::vector<Yuv> kBars709 = {{180, 128, 128}, {168, 44, 136}, {145, 147, 44}, {134, 63, 52},
                                   {63, 193, 204},  {51, 109, 212}, {28, 212, 120}, {16, 128, 128}};
// The same bars in 8-bit RGB (0.75 * 255 = 191).
const std::vector<Rgb> kBarsRgb = {{191, 191, 191}, {191, 191, 0}, {0, 191, 191}, {0, 191, 0},
                                   {191, 0, 191},   {191, 0, 0},   {0, 0, 191},   {0, 0, 0}};

void expect_pairs(const cv::Mat& rgb, const std::vector<Rgb>& expected) {
  ASSERT_EQ(rgb.cols, 2 * static_cast<int>(expected.size()));
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(pixel(rgb, 2 * static_cast<int>(i)), expected[i]) << "sample " << i;
    EXPECT_EQ(pixel(rgb, 2 * static_cast<int>(i) + 1), expected[i]) << "sample " << i;
  }
}

// Reference: the textbook formula in exact rational arithmetic (the
// coefficients are decimals: Kr = 0.299 = 2990/10000, ...), rounded half up
// and clamped. `tie_distance` says how far each channel is from a rounding
// tie (|fraction - 0.5|), where any finite-precision code may go either way.
struct Exact {
  Rgb rgb;
  std::array<double, 3> tie_distance;
};

Exact exact_rgb(Yuv s, YcbcrEncoding e, QuantisationRange r) {
  using I = __int128;
  const I KR = e == YcbcrEncoding::Bt709 ? 2126 : 2990, KB = e == YcbcrEncoding::Bt709 ? 722 : 1140;
  const I KG = 10000 - KR - KB;
  const bool full = r == QuantisationRange::Full;
  const I yo = full ? 0 : 16, ys = full ? 255 : 219, cs = full ? 255 : 224;
  const I y = 255 * (s[0] - yo), u = 255 * (s[1] - 128), v = 255 * (s[2] - 128);
  const I den = ys * cs * 10000 * KG;
  const I luma = y * cs * 10000 * KG;
  const I num[3] = {luma + 2 * (10000 - KR) * v * ys * KG,
                    luma - 2 * KB * (10000 - KB) * u * ys - 2 * KR * (10000 - KR) * v * ys,
                    luma + 2 * (10000 - KB) * u * ys * KG};
  Exact out{};
  for (int c = 0; c < 3; ++c) {
    const I twice = 2 * num[c] + den, two_den = 2 * den;  // floor(num/den + 1/2)
    I q = twice / two_den;
    if (twice % two_den != 0 && twice < 0) --q;
    I rem = num[c] % den;
    if (rem < 0) rem += den;
    out.rgb[c] = static_cast<int>(std::clamp<I>(q, 0, 255));
    out.tie_distance[c] = std::abs(static_cast<double>(rem) / static_cast<double>(den) - 0.5);
  }
  return out;
}

Rgb reference_rgb(Yuv s, YcbcrEncoding e, QuantisationRange r) { return exact_rgb(s, e, r).rgb; }

double psnr(const cv::Mat& a, const cv::Mat& b) { return cv::PSNR(a, b); }

// A smooth colourful test image: gradients in each channel.
cv::Mat gradient(int w, int h) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>(255 * x / (w - 1)),
                                          static_cast<std::uint8_t>(255 * y / (h - 1)),
                                          static_cast<std::uint8_t>(255 - 255 * (x + y) / (w + h - 2)));
  return img;
}

// Each 2x2 block one colour, so chroma subsampling loses nothing.
cv::Mat blocky(int w, int h) {
  cv::Mat img(h, w, CV_8UC3);
  cv::RNG rng(7);
  for (int y = 0; y < h; y += 2)
    for (int x = 0; x < w; x += 2) {
      const cv::Vec3b c(rng.uniform(0, 256), rng.uniform(0, 256), rng.uniform(0, 256));
      img(cv::Rect(x, y, 2, 2)).setTo(cv::Scalar(c[0], c[1], c[2]));
    }
  return img;
}

int max_abs_diff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  double m = 0;
  cv::minMaxLoc(diff.reshape(1), nullptr, &m);
  return static_cast<int>(m);
}

// ---------------------------------------------------------------------------

TEST(PixelFormat, NamesAndFourccsRoundTrip) {
  for (PixelFormat f : {PixelFormat::RGB24, PixelFormat::BGR24, PixelFormat::YUYV, PixelFormat::UYVY,
                        PixelFormat::NV12, PixelFormat::MJPEG, PixelFormat::GREY}) {
    EXPECT_EQ(pixel_format_from_string(to_string(f)), f);
    EXPECT_EQ(pixel_format_from_fourcc(fourcc(f)), f);
  }
  EXPECT_EQ(to_string(PixelFormat::YUYV), "YUYV");
  EXPECT_EQ(fourcc(PixelFormat::YUYV), v4l2_fourcc('Y', 'U', 'Y', 'V'));
  EXPECT_EQ(fourcc(PixelFormat::MJPEG), v4l2_fourcc('M', 'J', 'P', 'G'));
  EXPECT_EQ(fourcc(PixelFormat::NV12), v4l2_fourcc('N', 'V', '1', '2'));
  EXPECT_EQ(fourcc(PixelFormat::RGB24), v4l2_fourcc('R', 'G', 'B', '3'));
  EXPECT_EQ(fourcc(PixelFormat::GREY), v4l2_fourcc('G', 'R', 'E', 'Y'));
  EXPECT_EQ(pixel_format_from_fourcc(V4L2_PIX_FMT_JPEG), PixelFormat::MJPEG);
  EXPECT_EQ(pixel_format_from_string("mjpg"), PixelFormat::MJPEG);
  EXPECT_EQ(pixel_format_from_string("nv12"), PixelFormat::NV12);
  EXPECT_FALSE(pixel_format_from_string("H264"));
  EXPECT_FALSE(pixel_format_from_fourcc(v4l2_fourcc('H', '2', '6', '4')));
  EXPECT_EQ(to_string(CaptureStatus::EndOfStream), "EndOfStream");
  EXPECT_EQ(to_string(CaptureStatus::Ok), "Ok");
}

TEST(PixelFormat, StridesAndFrameSizes) {
  EXPECT_EQ(minimum_stride(PixelFormat::RGB24, 640), 1920);
  EXPECT_EQ(minimum_stride(PixelFormat::YUYV, 640), 1280);
  EXPECT_EQ(minimum_stride(PixelFormat::NV12, 640), 640);
  EXPECT_EQ(minimum_stride(PixelFormat::GREY, 641), 641);
  EXPECT_EQ(minimum_stride(PixelFormat::MJPEG, 640), 0);
  EXPECT_EQ(frame_bytes(format_of(PixelFormat::YUYV, 640, 480)), 640u * 480 * 2);
  EXPECT_EQ(frame_bytes(format_of(PixelFormat::YUYV, 640, 480, YcbcrEncoding::Bt601, QuantisationRange::Limited, 1344)),
            1344u * 480);
  EXPECT_EQ(frame_bytes(format_of(PixelFormat::NV12, 640, 480)), 640u * 480 * 3 / 2);
  EXPECT_EQ(frame_bytes(format_of(PixelFormat::BGR24, 3, 2)), 18u);
  EXPECT_GE(frame_bytes(format_of(PixelFormat::MJPEG, 640, 480)), 640u * 480 * 3);
}

TEST(PixelFormat, BadFormatsAreRefusedClearly) {
  const auto message = [](const FrameFormat& f) {
    try {
      validate_frame_format(f);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(format_of(PixelFormat::RGB24, 0, 480)).find("width 0 outside"), std::string::npos);
  EXPECT_NE(message(format_of(PixelFormat::RGB24, 640, -4)).find("height -4 outside"), std::string::npos);
  EXPECT_NE(message(format_of(PixelFormat::GREY, 16385, 2)).find("width 16385"), std::string::npos);
  EXPECT_NE(message(format_of(PixelFormat::YUYV, 641, 480)).find("width must be even"), std::string::npos);
  EXPECT_NE(message(format_of(PixelFormat::NV12, 640, 481)).find("height must be even"), std::string::npos);
  EXPECT_NE(message(format_of(PixelFormat::YUYV, 640, 480, YcbcrEncoding::Bt601, QuantisationRange::Limited, 1000))
                .find("stride 1000"),
            std::string::npos);
  EXPECT_EQ(message(format_of(PixelFormat::GREY, 641, 481)), "accepted");
  EXPECT_EQ(message(format_of(PixelFormat::UYVY, 2, 1)), "accepted");
  EXPECT_EQ(message(format_of(PixelFormat::MJPEG, 641, 481)), "accepted");
  EXPECT_THROW(frame_bytes(format_of(PixelFormat::RGB24, 16384, 16385)), std::runtime_error);
}

TEST(PixelFormat, ColourBarsBt601Limited) {
  const cv::Mat rgb = frame_to_rgb8(yuyv_pairs(kBars601, YcbcrEncoding::Bt601, QuantisationRange::Limited));
  // Exact values (computed with rational arithmetic): the bars' Y'CbCr is
  // itself rounded, so a few channels land one step off 191 / 0.
  expect_pairs(rgb, {{191, 191, 191}, {192, 192, 1}, {0, 191, 190}, {0, 191, 0},
                     {191, 0, 192}, {191, 0, 1}, {0, 1, 192}, {0, 0, 0}});
}

TEST(PixelFormat, ColourBarsBt709Limited) {
  const cv::Mat rgb = frame_to_rgb8(yuyv_pairs(kBars709, YcbcrEncoding::Bt709, QuantisationRange::Limited));
  expect_pairs(rgb, {{191, 191, 191}, {191, 191, 0}, {0, 191, 190}, {1, 192, 0},
                     {191, 0, 192}, {191, 0, 1}, {0, 0, 191}, {0, 0, 0}});
}

TEST(PixelFormat, EncodingAndRangeChangeTheColours) {
  // BT.601 bars read as BT.709 come out visibly wrong: the encoding is honoured.
  const cv::Mat as709 = frame_to_rgb8(yuyv_pairs(kBars601, YcbcrEncoding::Bt709, QuantisationRange::Limited));
  expect_pairs(as709, {{191, 191, 191}, {195, 180, 0}, {0, 173, 193}, {0, 161, 0},
                       {205, 30, 197}, {208, 18, 0}, {0, 12, 200}, {0, 0, 0}});
  // Limited-range bars read as full range: black is 16, white 180, colours washed out.
  const cv::Mat full = frame_to_rgb8(yuyv_pairs(kBars601, YcbcrEncoding::Bt601, QuantisationRange::Full));
  expect_pairs(full, {{180, 180, 180}, {182, 181, 13}, {13, 181, 181}, {14, 181, 13},
                      {182, 15, 183}, {183, 15, 15}, {15, 16, 184}, {16, 16, 16}});
}

TEST(PixelFormat, BlackWhiteAndClamping) {
  using E = YcbcrEncoding;
  using R = QuantisationRange;
  // Limited: 16 is black, 235 white; footroom and headroom clamp.
  expect_pairs(frame_to_rgb8(yuyv_pairs({{16, 128, 128}, {235, 128, 128}, {0, 128, 128}, {255, 128, 128}}, E::Bt601,
                                        R::Limited)),
               {{0, 0, 0}, {255, 255, 255}, {0, 0, 0}, {255, 255, 255}});
  // Full: 0 and 255; mid grey stays.
  expect_pairs(frame_to_rgb8(yuyv_pairs({{0, 128, 128}, {255, 128, 128}, {128, 128, 128}}, E::Bt709, R::Full)),
               {{0, 0, 0}, {255, 255, 255}, {128, 128, 128}});
  // Extreme chroma saturates instead of wrapping.
  expect_pairs(frame_to_rgb8(yuyv_pairs({{235, 255, 255}, {16, 0, 0}}, E::Bt601, R::Limited)),
               {reference_rgb({235, 255, 255}, E::Bt601, R::Limited), reference_rgb({16, 0, 0}, E::Bt601, R::Limited)});
  EXPECT_EQ(reference_rgb({235, 255, 255}, E::Bt601, R::Limited), (Rgb{255, 102, 255}));
  EXPECT_EQ(reference_rgb({16, 0, 0}, E::Bt601, R::Limited), (Rgb{0, 154, 0}));
}

TEST(PixelFormat, MatchesTheTextbookFormulaEverywhere) {
  // Every (Y, Cb, Cr) on a grid of step 3 for each encoding and range: the
  // integer loop equals the exactly rounded value, except at (or within 1e-5
  // of) a rounding tie, where one step either way is as right.
  for (YcbcrEncoding e : {YcbcrEncoding::Bt601, YcbcrEncoding::Bt709})
    for (QuantisationRange r : {QuantisationRange::Limited, QuantisationRange::Full}) {
      int ties = 0, channels = 0;
      for (int y = 0; y < 256; y += 3) {  // one frame per luma value
        std::vector<Yuv> samples;
        for (int u = 0; u < 256; u += 3)
          for (int v = 0; v < 256; v += 3) samples.push_back({y, u, v});
        const cv::Mat rgb = frame_to_rgb8(yuyv_pairs(samples, e, r));
        for (std::size_t i = 0; i < samples.size(); ++i) {
          const Rgb got = pixel(rgb, 2 * static_cast<int>(i));
          const Exact want = exact_rgb(samples[i], e, r);
          for (int c = 0; c < 3; ++c, ++channels) {
            const bool tie = want.tie_distance[c] < 1e-5;
            ties += tie;
            ASSERT_LE(std::abs(got[c] - want.rgb[c]), tie ? 1 : 0)
                << "Y'CbCr " << y << "," << samples[i][1] << "," << samples[i][2] << " channel " << c;
          }
        }
      }
      EXPECT_LT(ties, channels / 100);  // ties are rare (whole Cr columns in full range): exact elsewhere
    }
}

TEST(PixelFormat, UyvyAndNv12LayoutsGiveTheSameColours) {
  // A 4x2 image: distinct luma per pixel, one chroma sample per pair (and per
  // pair of rows for NV12), laid out three ways.
  const std::uint8_t y[2][4] = {{16, 60, 120, 235}, {30, 90, 150, 200}};
  const std::uint8_t u[2] = {44, 212}, v[2] = {142, 114};
  const std::vector<std::uint8_t> yuyv = {16, 44, 60, 142, 120, 212, 235, 114, 30, 44, 90, 142, 150, 212, 200, 114};
  const std::vector<std::uint8_t> uyvy = {44, 16, 142, 60, 212, 120, 114, 235, 44, 30, 142, 90, 212, 150, 114, 200};
  const std::vector<std::uint8_t> nv12 = {16, 60, 120, 235, 30, 90, 150, 200, 44, 142, 212, 114};
  const cv::Mat a = frame_to_rgb8(frame_from_bytes(format_of(PixelFormat::YUYV, 4, 2), yuyv));
  const cv::Mat b = frame_to_rgb8(frame_from_bytes(format_of(PixelFormat::UYVY, 4, 2), uyvy));
  const cv::Mat c = frame_to_rgb8(frame_from_bytes(format_of(PixelFormat::NV12, 4, 2), nv12));
  for (int row = 0; row < 2; ++row)
    for (int x = 0; x < 4; ++x) {
      const Rgb want = reference_rgb({y[row][x], u[x / 2], v[x / 2]}, YcbcrEncoding::Bt601, QuantisationRange::Limited);
      EXPECT_EQ(pixel(a, x, row), want) << x << "," << row;
      EXPECT_EQ(pixel(b, x, row), want) << x << "," << row;
      EXPECT_EQ(pixel(c, x, row), want) << x << "," << row;
    }
}

TEST(PixelFormat, RgbBgrAndGreyBytes) {
  const cv::Mat rgb24 = frame_to_rgb8(frame_from_bytes(format_of(PixelFormat::RGB24, 2, 1), {10, 20, 30, 40, 50, 60}));
  EXPECT_EQ(pixel(rgb24, 0), (Rgb{10, 20, 30}));
  EXPECT_EQ(pixel(rgb24, 1), (Rgb{40, 50, 60}));
  const cv::Mat bgr24 = frame_to_rgb8(frame_from_bytes(format_of(PixelFormat::BGR24, 2, 1), {10, 20, 30, 40, 50, 60}));
  EXPECT_EQ(pixel(bgr24, 0), (Rgb{30, 20, 10}));
  EXPECT_EQ(pixel(bgr24, 1), (Rgb{60, 50, 40}));
  const cv::Mat grey_full = frame_to_rgb8(frame_from_bytes(
      format_of(PixelFormat::GREY, 3, 1, YcbcrEncoding::Bt601, QuantisationRange::Full), {0, 77, 255}));
  EXPECT_EQ(pixel(grey_full, 1), (Rgb{77, 77, 77}));
  const cv::Mat grey_limited = frame_to_rgb8(frame_from_bytes(format_of(PixelFormat::GREY, 3, 1), {16, 126, 235}));
  EXPECT_EQ(pixel(grey_limited, 0), (Rgb{0, 0, 0}));
  EXPECT_EQ(pixel(grey_limited, 1), (Rgb{128, 128, 128}));  // (126 - 16) * 255 / 219 = 128.08
  EXPECT_EQ(pixel(grey_limited, 2), (Rgb{255, 255, 255}));
}

TEST(PixelFormat, PaddedStridesAreHonoured) {
  const cv::Mat img = gradient(64, 32);
  for (PixelFormat pf : {PixelFormat::RGB24, PixelFormat::BGR24, PixelFormat::YUYV, PixelFormat::UYVY,
                         PixelFormat::NV12, PixelFormat::GREY}) {
    const FrameFormat packed = format_of(pf, 64, 32);
    FrameFormat padded = packed;
    padded.stride = minimum_stride(pf, 64) + 40;
    const Frame a = rgb8_to_frame(img, packed);
    Frame b = rgb8_to_frame(img, padded);
    EXPECT_EQ(b.format.stride, padded.stride);
    EXPECT_EQ(b.bytes_used, frame_bytes(padded));
    // Garbage in the padding must not leak into the picture.
    std::vector<std::uint8_t> bytes(b.data().begin(), b.data().end());
    const int rows = pf == PixelFormat::NV12 ? 48 : 32;
    for (int r = 0; r < rows; ++r)
      for (int x = minimum_stride(pf, 64); x < padded.stride; ++x) bytes[r * padded.stride + x] = 0xA5;
    b = frame_from_bytes(padded, bytes);
    EXPECT_EQ(max_abs_diff(frame_to_rgb8(a), frame_to_rgb8(b)), 0) << to_string(pf);
  }
}

TEST(PixelFormat, RgbToFrameProducesTheStandardBars) {
  cv::Mat bars(1, 16, CV_8UC3);
  for (int i = 0; i < 16; ++i) {
    const Rgb& c = kBarsRgb[i / 2];
    bars.at<cv::Vec3b>(0, i) = cv::Vec3b(c[0], c[1], c[2]);
  }
  const Frame f = rgb8_to_frame(bars, format_of(PixelFormat::YUYV, 16, 1));
  // From 191/255 rather than 0.75 yellow's luma is 161.3, not the table's 162.
  const std::vector<Yuv> want = {{180, 128, 128}, {161, 44, 142}, {131, 156, 44}, {112, 72, 58},
                                 {84, 184, 198},  {65, 100, 212}, {35, 212, 114}, {16, 128, 128}};
  const auto b = f.data();
  ASSERT_EQ(b.size(), 32u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ((Yuv{b[4 * i], b[4 * i + 1], b[4 * i + 3]}), want[i]) << "bar " << i;
    EXPECT_EQ(b[4 * i + 2], b[4 * i]);
  }
  // BT.709 full range: white is 191, not 180; yellow's chroma moves.
  const Frame g = rgb8_to_frame(bars, format_of(PixelFormat::UYVY, 16, 1, YcbcrEncoding::Bt709, QuantisationRange::Full));
  const auto c = g.data();
  EXPECT_EQ((Yuv{c[1], c[0], c[2]}), (Yuv{191, 128, 128}));
  EXPECT_EQ((Yuv{c[5], c[4], c[6]}), (Yuv{177, 33, 137}));
}

TEST(PixelFormat, SubsampledChromaIsTheAverageOfItsPixels) {
  // A red and a blue pixel share one chroma sample: its Cb/Cr is the mean of
  // theirs (165, 175), not either one's (90, 240) / (240, 110).
  cv::Mat pair(2, 2, CV_8UC3);
  pair.at<cv::Vec3b>(0, 0) = pair.at<cv::Vec3b>(1, 0) = cv::Vec3b(255, 0, 0);
  pair.at<cv::Vec3b>(0, 1) = pair.at<cv::Vec3b>(1, 1) = cv::Vec3b(0, 0, 255);
  const Frame yuyv_frame = rgb8_to_frame(pair, format_of(PixelFormat::YUYV, 2, 2));
  const auto yuyv = yuyv_frame.data();
  EXPECT_EQ((std::vector<int>(yuyv.begin(), yuyv.begin() + 4)), (std::vector<int>{81, 165, 41, 175}));
  const Frame nv12_frame = rgb8_to_frame(pair, format_of(PixelFormat::NV12, 2, 2));
  const auto nv12 = nv12_frame.data();
  EXPECT_EQ((std::vector<int>(nv12.begin(), nv12.end())), (std::vector<int>{81, 41, 81, 41, 165, 175}));
}

TEST(PixelFormat, RoundTripsWithinStatedTolerances) {
  // Exact for RGB/BGR. For YUV on 2x2-constant blocks only the 8-bit Y'CbCr
  // quantisation is lost: at most 2 steps in limited range (219/224 levels),
  // 1 in full range.
  const cv::Mat img = blocky(64, 48);
  for (PixelFormat pf : {PixelFormat::RGB24, PixelFormat::BGR24})
    EXPECT_EQ(max_abs_diff(frame_to_rgb8(rgb8_to_frame(img, format_of(pf, 64, 48))), img), 0);
  for (PixelFormat pf : {PixelFormat::YUYV, PixelFormat::UYVY, PixelFormat::NV12})
    for (YcbcrEncoding e : {YcbcrEncoding::Bt601, YcbcrEncoding::Bt709}) {
      const cv::Mat limited =
          frame_to_rgb8(rgb8_to_frame(img, format_of(pf, 64, 48, e, QuantisationRange::Limited)));
      const cv::Mat full = frame_to_rgb8(rgb8_to_frame(img, format_of(pf, 64, 48, e, QuantisationRange::Full)));
      EXPECT_LE(max_abs_diff(limited, img), 2) << to_string(pf);
      EXPECT_LE(max_abs_diff(full, img), 1) << to_string(pf);
    }
  // Grey images through GREY: exact full range, within 1 limited.
  cv::Mat grey(16, 16, CV_8UC3);
  for (int i = 0; i < 256; ++i) grey.at<cv::Vec3b>(i / 16, i % 16) = cv::Vec3b(i, i, i);
  EXPECT_EQ(max_abs_diff(frame_to_rgb8(rgb8_to_frame(grey, format_of(PixelFormat::GREY, 16, 16, YcbcrEncoding::Bt709,
                                                                     QuantisationRange::Full))),
                         grey),
            0);
  EXPECT_LE(max_abs_diff(frame_to_rgb8(rgb8_to_frame(grey, format_of(PixelFormat::GREY, 16, 16))), grey), 1);
  // A smooth gradient through 4:2:0 keeps well above 40 dB.
  const cv::Mat smooth = gradient(160, 120);
  EXPECT_GT(psnr(frame_to_rgb8(rgb8_to_frame(smooth, format_of(PixelFormat::NV12, 160, 120))), smooth), 40);
}

TEST(PixelFormat, MjpegRoundTripsWithinPsnr) {
  const cv::Mat img = gradient(320, 240);
  const Frame f = rgb8_to_frame(img, format_of(PixelFormat::MJPEG, 320, 240), 92);
  EXPECT_EQ(f.format.stride, 0);
  ASSERT_GT(f.bytes_used, 100u);
  EXPECT_LT(f.bytes_used, 320u * 240 * 3 / 4);  // it did compress
  EXPECT_EQ(f.data()[0], 0xFF);
  EXPECT_EQ(f.data()[1], 0xD8);  // SOI
  const cv::Mat back = frame_to_rgb8(f);
  ASSERT_EQ(back.size(), img.size());
  EXPECT_GT(psnr(back, img), 38);
  // Odd sizes are fine for MJPEG.
  const cv::Mat odd = gradient(33, 17);
  EXPECT_GT(psnr(frame_to_rgb8(rgb8_to_frame(odd, format_of(PixelFormat::MJPEG, 33, 17))), odd), 30);
}

TEST(PixelFormat, CorruptMjpegGivesClearErrors) {
  const Frame good = rgb8_to_frame(gradient(64, 48), format_of(PixelFormat::MJPEG, 64, 48));
  const std::vector<std::uint8_t> bytes(good.data().begin(), good.data().end());
  const auto error_of = [](const Frame& f) {
    try {
      frame_to_rgb8(f);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("decoded");
  };
  // Truncated halfway: libjpeg would pad with grey; we refuse.
  const std::string truncated =
      error_of(frame_from_bytes(good.format, std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + bytes.size() / 2)));
  EXPECT_NE(truncated.find("cannot decode the JPEG"), std::string::npos) << truncated;
  EXPECT_NE(truncated.find("MJPEG 64x48"), std::string::npos) << truncated;
  const std::string garbage = error_of(frame_from_bytes(good.format, std::vector<std::uint8_t>(1000, 0x42)));
  EXPECT_NE(garbage.find("Not a JPEG file"), std::string::npos) << garbage;
  const std::string wrong_size = error_of(frame_from_bytes(format_of(PixelFormat::MJPEG, 640, 480), bytes));
  EXPECT_NE(wrong_size.find("the JPEG is 64x48, the frame format says 640x480"), std::string::npos) << wrong_size;
  EXPECT_NE(error_of(frame_from_bytes(good.format, {})).find("empty JPEG"), std::string::npos);
}

TEST(PixelFormat, ShortOrMissingBuffersAreErrors) {
  const FrameFormat f = format_of(PixelFormat::YUYV, 640, 480);
  EXPECT_THROW(frame_to_rgb8(frame_from_bytes(f, std::vector<std::uint8_t>(640 * 480 * 2 - 1))), std::runtime_error);
  try {
    frame_to_rgb8(frame_from_bytes(f, std::vector<std::uint8_t>(1000)));
    FAIL() << "a short buffer was converted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("needs 614400 bytes, has 1000"), std::string::npos) << e.what();
  }
  Frame lying = frame_from_bytes(f, std::vector<std::uint8_t>(640 * 480 * 2));
  lying.bytes_used = 640 * 480 * 2 + 1;
  EXPECT_THROW(frame_to_rgb8(lying), std::runtime_error);
  Frame empty;
  empty.format = f;
  EXPECT_THROW(frame_to_rgb8(empty), std::runtime_error);
  // A longer buffer (a driver's whole sizeimage) is fine.
  EXPECT_NO_THROW(frame_to_rgb8(frame_from_bytes(f, std::vector<std::uint8_t>(640 * 480 * 2 + 4096, 128))));
}

TEST(PixelFormat, RgbToFrameChecksItsInput) {
  EXPECT_THROW(rgb8_to_frame(cv::Mat(4, 4, CV_8UC1), format_of(PixelFormat::GREY, 4, 4)), std::runtime_error);
  EXPECT_THROW(rgb8_to_frame(gradient(4, 4), format_of(PixelFormat::RGB24, 8, 4)), std::runtime_error);
  EXPECT_THROW(rgb8_to_frame(gradient(5, 4), format_of(PixelFormat::YUYV, 5, 4)), std::runtime_error);
  EXPECT_THROW(rgb8_to_frame(gradient(4, 4), format_of(PixelFormat::MJPEG, 4, 4), 0), std::runtime_error);
}

TEST(PixelFormat, LinearIsTheSrgbCurveUndone) {
  const cv::Mat lin = frame_to_linear(frame_from_bytes(format_of(PixelFormat::RGB24, 2, 1), {255, 128, 0, 10, 10, 10}));
  ASSERT_EQ(lin.type(), CV_32FC3);
  const cv::Vec3f a = lin.at<cv::Vec3f>(0, 0), b = lin.at<cv::Vec3f>(0, 1);
  EXPECT_FLOAT_EQ(a[0], 1.f);
  EXPECT_NEAR(a[1], 0.2158605, 1e-6);  // sRGB 128
  EXPECT_FLOAT_EQ(a[2], 0.f);
  EXPECT_NEAR(b[0], srgb_to_linear(10 / 255.f), 1e-7);
}

}  // namespace
}  // namespace propcam::capture
