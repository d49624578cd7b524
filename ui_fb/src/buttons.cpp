#include "propcam/ui_fb/buttons.h"

#include <poll.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>

namespace propcam::ui_fb {
namespace {

constexpr std::array<std::string_view, kButtonCount> kButtonNames{"SHOOT", "NEXT", "PREV", "OK",
                                                                  "BACK"};

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const auto up = [](char c) { return (c >= 'a' && c <= 'z') ? static_cast<char>(c - 32) : c; };
    if (up(a[i]) != up(b[i])) return false;
  }
  return true;
}

// Times come from hardware and scripts; a huge one must not wrap a deadline.
std::int64_t saturating_add(std::int64_t a, std::int64_t b) {
  constexpr auto kMax = std::numeric_limits<std::int64_t>::max();
  constexpr auto kMin = std::numeric_limits<std::int64_t>::min();
  if (b > 0 && a > kMax - b) return kMax;
  if (b < 0 && a < kMin - b) return kMin;
  return a + b;
}

}  // namespace

std::string_view button_name(Button button) {
  const auto index = static_cast<std::size_t>(button);
  return index < kButtonCount ? kButtonNames[index] : std::string_view("?");
}

std::optional<Button> button_from_name(std::string_view name) {
  for (Button b : kAllButtons) {
    if (iequals(name, button_name(b))) return b;
  }
  return std::nullopt;
}

std::string_view kind_name(ButtonEvent::Kind kind) {
  switch (kind) {
    case ButtonEvent::Kind::Press: return "press";
    case ButtonEvent::Kind::Release: return "release";
    case ButtonEvent::Kind::LongPress: return "long-press";
    case ButtonEvent::Kind::Repeat: return "repeat";
  }
  return "?";
}

std::string to_string(const ButtonEvent& event) {
  char when[48];
  std::snprintf(when, sizeof when, "%.6fs", static_cast<double>(event.time_ns) / 1e9);
  return std::string(button_name(event.button)) + " " + std::string(kind_name(event.kind)) +
         " @ " + when;
}

void DebounceOptions::validate() const {
  if (debounce_ns < 0 || long_press_ns < 0 || repeat_delay_ns < 0) {
    throw std::invalid_argument("ui_fb: button debounce, long-press and repeat delay must not be negative");
  }
  // A zero interval would make one advance() emit repeats forever.
  if (repeat_interval_ns <= 0) {
    throw std::invalid_argument("ui_fb: button repeat interval must be positive");
  }
}

// --- ButtonDebouncer --------------------------------------------------------

ButtonDebouncer::ButtonDebouncer(DebounceOptions options) : options_(options) {
  options_.validate();
}

std::int64_t ButtonDebouncer::clamp(std::int64_t t) {
  if (!have_time_) {
    have_time_ = true;
    now_ns_ = t;
    return t;
  }
  if (t < now_ns_) {
    ++clamped_times_;
    return now_ns_;
  }
  return t;
}

std::optional<std::int64_t> ButtonDebouncer::deadline(std::size_t index, Due* what) const {
  const State& s = states_[index];
  if (s.raw != s.stable) {
    *what = Due::Settle;
    return saturating_add(s.last_edge_ns, options_.debounce_ns);
  }
  if (!s.stable) return std::nullopt;
  const ButtonBehaviour& b = options_.behaviour[index];
  std::optional<std::int64_t> best;
  if (b.long_press && !s.long_done) {
    *what = Due::Long;
    best = saturating_add(s.pressed_at_ns, options_.long_press_ns);
  }
  if (b.repeat && !s.repeat_exhausted && (!best || s.next_repeat_ns < *best)) {  // ties: LongPress first
    *what = Due::Repeat;
    best = s.next_repeat_ns;
  }
  return best;
}

void ButtonDebouncer::emit(std::size_t index, ButtonEvent::Kind kind, std::int64_t at) {
  queue_.push_back(ButtonEvent{kAllButtons[index], kind, at});
}

void ButtonDebouncer::fire(std::size_t index, Due what, std::int64_t at) {
  State& s = states_[index];
  switch (what) {
    case Due::Settle:
      s.stable = s.raw;
      if (s.stable) {
        s.pressed_at_ns = at;
        s.long_done = false;
        s.repeat_exhausted = false;
        s.next_repeat_ns = saturating_add(at, options_.repeat_delay_ns);
        emit(index, ButtonEvent::Kind::Press, at);
      } else {
        emit(index, ButtonEvent::Kind::Release, at);
      }
      break;
    case Due::Long:
      s.long_done = true;
      emit(index, ButtonEvent::Kind::LongPress, at);
      break;
    case Due::Repeat:
      // `at` is later than scheduled only after a paused (glitching) hold: keep
      // the interval from there rather than bursting the missed ones.
      s.next_repeat_ns = saturating_add(at, options_.repeat_interval_ns);
      // At the end of time the next repeat saturates onto this one: stop there.
      s.repeat_exhausted = s.next_repeat_ns == at;
      emit(index, ButtonEvent::Kind::Repeat, at);
      break;
  }
}

