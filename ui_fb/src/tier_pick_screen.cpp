// TierPick: the render tiers over the dimmed photo, each with its predicted
// time and samples per pixel.
#include "screen_kinds.h"

#include <algorithm>
#include <string>
#include <vector>

#include "screen_regions.h"

namespace propcam::ui_fb::detail {
namespace {

// Column widths fit the widest entry shown, up to these shares of the row.
constexpr double kMaxTimeColumnShare = 0.4;
constexpr double kMaxSppColumnShare = 0.25;

std::string tier_time_text(const TierChoice& tier) {
  const std::string predicted =
      tier.predicted_seconds > 0 ? format_predicted(tier.predicted_seconds) : std::string();
  return predicted.empty() ? "time unknown" : predicted;
}

std::string tier_spp_text(const TierChoice& tier) {
  return tier.samples_per_pixel > 0 ? std::to_string(tier.samples_per_pixel) + " spp" : "";
}

struct TierColumns {
  int time = 0;
  int spp = 0;
};

void draw_tier_row(Canvas& canvas, Rect row, const TierChoice& tier, bool selected,
                   const TierColumns& columns, const Metrics& m) {
  if (selected) canvas.fill_rect(row, colours::kHighlight);
  row = inset(row, m.pad, 0);
  const Rgb colour = selected ? colours::kText : colours::kDimText;
  draw_text_in(canvas, take_left(row, static_cast<int>(kMarkColumnEm * m.body_px)),
               selected ? "▶" : "", {m.body_px, colours::kText, FontWeight::Bold});
  draw_text_in(canvas, take_right(row, columns.spp), tier_spp_text(tier), {m.small_px, colour},
               Align::Right);
  draw_text_in(canvas, take_right(row, columns.time), tier_time_text(tier),
               {m.body_px, colours::kText}, Align::Right);
  draw_text_in(canvas, row, tier.name, {m.body_px, colours::kText, FontWeight::Bold});
}

}  // namespace

void draw_tier_pick(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no photo", c.m);
  dim_rect(c.canvas, image, kDimmedPhoto);
  const int row_h = row_height(c.m) + 2 * c.m.gap;
  const int count = static_cast<int>(std::min<std::size_t>(c.view.tiers.size(), 1 << 20));
  const int max_rows = std::max(0, (c.main.height - 4 * c.m.pad) / std::max(1, row_h));
  const int rows = std::min(std::max(count, 1), max_rows);
  const Rect panel = centred(c.main, panel_width(c.main, c.m), rows * row_h + 2 * c.m.pad);
  draw_panel(c.canvas, panel, colours::kTrack);
  Rect inner = inset(panel, c.m.pad, c.m.pad);
  if (count == 0) {
    draw_text_in(c.canvas, inner, "no render tiers", {c.m.body_px, colours::kDimText},
                 Align::Centre);
    return;
  }
  const bool has_selection = valid_index(c.view.selected_tier, c.view.tiers.size());
  const int first = first_visible_row(count, rows, has_selection ? c.view.selected_tier : 0);
  const int last = std::min(count, first + rows);
  const std::vector<TierChoice> shown(c.view.tiers.begin() + first, c.view.tiers.begin() + last);
  const int row_width = inner.width - 2 * c.m.pad;
  const TierColumns columns{
      column_width(shown, tier_time_text, {c.m.body_px}, 2 * c.m.pad,
                   static_cast<int>(row_width * kMaxTimeColumnShare)),
      column_width(shown, tier_spp_text, {c.m.small_px}, c.m.pad,
                   static_cast<int>(row_width * kMaxSppColumnShare))};
  for (int i = first; i < last; ++i) {
    draw_tier_row(c.canvas, take_top(inner, row_h), c.view.tiers[static_cast<std::size_t>(i)],
                  has_selection && i == c.view.selected_tier, columns, c.m);
  }
}

}  // namespace propcam::ui_fb::detail
