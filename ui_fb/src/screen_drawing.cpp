#include "screen_drawing.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

namespace propcam::ui_fb::detail {
namespace {

constexpr double kReferenceUnit = 240.0;  // the smallest panel, 320x240
constexpr double kBodyPxAtReference = 13.0;
constexpr double kTitleScale = 1.15;
constexpr double kSmallScale = 0.85;
constexpr double kLargeScale = 2.2;  // ✔ / ✖ and the fault's warning sign
constexpr int kMaxTextPx = 400;
constexpr double kPadEm = 0.45;
constexpr double kGapEm = 0.25;
// DejaVu Sans' ascender and descender in em, rounded up, so line boxes are
// known without FreeType (screen_layout needs no font).
constexpr double kAscenderEm = 0.93;
constexpr double kDescenderEm = 0.24;

int text_px(double body, double scale) {
  return std::clamp(static_cast<int>(std::lround(body * scale)), kMinTextPx, kMaxTextPx);
}

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

std::size_t skip_blanks(std::string_view text, std::size_t pos) {
  while (pos < text.size() && (text[pos] == ' ' || text[pos] == '\t' || text[pos] == '\r')) ++pos;
  return pos;
}

std::size_t word_end(std::string_view text, std::size_t pos, std::size_t limit) {
  while (pos < limit && text[pos] != ' ' && text[pos] != '\t' && text[pos] != '\r') ++pos;
  return pos;
}

constexpr double kSecondsPerMinute = 60.0;
constexpr double kSecondsPerHour = 3600.0;
constexpr double kLongestShownSeconds = 99.0 * kSecondsPerHour;

constexpr double kCaptionOpacity = 0.65;
constexpr double kPanelOpacity = 0.7;
constexpr Rgb kPanelColour{12, 14, 18};
constexpr double kPanelMinWidthEm = 22.0;
constexpr double kPanelWidthFraction = 0.7;

void draw_placeholder(Canvas& canvas, const Rect& area, std::string_view text, const Metrics& m) {
  canvas.fill_rect(area, colours::kPlaceholder);
  draw_text_in(canvas, inset(area, m.pad, 0), text, {m.body_px, colours::kDimText}, Align::Centre);
}

}  // namespace

// Sizes.

int line_height(int px) {
  return static_cast<int>(std::ceil(px * kAscenderEm)) +
         static_cast<int>(std::ceil(px * kDescenderEm));
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

// Geometry.

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

// Text.

int width_of(std::string_view text, const TextStyle& style) {
  return Canvas::text_width(text, style.px, style.weight);
}

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

int draw_text_in(Canvas& canvas, const Rect& box, std::string_view text, const TextStyle& style,
                 Align align) {
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

// Numbers.

std::string printf_string(const char* format, double a, double b) {
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

// Images.

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

cv::Point subpixel(const cv::Point2d& p) {
  return {static_cast<int>(std::lround(p.x * kSubpixelScale)),
          static_cast<int>(std::lround(p.y * kSubpixelScale))};
}

bool finite_point(const cv::Point2d& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

void draw_caption(Canvas& canvas, const Rect& rect, std::string_view text, Edge edge,
                  const Metrics& m) {
  if (text.empty() || rect.empty()) return;
  Rect area = rect;
  const int height = line_height(m.body_px) + 2 * m.gap;
  const Rect strip = edge == Edge::Bottom ? take_bottom(area, height) : take_top(area, height);
  shade_rect(canvas, strip, {0, 0, 0}, kCaptionOpacity);
  draw_text_in(canvas, inset(strip, m.pad, 0), text, {m.body_px, colours::kText}, Align::Centre);
}

void draw_panel(Canvas& canvas, const Rect& panel, Rgb border) {
  shade_rect(canvas, panel, kPanelColour, kPanelOpacity);
  canvas.stroke_rect(panel, border, 1);
}

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

}  // namespace propcam::ui_fb::detail