void ButtonDebouncer::advance(std::int64_t now_ns) {
  const std::int64_t target = clamp(now_ns);
  for (;;) {
    std::optional<std::int64_t> earliest;
    std::size_t which = 0;
    Due what = Due::Settle;
    for (std::size_t i = 0; i < kButtonCount; ++i) {
      Due due = Due::Settle;
      const auto d = deadline(i, &due);
      if (d && *d <= target && (!earliest || *d < *earliest)) {
        earliest = d;
        which = i;
        what = due;
      }
    }
    if (!earliest) break;
    now_ns_ = std::max(*earliest, now_ns_);
    fire(which, what, now_ns_);
  }
  now_ns_ = target;
}

void ButtonDebouncer::on_edge(const RawEdge& edge) {
  const auto index = static_cast<std::size_t>(edge.button);
  if (index >= kButtonCount) return;
  advance(edge.time_ns);
  State& s = states_[index];
  if (edge.pressed == s.raw) return;  // no level change: nothing to debounce
  s.raw = edge.pressed;
  s.last_edge_ns = now_ns_;
}

std::optional<ButtonEvent> ButtonDebouncer::pop_event() {
  if (queue_.empty()) return std::nullopt;
  ButtonEvent e = queue_.front();
  queue_.pop_front();
  return e;
}

std::vector<ButtonEvent> ButtonDebouncer::take_events() {
  std::vector<ButtonEvent> out(queue_.begin(), queue_.end());
  queue_.clear();
  return out;
}

std::optional<std::int64_t> ButtonDebouncer::next_deadline_ns() const {
  std::optional<std::int64_t> earliest;
  for (std::size_t i = 0; i < kButtonCount; ++i) {
    Due due = Due::Settle;
    const auto d = deadline(i, &due);
    if (d && (!earliest || *d < *earliest)) earliest = d;
  }
  if (earliest && have_time_) earliest = std::max(*earliest, now_ns_);
  return earliest;
}

bool ButtonDebouncer::is_held(Button button) const {
  const auto index = static_cast<std::size_t>(button);
  return index < kButtonCount && states_[index].stable;
}

bool ButtonDebouncer::idle() const {
  if (!queue_.empty()) return false;
  return std::all_of(states_.begin(), states_.end(),
                     [](const State& s) { return !s.raw && !s.stable; });
}

// --- FdButtonInput ----------------------------------------------------------

std::int64_t timeout_to_ns(std::chrono::milliseconds timeout) {
  constexpr std::int64_t kMaxMs = std::numeric_limits<std::int64_t>::max() / 1'000'000;
  return std::clamp<std::int64_t>(timeout.count(), 0, kMaxMs) * 1'000'000;
}

std::int64_t monotonic_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

namespace {

// Milliseconds to wait for `ns`, rounded up so a wake-up is never early.
int wait_ms(std::int64_t ns) {
  if (ns <= 0) return 0;
  const std::int64_t ms = (ns + 999'999) / 1'000'000;
  return static_cast<int>(std::min<std::int64_t>(ms, std::numeric_limits<int>::max()));
}

}  // namespace

void FdButtonInput::feed(const RawEdge& edge, std::int64_t now_ns) {
  RawEdge e = edge;
  e.time_ns = std::min(e.time_ns, now_ns);
  debouncer_.on_edge(e);
}

std::optional<ButtonEvent> FdButtonInput::next_event(std::chrono::milliseconds timeout) {
  const std::int64_t deadline = saturating_add(monotonic_now_ns(), timeout_to_ns(timeout));
  for (;;) {
    if (auto e = debouncer_.pop_event()) return e;
    std::int64_t now = monotonic_now_ns();
    int wait = wait_ms(deadline - now);
    if (auto d = debouncer_.next_deadline_ns()) wait = std::min(wait, wait_ms(*d - now));
    pollfd p{poll_fd(), POLLIN, 0};
    const int ready = ::poll(&p, 1, wait);
    if (ready < 0 && errno != EINTR) {
      throw std::runtime_error("ui_fb: " + name() + ": poll failed: " + std::strerror(errno));
    }
    now = monotonic_now_ns();
    if (ready > 0) {
      read_ready(now);  // device errors surface here as read errors
      // A hang-up with nothing left to read would otherwise spin until the timeout.
      if ((p.revents & (POLLERR | POLLHUP | POLLNVAL)) && !(p.revents & POLLIN)) {
        throw std::runtime_error("ui_fb: " + name() + ": input hung up");
      }
    }
    debouncer_.advance(now);
    if (auto e = debouncer_.pop_event()) return e;
    if (now >= deadline) return std::nullopt;
  }
}

}  // namespace propcam::ui_fb
