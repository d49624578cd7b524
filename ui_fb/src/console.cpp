#include "propcam/ui_fb/console.h"

#include <fcntl.h>
#include <linux/kd.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>

namespace propcam::ui_fb {
namespace {

// The VT in graphics mode, for the fatal-signal handler (-1: none).
std::atomic<int> g_taken_fd{-1};
constexpr int kFatalSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
struct sigaction g_previous[std::size(kFatalSignals)];

// Async-signal-safe: one ioctl, then the previous handler (a sanitizer's,
// or the default one that ends the process) gets the signal again.
extern "C" void restore_text_mode_and_reraise(int signal_number) {
  const int fd = g_taken_fd.exchange(-1);
  if (fd >= 0) ioctl(fd, KDSETMODE, KD_TEXT);
  for (std::size_t i = 0; i < std::size(kFatalSignals); ++i)
    if (kFatalSignals[i] == signal_number) sigaction(signal_number, &g_previous[i], nullptr);
  raise(signal_number);
}

void install_fatal_signal_handlers() {
  struct sigaction action {};
  action.sa_handler = restore_text_mode_and_reraise;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_NODEFER;
  for (std::size_t i = 0; i < std::size(kFatalSignals); ++i) sigaction(kFatalSignals[i], &action, &g_previous[i]);
}

void uninstall_fatal_signal_handlers() {
  for (std::size_t i = 0; i < std::size(kFatalSignals); ++i) sigaction(kFatalSignals[i], &g_previous[i], nullptr);
}

ConsoleMode mode_of(int fd, std::string& why) {
  int mode = 0;
  if (ioctl(fd, KDGETMODE, &mode) != 0) {
    why = std::string("not a virtual terminal (") + std::strerror(errno) + ")";
    return ConsoleMode::Unknown;
  }
  return mode == KD_GRAPHICS ? ConsoleMode::Graphics : ConsoleMode::Text;
}

int open_tty(const std::filesystem::path& tty, std::string& why) {
  const int fd = open(tty.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) why = "cannot open " + tty.string() + ": " + std::strerror(errno);
  return fd;
}

}  // namespace

ConsoleMode console_mode(const std::filesystem::path& tty, std::string& why) {
  const int fd = open_tty(tty, why);
  if (fd < 0) return ConsoleMode::Unknown;
  const ConsoleMode mode = mode_of(fd, why);
  close(fd);
  return mode;
}

bool restore_console_text_mode(const std::filesystem::path& tty, std::string& why) {
  const int fd = open_tty(tty, why);
  if (fd < 0) return false;
  bool ok = mode_of(fd, why) != ConsoleMode::Unknown;
  if (ok && ioctl(fd, KDSETMODE, KD_TEXT) != 0) {
    why = "cannot switch " + tty.string() + " to text mode: " + std::strerror(errno);
    ok = false;
  }
  close(fd);
  return ok;
}

ConsoleTakeover::ConsoleTakeover(const std::filesystem::path& fallback) {
  if (take(STDIN_FILENO, false, "standard input")) return;
  const std::string from_stdin = description_;
  std::string why;
  const int fd = open_tty(fallback, why);
  if (fd >= 0 && take(fd, true, fallback.string())) return;
  if (fd < 0) description_ = why;
  description_ = "console left alone: standard input: " + from_stdin + "; " + fallback.string() + ": " + description_;
}

bool ConsoleTakeover::take(int fd, bool owns_fd, const std::string& what) {
  std::string why;
  if (mode_of(fd, why) == ConsoleMode::Unknown) {
    description_ = why;
    if (owns_fd) close(fd);
    return false;
  }
  int expected = -1;
  if (!g_taken_fd.compare_exchange_strong(expected, fd)) {
    description_ = "another takeover holds the console";
    if (owns_fd) close(fd);
    return false;
  }
  if (ioctl(fd, KDSETMODE, KD_GRAPHICS) != 0) {
    description_ = std::string("cannot switch to graphics mode (") + std::strerror(errno) + ")";
    g_taken_fd.store(-1);
    if (owns_fd) close(fd);
    return false;
  }
  install_fatal_signal_handlers();
  fd_ = fd;
  owns_fd_ = owns_fd;
  description_ = what;
  return true;
}

void ConsoleTakeover::release() noexcept {
  if (fd_ < 0) return;
  uninstall_fatal_signal_handlers();
  int expected = fd_;
  g_taken_fd.compare_exchange_strong(expected, -1);
  ioctl(fd_, KDSETMODE, KD_TEXT);
  if (owns_fd_) close(fd_);
  fd_ = -1;
}

ConsoleTakeover::~ConsoleTakeover() { release(); }

}  // namespace propcam::ui_fb
