// Internal to ui_fb: one draw function per ScreenKind, each in its own file
// (viewfinder and captured share one), called by draw_screen for the main area.
#pragma once

#include "screen_drawing.h"

namespace propcam::ui_fb::detail {

void draw_viewfinder(const ScreenContext& c);
void draw_captured(const ScreenContext& c);
void draw_analysing(const ScreenContext& c);
void draw_carousel(const ScreenContext& c);
void draw_placement(const ScreenContext& c);
void draw_tier_pick(const ScreenContext& c);
void draw_rendering(const ScreenContext& c);
void draw_adjusting(const ScreenContext& c);
void draw_exporting(const ScreenContext& c);
void draw_fault(const ScreenContext& c);

}  // namespace propcam::ui_fb::detail
