// Analysing: the photo dimmed behind a panel listing the analysis stages,
// each with its mark, time and detail.
#include "screen_kinds.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "screen_regions.h"

namespace propcam::ui_fb::detail {
namespace {

struct StageMark {
  const char* glyph;
  Rgb colour;
};

StageMark stage_mark(StageLine::Status status) {
  switch (status) {
    case StageLine::Status::Pending: return {"○", colours::kDimText};
    case StageLine::Status::Running: return {"●", colours::kAccent};
    case StageLine::Status::Done: return {"✔", colours::kGood};
    case StageLine::Status::Failed: return {"✖", colours::kFault};
    case StageLine::Status::Skipped: return {"–", colours::kDimText};
  }
  return {"?", colours::kDimText};
}

// The stage to keep in view when the list is longer than the panel: the running
// one, else the last that finished.
int focus_stage(const std::vector<StageLine>& stages) {
  int last_finished = 0;
  for (std::size_t i = 0; i < stages.size(); ++i) {
    if (stages[i].status == StageLine::Status::Running) return static_cast<int>(i);
    if (stages[i].status != StageLine::Status::Pending) last_finished = static_cast<int>(i);
  }
  return last_finished;
}

constexpr double kSecondsColumnEm = 5.0;
constexpr double kNameShare = 0.45;  // of what remains after the mark and seconds columns

void draw_stage_row(Canvas& canvas, Rect row, const StageLine& stage, const Metrics& m) {
  const StageMark mark = stage_mark(stage.status);
  draw_text_in(canvas, take_left(row, static_cast<int>(kMarkColumnEm * m.body_px)), mark.glyph,
               {m.body_px, mark.colour, FontWeight::Bold});
  const bool timed = stage.status != StageLine::Status::Pending &&
                     stage.status != StageLine::Status::Skipped;
  draw_text_in(canvas, take_right(row, static_cast<int>(kSecondsColumnEm * m.body_px)),
               timed ? format_seconds(stage.seconds) : std::string(), {m.body_px, colours::kText},
               Align::Right);
  const Rgb name_colour =
      stage.status == StageLine::Status::Pending ? colours::kDimText : colours::kText;
  draw_text_in(canvas, take_left(row, static_cast<int>(row.width * kNameShare)), stage.name,
               {m.body_px, name_colour});
  const Rgb detail_colour =
      stage.status == StageLine::Status::Failed ? colours::kFault : colours::kDimText;
  draw_text_in(canvas, take_right(row, row.width - m.gap), stage.detail,
               {m.small_px, detail_colour});
}

}  // namespace

void draw_analysing(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no photo", c.m);
  dim_rect(c.canvas, image, kDimmedPhoto);
  const int row_h = row_height(c.m);
  const int stage_count = static_cast<int>(std::min<std::size_t>(c.view.stages.size(), 1 << 20));
  const int max_rows = std::max(0, (c.main.height - 4 * c.m.pad) / std::max(1, row_h) - 1);
  const int rows = std::min(std::max(stage_count, 1), max_rows);
  Rect panel = centred(c.main, panel_width(c.main, c.m), (rows + 1) * row_h + 2 * c.m.pad);
  draw_panel(c.canvas, panel, colours::kTrack);
  Rect inner = inset(panel, c.m.pad, c.m.pad);
  if (stage_count == 0) {
    draw_text_in(c.canvas, take_top(inner, row_h), "analysing…", {c.m.body_px, colours::kText});
  }
  const int first = first_visible_row(stage_count, rows, focus_stage(c.view.stages));
  for (int i = first; i < std::min(stage_count, first + rows); ++i) {
    draw_stage_row(c.canvas, take_top(inner, row_h), c.view.stages[static_cast<std::size_t>(i)],
                   c.m);
  }
  const std::string elapsed = format_seconds(c.view.elapsed_seconds);
  if (!elapsed.empty()) {
    draw_text_in(c.canvas, take_bottom(inner, row_h), "total " + elapsed,
                 {c.m.body_px, colours::kDimText}, Align::Right);
  }
}

}  // namespace propcam::ui_fb::detail
