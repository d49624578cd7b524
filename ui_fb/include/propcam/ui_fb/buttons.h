// The appliance's five buttons: a pure debouncer (raw edges in, press / release /
// long-press / repeat events out, driven by explicit times so it is testable with a
// fake clock) and the ButtonInput backends that feed it: libgpiod lines, a Linux
// evdev device (gpio-keys), and a script of timed presses for the virtual board.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace propcam::ui_fb {

enum class Button { Shoot, Next, Prev, Ok, Back };
inline constexpr std::size_t kButtonCount = 5;
inline constexpr std::array<Button, kButtonCount> kAllButtons{
    Button::Shoot, Button::Next, Button::Prev, Button::Ok, Button::Back};

// "SHOOT", "NEXT", "PREV", "OK", "BACK".
std::string_view button_name(Button button);
// Case-insensitive inverse of button_name(); nullopt for anything else.
std::optional<Button> button_from_name(std::string_view name);

struct ButtonEvent {
  enum class Kind { Press, Release, LongPress, Repeat };
  Button button;
  Kind kind;
  std::int64_t time_ns;  // CLOCK_MONOTONIC (steady_clock) nanoseconds

  bool operator==(const ButtonEvent&) const = default;
};

// "press", "release", "long-press", "repeat".
std::string_view kind_name(ButtonEvent::Kind kind);
// e.g. "OK long-press @ 1.234567s", for logs and test failure messages.
std::string to_string(const ButtonEvent& event);

// One level change as the hardware saw it, before debouncing.
struct RawEdge {
  Button button;
  bool pressed;
  std::int64_t time_ns;
};

struct ButtonBehaviour {
  bool long_press = false;  // emit LongPress once when held past long_press_ns
  bool repeat = false;      // emit Repeat while held (after repeat_delay_ns)
};

struct DebounceOptions {
  std::int64_t debounce_ns = 20'000'000;         // a level must hold this long to count
  std::int64_t long_press_ns = 800'000'000;      // held this long (from Press) -> LongPress
  std::int64_t repeat_delay_ns = 400'000'000;    // first Repeat this long after Press
  std::int64_t repeat_interval_ns = 100'000'000; // then one every interval while held
  // Indexed by Button. Defaults: NEXT and PREV repeat, OK long-presses (export).
  std::array<ButtonBehaviour, kButtonCount> behaviour{{
      {false, false},  // SHOOT
      {false, true},   // NEXT
      {false, true},   // PREV
      {true, false},   // OK
      {false, false},  // BACK
  }};

  ButtonBehaviour& of(Button b) { return behaviour[static_cast<std::size_t>(b)]; }
  const ButtonBehaviour& of(Button b) const { return behaviour[static_cast<std::size_t>(b)]; }
  // Throws std::invalid_argument for negative or zero-length parameters.
  void validate() const;
};

// Trailing-edge debouncer with long-press and auto-repeat timers. No clock, no
// threads: time only moves through on_edge() and advance().
//
// - A raw level change counts once the level has held debounce_ns after the last
//   raw edge, so a bounce burst collapses into one Press or Release and a glitch
//   shorter than the window (press and release inside it) produces nothing.
// - Every event is stamped with the moment the debouncer decides it (a Press comes
//   debounce_ns after the last bounce edge, a LongPress long_press_ns after the
//   Press, Repeats at Press + repeat_delay_ns + k * repeat_interval_ns), so the
//   queue is always in time order and the result does not depend on how often
//   advance() is called. Every due Repeat is emitted, even after a long gap.
// - Long-press and repeat timers pause while a release is being debounced; a
//   Release always follows a LongPress (the UI tells "long" from the LongPress).
// - A time earlier than the latest one seen is clamped to it (and counted), so a
//   clock that steps back cannot reorder or duplicate events.
// - An edge that does not change the raw level (press while down) is ignored.
class ButtonDebouncer {
 public:
  explicit ButtonDebouncer(DebounceOptions options = {});

  // Processes every deadline up to edge.time_ns, then applies the edge.
  void on_edge(const RawEdge& edge);
  // Processes every deadline up to now_ns.
  void advance(std::int64_t now_ns);

  std::optional<ButtonEvent> pop_event();
  std::vector<ButtonEvent> take_events();
  bool has_events() const { return !queue_.empty(); }
  // The earliest time at which advance() would produce an event or change state;
  // nullopt when nothing is pending (all buttons settled and not timing).
  std::optional<std::int64_t> next_deadline_ns() const;
  // True while the debounced level of `button` is pressed.
  bool is_held(Button button) const;
  // True when no button is held, nothing is being debounced and the queue is empty.
  bool idle() const;

  std::int64_t now_ns() const { return now_ns_; }
  std::uint64_t clamped_times() const { return clamped_times_; }
  const DebounceOptions& options() const { return options_; }

