#include "propcam/ui_fb/screens.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace propcam::ui_fb {

const char* to_string(ScreenKind kind) {
  switch (kind) {
    case ScreenKind::Viewfinder: return "viewfinder";
    case ScreenKind::Captured: return "captured";
    case ScreenKind::Analysing: return "analysing";
    case ScreenKind::Carousel: return "carousel";
    case ScreenKind::Placement: return "placement";
    case ScreenKind::TierPick: return "tier-pick";
    case ScreenKind::Rendering: return "rendering";
    case ScreenKind::Adjusting: return "adjusting";
    case ScreenKind::Exporting: return "exporting";
    case ScreenKind::Fault: return "fault";
  }
  return "unknown";
}

namespace {

namespace colours = screen_colours;

// ---------------------------------------------------------------------------
// Sizes. Text grows with the square root of the panel: a bigger panel is also
// looked at from further away, but not proportionally further.

constexpr double kReferenceUnit = 240.0;  // the smallest panel, 320x240
constexpr double kBodyPxAtReference = 13.0;
constexpr double kTitleScale = 1.15;
constexpr double kSmallScale = 0.85;
constexpr double kLargeScale = 2.2;  // ✔ / ✖ and the fault's warning sign
constexpr int kMinTextPx = 6;
constexpr int kMaxTextPx = 400;
constexpr double kPadEm = 0.45;
constexpr double kGapEm = 0.25;
// DejaVu Sans' ascender and descender in em, rounded up, so line boxes are
// known without FreeType (screen_layout needs no font).
constexpr double kAscenderEm = 0.93;
constexpr double kDescenderEm = 0.24;
constexpr double kMaxBarsFraction = 0.5;  // of the canvas height, on tiny canvases

struct Metrics {
  int body_px = kMinTextPx;
  int title_px = kMinTextPx;
  int small_px = kMinTextPx;
  int large_px = kMinTextPx;
  int pad = 1;  // between a box's edge and its contents
  int gap = 1;  // between neighbouring items
};

int line_height(int px) {
  return static_cast<int>(std::ceil(px * kAscenderEm)) +
         static_cast<int>(std::ceil(px * kDescenderEm));
}

int text_px(double body, double scale) {
  return std::clamp(static_cast<int>(std::lround(body * scale)), kMinTextPx, kMaxTextPx);
}

Metrics metrics_for(Size canvas) {
  const double unit =
      std::max(1.0, std::min<double>(canvas.height, canvas.width * 0.75));  // 4:3 equivalent
  const double body = kBodyPxAtReference * std::sqrt(unit / kReferenceUnit);
  Metrics m;
  m.body_px = text_px(body, 1.0);
  m.title_px = text_px(body, kTitleScale);
  m.small_px = text_px(body, kSmallScale);
  m.large_px = text_px(body, kLargeScale);
  m.pad = std::max(2, static_cast<int>(std::lround(body * kPadEm)));
  m.gap = std::max(1, static_cast<int>(std::lround(body * kGapEm)));
  return m;
}

cv::Rect to_cv(const Rect& r) { return {r.x, r.y, r.width, r.height}; }
cv::Scalar to_scalar(Rgb c) { return {static_cast<double>(c.r), static_cast<double>(c.g),
                                      static_cast<double>(c.b)}; }

Rect inset(const Rect& r, int dx, int dy) {
  return {r.x + dx, r.y + dy, std::max(0, r.width - 2 * dx), std::max(0, r.height - 2 * dy)};
}

// Splits `area` horizontally: the top `height` rows (clamped) and the rest.
Rect take_top(Rect& area, int height) {
  const int h = std::clamp(height, 0, std::max(0, area.height));
  const Rect top{area.x, area.y, area.width, h};
  area = {area.x, area.y + h, area.width, area.height - h};
  return top;
}
Rect take_bottom(Rect& area, int height) {
  const int h = std::clamp(height, 0, std::max(0, area.height));
  area.height -= h;
  return {area.x, area.bottom(), area.width, h};
}
Rect take_left(Rect& area, int width) {
  const int w = std::clamp(width, 0, std::max(0, area.width));
  const Rect left{area.x, area.y, w, area.height};
  area = {area.x + w, area.y, area.width - w, area.height};
  return left;
}
Rect take_right(Rect& area, int width) {
  const int w = std::clamp(width, 0, std::max(0, area.width));
  area.width -= w;
  return {area.right(), area.y, w, area.height};
}

// A rectangle of the given size centred in `area` (clamped to it).
Rect centred(const Rect& area, int width, int height) {
  const int w = std::clamp(width, 0, std::max(0, area.width));
  const int h = std::clamp(height, 0, std::max(0, area.height));
  return {area.x + (area.width - w) / 2, area.y + (area.height - h) / 2, w, h};
}

bool finite_non_negative(double value) { return std::isfinite(value) && value >= 0.0; }

// Whether `index` selects one of `count` items.
bool valid_index(long long index, std::size_t count) {
  return index >= 0 && static_cast<unsigned long long>(index) < count;
}

// The first of `visible` consecutive rows out of `count` such that `focus` is among them.
int first_visible_row(int count, int visible, int focus) {
  if (visible <= 0 || count <= visible) return 0;
  const int wanted = std::clamp(focus, 0, count - 1) - visible / 2;
  return std::clamp(wanted, 0, count - visible);
}

// ---------------------------------------------------------------------------
// Pixels.

// Multiplies the pixels of `rect` by `factor` (dims a photo behind a panel).
void dim_rect(Canvas& canvas, const Rect& rect, double factor) {
  const Rect visible = intersect(rect, canvas.bounds());
  if (visible.empty()) return;
  cv::Mat roi = canvas.pixels()(to_cv(visible));
  roi.convertTo(roi, -1, factor);
}

// Blends `colour` over `rect` with the given opacity: a see-through panel.
void shade_rect(Canvas& canvas, const Rect& rect, Rgb colour, double opacity) {
  const Rect visible = intersect(rect, canvas.bounds());
  if (visible.empty()) return;
  cv::Mat roi = canvas.pixels()(to_cv(visible));
  roi.convertTo(roi, -1, 1.0 - opacity);
  roi += to_scalar(colour) * opacity;
}

Rgb mix(Rgb a, Rgb b, double t) {
  const auto channel = [t](std::uint8_t x, std::uint8_t y) {
    return static_cast<std::uint8_t>(std::lround(x + (y - x) * t));
  };
  return {channel(a.r, b.r), channel(a.g, b.g), channel(a.b, b.b)};
}

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

constexpr std::string_view kEllipsis = "…";
// No DejaVu glyph that advances is narrower than this, which bounds how many
// code points of a long string can possibly fit into a width.
constexpr double kNarrowestAdvanceEm = 0.2;

bool is_continuation_byte(char c) { return (static_cast<unsigned char>(c) & 0xC0) == 0x80; }

// Control characters (newlines, tabs, ESC...) would draw as boxes: one line shows them as spaces.
std::string single_line(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7F) c = ' ';
  }
  return out;
}

// Byte offset just past the first `count` code points of `text` (or its size).
std::size_t prefix_bytes(std::string_view text, std::size_t count) {
  std::size_t seen = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (is_continuation_byte(text[i])) continue;
    if (seen == count) return i;
    ++seen;
  }
  return text.size();
}

// Byte offsets just past each code point.
std::vector<std::size_t> code_point_ends(std::string_view text) {
  std::vector<std::size_t> ends;
  for (std::size_t i = 1; i <= text.size(); ++i) {
    if (i == text.size() || !is_continuation_byte(text[i])) ends.push_back(i);
  }
  return ends;
}

std::size_t max_fitting_code_points(int px, int max_width) {
  return static_cast<std::size_t>(max_width / std::max(1.0, px * kNarrowestAdvanceEm)) + 2;
}

int width_of(std::string_view text, const TextStyle& style) {
  return Canvas::text_width(text, style.px, style.weight);
}

