// The script backend: parses the timed-press grammar documented in buttons.h into
// raw edges in segments (split by awaits) and plays them through the debouncer
// against a ButtonClock, pausing at each await until the appliance reports its state.
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

constexpr std::size_t kMaxLineBytes = 4096;
constexpr std::int64_t kMaxScriptNs = 24LL * 3600 * 1'000'000'000;  // 24 h
constexpr std::int64_t kDefaultTapNs = 100'000'000;
constexpr std::int64_t kDefaultAwaitTimeoutNs = 600LL * 1'000'000'000;  // 10 min
constexpr int kMaxBounces = 100;
constexpr std::uintmax_t kMaxScriptBytes = 16u << 20;

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

// 'word', built by appending (GCC 12 warns falsely on "'" + std::string(...)).
std::string quoted(std::string_view word) {
  std::string out;
  out.reserve(word.size() + 2);
  out.append(1, '\'').append(word).append(1, '\'');
  return out;
}

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

// One edge before bounce expansion, with the bounce setting in force on its line.
struct PendingEdge {
  RawEdge edge;  // time_ns relative to its segment's origin
  int line;
  std::size_t segment;
  int bounces;
  std::int64_t bounce_interval_ns;
};

// A state name: a letter, then letters, digits, '_', '-' or '/' (so "10s" is not one).
bool is_state_word(std::string_view word) {
  auto letter = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); };
  if (word.empty() || !letter(word[0])) return false;
  return std::all_of(word.begin(), word.end(), [&](char c) {
    return letter(c) || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '/';
  });
}

// "600s", "1500ms", "0.25ms": the shortest exact spelling in the script's units.
std::string duration_text(std::int64_t ns) {
  constexpr std::int64_t kNsPerMs = 1'000'000;
  constexpr std::int64_t kNsPerS = 1'000'000'000;
  if (ns % kNsPerS == 0) return std::to_string(ns / kNsPerS) + "s";
  if (ns % kNsPerMs == 0) return std::to_string(ns / kNsPerMs) + "ms";
  char text[32];
  std::snprintf(text, sizeof text, "%.6gms", static_cast<double>(ns) / kNsPerMs);
  return text;
}

class Parser {
 public:
  explicit Parser(std::string source) : source_(std::move(source)) {}

  void parse_line(std::string_view line, int number);
  ButtonScript finish();

 private:
  [[noreturn]] void fail(const std::string& message) const {
    throw ButtonScriptError(source_, line_, message);
  }
  std::int64_t parse_time(std::string_view word) const;
  Button parse_button(std::string_view word) const;
  std::string_view take(const std::vector<std::string_view>& words, std::size_t& i,
                        const char* what) const;
  void add_edge(Button b, bool pressed, std::int64_t t);
  void parse_await(const std::vector<std::string_view>& words, std::size_t& i, std::int64_t start);
  std::int64_t checked_sum(std::int64_t a, std::int64_t b) const;
  void check_line_bytes(std::string_view line) const;
  void check_alternation() const;
  void expand_bounces(ButtonScript& script) const;

  std::string source_;
  int line_ = 0;
  std::int64_t cursor_ns_ = 0;      // where "+" counts from: the previous step's end
  std::int64_t last_start_ns_ = 0;  // steps must not start before the previous one
  int bounces_ = 0;
  std::int64_t bounce_interval_ns_ = 1'000'000;
  std::vector<PendingEdge> edges_;
  std::vector<ButtonScript::Await> awaits_;  // awaits_[k] ends segment k
};

void Parser::check_line_bytes(std::string_view line) const {
  if (line.size() > kMaxLineBytes) {
    fail("line is " + std::to_string(line.size()) + " bytes, longer than the limit of " +
         std::to_string(kMaxLineBytes));
  }
  for (char c : line) {
    const auto u = static_cast<unsigned char>(c);
    if ((u < 0x20 && c != '\t') || u == 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02x", u);
      fail(std::string("control character ") + hex + " (not a text script?)");
    }
  }
}

std::int64_t Parser::parse_time(std::string_view word) const {
  const std::string w = lower(word);
  if (!w.empty() && w[0] == '-') fail("negative time " + quoted(word));
  std::size_t unit_at = 0;
  while (unit_at < w.size() && ((w[unit_at] >= '0' && w[unit_at] <= '9') || w[unit_at] == '.')) {
    ++unit_at;
  }
  const std::string_view number(w.data(), unit_at);
  const std::string_view unit(w.data() + unit_at, w.size() - unit_at);
  const bool has_digit = number.find_first_of("0123456789") != std::string_view::npos;
  double value = 0;
  const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
  if (!has_digit || ec != std::errc() || end != number.data() + number.size() ||
      (unit != "ms" && unit != "s")) {
    fail(quoted(word) + " is not a time (expected e.g. 500ms or 1.2s)");
  }
  const double ns = value * (unit == "s" ? 1e9 : 1e6);
  if (!std::isfinite(ns) || ns > static_cast<double>(kMaxScriptNs)) {
    fail("time " + quoted(word) + " is longer than 24h");
  }
  return static_cast<std::int64_t>(std::llround(ns));
}

