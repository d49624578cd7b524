// Hard cases for the debouncer and the script backend: degenerate scripts, garbage,
// floods of edges, extreme times. Everything on virtual time.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

constexpr std::int64_t ms(double v) { return static_cast<std::int64_t>(v * 1'000'000); }
using Kind = ButtonEvent::Kind;

bool time_ordered(const std::vector<ButtonEvent>& events) {
  return std::is_sorted(events.begin(), events.end(),
                        [](const ButtonEvent& a, const ButtonEvent& b) { return a.time_ns < b.time_ns; });
}

TEST(ButtonsHardCases, EmptyAndCommentOnlyScriptsEndAtOnce) {
  for (const char* text : {"", "\n\n\n", "# only a comment", "   \t  \r\n# x\n\n"}) {
    const auto script = ButtonScript::parse(text);
    EXPECT_TRUE(script.edges.empty());
    ManualButtonClock clock;
    ScriptButtonInput input(script, clock);
    EXPECT_TRUE(input.end_of_script());
    EXPECT_FALSE(input.next_event(std::chrono::milliseconds(0)));
    EXPECT_FALSE(input.next_event(std::chrono::hours(24)));
  }
}

TEST(ButtonsHardCases, HugeLineIsRejectedWithItsLineNumber) {
  std::string text = "press OK\n" + std::string(1'000'000, 'x') + "\n";
  try {
    ButtonScript::parse(text);
    ADD_FAILURE() << "no error";
  } catch (const ButtonScriptError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(std::string(e.what()).find("longer than the limit of 4096"), std::string::npos);
  }
  // A long but legal line (a comment at the limit) is fine.
  EXPECT_NO_THROW(ButtonScript::parse("press OK " + std::string("#") + std::string(4086, 'y')));
}

TEST(ButtonsHardCases, BinaryGarbageIsAScriptErrorNeverACrash) {
  std::mt19937 rng(1234);
  for (int round = 0; round < 200; ++round) {
    std::string text(1 + rng() % 2000, '\0');
    for (char& c : text) c = static_cast<char>(rng() & 0xff);
    try {
      ButtonScript::parse(text, "garbage");
    } catch (const ButtonScriptError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("garbage:", 0), 0u);
    }
  }
  try {
    ButtonScript::parse(std::string("press OK\0\n", 10));
    ADD_FAILURE() << "NUL accepted";
  } catch (const ButtonScriptError& e) {
    EXPECT_NE(std::string(e.what()).find("control character 0x00"), std::string::npos);
  }
}

TEST(ButtonsHardCases, OddTimeSpellings) {
  for (const char* bad : {"at 1.2.3s press OK", "at .s press OK", "at s press OK", "at 1 s press OK",
                          "at 1MS5 press OK", "at +1s press OK", "at 0x10ms press OK", "at 1e9s press OK"}) {
    EXPECT_THROW(ButtonScript::parse(bad), ButtonScriptError) << bad;
  }
  EXPECT_EQ(ButtonScript::parse("AT 1.5S PRESS ok 2MS").edges.at(1).edge.time_ns, ms(1502));
  EXPECT_EQ(ButtonScript::parse("at 1s press OK 0.000001ms").edges.at(1).edge.time_ns, ms(1000) + 1);
  EXPECT_THROW(ButtonScript::parse("at 1s press OK 0.0000001ms"), ButtonScriptError);  // rounds to 0
}