std::string trim_trailing_spaces(std::string text) {
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

// The largest k such that the first k code points (via `ends`) satisfy `fits`.
template <typename Fits>
std::size_t longest_prefix(const std::vector<std::size_t>& ends, Fits fits) {
  std::size_t low = 0;
  std::size_t high = ends.size();
  while (low < high) {
    const std::size_t mid = (low + high + 1) / 2;
    if (fits(ends[mid - 1])) {
      low = mid;
    } else {
      high = mid - 1;
    }
  }
  return low;
}

// `text` on one line, cut to fit `max_width` with a trailing "…" when it does
// not; empty when not even the ellipsis fits.
std::string elide(std::string_view raw, const TextStyle& style, int max_width) {
  if (max_width <= 0 || raw.empty()) return {};
  const std::size_t kept = prefix_bytes(raw, max_fitting_code_points(style.px, max_width));
  const std::string text = single_line(raw.substr(0, kept));
  if (kept == raw.size() && width_of(text, style) <= max_width) return text;
  if (width_of(kEllipsis, style) > max_width) return {};
  const auto with_ellipsis = [&](std::size_t bytes) {
    return trim_trailing_spaces(text.substr(0, bytes)) + std::string(kEllipsis);
  };
  const std::vector<std::size_t> ends = code_point_ends(text);
  const std::size_t count = longest_prefix(
      ends, [&](std::size_t bytes) { return width_of(with_ellipsis(bytes), style) <= max_width; });
  return with_ellipsis(count == 0 ? 0 : ends[count - 1]);
}

// Draws one line inside `box`, vertically centred, elided to the box's width.
// Returns the width drawn (0 if nothing fitted).
int draw_text_in(Canvas& canvas, const Rect& box, std::string_view text, const TextStyle& style,
                 Align align = Align::Left) {
  const Rect visible = intersect(box, canvas.bounds());
  if (visible.empty()) return 0;
  const std::string fitted = elide(text, style, box.width);
  if (fitted.empty()) return 0;
  const TextExtent extent = Canvas::measure_text(fitted, style.px, style.weight);
  const int top = box.y + (box.height - (extent.ascent + extent.descent)) / 2;
  int x = box.x;
  if (align == Align::Centre) x += (box.width - extent.width) / 2;
  if (align == Align::Right) x = box.right() - extent.width;
  Canvas clip(canvas.pixels()(to_cv(visible)));
  clip.draw_text(x - visible.x, top + extent.ascent - visible.y, fitted, style.px, style.colour,
                 style.weight);
  return extent.width;
}

std::size_t skip_blanks(std::string_view text, std::size_t pos) {
  while (pos < text.size() && (text[pos] == ' ' || text[pos] == '\t' || text[pos] == '\r')) ++pos;
  return pos;
}

std::size_t word_end(std::string_view text, std::size_t pos, std::size_t limit) {
  while (pos < limit && text[pos] != ' ' && text[pos] != '\t' && text[pos] != '\r') ++pos;
  return pos;
}

// Word-wraps `text` into at most `max_lines` lines of `max_width`; newlines
// break lines, a word wider than a line is broken between code points, and
// the last line is elided when text remains.
std::vector<std::string> wrap_lines(std::string_view text, const TextStyle& style, int max_width,
                                    int max_lines) {
  std::vector<std::string> lines;
  if (max_width <= 0 || max_lines <= 0) return lines;
  // A UTF-8 code point is at most 4 bytes, so longer candidates cannot fit.
  const std::size_t max_bytes = 4 * max_fitting_code_points(style.px, max_width);
  const auto fits = [&](std::string_view candidate) {
    return candidate.size() <= max_bytes && width_of(single_line(candidate), style) <= max_width;
  };
  std::size_t pos = 0;
  while (pos < text.size() && static_cast<int>(lines.size()) < max_lines) {
    pos = skip_blanks(text, pos);
    if (pos >= text.size()) break;
    if (text[pos] == '\n') {  // an empty paragraph
      lines.emplace_back();
      ++pos;
      continue;
    }
    if (static_cast<int>(lines.size()) == max_lines - 1) {
      lines.push_back(elide(text.substr(pos), style, max_width));
      break;
    }
    const std::size_t paragraph_end = std::min(text.find('\n', pos), text.size());
    std::size_t line_end = pos;
    for (std::size_t cursor = pos; cursor < paragraph_end;) {
      const std::size_t end = word_end(text, cursor, paragraph_end);
      if (!fits(text.substr(pos, end - pos))) break;
      line_end = end;
      cursor = skip_blanks(text, end);
    }
    if (line_end == pos) {  // the first word alone is too wide: break it
      const std::string_view word = text.substr(pos, word_end(text, pos, paragraph_end) - pos);
      const std::vector<std::size_t> ends =
          code_point_ends(word.substr(0, prefix_bytes(word, max_bytes)));
      const std::size_t count =
          longest_prefix(ends, [&](std::size_t bytes) { return fits(word.substr(0, bytes)); });
      line_end = pos + ends[std::max<std::size_t>(count, 1) - 1];  // at least one code point
    }
    lines.push_back(trim_trailing_spaces(single_line(text.substr(pos, line_end - pos))));
    pos = skip_blanks(text, line_end);
    if (pos < text.size() && text[pos] == '\n') ++pos;
  }
  return lines;
}

// ---------------------------------------------------------------------------
// Numbers a user reads: "0.42 s", "12.3 s", "2 min 05 s"; "~12 s", "~3 min".

constexpr double kSecondsPerMinute = 60.0;
constexpr double kSecondsPerHour = 3600.0;
constexpr double kLongestShownSeconds = 99.0 * kSecondsPerHour;

std::string printf_string(const char* format, double a, double b = 0.0) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, format, a, b);
  return buffer;
}

// A measured duration; empty for NaN, infinite or negative seconds.
std::string format_seconds(double seconds) {
  if (!finite_non_negative(seconds)) return {};
  if (seconds >= kLongestShownSeconds) return "> 99 h";
  if (seconds < 10.0) return printf_string("%.2f s", seconds);
  if (seconds < kSecondsPerMinute) return printf_string("%.1f s", seconds);
  const double whole = std::floor(seconds);
  if (seconds < kSecondsPerHour) {
    return printf_string("%.0f min %02.0f s", std::floor(whole / kSecondsPerMinute),
                         std::fmod(whole, kSecondsPerMinute));
  }
  return printf_string("%.0f h %02.0f min", std::floor(whole / kSecondsPerHour),
                       std::floor(std::fmod(whole, kSecondsPerHour) / kSecondsPerMinute));
}

// A prediction, deliberately rough; empty when unknown (negative, NaN, infinite).
std::string format_predicted(double seconds) {
  if (!finite_non_negative(seconds)) return {};
  if (seconds >= kLongestShownSeconds) return "> 99 h";
  if (seconds < 0.5) return "< 1 s";
  if (seconds < kSecondsPerMinute - 0.5) return printf_string("~%.0f s", seconds);
  if (seconds < kSecondsPerHour - kSecondsPerMinute / 2) {
    return printf_string("~%.0f min", std::max(1.0, std::round(seconds / kSecondsPerMinute)));
  }
  return printf_string("~%.0f h", std::max(1.0, std::round(seconds / kSecondsPerHour)));
}

std::string count_text(long long count, const char* singular, const char* plural) {
  return std::to_string(count) + " " + (count == 1 ? singular : plural);
}

// ---------------------------------------------------------------------------
// Images.

// The view's picture as blit_scaled takes it (CV_8UC3 or CV_32FC3), converting
// grey, RGBA and other depths; nullopt when there is nothing drawable.
std::optional<cv::Mat> drawable_image(const cv::Mat& image) {
  if (image.empty() || image.dims != 2 || image.cols <= 0 || image.rows <= 0) return std::nullopt;
  cv::Mat converted = image;
  switch (image.depth()) {
    case CV_8U:
    case CV_32F: break;
    case CV_16U: image.convertTo(converted, CV_8U, 1.0 / 257.0); break;
    case CV_64F: image.convertTo(converted, CV_32F); break;
    default: return std::nullopt;
  }
  switch (converted.channels()) {
    case 3: return converted;
    case 1: cv::cvtColor(converted, converted, cv::COLOR_GRAY2RGB); return converted;
    case 4: cv::cvtColor(converted, converted, cv::COLOR_RGBA2RGB); return converted;
    default: return std::nullopt;
  }
}

