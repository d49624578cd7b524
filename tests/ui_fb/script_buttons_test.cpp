// The script grammar, its errors, and what scripts produce through the debouncer
// (on a ManualButtonClock: virtual time, nothing sleeps for real but one bounded wait).
#include <gtest/gtest.h>

#include <fstream>
#include <unistd.h>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

constexpr std::int64_t ms(double v) { return static_cast<std::int64_t>(v * 1'000'000); }
using Kind = ButtonEvent::Kind;

struct E {
  Button button;
  bool pressed;
  std::int64_t t;
};

std::vector<E> edges_of(const ButtonScript& s) {
  std::vector<E> out;
  for (const auto& e : s.edges) out.push_back(E{e.edge.button, e.edge.pressed, e.edge.time_ns});
  return out;
}

bool operator==(const E& a, const E& b) {
  return a.button == b.button && a.pressed == b.pressed && a.t == b.t;
}

void PrintTo(const E& e, std::ostream* os) {
  *os << button_name(e.button) << (e.pressed ? " down @" : " up @") << e.t;
}

// Plays a whole script as fast as possible; bounded so a bug cannot hang the test.
std::vector<ButtonEvent> play(const std::string& text, std::int64_t start = ms(1000),
                              DebounceOptions options = {}) {
  ManualButtonClock clock(start);
  ScriptButtonInput input(ButtonScript::parse(text), clock, options);
  std::vector<ButtonEvent> out;
  for (int i = 0; i < 100'000 && !input.end_of_script(); ++i) {
    if (auto e = input.next_event(std::chrono::hours(1))) out.push_back(*e);
  }
  EXPECT_TRUE(input.end_of_script());
  return out;
}

