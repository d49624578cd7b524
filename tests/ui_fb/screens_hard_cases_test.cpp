// Hostile view contents: draw_screen must draw something sensible, never throw,
// and paint only its canvas, whatever the firmware hands it.
#include "propcam/ui_fb/screens.h"

#include <climits>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "screen_test_helpers.h"

namespace propcam::ui_fb {
namespace {

using namespace testing_helpers;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr Rgb kPhoto{90, 140, 60};
constexpr Rgb kGuardValue{7, 77, 177};
constexpr int kGuard = 16;  // sentinel pixels around the canvas

constexpr ScreenKind kAllKinds[] = {
    ScreenKind::Viewfinder, ScreenKind::Captured,  ScreenKind::Analysing, ScreenKind::Carousel,
    ScreenKind::Placement,  ScreenKind::TierPick,  ScreenKind::Rendering, ScreenKind::Adjusting,
    ScreenKind::Exporting,  ScreenKind::Fault};

// Long strings of the kinds that break naive text code.
std::vector<std::string> hostile_strings() {
  std::string words;
  while (words.size() < 10'000) words += "reconnecting ";
  std::string combining;
  while (combining.size() < 10'000) combining += "e\xCC\x81";  // e + U+0301
  std::string invalid;
  while (invalid.size() < 10'000) invalid += "\xFF\xC3(\xE2\x82\xF0\x9F\x98";
  std::string controls;
  while (controls.size() < 10'000) controls += "line\n\r\t\x1B[2J\x7F";
  std::string cjk_emoji;
  while (cjk_emoji.size() < 10'000) cjk_emoji += "相机😀";
  return {std::string(10'000, 'W'), words, combining, invalid, controls, cjk_emoji,
          std::string(10'000, ' ')};
}

cv::Mat nan_float_image(int width, int height) {
  cv::Mat image(height, width, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const int k = (x + y) % 4;
      if (k == 0) image.at<cv::Vec3f>(y, x) = cv::Vec3f(kNaN, kNaN, kNaN);
      if (k == 1) image.at<cv::Vec3f>(y, x) = cv::Vec3f(kInf, -kInf, 1e30f);
    }
  }
  return image;
}

// Images of every awkward shape and type, each used as the picture and as thumbnails.
std::vector<cv::Mat> hostile_images() {
  const int sizes_3d[] = {4, 4, 4};
  return {cv::Mat(),
          nan_float_image(64, 48),
          solid_image(1, 1, kPhoto),
          solid_image(10'000, 1, kPhoto),
          solid_image(1, 5'000, kPhoto),
          cv::Mat(20, 20, CV_8UC1, cv::Scalar(128)),
          cv::Mat(20, 20, CV_8UC4, cv::Scalar(1, 2, 3, 4)),
          cv::Mat(20, 20, CV_16UC3, cv::Scalar(65535, 0, 0)),
          cv::Mat(20, 20, CV_64FC3, cv::Scalar(kNaN, 2.0, -1.0)),
          cv::Mat(20, 20, CV_8SC3, cv::Scalar(-5, 5, 0)),
          cv::Mat(20, 20, CV_32FC2, cv::Scalar(0.5, 0.5)),
          cv::Mat(3, sizes_3d, CV_8UC3, cv::Scalar::all(9)),
          solid_image(200, 100, kPhoto)(cv::Rect(50, 20, 30, 40))};  // a non-continuous ROI
}

// Every field at once out of range, NaN, negative or huge.
ScreenView hostile_view(ScreenKind kind, const std::string& text, const cv::Mat& image) {
  ScreenView view;
  view.kind = kind;
  view.title = text;
  view.status = text;
  view.image = image;
  view.image_caption = text;
  for (int i = 0; i < 200; ++i) {
    view.hints.push_back({static_cast<Button>(i % 7 == 6 ? 99 : i % 5), text, i % 2 == 0});
  }
  const double odd_seconds[] = {kNaN, kInf, -kInf, -1.0, 1e300, 0.0, 59.999, 3599.6};
  for (int i = 0; i < 2000; ++i) {
    view.stages.push_back({text, static_cast<StageLine::Status>(i % 7), odd_seconds[i % 8], text});
  }
  view.elapsed_seconds = kNaN;
  for (int i = 0; i < 5; ++i) view.props.push_back({text, text, image, i % 2 == 0});
  view.selected_prop = INT_MIN;
  view.spots = {{kNaN, 1}, {kInf, -kInf}, {1e300, -1e300}, {-5, -5}, {1e6, 3}, {10, 10}};
  view.selected_spot = INT_MAX;
  view.footprint = {{kNaN, 0}, {1e300, 1e300}, {-1e300, 5}, {3, kInf}, {10, 10}};
  view.placement_text = text;
  view.tiers = {{text, kNaN, -5}, {text, kInf, INT_MAX}, {text, -kInf, INT_MIN}, {text, 1e300, 0}};
  view.selected_tier = INT_MIN;
  view.tiles = {{cv::Rect(INT_MAX - 5, INT_MAX - 5, INT_MAX, INT_MAX), true, false, kNaN, -1},
                {cv::Rect(-1000, -1000, 10, 10), true, false, kInf, 0},
                {cv::Rect(INT_MIN, INT_MIN, INT_MAX, INT_MAX), true, false, -kInf, 0},
                {cv::Rect(5, 5, -10, -10), true, false, 0.1, 0},
                {cv::Rect(0, 0, 100'000, 100'000), true, false, 1e300, INT_MIN},
                {cv::Rect(0, 0, 8, 8), false, true, kNaN, 0}};
  for (int i = 0; i < 20'000; ++i) {
    view.tiles.push_back({cv::Rect((i * 37) % 700 - 50, (i * 53) % 500 - 50, 16, 16), i % 3 != 0,
                          i % 5 == 0, i * 1e-4, i});
  }
  view.converged_fraction = kNaN;
  view.predicted_seconds_to_good = kInf;
  view.predicted_seconds_to_done = kNaN;
  view.samples_per_pixel = INT_MIN;
  view.skipped_tiles = INT_MIN;
  view.skipped_effects = std::vector<std::string>(300, text);
  view.sliders = {{text, INT_MAX, 10, -10, text},
                  {text, INT_MIN, INT_MIN, INT_MAX, ""},
                  {text, 5, 5, 5, text},
                  {"", 0, -10, 10, ""}};
  view.selected_slider = -1;
  view.export_text = text;
  view.export_succeeded = kind == ScreenKind::Exporting ? std::optional<bool>(false) : std::nullopt;
  view.fault_message = text;
  return view;
}

// A canvas wrapping the middle of a larger image whose border holds a sentinel,
// so any pixel written outside the canvas shows.
class GuardedCanvas {
 public:
  explicit GuardedCanvas(Size size)
      : storage_(size.height + 2 * kGuard, size.width + 2 * kGuard, CV_8UC3,
                 cv::Scalar(kGuardValue.r, kGuardValue.g, kGuardValue.b)),
        canvas_(storage_(cv::Rect(kGuard, kGuard, size.width, size.height))) {}

  Canvas& canvas() { return canvas_; }

  int touched_guard_pixels() const {
    int touched = 0;
    const cv::Rect inside(kGuard, kGuard, canvas_.width(), canvas_.height());
    const cv::Vec3b guard(kGuardValue.r, kGuardValue.g, kGuardValue.b);
    for (int y = 0; y < storage_.rows; ++y) {
      for (int x = 0; x < storage_.cols; ++x) {
        if (!inside.contains({x, y}) && storage_.at<cv::Vec3b>(y, x) != guard) ++touched;
      }
    }
    return touched;
  }

 private:
  cv::Mat storage_;
  Canvas canvas_;
};

TEST(ScreensHardCases, HostileViewsDrawWithoutThrowingInsideTheCanvas) {
  const std::vector<std::string> texts = hostile_strings();
  const std::vector<cv::Mat> images = hostile_images();
  const Size sizes[] = {{320, 240}, {1280, 800}, {1, 1}, {3, 500}, {500, 3}};
  for (ScreenKind kind : kAllKinds) {
    for (std::size_t t = 0; t < texts.size(); ++t) {
      // Each text with one image, cycling, keeps the run short but covers every pair kind.
      const cv::Mat& image = images[(t + static_cast<std::size_t>(kind)) % images.size()];
      const ScreenView view = hostile_view(kind, texts[t], image);
      for (Size size : sizes) {
        GuardedCanvas guarded(size);
        ASSERT_NO_THROW(draw_screen(guarded.canvas(), view))
            << to_string(kind) << " text " << t << " at " << size.width << "x" << size.height;
        EXPECT_EQ(guarded.touched_guard_pixels(), 0) << to_string(kind) << " text " << t;
      }
    }
  }
}

TEST(ScreensHardCases, EveryImageTypeDrawsOnEveryScreen) {
  for (ScreenKind kind : kAllKinds) {
    for (const cv::Mat& image : hostile_images()) {
      ScreenView view;
      view.kind = kind;
      view.image = image;
      view.props = {{"p", "m", image, true}};
      view.tiles = {{cv::Rect(0, 0, 4, 4), true, false, 0.5, 1}};
      GuardedCanvas guarded({320, 240});
      ASSERT_NO_THROW(draw_screen(guarded.canvas(), view))
          << to_string(kind) << " type " << image.type() << " " << image.cols << "x" << image.rows;
      EXPECT_EQ(guarded.touched_guard_pixels(), 0);
    }
  }
}

TEST(ScreensHardCases, NanFloatImageDrawsItsFinitePixels) {
  ScreenView view;
  view.image = nan_float_image(64, 48);
  Canvas canvas(640, 480);
  draw_screen(canvas, view);
  const Rect area = screen_image_area(canvas.size(), view);
  ASSERT_FALSE(area.empty());
  // Grey 0.5 is sRGB 188; NaN becomes black; nothing else may appear but their blends.
  EXPECT_GT(count_pixels(canvas, area, [](Rgb p) { return p.g > 100; }), 0);
}

TEST(ScreensHardCases, UnknownKindDrawsThePicture) {
  ScreenView view;
  view.kind = static_cast<ScreenKind>(42);
  view.image = solid_image(64, 48, kPhoto);
  Canvas canvas(320, 240);
  EXPECT_NO_THROW(draw_screen(canvas, view));
  EXPECT_STREQ(to_string(view.kind), "unknown");
  const Rect area = screen_image_area(canvas.size(), view);
  EXPECT_EQ(count_colour(canvas, area, kPhoto), area_of(area));
}

// Draws `short_view` and `long_view` and returns the bounding box of the pixels
// that differ between them.
Rect difference_box(const ScreenView& short_view, const ScreenView& long_view, Size size) {
  Canvas a(size);
  Canvas b(size);
  draw_screen(a, short_view);
  draw_screen(b, long_view);
  int left = size.width, top = size.height, right = 0, bottom = 0;
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      if (a.pixel(x, y) == b.pixel(x, y)) continue;
      left = std::min(left, x);
      top = std::min(top, y);
      right = std::max(right, x + 1);
      bottom = std::max(bottom, y + 1);
    }
  }
  if (right <= left) return {};
  return {left, top, right - left, bottom - top};
}

bool contains(const Rect& outer, const Rect& inner) { return intersect(outer, inner) == inner; }

TEST(ScreensHardCases, LongTextsStayInTheirBoxes) {
  const std::string huge = hostile_strings()[1];  // words: wraps and elides
  for (Size size : {Size{320, 240}, Size{1280, 800}}) {
    const ScreenLayout layout = screen_layout(size);
    ScreenView plain;
    plain.image = solid_image(640, 480, kPhoto);
    plain.hints = {{Button::Ok, "place", false}};
    plain.title = "t";
    plain.status = "s";

    ScreenView changed = plain;
    changed.title = huge;
    changed.status = huge;
    Rect box = difference_box(plain, changed, size);
    EXPECT_FALSE(box.empty());
    EXPECT_TRUE(contains(layout.title_bar, box)) << "title and status leave the title bar";

    changed = plain;
    changed.hints = std::vector<ButtonHint>(30, {Button::Back, huge, true});
    box = difference_box(plain, changed, size);
    EXPECT_TRUE(contains(layout.hint_bar, box)) << "hints leave the hint bar";

    changed = plain;
    changed.image_caption = huge;
    box = difference_box(plain, changed, size);
    EXPECT_TRUE(contains(screen_image_area(size, plain), box)) << "caption leaves the picture";

    ScreenView fault = plain;
    fault.kind = ScreenKind::Fault;
    changed = fault;
    changed.fault_message = huge;
    box = difference_box(fault, changed, size);
    EXPECT_TRUE(contains(layout.main, box)) << "fault message leaves the main area";
  }
}

TEST(ScreensHardCases, HostileDrawsAreDeterministic) {
  for (ScreenKind kind : kAllKinds) {
    const ScreenView view = hostile_view(kind, hostile_strings()[3], nan_float_image(32, 24));
    Canvas a(320, 240);
    Canvas b(320, 240);
    draw_screen(a, view);
    draw_screen(b, view);
    EXPECT_EQ(cv::norm(a.pixels(), b.pixels(), cv::NORM_INF), 0) << to_string(kind);
  }
}

}  // namespace
}  // namespace propcam::ui_fb