Size size_of(const cv::Mat& image) { return {image.cols, image.rows}; }

// Shrinking by more than 2x needs area averaging (bilinear would alias), and
// OpenCV averages areas fast only at whole factors (a 1280x960 frame to 640x480
// took 6 ms at a fractional one). So a big shrink first averages k×k blocks,
// k the whole part of the factor per axis, and bilinear does the rest (< 2x).
void blit_fitted(Canvas& canvas, const cv::Mat& image, const Rect& target) {
  if (target.empty()) return;
  const int block_x = std::max(1, image.cols / target.width);
  const int block_y = std::max(1, image.rows / target.height);
  if (block_x == 1 && block_y == 1) {
    canvas.blit_scaled(image, target, false, ScaleFilter::Bilinear);
    return;
  }
  // Whole blocks only (at most block-1 edge pixels go), so the factor is exact.
  const cv::Mat whole_blocks = image(cv::Rect(0, 0, image.cols - image.cols % block_x,
                                              image.rows - image.rows % block_y));
  cv::Mat averaged;
  cv::resize(whole_blocks, averaged,
             cv::Size(whole_blocks.cols / block_x, whole_blocks.rows / block_y), 0, 0,
             cv::INTER_AREA);
  canvas.blit_scaled(averaged, target, false, ScaleFilter::Bilinear);
}

void draw_placeholder(Canvas& canvas, const Rect& area, std::string_view text, const Metrics& m) {
  canvas.fill_rect(area, colours::kPlaceholder);
  draw_text_in(canvas, inset(area, m.pad, 0), text, {m.body_px, colours::kDimText}, Align::Centre);
}

// Draws the image fitted into `area`; returns where it went, or an empty
// rectangle after drawing the placeholder.
Rect draw_picture(Canvas& canvas, const Rect& area, const cv::Mat& image,
                  std::string_view placeholder, const Metrics& m) {
  if (area.empty()) return {};
  const std::optional<cv::Mat> drawable = drawable_image(image);
  if (!drawable) {
    draw_placeholder(canvas, area, placeholder, m);
    return {};
  }
  const Rect target = image_area(area, size_of(*drawable));
  blit_fitted(canvas, *drawable, target);
  return target;
}

// Marks further outside the picture than this (screen pixels) are clamped:
// cv's fixed-point drawing would overflow, and they could not be seen anyway.
constexpr double kFarOutside = 1e5;

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
constexpr int kSubpixelBits = 4;
constexpr double kSubpixelScale = 1 << kSubpixelBits;

cv::Point subpixel(const cv::Point2d& p) {
  return {static_cast<int>(std::lround(p.x * kSubpixelScale)),
          static_cast<int>(std::lround(p.y * kSubpixelScale))};
}

bool finite_point(const cv::Point2d& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// A caption strip over the top or bottom edge of `rect`.
enum class Edge { Top, Bottom };
constexpr double kCaptionOpacity = 0.65;

void draw_caption(Canvas& canvas, const Rect& rect, std::string_view text, Edge edge,
                  const Metrics& m) {
  if (text.empty() || rect.empty()) return;
  Rect area = rect;
  const int height = line_height(m.body_px) + 2 * m.gap;
  const Rect strip = edge == Edge::Bottom ? take_bottom(area, height) : take_top(area, height);
  shade_rect(canvas, strip, {0, 0, 0}, kCaptionOpacity);
  draw_text_in(canvas, inset(strip, m.pad, 0), text, {m.body_px, colours::kText}, Align::Centre);
}

// A see-through dark panel over a picture, with a thin border.
constexpr double kPanelOpacity = 0.7;
constexpr Rgb kPanelColour{12, 14, 18};
constexpr double kDimmedPhoto = 0.4;

void draw_panel(Canvas& canvas, const Rect& panel, Rgb border) {
  shade_rect(canvas, panel, kPanelColour, kPanelOpacity);
  canvas.stroke_rect(panel, border, 1);
}

// The panel's width on this main area: most of it on small screens, less on big ones.
constexpr double kPanelMinWidthEm = 22.0;
constexpr double kPanelWidthFraction = 0.7;

int panel_width(const Rect& main, const Metrics& m) {
  const int wanted = std::max(static_cast<int>(kPanelMinWidthEm * m.body_px),
                              static_cast<int>(main.width * kPanelWidthFraction));
  return std::min(wanted, main.width - 2 * m.pad);
}

void draw_progress_bar(Canvas& canvas, const Rect& bar, double fraction) {
  canvas.fill_rect(bar, colours::kTrack);
  const double clamped = std::isnan(fraction) ? 0.0 : std::clamp(fraction, 0.0, 1.0);
  canvas.fill_rect({bar.x, bar.y, static_cast<int>(std::lround(bar.width * clamped)), bar.height},
                   colours::kAccent);
}

// ---------------------------------------------------------------------------
// The frame: title bar and hint bar.

constexpr int kAccentLine = 2;  // under the title bar; red on Fault
constexpr double kStatusMaxFraction = 0.5;  // of the title bar the status may take

void draw_title_bar(Canvas& canvas, const Rect& bar, const ScreenView& view, const Metrics& m) {
  canvas.fill_rect(bar, colours::kBar);
  const Rgb accent = view.kind == ScreenKind::Fault ? colours::kFault : colours::kAccent;
  const int accent_height = std::min(kAccentLine, bar.height / 4);
  canvas.fill_rect({bar.x, bar.bottom() - accent_height, bar.width, accent_height}, accent);
  Rect inner = inset(bar, m.pad, 0);
  const TextStyle status_style{m.body_px, colours::kDimText};
  const std::string status =
      elide(view.status, status_style, static_cast<int>(inner.width * kStatusMaxFraction));
  const int status_width = status.empty() ? 0 : width_of(status, status_style);
  draw_text_in(canvas, take_right(inner, status_width), status, status_style, Align::Right);
  take_right(inner, status.empty() ? 0 : 2 * m.pad);
  draw_text_in(canvas, inner, view.title, {m.title_px, colours::kText, FontWeight::Bold});
}

// "OK", "hold OK", "▶" (NEXT), "◀" (PREV).
std::string key_label(const ButtonHint& hint) {
  std::string key;
  switch (hint.button) {
    case Button::Next: key = "▶"; break;
    case Button::Prev: key = "◀"; break;
    default: key = std::string(button_name(hint.button)); break;
  }
  return hint.long_press ? "hold " + key : key;
}

constexpr double kHintGapEm = 1.2;       // between two hints, when there is room
constexpr double kTightHintGapEm = 0.6;  // when there is not
constexpr double kKeyGapEm = 0.3;        // between a key and its label
constexpr std::size_t kMaxHints = 12;    // more could never be read in one bar

// Gives each label at most its natural width, sharing `available` fairly: short
// labels stay whole and the long ones are elided to what is left.
std::vector<int> share_widths(const std::vector<int>& natural, int available) {
  std::vector<std::size_t> order(natural.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return natural[a] < natural[b]; });
  std::vector<int> shares(natural.size(), 0);
  int remaining = std::max(0, available);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const int fair = remaining / static_cast<int>(order.size() - k);
    shares[order[k]] = std::min(natural[order[k]], fair);
    remaining -= shares[order[k]];
  }
  return shares;
}

struct HintWidths {
  std::vector<int> keys;
  std::vector<int> labels;  // including the gap after the key; 0 without a label
};

HintWidths measure_hints(const std::vector<ButtonHint>& hints, std::size_t count, int px,
                         int max_width) {
  const TextStyle key_style{px, colours::kAccent, FontWeight::Bold};
  const TextStyle label_style{px, colours::kText};
  const int key_gap = static_cast<int>(kKeyGapEm * px);
  HintWidths widths;
  for (std::size_t i = 0; i < count; ++i) {
    widths.keys.push_back(width_of(key_label(hints[i]), key_style));
    // Measuring only what could ever fit keeps a huge label cheap.
    const std::string label = elide(hints[i].label, label_style, max_width);
    widths.labels.push_back(label.empty() ? 0 : width_of(label, label_style) + key_gap);
  }
  return widths;
}

