// Internal to ui_fb: what every screen draws with. Sizes that follow the
// panel (Metrics), rectangle arithmetic, text that never leaves its box,
// the numbers a user reads, pictures fitted into an area, captions, panels
// and progress bars; and the ScreenContext each screen draws from.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>

#include "propcam/ui_fb/screens.h"

namespace propcam::ui_fb::detail {

namespace colours = screen_colours;

// ---------------------------------------------------------------------------
// Sizes. Text grows with the square root of the panel: a bigger panel is also
// looked at from further away, but not proportionally further.

inline constexpr int kMinTextPx = 6;
inline constexpr double kMaxBarsFraction = 0.5;  // of the canvas height, on tiny canvases

struct Metrics {
  int body_px = kMinTextPx;
  int title_px = kMinTextPx;
  int small_px = kMinTextPx;
  int large_px = kMinTextPx;
  int pad = 1;  // between a box's edge and its contents
  int gap = 1;  // between neighbouring items
};

// A line box's height for text of `px`, known without FreeType.
int line_height(int px);
Metrics metrics_for(Size canvas);

// ---------------------------------------------------------------------------
// Geometry.

cv::Rect to_cv(const Rect& r);
cv::Scalar to_scalar(Rgb c);
Rect inset(const Rect& r, int dx, int dy);
// Splits `area`: the top (bottom, left, right) `height` or `width` (clamped),
// leaving the rest in `area`.
Rect take_top(Rect& area, int height);
Rect take_bottom(Rect& area, int height);
Rect take_left(Rect& area, int width);
Rect take_right(Rect& area, int width);
// A rectangle of the given size centred in `area` (clamped to it).
Rect centred(const Rect& area, int width, int height);
bool finite_non_negative(double value);
// Whether `index` selects one of `count` items.
bool valid_index(long long index, std::size_t count);
// The first of `visible` consecutive rows out of `count` such that `focus` is among them.
int first_visible_row(int count, int visible, int focus);

// ---------------------------------------------------------------------------
// Pixels.

// Multiplies the pixels of `rect` by `factor` (dims a photo behind a panel).
void dim_rect(Canvas& canvas, const Rect& rect, double factor);
// Blends `colour` over `rect` with the given opacity: a see-through panel.
void shade_rect(Canvas& canvas, const Rect& rect, Rgb colour, double opacity);
Rgb mix(Rgb a, Rgb b, double t);

// ---------------------------------------------------------------------------
// Text. Everything is drawn through draw_text_in, which elides to the box's
// width and paints through a canvas wrapping only the box, so no glyph can
// land outside it whatever the string holds.

enum class Align { Left, Centre, Right };

struct TextStyle {
  int px = kMinTextPx;
  Rgb colour = colours::kText;
  FontWeight weight = FontWeight::Regular;
};

int width_of(std::string_view text, const TextStyle& style);
// `text` on one line, cut to fit `max_width` with a trailing "…" when it does
// not; empty when not even the ellipsis fits.
std::string elide(std::string_view raw, const TextStyle& style, int max_width);
// Draws one line inside `box`, vertically centred, elided to the box's width.
// Returns the width drawn (0 if nothing fitted).
int draw_text_in(Canvas& canvas, const Rect& box, std::string_view text, const TextStyle& style,
                 Align align = Align::Left);
// Word-wraps `text` into at most `max_lines` lines of `max_width`; newlines
// break lines, a word wider than a line is broken between code points, and
// the last line is elided when text remains.
std::vector<std::string> wrap_lines(std::string_view text, const TextStyle& style, int max_width,
                                    int max_lines);

// The widest entry of `column` among `rows`, plus a gap, capped to `limit`.
template <typename Items, typename Text>
int column_width(const Items& rows, Text column, const TextStyle& style, int gap, int limit) {
  int widest = 0;
  for (const auto& row : rows) {
    widest = std::max(widest, width_of(elide(column(row), style, limit), style) + gap);
  }
  return std::min(widest, limit);
}

// ---------------------------------------------------------------------------
// Numbers a user reads: "0.42 s", "12.3 s", "2 min 05 s"; "~12 s", "~3 min".

std::string printf_string(const char* format, double a, double b = 0.0);
// A measured duration; empty for NaN, infinite or negative seconds.
std::string format_seconds(double seconds);
// A prediction, deliberately rough; empty when unknown (negative, NaN, infinite).
std::string format_predicted(double seconds);
std::string count_text(long long count, const char* singular, const char* plural);

// ---------------------------------------------------------------------------
// Images.

// The view's picture as blit_scaled takes it (CV_8UC3 or CV_32FC3), converting
// grey, RGBA and other depths; nullopt when there is nothing drawable.
std::optional<cv::Mat> drawable_image(const cv::Mat& image);
Size size_of(const cv::Mat& image);
// `image` scaled into `target`, area-averaged first when it shrinks by more than 2x.
void blit_fitted(Canvas& canvas, const cv::Mat& image, const Rect& target);
// Draws the image fitted into `area`; returns where it went, or an empty
// rectangle after drawing the placeholder.
Rect draw_picture(Canvas& canvas, const Rect& area, const cv::Mat& image,
                  std::string_view placeholder, const Metrics& m);

// Marks further outside the picture than this (screen pixels) are clamped:
// cv's fixed-point drawing would overflow, and they could not be seen anyway.
inline constexpr double kFarOutside = 1e5;

// Maps image pixel coordinates (a point is a pixel's centre, a rectangle
// covers whole pixels) to where the image was drawn on screen.
class ImageMapping {
 public:
  ImageMapping(const Rect& screen, Size image)
      : screen_(screen), image_{std::max(1, image.width), std::max(1, image.height)} {}