TEST(ButtonsHardCases, HundredThousandEdgesInOneMillisecond) {
  ButtonDebouncer d;
  for (int i = 0; i < 100'000; ++i) {
    d.on_edge(RawEdge{Button::Shoot, i % 2 == 0, i * 10});  // 10 ns apart, ends up
  }
  d.advance(ms(100));
  EXPECT_FALSE(d.has_events());  // the whole millisecond is one long bounce, then released
  for (int i = 0; i < 100'001; ++i) {
    d.on_edge(RawEdge{Button::Shoot, i % 2 == 0, ms(200) + i * 10});  // ends down
  }
  d.advance(ms(300));
  const auto events = d.take_events();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0], (ButtonEvent{Button::Shoot, Kind::Press, ms(200) + 100'000 * 10 + ms(20)}));
}

TEST(ButtonsHardCases, RandomFloodOfEdgesOnAllButtons) {
  std::mt19937 rng(99);
  ButtonDebouncer d;
  for (int i = 0; i < 100'000; ++i) {
    d.on_edge(RawEdge{kAllButtons[rng() % kButtonCount], (rng() & 1) != 0,
                      static_cast<std::int64_t>(rng() % 1'000'000)});  // within 1 ms, unordered
  }
  d.advance(ms(10'000));
  const auto events = d.take_events();
  EXPECT_TRUE(time_ordered(events));
  for (Button b : kAllButtons) {
    const auto presses = std::count_if(events.begin(), events.end(), [&](const ButtonEvent& e) {
      return e.button == b && e.kind == Kind::Press;
    });
    EXPECT_LE(presses, 1) << button_name(b);
  }
  EXPECT_GT(d.clamped_times(), 0u);
}

TEST(ButtonsHardCases, AnHourLongGapWithNextHeldEmitsEveryRepeatExactly) {
  ButtonDebouncer d;
  d.on_edge(RawEdge{Button::Next, true, 0});
  d.advance(ms(3'600'000));
  const auto events = d.take_events();
  // Press at 20 ms, repeats at 420 ms + k * 100 ms up to 3600 s.
  ASSERT_EQ(events.size(), 1u + (3'600'000 - 420) / 100 + 1);
  EXPECT_EQ(events.back(), (ButtonEvent{Button::Next, Kind::Repeat, ms(3'599'920)}));
  EXPECT_TRUE(time_ordered(events));
}

TEST(ButtonsHardCases, ExtremeTimesDoNotOverflowOrHang) {
  constexpr auto kMax = std::numeric_limits<std::int64_t>::max();
  constexpr auto kMin = std::numeric_limits<std::int64_t>::min();
  ButtonDebouncer d;
  d.on_edge(RawEdge{Button::Ok, true, kMin});
  d.advance(kMin + ms(20));
  EXPECT_EQ(d.take_events(), (std::vector{ButtonEvent{Button::Ok, Kind::Press, kMin + ms(20)}}));
  d.on_edge(RawEdge{Button::Next, true, kMax - ms(500)});
  d.advance(kMax);
  d.advance(kMax);
  const auto events = d.take_events();
  EXPECT_TRUE(time_ordered(events));
  // OK long press, NEXT press, its repeats up to the end of time: the last one once.
  EXPECT_EQ(events.size(), 4u);
  EXPECT_EQ(events.back(), (ButtonEvent{Button::Next, Kind::Repeat, kMax}));
  EXPECT_EQ(d.now_ns(), kMax);
}

TEST(ButtonsHardCases, ExtremeTimeoutsAreClamped) {
  EXPECT_EQ(timeout_to_ns(std::chrono::milliseconds(-5)), 0);
  EXPECT_EQ(timeout_to_ns(std::chrono::milliseconds(3)), ms(3));
  EXPECT_GT(timeout_to_ns(std::chrono::milliseconds::max()), 0);
  ManualButtonClock clock(ms(10));
  ScriptButtonInput input(ButtonScript::parse("press OK\n"), clock);
  EXPECT_TRUE(input.next_event(std::chrono::milliseconds::max()));  // OK press, not an overflow
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(-1)));    // "just check"
}

TEST(ButtonsHardCases, OutOfRangeButtonIsIgnored) {
  ButtonDebouncer d;
  d.on_edge(RawEdge{static_cast<Button>(42), true, 0});
  d.advance(ms(100));
  EXPECT_FALSE(d.has_events());
  EXPECT_EQ(button_name(static_cast<Button>(42)), "?");
  EXPECT_FALSE(d.is_held(static_cast<Button>(42)));
}

TEST(ButtonsHardCases, LargeScriptWithMaximumBouncePlaysThrough) {
  std::string text = "bounce 100 0.01ms\n";
  for (int i = 0; i < 2000; ++i) text += "+50ms press " + std::string(button_name(kAllButtons[i % 5])) + " 30ms\n";
  const auto script = ButtonScript::parse(text);
  ManualButtonClock clock;
  ScriptButtonInput input(script, clock);
  std::size_t presses = 0, releases = 0;
  for (int i = 0; i < 1'000'000 && !input.end_of_script(); ++i) {
    if (auto e = input.next_event(std::chrono::hours(1))) {
      presses += e->kind == Kind::Press;
      releases += e->kind == Kind::Release;
    }
  }
  EXPECT_TRUE(input.end_of_script());
  EXPECT_EQ(presses, 2000u);
  EXPECT_EQ(releases, 2000u);
}

TEST(ButtonsHardCases, AButtonHeldAcrossAnAwaitKeepsRepeatingAndIsReleasedAfter) {
  ManualButtonClock clock(0);
  ScriptButtonInput input(ButtonScript::parse("down NEXT\nawait placing 2s\n+50ms up NEXT\n"), clock);
  std::vector<ButtonEvent> events;
  for (int i = 0; i < 8; ++i) events.push_back(input.next_event(std::chrono::hours(1)).value());
  // Press at 20 ms, then repeats at 420, 520, ... 1020 while the script waits.
  EXPECT_EQ(events[0], (ButtonEvent{Button::Next, Kind::Press, ms(20)}));
  EXPECT_EQ(events[7], (ButtonEvent{Button::Next, Kind::Repeat, ms(1020)}));
  EXPECT_EQ(input.awaiting(), "placing");
  clock.set(ms(1500));
  input.notify_state("placing");
  for (int i = 0; i < 1000 && !input.end_of_script(); ++i) {
    if (auto e = input.next_event(std::chrono::hours(1))) events.push_back(*e);
  }
  EXPECT_EQ(events.back(), (ButtonEvent{Button::Next, Kind::Release, ms(1570)}));
  EXPECT_EQ(events.end()[-2], (ButtonEvent{Button::Next, Kind::Repeat, ms(1520)}));
  EXPECT_TRUE(time_ordered(events));
  EXPECT_TRUE(input.end_of_script());
}

TEST(ButtonsHardCases, ChainedAwaitsForTheSameStatePassTogether) {
  // Only the latest report counts, so several awaits for the state already
  // reported all pass at once, and the time origin stays at the first one.
  ManualButtonClock clock(ms(100));
  ScriptButtonInput input(
      ButtonScript::parse("await placing\nawait PLACING\nawait placing 0s\n+10ms press OK\n"), clock);
  input.notify_state("placing");
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Ok, Kind::Press, ms(130)}));
  EXPECT_TRUE(input.next_event(std::chrono::hours(1)));
  EXPECT_TRUE(input.end_of_script());
}