int keys_width(const HintWidths& widths, std::size_t count, int gap) {
  int width = gap * static_cast<int>(count - 1);
  for (std::size_t i = 0; i < count; ++i) width += widths.keys[i];
  return width;
}

int natural_width(const HintWidths& widths, std::size_t count, int gap) {
  int width = keys_width(widths, count, gap);
  for (std::size_t i = 0; i < count; ++i) width += widths.labels[i];
  return width;
}

// Each hint is its key in bold accent ("OK", "hold OK", "▶") and its label.
// When they do not fit: tighter gaps, then the small font, then the longest
// labels are elided; keys are never cut (hints are dropped from the end first).
void draw_hint_bar(Canvas& canvas, const Rect& bar, const std::vector<ButtonHint>& hints,
                   const Metrics& m) {
  canvas.fill_rect(bar, colours::kBar);
  const Rect inner = inset(bar, m.pad, 0);
  if (hints.empty() || inner.empty()) return;
  std::size_t count = std::min(hints.size(), kMaxHints);
  int px = m.body_px;
  HintWidths widths = measure_hints(hints, count, px, inner.width);
  int gap = static_cast<int>(kHintGapEm * px);
  if (natural_width(widths, count, gap) > inner.width) {
    gap = static_cast<int>(kTightHintGapEm * px);
    if (natural_width(widths, count, gap) > inner.width) {
      px = m.small_px;
      gap = static_cast<int>(kTightHintGapEm * px);
      widths = measure_hints(hints, count, px, inner.width);
    }
  }
  while (count > 1 && keys_width(widths, count, gap) > inner.width) --count;
  widths.labels.resize(count);
  const std::vector<int> label_shares =
      share_widths(widths.labels, inner.width - keys_width(widths, count, gap));

  const TextStyle key_style{px, colours::kAccent, FontWeight::Bold};
  const TextStyle label_style{px, colours::kText};
  const int key_gap = static_cast<int>(kKeyGapEm * px);
  int x = inner.x;
  for (std::size_t i = 0; i < count; ++i) {
    draw_text_in(canvas, {x, inner.y, std::min(widths.keys[i], inner.right() - x), inner.height},
                 key_label(hints[i]), key_style);
    x += widths.keys[i];
    if (label_shares[i] > key_gap) {
      draw_text_in(canvas, {x + key_gap, inner.y, label_shares[i] - key_gap, inner.height},
                   hints[i].label, label_style);
    }
    x += label_shares[i] + gap;
  }
}

// ---------------------------------------------------------------------------
// Regions of the main area that depend on the screen.

int row_height(const Metrics& m) { return line_height(m.body_px) + 2 * m.gap; }

// Rendering: the progress bar and up to two rows of figures below the picture.
constexpr double kProgressBarEm = 0.5;
constexpr int kMainLinesForTwoInfoRows = 12;

int info_rows(const Rect& main, const Metrics& m) {
  return main.height >= kMainLinesForTwoInfoRows * line_height(m.small_px) ? 2 : 1;
}

int progress_bar_height(const Metrics& m) {
  return std::max(2, static_cast<int>(std::lround(kProgressBarEm * m.body_px)));
}

int rendering_strip_height(const Rect& main, const Metrics& m) {
  return m.gap + progress_bar_height(m) + info_rows(main, m) * (line_height(m.small_px) + m.gap);
}

// Adjusting: a row per slider below the picture, at most this many and this share.
constexpr int kMaxSliderRows = 4;
constexpr double kMaxSliderShare = 0.45;

int slider_rows(const Rect& main, const ScreenView& view, const Metrics& m) {
  const int fitting = static_cast<int>(main.height * kMaxSliderShare) / std::max(1, row_height(m));
  return std::min({static_cast<int>(std::min<std::size_t>(view.sliders.size(), kMaxSliderRows)),
                   fitting});
}

// Where the screen's picture goes.
Rect picture_region(const ScreenLayout& layout, const ScreenView& view, const Metrics& m) {
  Rect region = layout.main;
  if (view.kind == ScreenKind::Rendering) {
    take_bottom(region, rendering_strip_height(layout.main, m));
  } else if (view.kind == ScreenKind::Adjusting) {
    take_bottom(region, slider_rows(layout.main, view, m) * row_height(m));
  }
  return region;
}

// ---------------------------------------------------------------------------
// The screens. Each draws into main (and picture, where the image goes).

struct ScreenContext {
  Canvas& canvas;
  const ScreenView& view;
  const Metrics& m;
  Rect main;
  Rect picture;
};

void draw_viewfinder(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no camera frame", c.m);
  draw_caption(c.canvas, image.empty() ? c.picture : image, c.view.image_caption, Edge::Bottom,
               c.m);
}

constexpr double kFlashBorderEm = 0.3;

void draw_captured(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no camera frame", c.m);
  const Rect frame = image.empty() ? c.picture : image;
  c.canvas.stroke_rect(frame, colours::kFlash,
                       std::max(2, static_cast<int>(std::lround(kFlashBorderEm * c.m.body_px))));
  const std::string caption = c.view.image_caption.empty() ? "capturing…" : c.view.image_caption;
  draw_caption(c.canvas, frame, caption, Edge::Bottom, c.m);
}

// Analysing ------------------------------------------------------------------

struct StageMark {
  const char* glyph;
  Rgb colour;
};

StageMark stage_mark(StageLine::Status status) {
  switch (status) {
    case StageLine::Status::Pending: return {"○", colours::kDimText};
    case StageLine::Status::Running: return {"●", colours::kAccent};
    case StageLine::Status::Done: return {"✔", colours::kGood};
    case StageLine::Status::Failed: return {"✖", colours::kFault};
    case StageLine::Status::Skipped: return {"–", colours::kDimText};
  }
  return {"?", colours::kDimText};
}

// The stage to keep in view when the list is longer than the panel: the running
// one, else the last that finished.
int focus_stage(const std::vector<StageLine>& stages) {
  int last_finished = 0;
  for (std::size_t i = 0; i < stages.size(); ++i) {
    if (stages[i].status == StageLine::Status::Running) return static_cast<int>(i);
    if (stages[i].status != StageLine::Status::Pending) last_finished = static_cast<int>(i);
  }
  return last_finished;
}

constexpr double kMarkColumnEm = 1.5;
constexpr double kSecondsColumnEm = 5.0;
constexpr double kNameShare = 0.45;  // of what remains after the mark and seconds columns

void draw_stage_row(Canvas& canvas, Rect row, const StageLine& stage, const Metrics& m) {
  const StageMark mark = stage_mark(stage.status);
  draw_text_in(canvas, take_left(row, static_cast<int>(kMarkColumnEm * m.body_px)), mark.glyph,
               {m.body_px, mark.colour, FontWeight::Bold});
  const bool timed = stage.status != StageLine::Status::Pending &&
                     stage.status != StageLine::Status::Skipped;
  draw_text_in(canvas, take_right(row, static_cast<int>(kSecondsColumnEm * m.body_px)),
               timed ? format_seconds(stage.seconds) : std::string(), {m.body_px, colours::kText},
               Align::Right);
  const Rgb name_colour =
      stage.status == StageLine::Status::Pending ? colours::kDimText : colours::kText;
  draw_text_in(canvas, take_left(row, static_cast<int>(row.width * kNameShare)), stage.name,
               {m.body_px, name_colour});
  const Rgb detail_colour =
      stage.status == StageLine::Status::Failed ? colours::kFault : colours::kDimText;
  draw_text_in(canvas, take_right(row, row.width - m.gap), stage.detail,
               {m.small_px, detail_colour});
}

