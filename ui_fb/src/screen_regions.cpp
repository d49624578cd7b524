#include "screen_regions.h"

#include <algorithm>
#include <cmath>

namespace propcam::ui_fb::detail {
namespace {

// Rendering: the progress bar and up to two rows of figures below the picture.
constexpr double kProgressBarEm = 0.5;
constexpr int kMainLinesForTwoInfoRows = 12;

// Adjusting: a row per slider below the picture, at most this many and this share.
constexpr int kMaxSliderRows = 4;
constexpr double kMaxSliderShare = 0.45;

}  // namespace

int row_height(const Metrics& m) { return line_height(m.body_px) + 2 * m.gap; }

int info_rows(const Rect& main, const Metrics& m) {
  return main.height >= kMainLinesForTwoInfoRows * line_height(m.small_px) ? 2 : 1;
}

int progress_bar_height(const Metrics& m) {
  return std::max(2, static_cast<int>(std::lround(kProgressBarEm * m.body_px)));
}

int rendering_strip_height(const Rect& main, const Metrics& m) {
  return m.gap + progress_bar_height(m) + info_rows(main, m) * (line_height(m.small_px) + m.gap);
}

int slider_rows(const Rect& main, const ScreenView& view, const Metrics& m) {
  const int fitting = static_cast<int>(main.height * kMaxSliderShare) / std::max(1, row_height(m));
  return std::min({static_cast<int>(std::min<std::size_t>(view.sliders.size(), kMaxSliderRows)),
                   fitting});
}

Rect picture_region(const ScreenLayout& layout, const ScreenView& view, const Metrics& m) {
  Rect region = layout.main;
  if (view.kind == ScreenKind::Rendering) {
    take_bottom(region, rendering_strip_height(layout.main, m));
  } else if (view.kind == ScreenKind::Adjusting) {
    take_bottom(region, slider_rows(layout.main, view, m) * row_height(m));
  }
  return region;
}

}  // namespace propcam::ui_fb::detail