  // A pixel edge (column or row boundary) to a screen edge, clamped just
  // outside the picture so absurd coordinates stay integers.
  int edge_x(double x) const {
    return clamp_edge(screen_.x + x * screen_.width / image_.width, screen_.x, screen_.right());
  }
  int edge_y(double y) const {
    return clamp_edge(screen_.y + y * screen_.height / image_.height, screen_.y, screen_.bottom());
  }

  Rect rect(const cv::Rect& r) const {
    const int left = edge_x(r.x);
    const int top = edge_y(r.y);
    const int right = edge_x(static_cast<double>(r.x) + r.width);
    const int bottom = edge_y(static_cast<double>(r.y) + r.height);
    return intersect({left, top, right - left, bottom - top}, screen_);
  }

  // A pixel centre to a screen position relative to the picture's top-left
  // (for drawing into the picture's own pixels), clamped to a sane range.
  cv::Point2d local_point(const cv::Point2d& p) const {
    const auto clamp = [](double v) { return std::clamp(v, -kFarOutside, kFarOutside); };
    return {clamp((p.x + 0.5) * screen_.width / image_.width - 0.5),
            clamp((p.y + 0.5) * screen_.height / image_.height - 0.5)};
  }

 private:
  static int clamp_edge(double value, int low, int high) {
    if (std::isnan(value)) return low;
    return static_cast<int>(std::lround(std::clamp(value, low - 1.0, high + 1.0)));
  }

  Rect screen_;
  Size image_;
};

// cv drawing with sub-pixel precision: coordinates carry this many fraction bits.
inline constexpr int kSubpixelBits = 4;
inline constexpr double kSubpixelScale = 1 << kSubpixelBits;

cv::Point subpixel(const cv::Point2d& p);
bool finite_point(const cv::Point2d& p);

// A caption strip over the top or bottom edge of `rect`.
enum class Edge { Top, Bottom };
void draw_caption(Canvas& canvas, const Rect& rect, std::string_view text, Edge edge,
                  const Metrics& m);

// A see-through dark panel over a picture, with a thin border; the photo
// behind it is dimmed by kDimmedPhoto.
inline constexpr double kDimmedPhoto = 0.4;
void draw_panel(Canvas& canvas, const Rect& panel, Rgb border);
// The panel's width on this main area: most of it on small screens, less on big ones.
int panel_width(const Rect& main, const Metrics& m);

void draw_progress_bar(Canvas& canvas, const Rect& bar, double fraction);

// The column of a row's mark (a stage's ✔, the selected tier's ▶), in em.
inline constexpr double kMarkColumnEm = 1.5;

// ---------------------------------------------------------------------------
// What a screen draws from: it draws into main (and picture, where the image goes).

struct ScreenContext {
  Canvas& canvas;
  const ScreenView& view;
  const Metrics& m;
  Rect main;
  Rect picture;
};

}  // namespace propcam::ui_fb::detail
