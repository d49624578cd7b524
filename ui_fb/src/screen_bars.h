// Internal to ui_fb: the frame every screen has, the title bar on top and
// the hint bar at the bottom naming what each button does here.
#pragma once

#include <vector>

#include "screen_drawing.h"

namespace propcam::ui_fb::detail {

// The view's title, its status on the right; the accent line under it is red on Fault.
void draw_title_bar(Canvas& canvas, const Rect& bar, const ScreenView& view, const Metrics& m);
// Each hint is its key in bold accent ("OK", "hold OK", "▶") and its label.
// When they do not fit: tighter gaps, then the small font, then the longest
// labels are elided; keys are never cut (hints are dropped from the end first).
void draw_hint_bar(Canvas& canvas, const Rect& bar, const std::vector<ButtonHint>& hints,
                   const Metrics& m);

}  // namespace propcam::ui_fb::detail
