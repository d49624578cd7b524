#include "propcam/ui_fb/screens.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "screen_bars.h"
#include "screen_drawing.h"
#include "screen_kinds.h"
#include "screen_regions.h"

namespace propcam::ui_fb {

using namespace detail;

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

// The main area is the screen kind's own; the bars around it are the same on every screen.
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
