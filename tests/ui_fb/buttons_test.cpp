// The debouncer with a fake clock: every time is explicit, nothing sleeps.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

constexpr std::int64_t ms(double v) { return static_cast<std::int64_t>(v * 1'000'000); }

using Kind = ButtonEvent::Kind;

ButtonEvent ev(Button b, Kind k, std::int64_t t) { return ButtonEvent{b, k, t}; }

std::string dump(const std::vector<ButtonEvent>& events) {
  std::string out;
  for (const auto& e : events) out += to_string(e) + "\n";
  return out;
}

void edge(ButtonDebouncer& d, Button b, bool pressed, std::int64_t t) {
  d.on_edge(RawEdge{b, pressed, t});
}

TEST(ButtonNames, RoundTripAndCaseInsensitive) {
  for (Button b : kAllButtons) EXPECT_EQ(button_from_name(button_name(b)), b);
  EXPECT_EQ(button_name(Button::Shoot), "SHOOT");
  EXPECT_EQ(button_from_name("ok"), Button::Ok);
  EXPECT_EQ(button_from_name("Prev"), Button::Prev);
  EXPECT_FALSE(button_from_name("SELECT").has_value());
  EXPECT_FALSE(button_from_name("").has_value());
  EXPECT_FALSE(button_from_name("OK ").has_value());
  EXPECT_EQ(kind_name(Kind::LongPress), "long-press");
  EXPECT_EQ(to_string(ev(Button::Ok, Kind::LongPress, 1'234'567'000)), "OK long-press @ 1.234567s");
}

TEST(ButtonDebouncer, CleanPressAndReleaseAreReportedAfterTheWindow) {
  ButtonDebouncer d;
  edge(d, Button::Shoot, true, ms(1000));
  d.advance(ms(1019));
  EXPECT_FALSE(d.has_events());
  EXPECT_FALSE(d.is_held(Button::Shoot));
  d.advance(ms(1020));
  EXPECT_EQ(d.take_events(), (std::vector{ev(Button::Shoot, Kind::Press, ms(1020))}));
  EXPECT_TRUE(d.is_held(Button::Shoot));
  edge(d, Button::Shoot, false, ms(1300));
  d.advance(ms(2000));
  EXPECT_EQ(d.take_events(), (std::vector{ev(Button::Shoot, Kind::Release, ms(1320))}));
  EXPECT_TRUE(d.idle());
}

TEST(ButtonDebouncer, BounceBurstsCollapseIntoOneEvent) {
  ButtonDebouncer d;
  for (int i = 0; i < 5; ++i) edge(d, Button::Shoot, i % 2 == 0, ms(i));  // ends down at 4 ms
  d.advance(ms(200));
  for (int i = 0; i < 7; ++i) edge(d, Button::Shoot, i % 2 == 1, ms(300 + i * 0.5));  // ends up at 303 ms
  d.advance(ms(500));
  const auto events = d.take_events();
  EXPECT_EQ(events, (std::vector{ev(Button::Shoot, Kind::Press, ms(24)),
                                 ev(Button::Shoot, Kind::Release, ms(323))}))
      << dump(events);
}

TEST(ButtonDebouncer, GlitchShorterThanTheWindowIsIgnored) {
  ButtonDebouncer d;
  edge(d, Button::Back, true, ms(10));
  edge(d, Button::Back, false, ms(29));
  d.advance(ms(1000));
  EXPECT_FALSE(d.has_events());
  EXPECT_TRUE(d.idle());
  // A release glitch while held is ignored too.
  edge(d, Button::Back, true, ms(2000));
  d.advance(ms(2100));
  edge(d, Button::Back, false, ms(2200));
  edge(d, Button::Back, true, ms(2205));
  d.advance(ms(3000));
  EXPECT_EQ(d.take_events(), (std::vector{ev(Button::Back, Kind::Press, ms(2020))}));
  EXPECT_TRUE(d.is_held(Button::Back));
}

TEST(ButtonDebouncer, DuplicateEdgesAreIgnored) {
  ButtonDebouncer d;
  edge(d, Button::Back, false, ms(0));  // already up
  edge(d, Button::Back, true, ms(10));
  edge(d, Button::Back, true, ms(25));  // already down: must not restart the window
  d.advance(ms(30));
  EXPECT_EQ(d.take_events(), (std::vector{ev(Button::Back, Kind::Press, ms(30))}));
}

TEST(ButtonDebouncer, LongPressIsEmittedOnceAndTheReleaseStillFollows) {
  ButtonDebouncer d;
  edge(d, Button::Ok, true, 0);
  d.advance(ms(10'000));
  edge(d, Button::Ok, false, ms(10'000));
  d.advance(ms(11'000));
  const auto events = d.take_events();
  EXPECT_EQ(events, (std::vector{ev(Button::Ok, Kind::Press, ms(20)),
                                 ev(Button::Ok, Kind::LongPress, ms(820)),
                                 ev(Button::Ok, Kind::Release, ms(10'020))}))
      << dump(events);
}

TEST(ButtonDebouncer, ShortOkPressHasNoLongPress) {
  ButtonDebouncer d;
  edge(d, Button::Ok, true, 0);
  edge(d, Button::Ok, false, ms(799));  // 779 ms after the Press
  d.advance(ms(5000));
  EXPECT_EQ(d.take_events(), (std::vector{ev(Button::Ok, Kind::Press, ms(20)),
                                          ev(Button::Ok, Kind::Release, ms(819))}));
}

TEST(ButtonDebouncer, HeldNextRepeatsAtTheConfiguredTimes) {
  ButtonDebouncer d;
  edge(d, Button::Next, true, 0);
  edge(d, Button::Next, false, ms(1000));
  d.advance(ms(2000));
  std::vector<ButtonEvent> expected{ev(Button::Next, Kind::Press, ms(20))};
  for (int t = 420; t <= 1000; t += 100) expected.push_back(ev(Button::Next, Kind::Repeat, ms(t)));
  expected.push_back(ev(Button::Next, Kind::Release, ms(1020)));
  const auto events = d.take_events();
  EXPECT_EQ(events, expected) << dump(events);
  EXPECT_EQ(std::count_if(events.begin(), events.end(),
                          [](const ButtonEvent& e) { return e.kind == Kind::Repeat; }),
            6);
}

TEST(ButtonDebouncer, ResultDoesNotDependOnHowOftenAdvanceIsCalled) {
  const auto run = [](std::int64_t step) {
    ButtonDebouncer d;
    edge(d, Button::Prev, true, ms(3));
    edge(d, Button::Ok, true, ms(7));
    for (std::int64_t t = 0; t <= ms(2500); t += step) d.advance(t);
    edge(d, Button::Prev, false, ms(2500));
    edge(d, Button::Ok, false, ms(2501));
    d.advance(ms(4000));
    return d.take_events();
  };
  const auto coarse = run(ms(2500));
  EXPECT_EQ(run(ms(1)), coarse);
  EXPECT_EQ(run(ms(37)), coarse);
  EXPECT_GT(coarse.size(), 10u);
}

TEST(ButtonDebouncer, SeveralButtonsAtOnceAreIndependentAndInTimeOrder) {
  ButtonDebouncer d;
  edge(d, Button::Back, true, ms(0));
  edge(d, Button::Shoot, true, ms(0));
  edge(d, Button::Next, true, ms(5));
  edge(d, Button::Shoot, false, ms(100));
  edge(d, Button::Back, false, ms(450));
  edge(d, Button::Next, false, ms(450));
  d.advance(ms(1000));
  const auto events = d.take_events();
  EXPECT_EQ(events, (std::vector{ev(Button::Shoot, Kind::Press, ms(20)),  // ties: SHOOT before BACK
                                 ev(Button::Back, Kind::Press, ms(20)),
                                 ev(Button::Next, Kind::Press, ms(25)),
                                 ev(Button::Shoot, Kind::Release, ms(120)),
                                 ev(Button::Next, Kind::Repeat, ms(425)),
                                 ev(Button::Next, Kind::Release, ms(470)),
                                 ev(Button::Back, Kind::Release, ms(470))}))
      << dump(events);
}

TEST(ButtonDebouncer, TimeGoingBackwardsIsClampedDeterministically) {
  ButtonDebouncer d;
  edge(d, Button::Shoot, true, ms(100));
  d.advance(ms(50));  // backwards: treated as 100 ms
  EXPECT_EQ(d.clamped_times(), 1u);
  EXPECT_EQ(d.now_ns(), ms(100));
  edge(d, Button::Shoot, false, ms(90));  // also clamped to 100 ms: a glitch of 0 ms
  EXPECT_EQ(d.clamped_times(), 2u);
  d.advance(ms(500));
  EXPECT_FALSE(d.has_events());
  edge(d, Button::Shoot, true, ms(600));
  d.advance(ms(700));
  edge(d, Button::Shoot, false, ms(10));  // clamped to 700 ms
  d.advance(ms(800));
  const auto events = d.take_events();
  EXPECT_EQ(events, (std::vector{ev(Button::Shoot, Kind::Press, ms(620)),
                                 ev(Button::Shoot, Kind::Release, ms(720))}))
      << dump(events);
}

TEST(ButtonDebouncer, BehaviourIsConfigurablePerButton) {
  DebounceOptions o;
  o.of(Button::Next).repeat = false;
  o.of(Button::Back).long_press = true;
  o.of(Button::Ok).long_press = false;
  o.long_press_ns = ms(500);
  o.debounce_ns = ms(5);
  ButtonDebouncer d(o);
  for (Button b : {Button::Next, Button::Back, Button::Ok}) edge(d, b, true, 0);
  d.advance(ms(2000));
  const auto events = d.take_events();
  EXPECT_EQ(events, (std::vector{ev(Button::Next, Kind::Press, ms(5)), ev(Button::Ok, Kind::Press, ms(5)),
                                 ev(Button::Back, Kind::Press, ms(5)),
                                 ev(Button::Back, Kind::LongPress, ms(505))}))
      << dump(events);
}

TEST(ButtonDebouncer, GlitchDuringAHoldPausesTheTimers) {
  ButtonDebouncer d;
  edge(d, Button::Next, true, 0);
  d.advance(ms(410));
  edge(d, Button::Next, false, ms(410));  // a release glitch across the 420 ms repeat
  edge(d, Button::Next, true, ms(425));
  d.advance(ms(600));
  const auto events = d.take_events();
  // The paused repeat comes when the glitch ends; the next one an interval later.
  EXPECT_EQ(events, (std::vector{ev(Button::Next, Kind::Press, ms(20)),
                                 ev(Button::Next, Kind::Repeat, ms(425)),
                                 ev(Button::Next, Kind::Repeat, ms(525))}))
      << dump(events);
}

TEST(ButtonDebouncer, NextDeadlineSaysWhenToCallAdvance) {
  ButtonDebouncer d;
  EXPECT_FALSE(d.next_deadline_ns().has_value());
  edge(d, Button::Ok, true, ms(100));
  EXPECT_EQ(d.next_deadline_ns(), ms(120));
  d.advance(ms(120));
  EXPECT_EQ(d.next_deadline_ns(), ms(920));  // the long press
  d.advance(ms(920));
  EXPECT_FALSE(d.next_deadline_ns().has_value());  // held, nothing more to time
  edge(d, Button::Ok, false, ms(1000));
  EXPECT_EQ(d.next_deadline_ns(), ms(1020));
  edge(d, Button::Next, true, ms(1000));
  d.advance(ms(1020));
  EXPECT_EQ(d.next_deadline_ns(), ms(1420));
}

TEST(ButtonDebouncer, RejectsInvalidOptions) {
  DebounceOptions o;
  o.repeat_interval_ns = 0;
  EXPECT_THROW(ButtonDebouncer{o}, std::invalid_argument);
  o = DebounceOptions{};
  o.debounce_ns = -1;
  EXPECT_THROW(ButtonDebouncer{o}, std::invalid_argument);
  o = DebounceOptions{};
  o.debounce_ns = 0;  // no debouncing at all is allowed
  ButtonDebouncer d(o);
  edge(d, Button::Shoot, true, ms(5));
  d.advance(ms(5));
  EXPECT_EQ(d.take_events(), (std::vector{ev(Button::Shoot, Kind::Press, ms(5))}));
}

// The poll loop the device backends share, driven through a pipe: 'O' / 'o' are
// OK down / up at the read time. Real time, but every wait is bounded.
class PipeButtons : public FdButtonInput {
 public:
  PipeButtons() : FdButtonInput(DebounceOptions{}) {
    int fds[2];
    if (::pipe(fds) != 0) throw std::runtime_error("pipe");
    read_fd_ = fds[0];
    write_fd_ = fds[1];
  }
  ~PipeButtons() override {
    ::close(read_fd_);
    close_writer();
  }
  int poll_fd() const override { return read_fd_; }
  std::string name() const override { return "pipe"; }
  void send(char c) { ASSERT_EQ(::write(write_fd_, &c, 1), 1); }
  void close_writer() {
    if (write_fd_ >= 0) ::close(write_fd_);
    write_fd_ = -1;
  }

 private:
  void read_ready(std::int64_t now_ns) override {
    char buf[16];
    const ssize_t n = ::read(read_fd_, buf, sizeof buf);
    for (ssize_t i = 0; i < n; ++i) {
      feed(RawEdge{Button::Ok, buf[i] == 'O', now_ns + ms(1000)}, now_ns);  // future: clamped
    }
  }
  int read_fd_ = -1;
  int write_fd_ = -1;
};

TEST(FdButtonInput, PollLoopDeliversDebouncedEventsAndTimers) {
  PipeButtons input;
  const auto wait = std::chrono::milliseconds(3000);
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(0)));
  input.send('O');
  auto e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->kind, Kind::Press);
  EXPECT_LE(e->time_ns, monotonic_now_ns());  // the future timestamp was clamped
  e = input.next_event(wait);  // nothing to read: the long-press timer wakes the loop
  ASSERT_TRUE(e);
  EXPECT_EQ(e->kind, Kind::LongPress);
  input.send('o');
  e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->kind, Kind::Release);
  EXPECT_TRUE(input.debouncer().idle());
  input.close_writer();
  EXPECT_THROW(input.next_event(wait), std::runtime_error);  // hung up, no spinning
}

}  // namespace
}  // namespace propcam::ui_fb
