// The evdev backend: clear errors everywhere, and real events end to end through a
// uinput device when /dev/uinput is usable (skipped otherwise).
#include <gtest/gtest.h>

#include <fcntl.h>
#include <linux/uinput.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <fstream>
#include <thread>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(no error)";
}

std::filesystem::path temp_path(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         ("propcam_evdev_" + std::to_string(::getpid()) + "_" + name);
}

TEST(EvdevButtonInput, MissingDeviceNamesThePath) {
  const auto what = error_of([] { EvdevButtonInput("/dev/input/event-propcam-missing"); });
  EXPECT_NE(what.find("/dev/input/event-propcam-missing"), std::string::npos) << what;
  EXPECT_NE(what.find("cannot open"), std::string::npos) << what;
}

TEST(EvdevButtonInput, NonInputFileIsRejected) {
  const auto path = temp_path("plain");
  std::ofstream(path) << "not a device";
  const auto what = error_of([&] { EvdevButtonInput{path}; });
  EXPECT_NE(what.find(path.string()), std::string::npos) << what;
  EXPECT_NE(what.find("not an evdev input device"), std::string::npos) << what;
  std::filesystem::remove(path);
  const auto null_what = error_of([] { EvdevButtonInput("/dev/null"); });
  EXPECT_NE(null_what.find("not an evdev input device"), std::string::npos) << null_what;
}

TEST(EvdevButtonInput, FindDeviceSaysWhatItSaw) {
  const auto dir = temp_path("dir");
  std::filesystem::create_directories(dir);
  const auto what = error_of([&] { EvdevButtonInput::find_device("gpio-keys", dir); });
  EXPECT_NE(what.find("no input device named 'gpio-keys'"), std::string::npos) << what;
  EXPECT_NE(what.find("seen: none"), std::string::npos) << what;
  std::filesystem::remove_all(dir);
  const auto missing = error_of([&] { EvdevButtonInput::find_device("gpio-keys", dir); });
  EXPECT_NE(missing.find("cannot list input devices"), std::string::npos) << missing;
}

TEST(EvdevButtonInput, DefaultKeyMapCoversAllButtons) {
  const auto map = default_evdev_key_map();
  for (Button b : kAllButtons) {
    EXPECT_TRUE(std::any_of(map.begin(), map.end(), [&](const auto& kv) { return kv.second == b; }))
        << button_name(b);
  }
  EXPECT_EQ(map.at(KEY_CAMERA), Button::Shoot);
  EXPECT_EQ(map.at(KEY_ESC), Button::Back);
}

// A virtual gpio-keys-like device made with uinput; closed (and removed) on exit.
class UinputKeys {
 public:
  static constexpr const char* kName = "propcam-test-buttons";

  UinputKeys() {
    fd_ = ::open("/dev/uinput", O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) {
      error_ = std::string("cannot open /dev/uinput: ") + std::strerror(errno);
      return;
    }
    bool ok = ioctl(fd_, UI_SET_EVBIT, EV_KEY) == 0;
    for (int key : {KEY_CAMERA, KEY_RIGHT, KEY_LEFT, KEY_ENTER, KEY_ESC}) {
      ok = ok && ioctl(fd_, UI_SET_KEYBIT, key) == 0;
    }
    uinput_setup setup{};
    setup.id.bustype = BUS_VIRTUAL;
    std::strncpy(setup.name, kName, UINPUT_MAX_NAME_SIZE - 1);
    ok = ok && ioctl(fd_, UI_DEV_SETUP, &setup) == 0 && ioctl(fd_, UI_DEV_CREATE) == 0;
    if (!ok) error_ = std::string("uinput device setup failed: ") + std::strerror(errno);
  }
  ~UinputKeys() {
    if (fd_ >= 0) {
      ioctl(fd_, UI_DEV_DESTROY);
      ::close(fd_);
    }
  }
  const std::string& error() const { return error_; }

  void key(int code, int value) {
    emit(EV_KEY, code, value);
    emit(EV_SYN, SYN_REPORT, 0);
  }

 private:
  void emit(int type, int code, int value) {
    input_event ev{};
    ev.type = static_cast<unsigned short>(type);
    ev.code = static_cast<unsigned short>(code);
    ev.value = value;
    ASSERT_EQ(::write(fd_, &ev, sizeof ev), static_cast<ssize_t>(sizeof ev));
  }

  int fd_ = -1;
  std::string error_;
};

TEST(EvdevButtonInput, RealEventsThroughUinput) {
  if (!std::filesystem::exists("/dev/uinput")) {
    GTEST_SKIP() << "/dev/uinput does not exist (no uinput module or not exposed in this "
                    "container): the end-to-end evdev test needs it";
  }
  UinputKeys keys;
  if (!keys.error().empty()) GTEST_SKIP() << keys.error();
  // udev may take a moment to create the node: bounded retry.
  std::filesystem::path device;
  for (int i = 0; i < 200 && device.empty(); ++i) {
    try {
      device = EvdevButtonInput::find_device(UinputKeys::kName);
    } catch (const std::runtime_error&) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  if (device.empty()) GTEST_SKIP() << "uinput device created but no /dev/input/event* node appeared";

  EvdevButtonInput input(device);
  EXPECT_EQ(input.device_name(), UinputKeys::kName);
  EXPECT_GE(input.poll_fd(), 0);
  const auto wait = std::chrono::milliseconds(2000);

  keys.key(KEY_ENTER, 1);
  auto e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->button, Button::Ok);
  EXPECT_EQ(e->kind, ButtonEvent::Kind::Press);
  keys.key(KEY_ENTER, 2);  // the kernel's autorepeat: ignored
  keys.key(KEY_ENTER, 0);
  e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->button, Button::Ok);
  EXPECT_EQ(e->kind, ButtonEvent::Kind::Release);

  keys.key(KEY_CAMERA, 1);
  e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->button, Button::Shoot);
  EXPECT_EQ(e->kind, ButtonEvent::Kind::Press);
  keys.key(KEY_CAMERA, 0);
  e = input.next_event(wait);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->kind, ButtonEvent::Kind::Release);
  EXPECT_FALSE(input.next_event(std::chrono::milliseconds(50)));
}

}  // namespace
}  // namespace propcam::ui_fb
