#include "screen_bars.h"

#include <algorithm>
#include <string>

namespace propcam::ui_fb::detail {
namespace {

constexpr int kAccentLine = 2;  // under the title bar; red on Fault
constexpr double kStatusMaxFraction = 0.5;  // of the title bar the status may take

}  // namespace

void draw_title_bar(Canvas& canvas, const Rect& bar, const ScreenView& view, const Metrics& m) {
  canvas.fill_rect(bar, colours::kBar);
  const Rgb accent = view.kind == ScreenKind::Fault ? colours::kFault : colours::kAccent;
  const int accent_height = std::min(kAccentLine, bar.height / 4);
  canvas.fill_rect({bar.x, bar.bottom() - accent_height, bar.width, accent_height}, accent);
  Rect inner = inset(bar, m.pad, 0);
  const TextStyle status_style{m.body_px, colours::kDimText};
  const std::string status =
      elide(view.status, status_style, static_cast<int>(inner.width * kStatusMaxFraction));
  const int status_width = status.empty() ? 0 : width_of(status, status_style);
  draw_text_in(canvas, take_right(inner, status_width), status, status_style, Align::Right);
  take_right(inner, status.empty() ? 0 : 2 * m.pad);
  draw_text_in(canvas, inner, view.title, {m.title_px, colours::kText, FontWeight::Bold});
}

namespace {

// "OK", "hold OK", "▶" (NEXT), "◀" (PREV).
std::string key_label(const ButtonHint& hint) {
  std::string key;
  switch (hint.button) {
    case Button::Next: key = "▶"; break;
    case Button::Prev: key = "◀"; break;
    default: key = std::string(button_name(hint.button)); break;
  }
  return hint.long_press ? "hold " + key : key;
}

constexpr double kHintGapEm = 1.2;       // between two hints, when there is room
constexpr double kTightHintGapEm = 0.6;  // when there is not
constexpr double kKeyGapEm = 0.3;        // between a key and its label
constexpr std::size_t kMaxHints = 12;    // more could never be read in one bar

// Gives each label at most its natural width, sharing `available` fairly: short
// labels stay whole and the long ones are elided to what is left.
std::vector<int> share_widths(const std::vector<int>& natural, int available) {
  std::vector<std::size_t> order(natural.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return natural[a] < natural[b]; });
  std::vector<int> shares(natural.size(), 0);
  int remaining = std::max(0, available);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const int fair = remaining / static_cast<int>(order.size() - k);
    shares[order[k]] = std::min(natural[order[k]], fair);
    remaining -= shares[order[k]];
  }
  return shares;
}

struct HintWidths {
  std::vector<int> keys;
  std::vector<int> labels;  // including the gap after the key; 0 without a label
};

HintWidths measure_hints(const std::vector<ButtonHint>& hints, std::size_t count, int px,
                         int max_width) {
  const TextStyle key_style{px, colours::kAccent, FontWeight::Bold};
  const TextStyle label_style{px, colours::kText};
  const int key_gap = static_cast<int>(kKeyGapEm * px);
  HintWidths widths;
  for (std::size_t i = 0; i < count; ++i) {
    widths.keys.push_back(width_of(key_label(hints[i]), key_style));
    // Measuring only what could ever fit keeps a huge label cheap.
    const std::string label = elide(hints[i].label, label_style, max_width);
    widths.labels.push_back(label.empty() ? 0 : width_of(label, label_style) + key_gap);
  }
  return widths;
}

int keys_width(const HintWidths& widths, std::size_t count, int gap) {
  int width = gap * static_cast<int>(count - 1);
  for (std::size_t i = 0; i < count; ++i) width += widths.keys[i];
  return width;
}

int natural_width(const HintWidths& widths, std::size_t count, int gap) {
  int width = keys_width(widths, count, gap);
  for (std::size_t i = 0; i < count; ++i) width += widths.labels[i];
  return width;
}

}  // namespace

void draw_hint_bar(Canvas& canvas, const Rect& bar, const std::vector<ButtonHint>& hints,
                   const Metrics& m) {
  canvas.fill_rect(bar, colours::kBar);
  const Rect inner = inset(bar, m.pad, 0);
  if (hints.empty() || inner.empty()) return;
  std::size_t count = std::min(hints.size(), kMaxHints);
  int px = m.body_px;
  HintWidths widths = measure_hints(hints, count, px, inner.width);
  int gap = static_cast<int>(kHintGapEm * px);
  if (natural_width(widths, count, gap) > inner.width) {
    gap = static_cast<int>(kTightHintGapEm * px);
    if (natural_width(widths, count, gap) > inner.width) {
      px = m.small_px;
      gap = static_cast<int>(kTightHintGapEm * px);
      widths = measure_hints(hints, count, px, inner.width);
    }
  }
  while (count > 1 && keys_width(widths, count, gap) > inner.width) --count;
  widths.labels.resize(count);
  const std::vector<int> label_shares =
      share_widths(widths.labels, inner.width - keys_width(widths, count, gap));

  const TextStyle key_style{px, colours::kAccent, FontWeight::Bold};
  const TextStyle label_style{px, colours::kText};
  const int key_gap = static_cast<int>(kKeyGapEm * px);
  int x = inner.x;
  for (std::size_t i = 0; i < count; ++i) {
    draw_text_in(canvas, {x, inner.y, std::min(widths.keys[i], inner.right() - x), inner.height},
                 key_label(hints[i]), key_style);
    x += widths.keys[i];
    if (label_shares[i] > key_gap) {
      draw_text_in(canvas, {x + key_gap, inner.y, label_shares[i] - key_gap, inner.height},
                   hints[i].label, label_style);
    }
    x += label_shares[i] + gap;
  }
}

}  // namespace propcam::ui_fb::detail