 private:
  struct State {
    bool raw = false;      // last raw level
    bool stable = false;   // debounced level
    std::int64_t last_edge_ns = 0;
    std::int64_t pressed_at_ns = 0;
    bool long_done = false;
    std::int64_t next_repeat_ns = 0;
    bool repeat_exhausted = false;  // saturated at INT64_MAX
  };
  enum class Due { Settle, Long, Repeat };

  std::int64_t clamp(std::int64_t t);
  std::optional<std::int64_t> deadline(std::size_t index, Due* what) const;
  void fire(std::size_t index, Due what, std::int64_t at);
  void emit(std::size_t index, ButtonEvent::Kind kind, std::int64_t at);

  DebounceOptions options_;
  std::array<State, kButtonCount> states_{};
  std::deque<ButtonEvent> queue_;
  std::int64_t now_ns_ = 0;
  bool have_time_ = false;
  std::uint64_t clamped_times_ = 0;
};

// CLOCK_MONOTONIC now, in nanoseconds (the clock ButtonEvent times use).
std::int64_t monotonic_now_ns();
// A next_event() timeout in nanoseconds: negative counts as 0, huge ones saturate.
std::int64_t timeout_to_ns(std::chrono::milliseconds timeout);

// A source of debounced button events.
class ButtonInput {
 public:
  virtual ~ButtonInput() = default;
  // Waits at most `timeout` (0 = just check) for the next event; nullopt if none.
  virtual std::optional<ButtonEvent> next_event(std::chrono::milliseconds timeout) = 0;
  // A descriptor that turns readable when raw input arrives, for an outer poll
  // loop; -1 if there is none. Long presses and repeats are timer-driven, so a
  // caller polling it must still call next_event() by next_deadline_ns().
  virtual int poll_fd() const { return -1; }
  // Human-readable identity for logs.
  virtual std::string name() const = 0;
  virtual const ButtonDebouncer& debouncer() const = 0;
};

// Shared by the device backends: waits on one pollable descriptor, reads the raw
// edges it yields and runs them, and the debouncer's timers, against
// monotonic_now_ns().
class FdButtonInput : public ButtonInput {
 public:
  std::optional<ButtonEvent> next_event(std::chrono::milliseconds timeout) final;
  const ButtonDebouncer& debouncer() const final { return debouncer_; }

 protected:
  explicit FdButtonInput(DebounceOptions options) : debouncer_(options) {}
  // Reads whatever raw input is ready without blocking and passes it to feed().
  virtual void read_ready(std::int64_t now_ns) = 0;
  // Feeds an edge; a device timestamp in the future is clamped to now_ns.
  void feed(const RawEdge& edge, std::int64_t now_ns);

 private:
  ButtonDebouncer debouncer_;
};

// ---------------------------------------------------------------------------
// libgpiod (v1 API, Debian's 1.6): one line per button, requested for both edges,
// active-low with the pull-up bias (retried without bias if the kernel refuses,
// recorded in notes()). Events are read with their kernel timestamps (monotonic on
// Linux >= 5.7; an implausible timestamp is replaced by the read time).

struct GpiodButtonOptions {
  // A chip as gpiod_chip_open_lookup understands it: "gpiochip0", "/dev/gpiochip0",
  // a number or a label.
  std::string chip = "gpiochip0";
  // Button -> line name (gpiod_chip_find_line); a name that is not found and is
  // all digits is taken as a line offset.
  std::map<Button, std::string> lines;
  bool active_low = true;
  bool pull_up = true;
  std::string consumer = "propcam-buttons";
  DebounceOptions debounce;
};

class GpiodButtonInput : public FdButtonInput {
 public:
  // Throws std::runtime_error naming the chip or line that is missing or busy.
  explicit GpiodButtonInput(GpiodButtonOptions options);
  ~GpiodButtonInput() override;
  GpiodButtonInput(const GpiodButtonInput&) = delete;
  GpiodButtonInput& operator=(const GpiodButtonInput&) = delete;

  int poll_fd() const override;
  std::string name() const override;
  // Fallbacks taken while opening (e.g. "bias not supported on line X").
  const std::vector<std::string>& notes() const { return notes_; }

 private:
  struct Impl;
  void read_ready(std::int64_t now_ns) override;

  std::unique_ptr<Impl> impl_;
  std::vector<std::string> notes_;
};

// ---------------------------------------------------------------------------
// Linux evdev: gpio-keys device-tree buttons (or any keyboard) as /dev/input/eventN.
// Key value 1 is a press and 0 a release; the kernel's autorepeat (value 2) is
// ignored, since the debouncer repeats. Timestamps come from the events, with the
// device switched to CLOCK_MONOTONIC (EVIOCSCLOCKID); if the driver refuses, the
// read time is used. After SYN_DROPPED the key state is re-read (EVIOCGKEY).

