// Internal to ui_fb: regions of the main area that depend on the screen,
// shared by the screens that draw them and screen_image_area, which must
// agree with them on where the picture goes.
#pragma once

#include "screen_drawing.h"

namespace propcam::ui_fb::detail {

// A list row: a line of body text and its gaps.
int row_height(const Metrics& m);

// Rendering: the progress bar and up to two rows of figures below the picture.
int info_rows(const Rect& main, const Metrics& m);
int progress_bar_height(const Metrics& m);
int rendering_strip_height(const Rect& main, const Metrics& m);

// Adjusting: a row per slider below the picture, as many as fit.
int slider_rows(const Rect& main, const ScreenView& view, const Metrics& m);

// Where the screen's picture goes.
Rect picture_region(const ScreenLayout& layout, const ScreenView& view, const Metrics& m);

}  // namespace propcam::ui_fb::detail
