// The libgpiod backend: clear errors, and real edges on a simulated chip
// (gpio-sim or gpio-mockup) where the kernel has one (skipped otherwise).
#include <gtest/gtest.h>

#include <gpiod.h>

#include <fstream>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

std::string error_of(const GpiodButtonOptions& options) {
  try {
    GpiodButtonInput input(options);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(GpiodButtonInput, MissingChipIsNamed) {
  GpiodButtonOptions o;
  o.chip = "propcam-no-such-chip";
  o.lines = {{Button::Ok, "BTN_OK"}};
  const auto what = error_of(o);
  EXPECT_NE(what.find("gpio chip propcam-no-such-chip"), std::string::npos) << what;
  EXPECT_NE(what.find("cannot open"), std::string::npos) << what;
}

TEST(GpiodButtonInput, NoLinesIsAnError) {
  GpiodButtonOptions o;
  o.chip = "propcam-no-such-chip";
  const auto what = error_of(o);
  EXPECT_NE(what.find("no button lines configured"), std::string::npos) << what;
}

// A simulated chip whose line 0 the test can drive, if the kernel offers one.
struct SimChip {
  std::string name;          // gpiochipN
  std::filesystem::path pull;  // gpio-sim: "pull-up"/"pull-down"; gpio-mockup: "1"/"0"
  bool sim = false;

  static std::optional<SimChip> find() {
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind("gpiochip", 0) != 0) continue;
      gpiod_chip* chip = gpiod_chip_open(entry.path().c_str());
      if (!chip) continue;
      const std::string label = gpiod_chip_label(chip);
      gpiod_chip_close(chip);
      SimChip c;
      c.name = name;
      if (label.rfind("gpio-sim", 0) == 0) {
        c.sim = true;
        c.pull = "/sys/bus/gpio/devices/" + name + "/sim_gpio0/pull";
      } else if (label.rfind("gpio-mockup", 0) == 0) {
        c.pull = "/sys/kernel/debug/gpio-mockup/" + name + "/0";
      } else {
        continue;
      }
      if (std::filesystem::exists(c.pull)) return c;
    }
    return std::nullopt;
  }
  // Pressed = the line pulled low (the buttons are active-low).
  void set_pressed(bool pressed) const {
    std::ofstream out(pull);
    out << (sim ? (pressed ? "pull-down" : "pull-up") : (pressed ? "0" : "1"));
  }
};

TEST(GpiodButtonInput, EdgesOnASimulatedChip) {
  const auto chip = SimChip::find();
  if (!chip) {
    GTEST_SKIP() << "no gpio-sim or gpio-mockup chip with a writable line 0 (no /dev/gpiochip* "
                    "from those drivers here): load gpio-sim or gpio-mockup to run this";
  }
  GpiodButtonOptions bad;
  bad.chip = chip->name;
  bad.lines = {{Button::Back, "propcam-no-such-line"}};
  const auto what = error_of(bad);
  EXPECT_NE(what.find("line 'propcam-no-such-line' (BACK) not found"), std::string::npos) << what;

  chip->set_pressed(false);
  GpiodButtonOptions o;
  o.chip = chip->name;
  o.lines = {{Button::Ok, "0"}};  // by offset
  GpiodButtonInput input(o);
  EXPECT_GE(input.poll_fd(), 0);
  const auto wait = std::chrono::milliseconds(2000);
  chip->set_pressed(true);
  auto e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->button, Button::Ok);
  EXPECT_EQ(e->kind, ButtonEvent::Kind::Press);
  chip->set_pressed(false);
  e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->kind, ButtonEvent::Kind::Release);
}

}  // namespace
}  // namespace propcam::ui_fb
