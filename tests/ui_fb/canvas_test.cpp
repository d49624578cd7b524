#include "propcam/ui_fb/canvas.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace propcam::ui_fb {
namespace {

constexpr Rgb kBlack{0, 0, 0};
constexpr Rgb kRed{255, 0, 0};
constexpr Rgb kBackground{10, 20, 30};
constexpr Rgb kInk{250, 240, 100};

// Reference sRGB encoding straight from IEC 61966-2-1, in double precision.
int reference_srgb8(double linear) {
  if (std::isnan(linear)) return 0;
  const double c = std::clamp(linear, 0.0, 1.0);
  const double encoded = c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
  return static_cast<int>(std::lround(255.0 * encoded));
}

TEST(Canvas, FillRectIsClippedToTheCanvas) {
  Canvas canvas(10, 8);
  canvas.fill_rect({-3, -2, 6, 5}, kRed);       // covers x 0..2, y 0..2
  canvas.fill_rect({8, 6, 100, 100}, kRed);     // covers x 8..9, y 6..7
  canvas.fill_rect({20, 20, 5, 5}, kRed);       // entirely outside
  canvas.fill_rect({4, 4, -2, 3}, kRed);        // empty
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 10; ++x) {
      const bool inside = (x < 3 && y < 3) || (x >= 8 && y >= 6);
      EXPECT_EQ(canvas.pixel(x, y), inside ? kRed : kBlack) << "at " << x << "," << y;
    }
  }
}

TEST(Canvas, StrokeRectDrawsAnInsideBorder) {
  Canvas canvas(8, 8);
  canvas.stroke_rect({1, 1, 6, 5}, kRed, 1);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      const bool in_rect = x >= 1 && x < 7 && y >= 1 && y < 6;
      const bool on_border = in_rect && (x == 1 || x == 6 || y == 1 || y == 5);
      EXPECT_EQ(canvas.pixel(x, y), on_border ? kRed : kBlack) << "at " << x << "," << y;
    }
  }
}

TEST(Canvas, CopiesOwnTheirPixelsButWrappingShares) {
  cv::Mat image(4, 4, CV_8UC3, cv::Scalar::all(0));
  Canvas wrapped(image);
  wrapped.fill(kRed);
  EXPECT_EQ(image.at<cv::Vec3b>(2, 2), cv::Vec3b(255, 0, 0));  // R,G,B byte order
  Canvas copy = wrapped;
  copy.fill(kBlack);
  EXPECT_EQ(wrapped.pixel(0, 0), kRed);
  EXPECT_THROW(Canvas(cv::Mat(4, 4, CV_8UC1)), std::invalid_argument);
}

// Draws `text` on a plain background and checks that every changed pixel lies in the
// box measure_text promises, and that the text actually drew anti-aliased ink.
void expect_text_inside_measured_box(const std::string& text, int pixel_size, FontWeight weight) {
  Canvas canvas(400, 120);
  canvas.fill(kBackground);
  const int x = 20;
  const int baseline = 80;
  const TextExtent extent = Canvas::measure_text(text, pixel_size, weight);
  const int returned_width = canvas.draw_text(x, baseline, text, pixel_size, kInk, weight);
  EXPECT_EQ(returned_width, extent.width);
  EXPECT_EQ(Canvas::text_width(text, pixel_size, weight), extent.width);

  int inked = 0;
  int partial = 0;
  int leftmost = canvas.width();
  int rightmost = -1;
  for (int y = 0; y < canvas.height(); ++y) {
    for (int xx = 0; xx < canvas.width(); ++xx) {
      const Rgb p = canvas.pixel(xx, y);
      if (p == kBackground) continue;
      ++inked;
      if (p != kInk) ++partial;
      leftmost = std::min(leftmost, xx);
      rightmost = std::max(rightmost, xx);
      EXPECT_GE(xx, x) << text << ": ink left of the box at " << xx << "," << y;
      EXPECT_LT(xx, x + extent.width) << text << ": ink right of the box at " << xx << "," << y;
      EXPECT_GE(y, baseline - extent.ascent) << text << ": ink above the box";
      EXPECT_LT(y, baseline + extent.descent) << text << ": ink below the box";
    }
  }
  EXPECT_GT(inked, 50) << text;
  EXPECT_GT(partial, 10) << text << ": expected anti-aliased edges";
  // The box is tight: ink reaches within a few pixels of both ends.
  EXPECT_LE(leftmost - x, 3) << text;
  EXPECT_LE(x + extent.width - 1 - rightmost, 4) << text;
}

TEST(Canvas, DrawTextStaysInsideItsMeasuredBox) {
  expect_text_inside_measured_box("PropCam 12:34", 32, FontWeight::Regular);
  // 'j' overhangs to the left, 'f' and 'y' to the right and below, accents above.
  expect_text_inside_measured_box("jump fly \xC3\x85ngstr\xC3\xB6m", 28, FontWeight::Regular);
  expect_text_inside_measured_box("REC \xE2\x97\x8F", 40, FontWeight::Bold);
}

TEST(Canvas, TextWidthGrowsWithContent) {
  EXPECT_EQ(Canvas::text_width("", 20), 0);
  EXPECT_LT(Canvas::text_width("iii", 20), Canvas::text_width("WWW", 20));
  EXPECT_LT(Canvas::text_width("Hello", 12), Canvas::text_width("Hello", 24));
  EXPECT_LT(Canvas::text_width("Hello", 24), Canvas::text_width("Hello", 24, FontWeight::Bold));
  EXPECT_THROW(Canvas::text_width("x", 0), std::invalid_argument);
  // Malformed UTF-8 measures (as U+FFFD) instead of failing.
  EXPECT_GT(Canvas::text_width("bad \xFF\xC3 utf8", 20), Canvas::text_width("bad  utf8", 20));
}