// KEY_CAMERA -> SHOOT; KEY_NEXT, KEY_RIGHT -> NEXT; KEY_PREVIOUS, KEY_LEFT -> PREV;
// KEY_OK, KEY_ENTER, KEY_SELECT -> OK; KEY_BACK, KEY_ESC -> BACK.
std::map<int, Button> default_evdev_key_map();

struct EvdevButtonOptions {
  std::map<int, Button> keys = default_evdev_key_map();  // key code -> button
  bool grab = false;  // EVIOCGRAB: keep the keys from the console
  DebounceOptions debounce;
};

class EvdevButtonInput : public FdButtonInput {
 public:
  // Throws std::runtime_error naming the device: missing, not an input device, or
  // reporting none of the mapped keys.
  explicit EvdevButtonInput(const std::filesystem::path& device, EvdevButtonOptions options = {});
  EvdevButtonInput(const EvdevButtonInput&) = delete;
  EvdevButtonInput& operator=(const EvdevButtonInput&) = delete;
  ~EvdevButtonInput() override;

  // The first <dir>/event* whose EVIOCGNAME equals `device_name` (e.g. "gpio-keys");
  // throws std::runtime_error listing the names seen if there is none.
  static std::filesystem::path find_device(std::string_view device_name,
                                           const std::filesystem::path& dir = "/dev/input");

  int poll_fd() const override { return fd_; }
  std::string name() const override;
  const std::string& device_name() const { return device_name_; }
  // False if the driver kept CLOCK_REALTIME and read times are used instead.
  bool kernel_timestamps() const { return kernel_timestamps_; }

 private:
  void read_ready(std::int64_t now_ns) override;
  void set_key(int code, bool down, std::int64_t time_ns, std::int64_t now_ns);
  void resync(std::int64_t now_ns);

  std::filesystem::path path_;
  EvdevButtonOptions options_;
  int fd_ = -1;
  std::string device_name_;
  bool kernel_timestamps_ = false;
  bool dropping_ = false;              // between SYN_DROPPED and the next SYN_REPORT
  std::map<int, bool> key_down_;       // mapped key code -> level
};

// ---------------------------------------------------------------------------
// Script backend: timed presses from a text file, for the virtual board and tests.
//
// Grammar (one step per line; '#' starts a comment; blank lines are ignored;
// keywords and button names are case-insensitive):
//
//   line     := [ when ] action
//   when     := "at" TIME          absolute, from the start of the script or, after
//                                  an await, from the moment the await passed
//             | "+" TIME           after the previous step ends (a press/hold ends
//                                  at its release); a step without `when` is "+0ms"
//   action   := "press" BUTTON [DURATION]   down, then up after DURATION (default 100ms)
//             | "hold"  BUTTON DURATION     the same, DURATION required
//             | "down"  BUTTON              level changes only, for chords
//             | "up"    BUTTON
//             | "wait"  DURATION            nothing; moves the "+" origin on
//             | "bounce" COUNT [INTERVAL]   from here on, every edge is followed by
//                                           COUNT bounces (back, then forth again),
//                                           toggles INTERVAL apart (default 1ms);
//                                           "bounce 0" turns it off
//             | "await" STATE [TIMEOUT]     pauses until the appliance reports STATE
//                                           (notify_state); TIMEOUT default 600s
//   TIME, DURATION, TIMEOUT := decimal number + unit "ms" or "s" (e.g. 500ms, 1.2s,
//                     0s); at most 24h; negative, NaN, infinite or unit-less is an error
//   BUTTON   := SHOOT | NEXT | PREV | OK | BACK
//   STATE    := a letter, then letters, digits, '_', '-' or '/' (case-insensitive)
//
// An await starts at its `when`, but not before every earlier edge (bounces
// included) has played. It passes as soon as the most recently reported state is
// STATE, at once if the appliance is already in it. The steps after it are timed
// from the moment it passed (the report, or the await's start if the state was
// reported earlier): both "+" and "at" count from there, so each await starts a new
// time origin. If TIMEOUT passes first, next_event() throws a ButtonScriptError.
//
// Steps must be in time order ("at" may not go back before the previous step's
// start). A button pressed while already down, or released while up, is an error,
// as is a line over 4096 bytes or one holding control characters. A bounce that
// would reach the same button's next edge is dropped, so the intended levels stay.
// Errors are ButtonScriptError: "<source>:<line>: ...".
//
// Example:
//   # export after placing a prop
//   at 0.5s press SHOOT
//   await placing          # analysis takes seconds, different on every machine
//   +200ms press OK
//   +1s hold OK 1200ms     # long press: export

class ButtonScriptError : public std::runtime_error {
 public:
  ButtonScriptError(const std::string& source, int line, const std::string& message);
  int line() const { return line_; }