Button Parser::parse_button(std::string_view word) const {
  if (auto b = button_from_name(word)) return *b;
  fail("unknown button " + quoted(word) + " (expected SHOOT, NEXT, PREV, OK or BACK)");
}

std::string_view Parser::take(const std::vector<std::string_view>& words, std::size_t& i,
                              const char* what) const {
  if (i >= words.size()) fail(std::string("missing ") + what);
  return words[i++];
}

std::int64_t Parser::checked_sum(std::int64_t a, std::int64_t b) const {
  if (a + b > kMaxScriptNs) fail("the script runs past 24h");
  return a + b;
}

void Parser::add_edge(Button b, bool pressed, std::int64_t t) {
  edges_.push_back(
      PendingEdge{RawEdge{b, pressed, t}, line_, awaits_.size(), bounces_, bounce_interval_ns_});
}

// Ends the current segment; the next one is timed from the moment the state is reported.
void Parser::parse_await(const std::vector<std::string_view>& words, std::size_t& i,
                         std::int64_t start) {
  const std::string_view state = take(words, i, "state after 'await' (e.g. await placing)");
  if (!is_state_word(state)) {
    fail(quoted(state) + " is not a state name (expected a word such as placing, then an "
         "optional timeout)");
  }
  std::int64_t timeout = kDefaultAwaitTimeoutNs;
  if (i < words.size()) timeout = parse_time(take(words, i, "await timeout"));
  // start_ns is raised to the segment's last edge in finish(), once bounces are known.
  awaits_.push_back(ButtonScript::Await{std::string(state), start, timeout, line_});
  cursor_ns_ = 0;
  last_start_ns_ = 0;
}