// The line number and message of the error `text` raises.
std::pair<int, std::string> error_of(const std::string& text) {
  try {
    ButtonScript::parse(text);
  } catch (const ButtonScriptError& e) {
    return {e.line(), e.what()};
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return {0, ""};
}

TEST(ButtonScript, ParsesTimesRelativeAndAbsolute) {
  const auto s = ButtonScript::parse(
      "# a comment\n"
      "\n"
      "at 0.5s press NEXT\n"
      "+200ms press ok 50ms   # trailing comment\r\n"
      "  + 1s hold Shoot 1.5s\n"
      "wait 250ms\n"
      "press BACK\n");
  EXPECT_EQ(edges_of(s), (std::vector<E>{{Button::Next, true, ms(500)},
                                         {Button::Next, false, ms(600)},
                                         {Button::Ok, true, ms(800)},
                                         {Button::Ok, false, ms(850)},
                                         {Button::Shoot, true, ms(1850)},
                                         {Button::Shoot, false, ms(3350)},
                                         {Button::Back, true, ms(3600)},
                                         {Button::Back, false, ms(3700)}}));
  EXPECT_EQ(s.edges[2].line, 4);
  EXPECT_EQ(s.end_ns, ms(3700));
}

TEST(ButtonScript, DownAndUpMakeChordsInTimeOrder) {
  const auto s = ButtonScript::parse(
      "at 0s down SHOOT\n"
      "at 100ms press OK\n"
      "at 150ms up SHOOT\n");
  EXPECT_EQ(edges_of(s), (std::vector<E>{{Button::Shoot, true, 0},
                                         {Button::Ok, true, ms(100)},
                                         {Button::Shoot, false, ms(150)},
                                         {Button::Ok, false, ms(200)}}));
}

TEST(ButtonScript, BounceAddsTogglesAfterEachEdgeButNeverPastTheNextOne) {
  const auto s = ButtonScript::parse("bounce 2\npress OK 100ms\nbounce 3 10ms\npress NEXT 30ms\n");
  EXPECT_EQ(edges_of(s), (std::vector<E>{{Button::Ok, true, 0},
                                         {Button::Ok, false, ms(1)},
                                         {Button::Ok, true, ms(2)},
                                         {Button::Ok, false, ms(3)},
                                         {Button::Ok, true, ms(4)},
                                         {Button::Ok, false, ms(100)},  // line 2 before line 4
                                         // NEXT down at 100: one bounce fits before its release
                                         {Button::Next, true, ms(100)},
                                         {Button::Ok, true, ms(101)},
                                         {Button::Ok, false, ms(102)},
                                         {Button::Ok, true, ms(103)},
                                         {Button::Ok, false, ms(104)},
                                         {Button::Next, false, ms(110)},
                                         {Button::Next, true, ms(120)},
                                         {Button::Next, false, ms(130)},
                                         {Button::Next, true, ms(140)},
                                         {Button::Next, false, ms(150)},
                                         {Button::Next, true, ms(160)},
                                         {Button::Next, false, ms(170)},
                                         {Button::Next, true, ms(180)},
                                         {Button::Next, false, ms(190)}}));
}

TEST(ButtonScript, ErrorsNameTheSourceAndLine) {
  struct Case {
    const char* text;
    int line;
    const char* says;
  };
  const Case cases[] = {
      {"press OK\n\npress FOO\n", 3, "unknown button 'FOO'"},
      {"at -1s press OK\n", 1, "negative time"},
      {"at nanms press OK\n", 1, "is not a time"},
      {"at infs press OK\n", 1, "is not a time"},
      {"at 500 press OK\n", 1, "is not a time"},
      {"at 1e3ms press OK\n", 1, "is not a time"},
      {"at 25h press OK\n", 1, "is not a time"},
      {"at 90000s press OK\n", 1, "longer than 24h"},
      {"at 99999999999999999999999999s press OK\n", 1, "longer than 24h"},
      {"at 1s press OK\nat 0.5s press NEXT\n", 2, "goes back in time"},
      {"at 0s down OK\nat 1s press OK\nat 2s up OK\n", 2, "OK is already down (pressed on line 1)"},
      {"up BACK\n", 1, "BACK is released but is not down"},
      {"# x\ndown SHOOT\n", 2, "SHOOT is still down at the end"},
      {"press OK 10ms extra\n", 1, "unexpected 'extra'"},
      {"jump OK\n", 1, "unknown action 'jump'"},
      {"hold OK\n", 1, "missing duration"},
      {"press\n", 1, "missing button"},
      {"at\n", 1, "missing time after 'at'"},
      {"+\n", 1, "missing time after '+'"},
      {"+5ms\n", 1, "missing action"},
      {"press OK 0ms\n", 1, "positive duration"},
      {"bounce -1\n", 1, "bounce count '-1'"},
      {"bounce 101\n", 1, "bounce count '101'"},
      {"bounce 2 0ms\n", 1, "bounce interval must be positive"},
      {"at 82800s hold OK 7200s\n", 1, "runs past 24h"},
      {"press OK\x01\n", 1, "control character 0x01"},
      {"press OK\nawait\n", 2, "missing state after 'await'"},
      {"await placing 10\n", 1, "'10' is not a time"},
      {"await placing -1s\n", 1, "negative time"},
      {"await placing 25h\n", 1, "is not a time"},
      {"await placing 90000s\n", 1, "longer than 24h"},
      {"await 10s\n", 1, "'10s' is not a state name"},
      {"await placing 10s extra\n", 1, "unexpected 'extra'"},
      {"at 2s press OK\nat 1s await placing\n", 2, "goes back in time"},
      {"await placing\nup OK\n", 2, "OK is released but is not down"},
  };
  for (const Case& c : cases) {
    const auto [line, what] = error_of(c.text);
    EXPECT_EQ(line, c.line) << c.text;
    EXPECT_NE(what.find(c.says), std::string::npos) << "message: " << what << "\nscript: " << c.text;
    EXPECT_EQ(what.rfind("<script>:" + std::to_string(c.line) + ": ", 0), 0u) << what;
  }
}

TEST(ButtonScript, LoadNamesTheFileInErrors) {
  EXPECT_THROW(
      {
        try {
          ButtonScript::load("/nonexistent/propcam/buttons.txt");
        } catch (const std::runtime_error& e) {
          EXPECT_NE(std::string(e.what()).find("/nonexistent/propcam/buttons.txt"), std::string::npos);
          throw;
        }
      },
      std::runtime_error);
  const auto path = std::filesystem::temp_directory_path() /
                    ("propcam_buttons_" + std::to_string(::getpid()) + ".txt");
  std::ofstream(path) << "press OK\npress WHAT\n";
  try {
    ButtonScript::load(path);
    ADD_FAILURE() << "no error";
  } catch (const ButtonScriptError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_EQ(std::string(e.what()).rfind(path.string() + ":2: ", 0), 0u) << e.what();
  }
  std::ofstream(path) << "press OK\n";
  EXPECT_EQ(ButtonScript::load(path).edges.size(), 2u);
  std::filesystem::remove(path);
}

TEST(ScriptButtonInput, BouncyPressesBecomeCleanEvents) {
  const auto events = play("bounce 3 2ms\nat 100ms press SHOOT 200ms\n");
  // Down at 100 bounces until 112 -> Press 20 ms later; up at 300 bounces until 312.
  EXPECT_EQ(events, (std::vector{ButtonEvent{Button::Shoot, Kind::Press, ms(1000 + 132)},
                                 ButtonEvent{Button::Shoot, Kind::Release, ms(1000 + 332)}}));
}

TEST(ScriptButtonInput, LongPressRepeatAndGlitchThroughTheRealDebouncer) {
  const auto events = play(
      "hold OK 1200ms\n"
      "+100ms hold NEXT 1s\n"
      "+100ms hold BACK 5ms   # a glitch: nothing\n",
      0);
  std::vector<ButtonEvent> expected{{Button::Ok, Kind::Press, ms(20)},
                                    {Button::Ok, Kind::LongPress, ms(820)},
                                    {Button::Ok, Kind::Release, ms(1220)},
                                    {Button::Next, Kind::Press, ms(1320)}};
  for (int t = 1720; t <= 2300; t += 100) expected.push_back({Button::Next, Kind::Repeat, ms(t)});
  expected.push_back({Button::Next, Kind::Release, ms(2320)});
  EXPECT_EQ(events, expected);
}

TEST(ScriptButtonInput, TheReadmeExamplePlays) {
  const auto events = play(
      "# place a prop, render, export\n"
      "at 0.5s press NEXT\n"
      "+200ms press OK\n"
      "+300ms press OK        # render\n"
      "+1s hold OK 1200ms     # long press: export\n"
      "bounce 3 2ms           # a worn switch from here on\n"
      "+500ms press BACK\n");
  std::string seen;
  for (const auto& e : events) {
    seen += std::string(button_name(e.button)) + " " + std::string(kind_name(e.kind)) + "; ";
  }
  EXPECT_EQ(seen,
            "NEXT press; NEXT release; OK press; OK release; OK press; OK release; "
            "OK press; OK long-press; OK release; BACK press; BACK release; ");
}

TEST(ScriptButtonInput, ManualClockSteppedByTheTest) {
  ManualButtonClock clock(ms(5000));
  ScriptButtonInput input(ButtonScript::parse("at 1s press OK\n"), clock);
  EXPECT_FALSE(input.end_of_script());
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(0)));
  clock.advance(ms(1019));
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(0)));
  clock.advance(ms(1));
  EXPECT_EQ(input.next_event(std::chrono::milliseconds(0)),
            (ButtonEvent{Button::Ok, Kind::Press, ms(6020)}));
  // A timeout on the manual clock moves virtual time by at most the timeout.
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(50)));
  EXPECT_EQ(clock.now_ns(), ms(6070));
  EXPECT_EQ(input.next_event(std::chrono::milliseconds(1000)),
            (ButtonEvent{Button::Ok, Kind::Release, ms(6120)}));
  EXPECT_EQ(clock.now_ns(), ms(6120));
  EXPECT_TRUE(input.end_of_script());
  EXPECT_EQ(input.name(), "script <script>");
}

