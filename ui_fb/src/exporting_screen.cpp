// Exporting: a panel over the composite with a spinner while the export
// runs, then ✔ or ✖, and what happened.
#include "screen_kinds.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace propcam::ui_fb::detail {
namespace {

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

}  // namespace

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

}  // namespace propcam::ui_fb::detail