void Parser::parse_line(std::string_view line, int number) {
  line_ = number;
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  check_line_bytes(line);
  if (auto hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
  const auto words = split_words(line);
  if (words.empty()) return;

  std::size_t i = 0;
  std::int64_t start = cursor_ns_;
  const std::string first = lower(words[0]);
  if (first == "at") {
    ++i;
    start = parse_time(take(words, i, "time after 'at'"));
    if (start < last_start_ns_) {
      fail("'at' goes back in time, before the previous step's start");
    }
  } else if (first[0] == '+') {
    ++i;
    const std::string_view rest = words[0].substr(1);
    start = checked_sum(cursor_ns_, parse_time(rest.empty() ? take(words, i, "time after '+'") : rest));
  }
  last_start_ns_ = start;

  const std::string action =
      lower(take(words, i, "action (press, hold, down, up, wait, bounce, await)"));
  if (action == "press" || action == "hold") {
    const Button b = parse_button(take(words, i, "button"));
    std::int64_t duration = kDefaultTapNs;
    if (action == "hold" || i < words.size()) duration = parse_time(take(words, i, "duration"));
    if (duration <= 0) fail("a " + action + " needs a positive duration");
    const std::int64_t end = checked_sum(start, duration);
    add_edge(b, true, start);
    add_edge(b, false, end);
    cursor_ns_ = end;
  } else if (action == "down" || action == "up") {
    add_edge(parse_button(take(words, i, "button")), action == "down", start);
    cursor_ns_ = start;
  } else if (action == "wait") {
    cursor_ns_ = checked_sum(start, parse_time(take(words, i, "duration")));
  } else if (action == "bounce") {
    const std::string_view count = take(words, i, "bounce count");
    int n = -1;
    const auto [end, ec] = std::from_chars(count.data(), count.data() + count.size(), n);
    if (ec != std::errc() || end != count.data() + count.size() || n < 0 || n > kMaxBounces) {
      fail("bounce count " + quoted(count) + " is not a whole number from 0 to " +
           std::to_string(kMaxBounces));
    }
    std::int64_t interval = 1'000'000;
    if (i < words.size()) interval = parse_time(take(words, i, "bounce interval"));
    if (interval <= 0) fail("the bounce interval must be positive");
    bounces_ = n;
    bounce_interval_ns_ = interval;
    cursor_ns_ = start;
  } else if (action == "await") {
    parse_await(words, i, start);
  } else {
    fail("unknown action " + quoted(words[i - 1]) +
         " (expected press, hold, down, up, wait, bounce or await)");
  }
  if (i < words.size()) fail("unexpected " + quoted(words[i]));
}

// Each button must alternate down / up across the whole script, and end up.
void Parser::check_alternation() const {
  std::array<const PendingEdge*, kButtonCount> last_of{};
  for (const PendingEdge& e : edges_) {
    const PendingEdge*& last = last_of[static_cast<std::size_t>(e.edge.button)];
    const bool down = last != nullptr && last->edge.pressed;
    if (e.edge.pressed == down) {
      const std::string name(button_name(e.edge.button));
      throw ButtonScriptError(
          source_, e.line,
          down ? name + " is already down (pressed on line " + std::to_string(last->line) + ")"
               : name + " is released but is not down");
    }
    last = &e;
  }
  for (const PendingEdge* last : last_of) {
    if (last != nullptr && last->edge.pressed) {
      throw ButtonScriptError(source_, last->line,
                              std::string(button_name(last->edge.button)) +
                                  " is still down at the end of the script");
    }
  }
}

// Copies the edges into `script`, each followed by its bounces. Bounces that would
// reach the button's next edge in the same segment are dropped; a segment's bounces
// all play before its await begins, so a later segment never limits them.
void Parser::expand_bounces(ButtonScript& script) const {
  std::array<std::vector<const PendingEdge*>, kButtonCount> per_button;
  for (const PendingEdge& e : edges_) per_button[static_cast<std::size_t>(e.edge.button)].push_back(&e);
  for (const auto& list : per_button) {
    for (std::size_t k = 0; k < list.size(); ++k) {
      const PendingEdge& e = *list[k];
      script.edges.push_back(ButtonScript::Edge{e.edge, e.line, e.segment});
      const bool next_in_segment = k + 1 < list.size() && list[k + 1]->segment == e.segment;
      const std::int64_t limit = next_in_segment ? list[k + 1]->edge.time_ns : kMaxScriptNs * 2;
      for (int n = 1; n <= e.bounces; ++n) {
        const std::int64_t back = e.edge.time_ns + (2 * n - 1) * e.bounce_interval_ns;
        const std::int64_t forth = e.edge.time_ns + 2 * n * e.bounce_interval_ns;
        if (forth >= limit) break;
        script.edges.push_back(
            ButtonScript::Edge{RawEdge{e.edge.button, !e.edge.pressed, back}, e.line, e.segment});
        script.edges.push_back(
            ButtonScript::Edge{RawEdge{e.edge.button, e.edge.pressed, forth}, e.line, e.segment});
      }
    }
  }
}

ButtonScript Parser::finish() {
  std::stable_sort(edges_.begin(), edges_.end(), [](const PendingEdge& a, const PendingEdge& b) {
    if (a.segment != b.segment) return a.segment < b.segment;
    return a.edge.time_ns < b.edge.time_ns;
  });
  check_alternation();
  ButtonScript script;
  script.source = source_;
  expand_bounces(script);
  // Segment order first; ties keep script order (the line), whichever button.
  std::stable_sort(script.edges.begin(), script.edges.end(),
                   [](const ButtonScript::Edge& a, const ButtonScript::Edge& b) {
                     if (a.segment != b.segment) return a.segment < b.segment;
                     if (a.edge.time_ns != b.edge.time_ns) return a.edge.time_ns < b.edge.time_ns;
                     return a.line < b.line;
                   });
  script.awaits = awaits_;
  // An await begins only once everything before it, bounces included, has played.
  for (const ButtonScript::Edge& e : script.edges) {
    if (e.segment < script.awaits.size()) {
      std::int64_t& start = script.awaits[e.segment].start_ns;
      start = std::max(start, e.edge.time_ns);
    }
  }
  script.end_ns = cursor_ns_;
  if (!script.edges.empty() && script.edges.back().segment == awaits_.size()) {
    script.end_ns = std::max(script.end_ns, script.edges.back().edge.time_ns);
  }
  return script;
}

}  // namespace

ButtonScriptError::ButtonScriptError(const std::string& source, int line, const std::string& message)
    : std::runtime_error(source + ":" + std::to_string(line) + ": " + message), line_(line) {}

ButtonScript ButtonScript::parse(std::string_view text, std::string source) {
  Parser parser(std::move(source));
  int number = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    parser.parse_line(text.substr(pos, nl - pos), ++number);
    pos = nl + 1;
  }
  return parser.finish();
}

ButtonScript ButtonScript::load(const std::filesystem::path& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > kMaxScriptBytes) {
    throw std::runtime_error("ui_fb: button script " + path.string() + " is " +
                             std::to_string(size) + " bytes, over the 16 MiB limit");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw std::runtime_error("ui_fb: cannot read button script " + path.string() + ": " +
                             std::strerror(errno));
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw std::runtime_error("ui_fb: error reading button script " + path.string());
  return parse(text.str(), path.string());
}

// --- clocks -------------------------------------------------------------------