// --- await ---------------------------------------------------------------------

TEST(ButtonScript, AwaitSplitsTheScriptIntoSegmentsWithTheirOwnOrigins) {
  const auto s = ButtonScript::parse(
      "at 1s press SHOOT\n"
      "+50ms await Placing 30s   # analysis\n"
      "+200ms press OK\n"
      "at 1s press NEXT\n"
      "await adjusting\n");
  EXPECT_EQ(edges_of(s), (std::vector<E>{{Button::Shoot, true, ms(1000)},
                                         {Button::Shoot, false, ms(1100)},
                                         {Button::Ok, true, ms(200)},
                                         {Button::Ok, false, ms(300)},
                                         {Button::Next, true, ms(1000)},
                                         {Button::Next, false, ms(1100)}}));
  EXPECT_EQ(s.edges[1].segment, 0u);
  EXPECT_EQ(s.edges[2].segment, 1u);
  ASSERT_EQ(s.awaits.size(), 2u);
  EXPECT_EQ(s.awaits[0].state, "Placing");
  EXPECT_EQ(s.awaits[0].start_ns, ms(1150));
  EXPECT_EQ(s.awaits[0].timeout_ns, ms(30'000));
  EXPECT_EQ(s.awaits[0].line, 2);
  EXPECT_EQ(s.awaits[1].start_ns, ms(1100));  // after NEXT's release
  EXPECT_EQ(s.awaits[1].timeout_ns, ms(600'000));
  EXPECT_EQ(s.end_ns, 0);  // the last segment is empty
}

TEST(ButtonScript, AnAwaitStartsOnlyAfterTheBouncesBeforeIt) {
  const auto s = ButtonScript::parse("bounce 3 10ms\npress OK 100ms\nawait placing\n");
  EXPECT_EQ(s.awaits.at(0).start_ns, ms(160));  // the release at 100 bounces until 160
}

TEST(ScriptButtonInput, AwaitPassesWhenNotifiedAndTimesTheRestFromThatMoment) {
  ManualButtonClock clock(ms(1000));
  ScriptButtonInput input(ButtonScript::parse("press SHOOT\n"
                                              "await placing\n"
                                              "+200ms press OK\n"
                                              "at 1s press NEXT\n"),
                          clock);
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Shoot, Kind::Press, ms(1020)}));
  // The release is delivered although the script now waits.
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Shoot, Kind::Release, ms(1120)}));
  EXPECT_FALSE(input.next_event(std::chrono::seconds(5)));
  EXPECT_EQ(clock.now_ns(), ms(6120));  // waited exactly the timeout given
  EXPECT_EQ(input.awaiting(), "placing");
  EXPECT_FALSE(input.end_of_script());
  input.notify_state("analysing");
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(0)));
  clock.set(ms(7000));
  input.notify_state("PLACING");
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Ok, Kind::Press, ms(7220)}));
  EXPECT_FALSE(input.awaiting());
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Ok, Kind::Release, ms(7320)}));
  // "at 1s" after the await counts from the notify too.
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Next, Kind::Press, ms(8020)}));
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Next, Kind::Release, ms(8120)}));
  EXPECT_TRUE(input.end_of_script());
}

