// Linux evdev backend: gpio-keys (or any key device) through /dev/input/eventN.
#include <fcntl.h>
#include <linux/input.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

// Closes the descriptor unless ownership is handed on with release().
class FdGuard {
 public:
  explicit FdGuard(int fd) : fd_(fd) {}
  ~FdGuard() {
    if (fd_ >= 0) ::close(fd_);
  }
  FdGuard(const FdGuard&) = delete;
  FdGuard& operator=(const FdGuard&) = delete;
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

constexpr std::size_t kKeyBytes = KEY_MAX / 8 + 1;

bool bit_set(const unsigned char* bits, int code) {
  return (bits[code / 8] >> (code % 8)) & 1;
}

std::string device_name_of(int fd) {
  char name[256] = {};
  if (ioctl(fd, EVIOCGNAME(sizeof name - 1), name) < 0) return {};
  return name;
}

[[noreturn]] void fail(const std::filesystem::path& device, const std::string& what, int err = 0) {
  throw std::runtime_error("ui_fb: input device " + device.string() + ": " + what +
                           (err ? std::string(": ") + std::strerror(err) : std::string()));
}

}  // namespace

std::map<int, Button> default_evdev_key_map() {
  return {
      {KEY_CAMERA, Button::Shoot}, {KEY_NEXT, Button::Next},    {KEY_RIGHT, Button::Next},
      {KEY_PREVIOUS, Button::Prev}, {KEY_LEFT, Button::Prev},   {KEY_OK, Button::Ok},
      {KEY_ENTER, Button::Ok},      {KEY_SELECT, Button::Ok},   {KEY_BACK, Button::Back},
      {KEY_ESC, Button::Back},
  };
}

EvdevButtonInput::EvdevButtonInput(const std::filesystem::path& device, EvdevButtonOptions options)
    : FdButtonInput(options.debounce), path_(device), options_(std::move(options)) {
  FdGuard fd(::open(device.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  if (fd.get() < 0) fail(device, "cannot open", errno);
  int version = 0;
  if (ioctl(fd.get(), EVIOCGVERSION, &version) < 0) {
    fail(device, "not an evdev input device (EVIOCGVERSION failed)", errno);
  }
  device_name_ = device_name_of(fd.get());

  unsigned char keys[kKeyBytes] = {};
  if (ioctl(fd.get(), EVIOCGBIT(EV_KEY, sizeof keys), keys) < 0) {
    fail(device, "cannot read its key capabilities", errno);
  }
  for (const auto& [code, button] : options_.keys) {
    if (code >= 0 && code <= KEY_MAX && bit_set(keys, code)) key_down_[code] = false;
  }
  if (key_down_.empty()) {
    fail(device, "'" + device_name_ + "' reports none of the " +
                     std::to_string(options_.keys.size()) + " mapped key codes");
  }
  // Event times on the clock ButtonEvent uses; older drivers may refuse.
  const int clock = CLOCK_MONOTONIC;
  kernel_timestamps_ = ioctl(fd.get(), EVIOCSCLOCKID, &clock) == 0;
  if (options_.grab && ioctl(fd.get(), EVIOCGRAB, 1) < 0) fail(device, "EVIOCGRAB", errno);
  fd_ = fd.release();
}

EvdevButtonInput::~EvdevButtonInput() {
  if (fd_ >= 0) ::close(fd_);
}

std::filesystem::path EvdevButtonInput::find_device(std::string_view wanted,
                                                    const std::filesystem::path& dir) {
  std::error_code ec;
  std::vector<std::filesystem::path> candidates;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.path().filename().string().rfind("event", 0) == 0) candidates.push_back(entry.path());
  }
  if (ec) fail(dir, "cannot list input devices: " + ec.message());
  std::sort(candidates.begin(), candidates.end());
  std::string seen;
  for (const auto& path : candidates) {
    FdGuard fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));
    if (fd.get() < 0) continue;
    const std::string name = device_name_of(fd.get());
    if (name == wanted) return path;
    seen += (seen.empty() ? "" : ", ") + path.filename().string() + " '" + name + "'";
  }
  fail(dir, "no input device named '" + std::string(wanted) + "' (seen: " +
                (seen.empty() ? std::string("none") : seen) + ")");
}

std::string EvdevButtonInput::name() const {
  return "evdev " + path_.string() + " '" + device_name_ + "'";
}

void EvdevButtonInput::set_key(int code, bool down, std::int64_t time_ns, std::int64_t now_ns) {
  const auto key = key_down_.find(code);
  if (key == key_down_.end() || key->second == down) return;
  const Button button = options_.keys.at(code);
  // Several keys may map to one button: its level is "any of them down".
  const auto any_down = [&] {
    return std::any_of(key_down_.begin(), key_down_.end(), [&](const auto& kv) {
      return kv.second && options_.keys.at(kv.first) == button;
    });
  };
  const bool before = any_down();
  key->second = down;
  const bool after = any_down();
  if (before != after) feed(RawEdge{button, after, time_ns}, now_ns);
}

void EvdevButtonInput::resync(std::int64_t now_ns) {
  unsigned char state[kKeyBytes] = {};
  if (ioctl(fd_, EVIOCGKEY(sizeof state), state) < 0) fail(path_, "EVIOCGKEY", errno);
  for (const auto& kv : key_down_) set_key(kv.first, bit_set(state, kv.first), now_ns, now_ns);
}

void EvdevButtonInput::read_ready(std::int64_t now_ns) {
  input_event events[64];
  for (;;) {
    const ssize_t got = ::read(fd_, events, sizeof events);
    if (got < 0) {
      if (errno == EAGAIN || errno == EINTR) return;
      fail(path_, errno == ENODEV ? "device disconnected" : "read failed", errno);
    }
    if (got == 0) return;
    for (std::size_t i = 0; i < static_cast<std::size_t>(got) / sizeof(input_event); ++i) {
      const input_event& ev = events[i];
      if (ev.type == EV_SYN && ev.code == SYN_DROPPED) {
        dropping_ = true;  // the queue overflowed: skip to the next report, then re-read
      } else if (dropping_) {
        if (ev.type == EV_SYN && ev.code == SYN_REPORT) {
          dropping_ = false;
          resync(now_ns);
        }
      } else if (ev.type == EV_KEY && (ev.value == 0 || ev.value == 1)) {
        const std::int64_t t = kernel_timestamps_
                                   ? static_cast<std::int64_t>(ev.input_event_sec) * 1'000'000'000 +
                                         static_cast<std::int64_t>(ev.input_event_usec) * 1000
                                   : now_ns;
        set_key(ev.code, ev.value == 1, t, now_ns);
      }
    }
  }
}

}  // namespace propcam::ui_fb