void draw_analysing(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no photo", c.m);
  dim_rect(c.canvas, image, kDimmedPhoto);
  const int row_h = row_height(c.m);
  const int stage_count = static_cast<int>(std::min<std::size_t>(c.view.stages.size(), 1 << 20));
  const int max_rows = std::max(0, (c.main.height - 4 * c.m.pad) / std::max(1, row_h) - 1);
  const int rows = std::min(std::max(stage_count, 1), max_rows);
  Rect panel = centred(c.main, panel_width(c.main, c.m), (rows + 1) * row_h + 2 * c.m.pad);
  draw_panel(c.canvas, panel, colours::kTrack);
  Rect inner = inset(panel, c.m.pad, c.m.pad);
  if (stage_count == 0) {
    draw_text_in(c.canvas, take_top(inner, row_h), "analysing…", {c.m.body_px, colours::kText});
  }
  const int first = first_visible_row(stage_count, rows, focus_stage(c.view.stages));
  for (int i = first; i < std::min(stage_count, first + rows); ++i) {
    draw_stage_row(c.canvas, take_top(inner, row_h), c.view.stages[static_cast<std::size_t>(i)],
                   c.m);
  }
  const std::string elapsed = format_seconds(c.view.elapsed_seconds);
  if (!elapsed.empty()) {
    draw_text_in(c.canvas, take_bottom(inner, row_h), "total " + elapsed,
                 {c.m.body_px, colours::kDimText}, Align::Right);
  }
}

// Carousel ------------------------------------------------------------------

constexpr double kLargeCardWidthShare = 0.42;  // of the main area
constexpr double kNeighbourScale = 0.5;        // of the large thumbnail
constexpr int kMaxNeighboursPerSide = 2;
constexpr int kSelectionBorder = 2;

void draw_usb_badge(Canvas& canvas, const Rect& thumbnail, int px, const Metrics& m) {
  const TextStyle style{px, colours::kBackground, FontWeight::Bold};
  const int width = width_of("USB", style) + 2 * m.gap;
  const Rect badge{thumbnail.right() - width - m.gap, thumbnail.y + m.gap, width,
                   line_height(px) + m.gap};
  if (badge.x < thumbnail.x || badge.bottom() > thumbnail.bottom()) return;  // no room
  canvas.fill_rect(badge, colours::kUsbBadge);
  draw_text_in(canvas, badge, "USB", style, Align::Centre);
}

// A prop's thumbnail fitted into `box` (dark box behind, placeholder when empty).
void draw_thumbnail(Canvas& canvas, const Rect& box, const PropCard& prop, int badge_px,
                    const Metrics& m) {
  canvas.fill_rect(box, colours::kPlaceholder);
  if (const std::optional<cv::Mat> thumbnail = drawable_image(prop.thumbnail)) {
    blit_fitted(canvas, *thumbnail, image_area(box, size_of(*thumbnail)));
  } else {
    draw_text_in(canvas, inset(box, m.gap, 0), "no preview", {m.small_px, colours::kDimText},
                 Align::Centre);
  }
  if (prop.from_usb) draw_usb_badge(canvas, box, badge_px, m);
}

// How many neighbours to show on each side so that no prop appears twice
// (the carousel wraps around: NEXT after the last one is the first).
int neighbours_right(std::size_t count) { return static_cast<int>(count / 2); }
int neighbours_left(std::size_t count) {
  return count == 0 ? 0 : static_cast<int>((count - 1) / 2);
}

std::size_t wrapped(long long index, std::size_t count) {
  const long long n = static_cast<long long>(count);
  return static_cast<std::size_t>(((index % n) + n) % n);
}

// The selected prop's name (may be a little wider than its thumbnail) and material.
void draw_prop_caption(const ScreenContext& c, const PropCard& prop, const Rect& area,
                       Rect name_row, Rect material_row, int thumbnail_side) {
  const int width = std::min(area.width, thumbnail_side + thumbnail_side / 2);
  const int x = area.x + (area.width - width) / 2;
  name_row = {x, name_row.y, width, name_row.height};
  material_row = {x, material_row.y, width, material_row.height};
  draw_text_in(c.canvas, name_row, prop.name, {c.m.title_px, colours::kText, FontWeight::Bold},
               Align::Centre);
  draw_text_in(c.canvas, material_row, prop.material, {c.m.small_px, colours::kDimText},
               Align::Centre);
}

// The props before and after the selected one, small, as far as whole cards fit.
void draw_neighbours(const ScreenContext& c, std::size_t selected, const Rect& large,
                     const Rect& area) {
  const std::vector<PropCard>& props = c.view.props;
  const int side = static_cast<int>(large.width * kNeighbourScale);
  const int spacing = side + 2 * c.m.pad;
  const int y = large.y + (large.height - side) / 2;
  const auto draw_neighbour = [&](int x, long long index) {
    const Rect box{x, y, side, side};
    if (box.empty() || box.x < area.x || box.right() > area.right()) return;
    draw_thumbnail(c.canvas, box, props[wrapped(index, props.size())], c.m.small_px, c.m);
  };
  const long long centre = static_cast<long long>(selected);
  for (int d = 1; d <= std::min(kMaxNeighboursPerSide, neighbours_right(props.size())); ++d) {
    draw_neighbour(large.right() + 2 * c.m.pad + (d - 1) * spacing, centre + d);
  }
  for (int d = 1; d <= std::min(kMaxNeighboursPerSide, neighbours_left(props.size())); ++d) {
    draw_neighbour(large.x - d * spacing, centre - d);
  }
}

void draw_carousel(const ScreenContext& c) {
  const std::vector<PropCard>& props = c.view.props;
  Rect area = inset(c.main, c.m.pad, c.m.pad);
  if (props.empty()) {
    draw_text_in(c.canvas, area, "no props", {c.m.body_px, colours::kDimText}, Align::Centre);
    return;
  }
  const std::size_t selected = valid_index(c.view.selected_prop, props.size())
                                   ? static_cast<std::size_t>(c.view.selected_prop)
                                   : 0;
  draw_text_in(c.canvas, take_top(area, line_height(c.m.small_px)),
               std::to_string(selected + 1) + " / " + std::to_string(props.size()),
               {c.m.small_px, colours::kDimText}, Align::Right);
  const Rect material_row = take_bottom(area, line_height(c.m.small_px));
  const Rect name_row = take_bottom(area, line_height(c.m.title_px) + c.m.gap);
  const int side = std::min(static_cast<int>(c.main.width * kLargeCardWidthShare), area.height);
  const Rect large = centred(area, side, side);
  draw_thumbnail(c.canvas, large, props[selected], c.m.small_px, c.m);
  c.canvas.stroke_rect(inset(large, -kSelectionBorder, -kSelectionBorder), colours::kAccent,
                       kSelectionBorder);
  draw_prop_caption(c, props[selected], area, name_row, material_row, side);
  draw_neighbours(c, selected, large, area);
}

// Placement -----------------------------------------------------------------

constexpr double kSpotRadiusEm = 0.22;
constexpr double kCursorArmEm = 1.1;
constexpr double kFootprintLineEm = 0.15;

// A white dot with a half-pixel dark rim, visible on light and dark photos.
void draw_spot(cv::Mat& pixels, const cv::Point2d& at, int radius) {
  constexpr int kRim = static_cast<int>(kSubpixelScale) / 2;
  cv::circle(pixels, subpixel(at), radius * static_cast<int>(kSubpixelScale) + kRim,
             cv::Scalar(0, 0, 0), cv::FILLED, cv::LINE_AA, kSubpixelBits);
  cv::circle(pixels, subpixel(at), radius * static_cast<int>(kSubpixelScale),
             to_scalar(colours::kSpot), cv::FILLED, cv::LINE_AA, kSubpixelBits);
}

// A crosshair with a gap in the middle, so the spot under it stays visible.
void draw_cursor(cv::Mat& pixels, const cv::Point2d& at, int arm, int gap, int thickness) {
  const cv::Scalar colour = to_scalar(colours::kCursor);
  const cv::Point2d directions[] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  for (const cv::Point2d& d : directions) {
    cv::line(pixels, subpixel(at + d * gap), subpixel(at + d * arm), colour, thickness, cv::LINE_AA,
             kSubpixelBits);
  }
  cv::circle(pixels, subpixel(at), gap * static_cast<int>(kSubpixelScale), colour, thickness,
             cv::LINE_AA, kSubpixelBits);
}