TEST(ScriptButtonInput, AwaitForTheStateAlreadyReportedPassesAtOnce) {
  ManualButtonClock clock(0);
  ScriptButtonInput input(ButtonScript::parse("at 1s await viewfinder\n+100ms press BACK\n"), clock);
  input.notify_state("Viewfinder");
  // The script reaches the await at 1s; the steps after it count from then.
  EXPECT_EQ(input.next_event(std::chrono::hours(1)), (ButtonEvent{Button::Back, Kind::Press, ms(1120)}));
  EXPECT_FALSE(input.awaiting());
  // Only the most recent report counts.
  ScriptButtonInput second(ButtonScript::parse("await placing\npress OK\n"), clock);
  second.notify_state("placing");
  second.notify_state("rendering");
  EXPECT_FALSE(second.next_event(std::chrono::milliseconds(10)));
  EXPECT_EQ(second.awaiting(), "placing");
}

TEST(ScriptButtonInput, AwaitTimeoutIsAnErrorNamingTheLineAndTheLastState) {
  ManualButtonClock clock(ms(500));
  ScriptButtonInput input(ButtonScript::parse("press OK\n\nawait placing\n", "tour.txt"), clock);
  input.notify_state("analysing");
  EXPECT_TRUE(input.next_event(std::chrono::hours(1)));  // OK press
  EXPECT_TRUE(input.next_event(std::chrono::hours(1)));  // OK release
  try {
    input.next_event(std::chrono::hours(1));
    ADD_FAILURE() << "no timeout";
  } catch (const ButtonScriptError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_STREQ(e.what(), "tour.txt:3: timed out after 600s waiting for state placing "
                           "(last state: analysing)");
  }
  // The await began at the release (600 ms) and lasted 600 s on the manual clock.
  EXPECT_EQ(clock.now_ns(), ms(600 + 600'000));
  EXPECT_FALSE(input.end_of_script());
}

TEST(ScriptButtonInput, AwaitTimeoutWithNothingReportedAndACustomTimeout) {
  ManualButtonClock clock(0);
  ScriptButtonInput input(ButtonScript::parse("await adjusting 1.5s\n"), clock);
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(1499)));
  EXPECT_EQ(input.awaiting(), "adjusting");
  try {
    input.next_event(std::chrono::milliseconds(1));
    ADD_FAILURE() << "no timeout";
  } catch (const ButtonScriptError& e) {
    EXPECT_STREQ(e.what(), "<script>:1: timed out after 1500ms waiting for state adjusting "
                           "(last state: none reported)");
  }
}