 private:
  int line_;
};

// Awaits split a script into segments, each with its own time origin: segment 0
// starts with the script, segment k + 1 when awaits[k] passes.
struct ButtonScript {
  struct Edge {
    RawEdge edge;             // time_ns relative to its segment's origin
    int line;                 // the script line that produced it
    std::size_t segment = 0;  // which segment it belongs to
  };
  struct Await {
    std::string state;        // as written; compared case-insensitively
    std::int64_t start_ns;    // when waiting begins, relative to its segment's origin
                              // (never before that segment's last edge)
    std::int64_t timeout_ns;  // from start_ns
    int line;
  };
  std::string source;          // file name or "<script>", for messages
  std::vector<Edge> edges;     // by segment, then time (stable: script order on ties)
  std::vector<Await> awaits;   // awaits[k] ends segment k
  std::int64_t end_ns = 0;     // the last segment's last edge (or wait's end), relative
                               // to that segment's origin

  static ButtonScript parse(std::string_view text, std::string source = "<script>");
  // Throws std::runtime_error if the file cannot be read, ButtonScriptError if it
  // does not parse.
  static ButtonScript load(const std::filesystem::path& path);
};

// Where a ScriptButtonInput gets its time and how it waits.
class ButtonClock {
 public:
  virtual ~ButtonClock() = default;
  virtual std::int64_t now_ns() const = 0;
  virtual void sleep_until(std::int64_t deadline_ns) = 0;
};

// steady_clock; sleeps for real.
class SteadyButtonClock : public ButtonClock {
 public:
  std::int64_t now_ns() const override { return monotonic_now_ns(); }
  void sleep_until(std::int64_t deadline_ns) override;
};

// Virtual time: starts at `start_ns`, moves only through set/advance and
// sleep_until (which jumps there at once), so a script plays as fast as possible
// and deterministically.
class ManualButtonClock : public ButtonClock {
 public:
  explicit ManualButtonClock(std::int64_t start_ns = 0) : now_(start_ns) {}
  std::int64_t now_ns() const override { return now_; }
  void sleep_until(std::int64_t deadline_ns) override;
  void set(std::int64_t now_ns) { now_ = now_ns; }
  void advance(std::int64_t delta_ns) { now_ += delta_ns; }

 private:
  std::int64_t now_;
};

class ScriptButtonInput : public ButtonInput {
 public:
  // Plays against `clock` (which must outlive this), from clock.now_ns() now.
  ScriptButtonInput(ButtonScript script, ButtonClock& clock, DebounceOptions options = {});
  // Plays in real time on an internal SteadyButtonClock.
  explicit ScriptButtonInput(ButtonScript script, DebounceOptions options = {});

  std::optional<ButtonEvent> next_event(std::chrono::milliseconds timeout) override;
  std::string name() const override { return "script " + script_.source; }
  const ButtonDebouncer& debouncer() const override { return debouncer_; }

  // While the script waits at an await, next_event() returns nullopt after at most
  // `timeout` as usual (the debouncer keeps running), and throws ButtonScriptError
  // "<source>:<line>: timed out after 600s waiting for state placing (last state:
  // analysing)" once the await's own timeout has passed on the clock.
  //
  // The appliance reports its state (e.g. "placing") after every change, from the
  // thread that calls next_event(). The last report is remembered with the clock's
  // time, so an await for the state the appliance is already in passes at once.
  void notify_state(std::string_view state);
  // The state the script is waiting for, while it waits at an await.
  std::optional<std::string> awaiting() const;

  // True once every scripted edge has been fed and every await passed, the debouncer
  // has settled with no button held and every event has been returned.
  bool end_of_script() const;
  std::int64_t start_ns() const { return start_ns_; }
  const ButtonScript& script() const { return script_; }

 private:
  void feed_until(std::int64_t now_ns);
  void feed_segment_until(std::int64_t now_ns);
  bool segment_fed() const;
  // Starts the pending await once due; passes it if the state was reported.
  bool try_pass_await(std::int64_t now_ns);
  void throw_if_await_timed_out(std::int64_t now_ns) const;
  std::int64_t next_wake_ns(std::int64_t deadline_ns) const;

  ButtonScript script_;
  std::unique_ptr<ButtonClock> owned_clock_;
  ButtonClock* clock_;
  ButtonDebouncer debouncer_;
  std::int64_t start_ns_;
  std::size_t next_edge_ = 0;
  std::size_t segment_ = 0;         // the segment being played
  std::int64_t segment_origin_ns_;  // when it started (clock time)
  bool awaiting_ = false;           // segment_'s await has begun and not yet passed
  std::optional<std::string> last_state_;  // lower-case, as last reported
  std::int64_t last_state_ns_ = 0;
};

}  // namespace propcam::ui_fb