void SteadyButtonClock::sleep_until(std::int64_t deadline_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(deadline_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void ManualButtonClock::sleep_until(std::int64_t deadline_ns) {
  now_ = std::max(now_, deadline_ns);
}

// --- ScriptButtonInput --------------------------------------------------------

ScriptButtonInput::ScriptButtonInput(ButtonScript script, ButtonClock& clock, DebounceOptions options)
    : script_(std::move(script)),
      clock_(&clock),
      debouncer_(options),
      start_ns_(clock.now_ns()),
      segment_origin_ns_(start_ns_) {}

ScriptButtonInput::ScriptButtonInput(ButtonScript script, DebounceOptions options)
    : script_(std::move(script)),
      owned_clock_(std::make_unique<SteadyButtonClock>()),
      clock_(owned_clock_.get()),
      debouncer_(options),
      start_ns_(clock_->now_ns()),
      segment_origin_ns_(start_ns_) {}

void ScriptButtonInput::notify_state(std::string_view state) {
  last_state_ = lower(state);
  last_state_ns_ = clock_->now_ns();
}

std::optional<std::string> ScriptButtonInput::awaiting() const {
  if (!awaiting_) return std::nullopt;
  return script_.awaits[segment_].state;
}

bool ScriptButtonInput::segment_fed() const {
  return next_edge_ == script_.edges.size() || script_.edges[next_edge_].segment != segment_;
}

void ScriptButtonInput::feed_segment_until(std::int64_t now_ns) {
  while (!segment_fed()) {
    RawEdge e = script_.edges[next_edge_].edge;
    e.time_ns += segment_origin_ns_;
    if (e.time_ns > now_ns) break;
    debouncer_.on_edge(e);
    ++next_edge_;
  }
}

bool ScriptButtonInput::try_pass_await(std::int64_t now_ns) {
  if (segment_ >= script_.awaits.size() || !segment_fed()) return false;
  const ButtonScript::Await& await = script_.awaits[segment_];
  const std::int64_t begins_ns = segment_origin_ns_ + await.start_ns;
  if (begins_ns > now_ns) return false;
  awaiting_ = true;
  if (last_state_ != lower(await.state)) return false;
  // A state reported before the await began counts from the await's start.
  segment_origin_ns_ = std::max(begins_ns, last_state_ns_);
  ++segment_;
  awaiting_ = false;
  return true;
}

void ScriptButtonInput::feed_until(std::int64_t now_ns) {
  do {
    feed_segment_until(now_ns);
  } while (try_pass_await(now_ns));
  debouncer_.advance(now_ns);
}

void ScriptButtonInput::throw_if_await_timed_out(std::int64_t now_ns) const {
  if (!awaiting_) return;
  const ButtonScript::Await& await = script_.awaits[segment_];
  if (now_ns < segment_origin_ns_ + await.start_ns + await.timeout_ns) return;
  throw ButtonScriptError(script_.source, await.line,
                          "timed out after " + duration_text(await.timeout_ns) +
                              " waiting for state " + await.state + " (last state: " +
                              last_state_.value_or("none reported") + ")");
}

// The earliest moment something can change: the next edge of this segment, the
// pending await's start or timeout, a debouncer deadline, or the caller's deadline.
std::int64_t ScriptButtonInput::next_wake_ns(std::int64_t deadline_ns) const {
  std::int64_t wake = deadline_ns;
  if (!segment_fed()) {
    wake = std::min(wake, segment_origin_ns_ + script_.edges[next_edge_].edge.time_ns);
  } else if (segment_ < script_.awaits.size()) {
    const ButtonScript::Await& await = script_.awaits[segment_];
    const std::int64_t begins_ns = segment_origin_ns_ + await.start_ns;
    wake = std::min(wake, awaiting_ ? begins_ns + await.timeout_ns : begins_ns);
  }
  if (auto d = debouncer_.next_deadline_ns()) wake = std::min(wake, *d);
  return wake;
}

std::optional<ButtonEvent> ScriptButtonInput::next_event(std::chrono::milliseconds timeout) {
  const std::int64_t now = clock_->now_ns();
  const std::int64_t wait = timeout_to_ns(timeout);
  const std::int64_t deadline =
      now > std::numeric_limits<std::int64_t>::max() - wait ? std::numeric_limits<std::int64_t>::max()
                                                            : now + wait;
  for (;;) {
    if (auto e = debouncer_.pop_event()) return e;
    const std::int64_t now = clock_->now_ns();
    feed_until(now);
    if (auto e = debouncer_.pop_event()) return e;
    // Events due before the timeout have been returned by now.
    throw_if_await_timed_out(now);
    if (now >= deadline) return std::nullopt;
    clock_->sleep_until(std::max(next_wake_ns(deadline), now));
  }
}

bool ScriptButtonInput::end_of_script() const {
  return next_edge_ == script_.edges.size() && segment_ == script_.awaits.size() &&
         debouncer_.idle();
}

}  // namespace propcam::ui_fb
