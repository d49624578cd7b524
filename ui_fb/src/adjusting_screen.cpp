// Adjusting: the composite above a row per slider (name, track, value), the
// selected one highlighted.
#include "screen_kinds.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "screen_regions.h"

namespace propcam::ui_fb::detail {
namespace {

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

}  // namespace

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

}  // namespace propcam::ui_fb::detail