TEST(ButtonsHardCases, AZeroTimeoutAwaitFailsAtOnceUnlessAlreadyInState) {
  ManualButtonClock clock(0);
  ScriptButtonInput input(ButtonScript::parse("await placing 0s\n"), clock);
  EXPECT_THROW(input.next_event(std::chrono::milliseconds(0)), ButtonScriptError);
  // The error repeats until the state is reported; then the await passes.
  EXPECT_THROW(input.next_event(std::chrono::milliseconds(0)), ButtonScriptError);
  input.notify_state("placing");
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(0)));
  EXPECT_TRUE(input.end_of_script());
}

TEST(ButtonsHardCases, AwaitsCanBeManyAndEachSegmentMayRunForADay) {
  std::string text;
  for (int i = 0; i < 1000; ++i) text += "at 82800s press OK\nawait s" + std::to_string(i) + " 86400s\n";
  const auto script = ButtonScript::parse(text);
  ASSERT_EQ(script.awaits.size(), 1000u);
  ManualButtonClock clock(0);
  ScriptButtonInput input(script, clock);
  std::size_t presses = 0;
  for (int i = 0; i < 100'000 && !input.end_of_script(); ++i) {
    if (auto state = input.awaiting()) input.notify_state(*state);
    if (auto e = input.next_event(std::chrono::hours(48))) presses += e->kind == Kind::Press;
  }
  EXPECT_TRUE(input.end_of_script());
  EXPECT_EQ(presses, 1000u);
  EXPECT_THROW(ButtonScript::parse("await x\nat 82800s hold OK 7200s\n"), ButtonScriptError);
}

TEST(ButtonsHardCases, StateNamesAreWordsNotGarbage) {
  for (const char* bad : {"await 'placing'", "await placing\x7f", "await #placing", "await +1s",
                          "await _x", "await placing 1s 2s"}) {
    EXPECT_THROW(ButtonScript::parse(bad), ButtonScriptError) << bad;
  }
  EXPECT_EQ(ButtonScript::parse("AWAIT Placing/Tier_2-b 1MS").awaits.at(0).state, "Placing/Tier_2-b");
}

}  // namespace
}  // namespace propcam::ui_fb
