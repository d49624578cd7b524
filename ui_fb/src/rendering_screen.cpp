// Rendering: the composite as it converges, its unfinished tiles outlined by
// their estimated error, and below it the progress bar and the figures.
#include "screen_kinds.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "screen_regions.h"

namespace propcam::ui_fb::detail {
namespace {

constexpr int kTileOutlineMinSideForThick = 24;  // screen pixels

void draw_tile_overlay(Canvas& canvas, const Rect& image, Size image_size,
                       const std::vector<TileView>& tiles) {
  const ImageMapping mapping(image, image_size);
  for (const TileView& tile : tiles) {
    // Culled tiles stay untouched (they are the photo); finished ones need no attention.
    if (!tile.affected || tile.done) continue;
    const Rect screen = mapping.rect(tile.rect);
    if (screen.empty()) continue;
    const int thickness =
        std::min(screen.width, screen.height) >= kTileOutlineMinSideForThick ? 2 : 1;
    canvas.stroke_rect(screen, tile_error_colour(tile.relative_error), thickness);
  }
}

// The figures below the progress bar, in the order a user looks for them.
std::vector<std::string> rendering_figures(const ScreenView& view) {
  std::vector<std::string> figures;
  if (const std::string elapsed = format_seconds(view.elapsed_seconds); !elapsed.empty()) {
    figures.push_back(elapsed);
  }
  if (const std::string good = format_predicted(view.predicted_seconds_to_good); !good.empty()) {
    figures.push_back("good in " + good);
  }
  if (const std::string done = format_predicted(view.predicted_seconds_to_done); !done.empty()) {
    figures.push_back("done in " + done);
  }
  if (view.samples_per_pixel > 0) {
    figures.push_back(std::to_string(view.samples_per_pixel) + " spp");
  }
  if (view.skipped_tiles > 0) {
    figures.push_back(count_text(view.skipped_tiles, "tile skipped", "tiles skipped"));
  }
  std::string effects;
  for (const std::string& effect : view.skipped_effects) {
    if (effect.empty()) continue;
    if (!effects.empty()) effects += ", ";
    effects += effect;
    if (effects.size() > 1024) break;  // more could not be shown anyway
  }
  if (!effects.empty()) figures.push_back(effects);
  return figures;
}

constexpr std::string_view kFigureSeparator = "  ·  ";

// Flows `figures` into at most `rows` lines of `width`; the last line takes the rest (elided).
std::vector<std::string> flow_figures(const std::vector<std::string>& figures, int rows, int width,
                                      const TextStyle& style) {
  std::vector<std::string> lines;
  std::string line;
  for (const std::string& figure : figures) {
    const std::string candidate =
        line.empty() ? figure : line + std::string(kFigureSeparator) + figure;
    const bool last_row = static_cast<int>(lines.size()) + 1 >= rows;
    if (line.empty() || last_row || width_of(elide(candidate, style, 1 << 14), style) <= width) {
      line = candidate;
    } else {
      lines.push_back(line);
      line = figure;
    }
    if (line.size() > 4096) break;  // a huge figure: the rest would be elided anyway
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

// Below the composite: the progress bar, then the converged share and the figures.
void draw_rendering_strip(const ScreenContext& c, Rect strip) {
  take_top(strip, c.m.gap);
  const double fraction = std::isnan(c.view.converged_fraction)
                              ? 0.0
                              : std::clamp(c.view.converged_fraction, 0.0, 1.0);
  draw_progress_bar(c.canvas, take_top(strip, progress_bar_height(c.m)), fraction);
  const TextStyle small{c.m.small_px, colours::kText};
  const int text_h = line_height(c.m.small_px) + c.m.gap;
  Rect first_row = take_top(strip, text_h);
  // Right-aligned under the bar's end, where the eye lands after following the bar.
  const Rect percent_box = take_right(first_row, width_of("100 % converged", small) + c.m.pad);
  draw_text_in(c.canvas, percent_box,
               printf_string("%.0f %% converged", std::floor(fraction * 100.0)), small,
               Align::Right);
  const std::vector<std::string> lines = flow_figures(
      rendering_figures(c.view), info_rows(c.main, c.m), first_row.width, small);
  if (!lines.empty()) draw_text_in(c.canvas, first_row, lines[0], small);
  for (std::size_t i = 1; i < lines.size(); ++i) {
    draw_text_in(c.canvas, take_top(strip, text_h), lines[i], {c.m.small_px, colours::kDimText});
  }
}

}  // namespace

void draw_rendering(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no composite yet", c.m);
  if (!image.empty()) draw_tile_overlay(c.canvas, image, size_of(c.view.image), c.view.tiles);
  draw_caption(c.canvas, image.empty() ? c.picture : image, c.view.image_caption, Edge::Bottom,
               c.m);
  const Rect below{c.main.x, c.picture.bottom(), c.main.width,
                   c.main.bottom() - c.picture.bottom()};
  draw_rendering_strip(c, inset(below, c.m.pad, 0));
}

}  // namespace propcam::ui_fb::detail
