// Fault: the whole main area for the one message the user must read.
#include "screen_kinds.h"

#include <algorithm>
#include <string>
#include <string_view>
#include <vector>

namespace propcam::ui_fb::detail {
namespace {

constexpr double kFaultStripeEm = 0.35;

}  // namespace

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

}  // namespace propcam::ui_fb::detail