void draw_footprint(cv::Mat& pixels, const ImageMapping& mapping,
                    const std::vector<cv::Point2d>& footprint, int thickness) {
  std::vector<cv::Point> polygon;
  for (const cv::Point2d& p : footprint) {
    if (finite_point(p)) polygon.push_back(subpixel(mapping.local_point(p)));
  }
  if (polygon.size() < 2) return;
  cv::polylines(pixels, polygon, true, to_scalar(colours::kFootprint), thickness, cv::LINE_AA,
                kSubpixelBits);
}

void draw_placement(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no photo", c.m);
  const Rect visible = intersect(image, c.canvas.bounds());
  if (!visible.empty() && visible == image) {
    // Marks are drawn into the picture's own pixels, so none can leave it.
    cv::Mat pixels = c.canvas.pixels()(to_cv(image));
    const ImageMapping mapping(image, size_of(c.view.image));
    const double em = c.m.body_px;
    draw_footprint(pixels, mapping, c.view.footprint,
                   std::max(1, static_cast<int>(std::lround(kFootprintLineEm * em))));
    const int radius = std::max(2, static_cast<int>(std::lround(kSpotRadiusEm * em)));
    for (const cv::Point2d& spot : c.view.spots) {
      if (finite_point(spot)) draw_spot(pixels, mapping.local_point(spot), radius);
    }
    if (valid_index(c.view.selected_spot, c.view.spots.size())) {
      const cv::Point2d& spot = c.view.spots[static_cast<std::size_t>(c.view.selected_spot)];
      if (finite_point(spot)) {
        draw_cursor(pixels, mapping.local_point(spot),
                    static_cast<int>(kCursorArmEm * em), 2 * radius, std::max(1, radius / 2));
      }
    }
  }
  const Rect frame = image.empty() ? c.picture : image;
  draw_caption(c.canvas, frame, c.view.placement_text, Edge::Bottom, c.m);
  draw_caption(c.canvas, frame, c.view.image_caption,
               c.view.placement_text.empty() ? Edge::Bottom : Edge::Top, c.m);
}

// TierPick ------------------------------------------------------------------

// Column widths fit the widest entry shown, up to these shares of the row.
constexpr double kMaxTimeColumnShare = 0.4;
constexpr double kMaxSppColumnShare = 0.25;

std::string tier_time_text(const TierChoice& tier) {
  const std::string predicted =
      tier.predicted_seconds > 0 ? format_predicted(tier.predicted_seconds) : std::string();
  return predicted.empty() ? "time unknown" : predicted;
}

std::string tier_spp_text(const TierChoice& tier) {
  return tier.samples_per_pixel > 0 ? std::to_string(tier.samples_per_pixel) + " spp" : "";
}

struct TierColumns {
  int time = 0;
  int spp = 0;
};

// The widest entry of `column` among `rows`, plus a gap, capped to `limit`.
template <typename Items, typename Text>
int column_width(const Items& rows, Text column, const TextStyle& style, int gap, int limit) {
  int widest = 0;
  for (const auto& row : rows) {
    widest = std::max(widest, width_of(elide(column(row), style, limit), style) + gap);
  }
  return std::min(widest, limit);
}

void draw_tier_row(Canvas& canvas, Rect row, const TierChoice& tier, bool selected,
                   const TierColumns& columns, const Metrics& m) {
  if (selected) canvas.fill_rect(row, colours::kHighlight);
  row = inset(row, m.pad, 0);
  const Rgb colour = selected ? colours::kText : colours::kDimText;
  draw_text_in(canvas, take_left(row, static_cast<int>(kMarkColumnEm * m.body_px)),
               selected ? "▶" : "", {m.body_px, colours::kText, FontWeight::Bold});
  draw_text_in(canvas, take_right(row, columns.spp), tier_spp_text(tier), {m.small_px, colour},
               Align::Right);
  draw_text_in(canvas, take_right(row, columns.time), tier_time_text(tier),
               {m.body_px, colours::kText}, Align::Right);
  draw_text_in(canvas, row, tier.name, {m.body_px, colours::kText, FontWeight::Bold});
}

void draw_tier_pick(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no photo", c.m);
  dim_rect(c.canvas, image, kDimmedPhoto);
  const int row_h = row_height(c.m) + 2 * c.m.gap;
  const int count = static_cast<int>(std::min<std::size_t>(c.view.tiers.size(), 1 << 20));
  const int max_rows = std::max(0, (c.main.height - 4 * c.m.pad) / std::max(1, row_h));
  const int rows = std::min(std::max(count, 1), max_rows);
  const Rect panel = centred(c.main, panel_width(c.main, c.m), rows * row_h + 2 * c.m.pad);
  draw_panel(c.canvas, panel, colours::kTrack);
  Rect inner = inset(panel, c.m.pad, c.m.pad);
  if (count == 0) {
    draw_text_in(c.canvas, inner, "no render tiers", {c.m.body_px, colours::kDimText},
                 Align::Centre);
    return;
  }
  const bool has_selection = valid_index(c.view.selected_tier, c.view.tiers.size());
  const int first = first_visible_row(count, rows, has_selection ? c.view.selected_tier : 0);
  const int last = std::min(count, first + rows);
  const std::vector<TierChoice> shown(c.view.tiers.begin() + first, c.view.tiers.begin() + last);
  const int row_width = inner.width - 2 * c.m.pad;
  const TierColumns columns{
      column_width(shown, tier_time_text, {c.m.body_px}, 2 * c.m.pad,
                   static_cast<int>(row_width * kMaxTimeColumnShare)),
      column_width(shown, tier_spp_text, {c.m.small_px}, c.m.pad,
                   static_cast<int>(row_width * kMaxSppColumnShare))};
  for (int i = first; i < last; ++i) {
    draw_tier_row(c.canvas, take_top(inner, row_h), c.view.tiers[static_cast<std::size_t>(i)],
                  has_selection && i == c.view.selected_tier, columns, c.m);
  }
}

// Rendering -----------------------------------------------------------------

constexpr int kTileOutlineMinSideForThick = 24;  // screen pixels

void draw_tile_overlay(Canvas& canvas, const Rect& image, Size image_size,
                       const std::vector<TileView>& tiles) {
  const ImageMapping mapping(image, image_size);
  for (const TileView& tile : tiles) {
    // Culled tiles stay untouched (they are the photo); finished ones need no attention.
    if (!tile.affected || tile.done) continue;
    const Rect screen = mapping.rect(tile.rect);
    if (screen.empty()) continue;
    const int thickness =
        std::min(screen.width, screen.height) >= kTileOutlineMinSideForThick ? 2 : 1;
    canvas.stroke_rect(screen, tile_error_colour(tile.relative_error), thickness);
  }
}

// The figures below the progress bar, in the order a user looks for them.
std::vector<std::string> rendering_figures(const ScreenView& view) {
  std::vector<std::string> figures;
  if (const std::string elapsed = format_seconds(view.elapsed_seconds); !elapsed.empty()) {
    figures.push_back(elapsed);
  }
  if (const std::string good = format_predicted(view.predicted_seconds_to_good); !good.empty()) {
    figures.push_back("good in " + good);
  }
  if (const std::string done = format_predicted(view.predicted_seconds_to_done); !done.empty()) {
    figures.push_back("done in " + done);
  }
  if (view.samples_per_pixel > 0) {
    figures.push_back(std::to_string(view.samples_per_pixel) + " spp");
  }
  if (view.skipped_tiles > 0) {
    figures.push_back(count_text(view.skipped_tiles, "tile skipped", "tiles skipped"));
  }
  std::string effects;
  for (const std::string& effect : view.skipped_effects) {
    if (effect.empty()) continue;
    if (!effects.empty()) effects += ", ";
    effects += effect;
    if (effects.size() > 1024) break;  // more could not be shown anyway
  }
  if (!effects.empty()) figures.push_back(effects);
  return figures;
}

constexpr std::string_view kFigureSeparator = "  ·  ";