TEST(ScriptButtonInput, ALastAwaitEndsTheScriptOnlyWhenSatisfied) {
  ManualButtonClock clock(0);
  ScriptButtonInput input(ButtonScript::parse("press OK\nawait exporting\n"), clock);
  for (int i = 0; i < 2; ++i) EXPECT_TRUE(input.next_event(std::chrono::hours(1)));
  EXPECT_FALSE(input.next_event(std::chrono::seconds(1)));
  EXPECT_FALSE(input.end_of_script());
  input.notify_state("exporting");
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(0)));
  EXPECT_TRUE(input.end_of_script());
  EXPECT_FALSE(input.awaiting());
}

TEST(ScriptButtonInput, AwaitStaysResponsiveOnTheRealClock) {
  ScriptButtonInput input(ButtonScript::parse("await placing 10s\npress NEXT 30ms\n"));
  const auto before = std::chrono::steady_clock::now();
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(30)));
  EXPECT_LT(std::chrono::steady_clock::now() - before, std::chrono::seconds(1));
  input.notify_state("placing");
  std::vector<ButtonEvent::Kind> kinds;
  for (int i = 0; i < 20 && !input.end_of_script(); ++i) {
    if (auto e = input.next_event(std::chrono::milliseconds(100))) kinds.push_back(e->kind);
  }
  EXPECT_EQ(kinds, (std::vector{Kind::Press, Kind::Release}));
}

TEST(ScriptButtonInput, TheReadmeAwaitExamplePlays) {
  ManualButtonClock clock(0);
  ScriptButtonInput input(ButtonScript::parse("# place a prop, render, export\n"
                                              "at 0.5s press SHOOT\n"
                                              "await placing\n"
                                              "+200ms press OK\n"
                                              "+300ms press OK\n"
                                              "+300ms press OK        # render\n"
                                              "await adjusting 1200s  # rendering converged\n"
                                              "+1s hold OK 1200ms     # long press: export\n"
                                              "bounce 3 2ms\n"
                                              "+500ms press BACK\n"),
                          clock);
  int presses = 0;
  for (int i = 0; i < 100 && !input.end_of_script(); ++i) {
    if (input.awaiting() == "placing") input.notify_state("placing");
    if (input.awaiting() == "adjusting" && presses == 4) input.notify_state("adjusting");
    if (auto e = input.next_event(std::chrono::seconds(1))) presses += e->kind == Kind::Press;
  }
  EXPECT_TRUE(input.end_of_script());
  EXPECT_EQ(presses, 6);
}

TEST(ScriptButtonInput, PlaysOnTheRealClock) {
  ScriptButtonInput input(ButtonScript::parse("press NEXT 30ms\n"));
  std::vector<ButtonEvent::Kind> kinds;
  for (int i = 0; i < 20 && !input.end_of_script(); ++i) {
    if (auto e = input.next_event(std::chrono::milliseconds(100))) kinds.push_back(e->kind);
  }
  EXPECT_EQ(kinds, (std::vector{Kind::Press, Kind::Release}));
  EXPECT_TRUE(input.end_of_script());
  EXPECT_EQ(input.poll_fd(), -1);
}

}  // namespace
}  // namespace propcam::ui_fb
