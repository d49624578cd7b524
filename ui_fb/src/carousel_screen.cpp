// Carousel: the selected prop large in the middle, its neighbours small on
// either side, its name and material below.
#include "screen_kinds.h"

#include <algorithm>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace propcam::ui_fb::detail {
namespace {

constexpr double kLargeCardWidthShare = 0.42;  // of the main area
constexpr double kNeighbourScale = 0.5;        // of the large thumbnail
constexpr int kMaxNeighboursPerSide = 2;
constexpr int kSelectionBorder = 2;

void draw_usb_badge(Canvas& canvas, const Rect& thumbnail, int px, const Metrics& m) {
  const TextStyle style{px, colours::kBackground, FontWeight::Bold};
  const int width = width_of("USB", style) + 2 * m.gap;
  const Rect badge{thumbnail.right() - width - m.gap, thumbnail.y + m.gap, width,
                   line_height(px) + m.gap};
  if (badge.x < thumbnail.x || badge.bottom() > thumbnail.bottom()) return;  // no room
  canvas.fill_rect(badge, colours::kUsbBadge);
  draw_text_in(canvas, badge, "USB", style, Align::Centre);
}

// A prop's thumbnail fitted into `box` (dark box behind, placeholder when empty).
void draw_thumbnail(Canvas& canvas, const Rect& box, const PropCard& prop, int badge_px,
                    const Metrics& m) {
  canvas.fill_rect(box, colours::kPlaceholder);
  if (const std::optional<cv::Mat> thumbnail = drawable_image(prop.thumbnail)) {
    blit_fitted(canvas, *thumbnail, image_area(box, size_of(*thumbnail)));
  } else {
    draw_text_in(canvas, inset(box, m.gap, 0), "no preview", {m.small_px, colours::kDimText},
                 Align::Centre);
  }
  if (prop.from_usb) draw_usb_badge(canvas, box, badge_px, m);
}

// How many neighbours to show on each side so that no prop appears twice
// (the carousel wraps around: NEXT after the last one is the first).
int neighbours_right(std::size_t count) { return static_cast<int>(count / 2); }
int neighbours_left(std::size_t count) {
  return count == 0 ? 0 : static_cast<int>((count - 1) / 2);
}

std::size_t wrapped(long long index, std::size_t count) {
  const long long n = static_cast<long long>(count);
  return static_cast<std::size_t>(((index % n) + n) % n);
}

// The selected prop's name (may be a little wider than its thumbnail) and material.
void draw_prop_caption(const ScreenContext& c, const PropCard& prop, const Rect& area,
                       Rect name_row, Rect material_row, int thumbnail_side) {
  const int width = std::min(area.width, thumbnail_side + thumbnail_side / 2);
  const int x = area.x + (area.width - width) / 2;
  name_row = {x, name_row.y, width, name_row.height};
  material_row = {x, material_row.y, width, material_row.height};
  draw_text_in(c.canvas, name_row, prop.name, {c.m.title_px, colours::kText, FontWeight::Bold},
               Align::Centre);
  draw_text_in(c.canvas, material_row, prop.material, {c.m.small_px, colours::kDimText},
               Align::Centre);
}

// The props before and after the selected one, small, as far as whole cards fit.
void draw_neighbours(const ScreenContext& c, std::size_t selected, const Rect& large,
                     const Rect& area) {
  const std::vector<PropCard>& props = c.view.props;
  const int side = static_cast<int>(large.width * kNeighbourScale);
  const int spacing = side + 2 * c.m.pad;
  const int y = large.y + (large.height - side) / 2;
  const auto draw_neighbour = [&](int x, long long index) {
    const Rect box{x, y, side, side};
    if (box.empty() || box.x < area.x || box.right() > area.right()) return;
    draw_thumbnail(c.canvas, box, props[wrapped(index, props.size())], c.m.small_px, c.m);
  };
  const long long centre = static_cast<long long>(selected);
  for (int d = 1; d <= std::min(kMaxNeighboursPerSide, neighbours_right(props.size())); ++d) {
    draw_neighbour(large.right() + 2 * c.m.pad + (d - 1) * spacing, centre + d);
  }
  for (int d = 1; d <= std::min(kMaxNeighboursPerSide, neighbours_left(props.size())); ++d) {
    draw_neighbour(large.x - d * spacing, centre - d);
  }
}

}  // namespace

void draw_carousel(const ScreenContext& c) {
  const std::vector<PropCard>& props = c.view.props;
  Rect area = inset(c.main, c.m.pad, c.m.pad);
  if (props.empty()) {
    draw_text_in(c.canvas, area, "no props", {c.m.body_px, colours::kDimText}, Align::Centre);
    return;
  }
  const std::size_t selected = valid_index(c.view.selected_prop, props.size())
                                   ? static_cast<std::size_t>(c.view.selected_prop)
                                   : 0;
  draw_text_in(c.canvas, take_top(area, line_height(c.m.small_px)),
               std::to_string(selected + 1) + " / " + std::to_string(props.size()),
               {c.m.small_px, colours::kDimText}, Align::Right);
  const Rect material_row = take_bottom(area, line_height(c.m.small_px));
  const Rect name_row = take_bottom(area, line_height(c.m.title_px) + c.m.gap);
  const int side = std::min(static_cast<int>(c.main.width * kLargeCardWidthShare), area.height);
  const Rect large = centred(area, side, side);
  draw_thumbnail(c.canvas, large, props[selected], c.m.small_px, c.m);
  c.canvas.stroke_rect(inset(large, -kSelectionBorder, -kSelectionBorder), colours::kAccent,
                       kSelectionBorder);
  draw_prop_caption(c, props[selected], area, name_row, material_row, side);
  draw_neighbours(c, selected, large, area);
}

}  // namespace propcam::ui_fb::detail