TEST(Canvas, TextClipsAtTheCanvasEdge) {
  Canvas canvas(30, 20);
  canvas.draw_text(-10, 15, "Clipped text", 24, kRed);
  canvas.draw_text(10, 50, "below", 24, kRed);  // fully outside: no effect, no crash
  int inked = 0;
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 30; ++x) inked += canvas.pixel(x, y) != kBlack;
  EXPECT_GT(inked, 0);
}

TEST(Canvas, FindFontExplainsAMissingFont) {
  const std::filesystem::path empty_dir =
      std::filesystem::path(testing::TempDir()) / ("no_fonts_" + std::to_string(::getpid()));
  std::filesystem::create_directories(empty_dir);
  try {
    find_font(FontWeight::Bold, empty_dir);
    ADD_FAILURE() << "expected an exception";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("DejaVuSans-Bold.ttf"), std::string::npos) << message;
    EXPECT_NE(message.find("fonts-dejavu-core"), std::string::npos) << message;
  }
  std::filesystem::remove_all(empty_dir);
  EXPECT_EQ(find_font(FontWeight::Regular).filename(), "DejaVuSans.ttf");
}

TEST(Canvas, LinearToSrgbMatchesTheExactTransferFunction) {
  std::mt19937 random(1234);
  std::uniform_real_distribution<float> distribution(-0.1f, 1.1f);
  for (int i = 0; i < 20000; ++i) {
    const float value = distribution(random);
    ASSERT_EQ(linear_to_srgb8(value), reference_srgb8(value)) << "linear " << value;
  }
  EXPECT_EQ(linear_to_srgb8(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(linear_to_srgb8(std::numeric_limits<float>::infinity()), 255);
}

TEST(Canvas, BlitOfLinearFloatImageGivesSrgbValues) {
  // One row of linear values, R,G,B per pixel, covering both transfer-function
  // segments, clamping and NaN.
  const float values[][3] = {{0.0f, 1.0f, 0.5f},
                             {0.18f, 0.002f, 0.0031308f},
                             {0.01f, 0.214f, 0.9f},
                             {-1.0f, 2.0f, std::numeric_limits<float>::quiet_NaN()}};
  cv::Mat image(1, 4, CV_32FC3);
  for (int x = 0; x < 4; ++x) image.at<cv::Vec3f>(0, x) = {values[x][0], values[x][1], values[x][2]};

  Canvas canvas(6, 3);
  const Rect covered = canvas.blit_scaled(image, {1, 1, 4, 1}, false);
  EXPECT_EQ(covered, (Rect{1, 1, 4, 1}));
  for (int x = 0; x < 4; ++x) {
    const Rgb p = canvas.pixel(1 + x, 1);
    EXPECT_EQ(p.r, reference_srgb8(values[x][0])) << "pixel " << x;
    EXPECT_EQ(p.g, reference_srgb8(values[x][1])) << "pixel " << x;
    EXPECT_EQ(p.b, reference_srgb8(values[x][2])) << "pixel " << x;
  }
  // Spot values from the sRGB standard: 0.5 linear is 188, 0.18 is 118, 0.002 is 7.
  EXPECT_EQ(canvas.pixel(1, 1), (Rgb{0, 255, 188}));
  EXPECT_EQ(canvas.pixel(2, 1).r, 118);
  EXPECT_EQ(canvas.pixel(2, 1).g, 7);
  EXPECT_EQ(canvas.pixel(4, 1), (Rgb{0, 255, 0}));
  EXPECT_EQ(canvas.pixel(0, 1), kBlack);  // outside the destination
}

TEST(Canvas, AreaShrinkOfFloatImageAveragesInLinearLight) {
  // A 0/1 checkerboard shrunk 2x averages to linear 0.5, i.e. sRGB 188, not 128.
  cv::Mat checker(4, 4, CV_32FC3);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) checker.at<cv::Vec3f>(y, x) = cv::Vec3f::all((x + y) % 2 ? 1.f : 0.f);
  Canvas canvas(2, 2);
  canvas.blit_scaled(checker, canvas.bounds(), false, ScaleFilter::Area);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 2; ++x) EXPECT_EQ(canvas.pixel(x, y), (Rgb{188, 188, 188}));
}

TEST(Canvas, BlitKeepsAspectAndClips) {
  cv::Mat wide(2, 4, CV_8UC3, cv::Scalar(255, 0, 0));  // red in R,G,B order
  Canvas canvas(10, 10);
  // 4x2 into 10x10: scaled to 10x5, centred vertically at rows 2..6.
  EXPECT_EQ(canvas.blit_scaled(wide, {0, 0, 10, 10}, true), (Rect{0, 2, 10, 5}));
  for (int y = 0; y < 10; ++y) {
    EXPECT_EQ(canvas.pixel(5, y), (y >= 2 && y < 7) ? kRed : kBlack) << "row " << y;
  }
  // Stretching into a destination hanging off the bottom-right corner clips.
  Canvas clipped(10, 10);
  EXPECT_EQ(clipped.blit_scaled(wide, {6, 6, 8, 8}, false, ScaleFilter::Area), (Rect{6, 6, 8, 8}));
  EXPECT_EQ(clipped.pixel(9, 9), kRed);
  EXPECT_EQ(clipped.pixel(5, 9), kBlack);

  EXPECT_THROW(canvas.blit_scaled(cv::Mat(2, 2, CV_16UC3), {0, 0, 2, 2}, false),
               std::invalid_argument);
}

}  // namespace
}  // namespace propcam::ui_fb