// Flows `figures` into at most `rows` lines of `width`; the last line takes the rest (elided).
std::vector<std::string> flow_figures(const std::vector<std::string>& figures, int rows, int width,
                                      const TextStyle& style) {
  std::vector<std::string> lines;
  std::string line;
  for (const std::string& figure : figures) {
    const std::string candidate =
        line.empty() ? figure : line + std::string(kFigureSeparator) + figure;
    const bool last_row = static_cast<int>(lines.size()) + 1 >= rows;
    if (line.empty() || last_row || width_of(elide(candidate, style, 1 << 14), style) <= width) {
      line = candidate;
    } else {
      lines.push_back(line);
      line = figure;
    }
    if (line.size() > 4096) break;  // a huge figure: the rest would be elided anyway
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

// Below the composite: the progress bar, then the converged share and the figures.
void draw_rendering_strip(const ScreenContext& c, Rect strip) {
  take_top(strip, c.m.gap);
  const double fraction = std::isnan(c.view.converged_fraction)
                              ? 0.0
                              : std::clamp(c.view.converged_fraction, 0.0, 1.0);
  draw_progress_bar(c.canvas, take_top(strip, progress_bar_height(c.m)), fraction);
  const TextStyle small{c.m.small_px, colours::kText};
  const int text_h = line_height(c.m.small_px) + c.m.gap;
  Rect first_row = take_top(strip, text_h);
  // Right-aligned under the bar's end, where the eye lands after following the bar.
  const Rect percent_box = take_right(first_row, width_of("100 % converged", small) + c.m.pad);
  draw_text_in(c.canvas, percent_box,
               printf_string("%.0f %% converged", std::floor(fraction * 100.0)), small,
               Align::Right);
  const std::vector<std::string> lines = flow_figures(
      rendering_figures(c.view), info_rows(c.main, c.m), first_row.width, small);
  if (!lines.empty()) draw_text_in(c.canvas, first_row, lines[0], small);
  for (std::size_t i = 1; i < lines.size(); ++i) {
    draw_text_in(c.canvas, take_top(strip, text_h), lines[i], {c.m.small_px, colours::kDimText});
  }
}

void draw_rendering(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no composite yet", c.m);
  if (!image.empty()) draw_tile_overlay(c.canvas, image, size_of(c.view.image), c.view.tiles);
  draw_caption(c.canvas, image.empty() ? c.picture : image, c.view.image_caption, Edge::Bottom,
               c.m);
  const Rect below{c.main.x, c.picture.bottom(), c.main.width,
                   c.main.bottom() - c.picture.bottom()};
  draw_rendering_strip(c, inset(below, c.m.pad, 0));
}

// Adjusting -----------------------------------------------------------------

constexpr double kMaxSliderNameShare = 0.35;
constexpr double kMaxSliderValueShare = 0.3;
constexpr double kTrackEm = 0.2;
constexpr double kKnobEm = 0.45;

// Where `value` sits on [low, high] as a fraction; the middle when the range is empty.
double fraction_of_range(double value, double low, double high) {
  if (!(high > low)) return 0.5;
  return std::clamp((value - low) / (high - low), 0.0, 1.0);
}

void draw_slider_track(Canvas& canvas, const Rect& area, const SliderView& slider, bool selected,
                       const Metrics& m) {
  const int track_h = std::max(2, static_cast<int>(std::lround(kTrackEm * m.body_px)));
  const Rect track{area.x, area.y + (area.height - track_h) / 2, area.width, track_h};
  canvas.fill_rect(track, colours::kTrack);
  // Filled from zero when the range spans it (bipolar: relight EV), else from the minimum.
  const double zero =
      slider.min < 0 && slider.max > 0 ? fraction_of_range(0, slider.min, slider.max) : 0.0;
  const double position = fraction_of_range(slider.value, slider.min, slider.max);
  const int from = track.x + static_cast<int>(std::lround(std::min(zero, position) * track.width));
  const int to = track.x + static_cast<int>(std::lround(std::max(zero, position) * track.width));
  canvas.fill_rect({from, track.y, to - from, track.height}, colours::kAccent);
  const int knob = std::max(3, static_cast<int>(std::lround(kKnobEm * m.body_px)));
  const int knob_x = track.x + static_cast<int>(std::lround(position * track.width)) - knob / 2;
  canvas.fill_rect(intersect({knob_x, area.y + (area.height - 2 * knob) / 2, knob, 2 * knob}, area),
                   selected ? colours::kText : colours::kDimText);
}

std::string slider_value_text(const SliderView& slider) {
  return slider.value_text.empty() ? std::to_string(slider.value) : slider.value_text;
}
std::string slider_name(const SliderView& slider) { return slider.name; }

struct SliderColumns {
  int name = 0;
  int value = 0;
};

void draw_slider_row(Canvas& canvas, Rect row, const SliderView& slider, bool selected,
                     const SliderColumns& columns, const Metrics& m) {
  if (selected) canvas.fill_rect(row, colours::kHighlight);
  row = inset(row, m.pad, 0);
  const Rgb colour = selected ? colours::kText : colours::kDimText;
  draw_text_in(canvas, take_left(row, columns.name), slider.name,
               {m.body_px, colour, selected ? FontWeight::Bold : FontWeight::Regular});
  draw_text_in(canvas, take_right(row, columns.value), slider_value_text(slider),
               {m.body_px, colour}, Align::Right);
  draw_slider_track(canvas, inset(row, m.pad, 0), slider, selected, m);
}

void draw_adjusting(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no composite yet", c.m);
  draw_caption(c.canvas, image.empty() ? c.picture : image, c.view.image_caption, Edge::Bottom,
               c.m);
  const int rows = slider_rows(c.main, c.view, c.m);
  if (rows <= 0) return;
  Rect strip{c.main.x, c.picture.bottom(), c.main.width, c.main.bottom() - c.picture.bottom()};
  const int count = static_cast<int>(std::min<std::size_t>(c.view.sliders.size(), 1 << 20));
  const bool has_selection = valid_index(c.view.selected_slider, c.view.sliders.size());
  const int first = first_visible_row(count, rows, has_selection ? c.view.selected_slider : 0);
  const int last = std::min(count, first + rows);
  const std::vector<SliderView> shown(c.view.sliders.begin() + first,
                                      c.view.sliders.begin() + last);
  const int row_width = strip.width - 2 * c.m.pad;
  // Bold for the selected name, so the column fits either weight.
  const SliderColumns columns{
      column_width(shown, slider_name, {c.m.body_px, colours::kText, FontWeight::Bold},
                   2 * c.m.pad, static_cast<int>(row_width * kMaxSliderNameShare)),
      column_width(shown, slider_value_text, {c.m.body_px}, 2 * c.m.pad,
                   static_cast<int>(row_width * kMaxSliderValueShare))};
  for (int i = first; i < last; ++i) {
    draw_slider_row(c.canvas, take_top(strip, row_height(c.m)),
                    c.view.sliders[static_cast<std::size_t>(i)],
                    has_selection && i == c.view.selected_slider, columns, c.m);
  }
}

// Exporting -----------------------------------------------------------------

constexpr int kSpinnerDots = 8;
constexpr double kSpinnerTurnsPerSecond = 1.0;
constexpr double kSpinnerTailFade = 0.8;
constexpr int kExportTextLines = 3;

// Eight dots in a ring, the brightest one going round with the elapsed time,
// so each redraw during an export moves it on (and the same view draws the same).
void draw_spinner(Canvas& canvas, const Rect& box, double elapsed_seconds) {
  const Rect visible = intersect(box, canvas.bounds());
  if (visible.empty() || visible != box) return;
  cv::Mat pixels = canvas.pixels()(to_cv(box));
  const double radius = std::min(box.width, box.height) * 0.35;
  const int dot = std::max(1, static_cast<int>(std::lround(radius * 0.25)));
  const double turns = finite_non_negative(elapsed_seconds)
                           ? std::fmod(elapsed_seconds * kSpinnerTurnsPerSecond, 1.0)
                           : 0.0;
  const int head = static_cast<int>(turns * kSpinnerDots) % kSpinnerDots;
  const cv::Point2d centre((box.width - 1) / 2.0, (box.height - 1) / 2.0);
  for (int i = 0; i < kSpinnerDots; ++i) {
    const double angle = 2.0 * CV_PI * i / kSpinnerDots - CV_PI / 2;
    const cv::Point2d at = centre + cv::Point2d(std::cos(angle), std::sin(angle)) * radius;
    const int age = (head - i + kSpinnerDots) % kSpinnerDots;
    const Rgb colour = mix(colours::kAccent, colours::kTrack,
                           kSpinnerTailFade * age / (kSpinnerDots - 1));
    cv::circle(pixels, subpixel(at), dot * static_cast<int>(kSubpixelScale), to_scalar(colour),
               cv::FILLED, cv::LINE_AA, kSubpixelBits);
  }
}

void draw_exporting(const ScreenContext& c) {
  draw_picture(c.canvas, c.picture, c.view.image, "no composite yet", c.m);
  const std::optional<bool>& result = c.view.export_succeeded;
  const Rgb accent = !result ? colours::kAccent : (*result ? colours::kGood : colours::kFault);
  const int line_h = line_height(c.m.body_px);
  const int mark_side = line_height(c.m.large_px);
  const int text_h = std::max(mark_side, kExportTextLines * line_h);
  Rect panel = centred(c.main, panel_width(c.main, c.m), text_h + line_h + 3 * c.m.pad);
  draw_panel(c.canvas, panel, accent);
  Rect inner = inset(panel, c.m.pad, c.m.pad);
  Rect mark = take_left(inner, mark_side);
  mark.height = std::min(mark.height, mark_side);
  if (result) {
    draw_text_in(c.canvas, mark, *result ? "✔" : "✖", {c.m.large_px, accent, FontWeight::Bold},
                 Align::Centre);
  } else {
    draw_spinner(c.canvas, mark, c.view.elapsed_seconds);
  }
  take_left(inner, c.m.pad);
  const std::string fallback = !result ? "exporting…" : (*result ? "exported" : "export failed");
  const std::string_view text = c.view.export_text.empty() ? fallback : c.view.export_text;
  const std::string elapsed = format_seconds(c.view.elapsed_seconds);
  const Rect elapsed_row = take_bottom(inner, line_h);
  if (!elapsed.empty()) {
    draw_text_in(c.canvas, elapsed_row, elapsed, {c.m.small_px, colours::kDimText}, Align::Right);
  }
  const TextStyle style{c.m.body_px, colours::kText};
  for (const std::string& line : wrap_lines(text, style, inner.width, kExportTextLines)) {
    draw_text_in(c.canvas, take_top(inner, line_h), line, style);
  }
}

// Fault ---------------------------------------------------------------------

constexpr double kFaultStripeEm = 0.35;

void draw_fault(const ScreenContext& c) {
  const Rect panel = inset(c.main, c.m.pad, c.m.pad);
  c.canvas.fill_rect(panel, colours::kFaultPanel);
  c.canvas.stroke_rect(panel, colours::kFault, 1);
  Rect inner = panel;
  c.canvas.fill_rect(take_left(inner, std::max(3, static_cast<int>(kFaultStripeEm * c.m.body_px))),
                     colours::kFault);
  inner = inset(inner, c.m.pad, c.m.pad);
  const int sign_side = line_height(c.m.large_px);
  Rect sign = take_left(inner, sign_side);
  sign.height = std::min(sign.height, sign_side);
  draw_text_in(c.canvas, sign, "⚠", {c.m.large_px, colours::kFault, FontWeight::Bold},
               Align::Centre);
  take_left(inner, c.m.pad);
  // A little larger than body text: this is the one thing to read here.
  const TextStyle style{c.m.title_px, colours::kText};
  const int line_h = line_height(c.m.title_px) + c.m.gap;
  const std::string_view message =
      c.view.fault_message.empty() ? std::string_view("unknown fault") : c.view.fault_message;
  for (const std::string& line : wrap_lines(message, style, inner.width, inner.height / line_h)) {
    draw_text_in(c.canvas, take_top(inner, line_h), line, style);
  }
}

void draw_main(const ScreenContext& c) {
  switch (c.view.kind) {
    case ScreenKind::Viewfinder: draw_viewfinder(c); return;
    case ScreenKind::Captured: draw_captured(c); return;
    case ScreenKind::Analysing: draw_analysing(c); return;
    case ScreenKind::Carousel: draw_carousel(c); return;
    case ScreenKind::Placement: draw_placement(c); return;
    case ScreenKind::TierPick: draw_tier_pick(c); return;
    case ScreenKind::Rendering: draw_rendering(c); return;
    case ScreenKind::Adjusting: draw_adjusting(c); return;
    case ScreenKind::Exporting: draw_exporting(c); return;
    case ScreenKind::Fault: draw_fault(c); return;
  }
  draw_viewfinder(c);  // an unknown kind still shows the picture
}

}  // namespace

ScreenLayout screen_layout(Size canvas) {
  const int width = std::max(0, canvas.width);
  const int height = std::max(0, canvas.height);
  const Metrics m = metrics_for({width, height});
  int title = line_height(m.title_px) + 2 * m.gap;
  int hint = line_height(m.body_px) + 2 * m.gap;
  // On tiny canvases the bars give way so the main area keeps half the height.
  const int bars_limit = static_cast<int>(height * kMaxBarsFraction);
  if (title + hint > bars_limit) {
    const double shrink = static_cast<double>(bars_limit) / (title + hint);
    title = static_cast<int>(title * shrink);
    hint = static_cast<int>(hint * shrink);
  }
  ScreenLayout layout;
  layout.title_bar = {0, 0, width, title};
  layout.hint_bar = {0, height - hint, width, hint};
  layout.main = {0, title, width, height - title - hint};
  return layout;
}

Rect image_area(const Rect& area, Size image) {
  if (area.empty() || image.width <= 0 || image.height <= 0) return {};
  // The same fit as Canvas::blit_scaled(keep_aspect = true).
  const double scale = std::min(static_cast<double>(area.width) / image.width,
                                static_cast<double>(area.height) / image.height);
  Rect target;
  target.width = std::clamp(static_cast<int>(std::lround(image.width * scale)), 1, area.width);
  target.height = std::clamp(static_cast<int>(std::lround(image.height * scale)), 1, area.height);
  target.x = area.x + (area.width - target.width) / 2;
  target.y = area.y + (area.height - target.height) / 2;
  return target;
}

Rect screen_image_area(Size canvas, const ScreenView& view) {
  const std::optional<cv::Mat> drawable = drawable_image(view.image);
  if (!drawable || view.kind == ScreenKind::Carousel || view.kind == ScreenKind::Fault) return {};
  const ScreenLayout layout = screen_layout(canvas);
  return image_area(picture_region(layout, view, metrics_for(canvas)), size_of(*drawable));
}

Rgb tile_error_colour(double relative_error) {
  constexpr Rgb kLow{60, 220, 80};
  constexpr Rgb kMiddle{250, 210, 40};
  constexpr Rgb kHigh{240, 60, 40};
  double t = 1.0;  // NaN: no estimate yet, as bad as it gets
  if (!std::isnan(relative_error)) {
    t = relative_error <= kTileErrorLow
            ? 0.0
            : std::clamp(std::log(relative_error / kTileErrorLow) /
                             std::log(kTileErrorHigh / kTileErrorLow),
                         0.0, 1.0);
  }
  return t < 0.5 ? mix(kLow, kMiddle, 2.0 * t) : mix(kMiddle, kHigh, 2.0 * t - 1.0);
}

void draw_screen(Canvas& canvas, const ScreenView& view) {
  const Metrics m = metrics_for(canvas.size());
  const ScreenLayout layout = screen_layout(canvas.size());
  canvas.fill(colours::kBackground);
  const ScreenContext context{canvas, view, m, layout.main, picture_region(layout, view, m)};
  draw_main(context);
  draw_title_bar(canvas, layout.title_bar, view, m);
  draw_hint_bar(canvas, layout.hint_bar, view.hints, m);
}

}  // namespace propcam::ui_fb
