// The camera's live picture (Viewfinder) and the moment of capture
// (Captured: the same picture in a flash-coloured border).
#include "screen_kinds.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace propcam::ui_fb::detail {
namespace {

constexpr double kFlashBorderEm = 0.3;

}  // namespace

void draw_viewfinder(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no camera frame", c.m);
  draw_caption(c.canvas, image.empty() ? c.picture : image, c.view.image_caption, Edge::Bottom,
               c.m);
}

void draw_captured(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no camera frame", c.m);
  const Rect frame = image.empty() ? c.picture : image;
  c.canvas.stroke_rect(frame, colours::kFlash,
                       std::max(2, static_cast<int>(std::lround(kFlashBorderEm * c.m.body_px))));
  const std::string caption = c.view.image_caption.empty() ? "capturing…" : c.view.image_caption;
  draw_caption(c.canvas, frame, caption, Edge::Bottom, c.m);
}

}  // namespace propcam::ui_fb::detail
