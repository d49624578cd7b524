// The Linux virtual terminal under a framebuffer or DRM display. While the
// appliance's UI is on the screen, the console must not draw its cursor,
// kernel messages or a login prompt over it: taking the console puts its VT
// in graphics mode (KDSETMODE KD_GRAPHICS), where the kernel draws no text.
// Letting go, the destructor, and a fatal signal (SIGSEGV, SIGBUS, SIGFPE,
// SIGILL, SIGABRT) put it back in text mode; after SIGKILL the service's
// ExecStopPost (`propcam console --restore`) does.
#pragma once

#include <filesystem>
#include <string>

namespace propcam::ui_fb {

enum class ConsoleMode { Text, Graphics, Unknown };

// The mode of the VT at `tty`; Unknown with `why` when it is not a VT or
// cannot be opened. Never throws.
ConsoleMode console_mode(const std::filesystem::path& tty, std::string& why);

// Puts the VT at `tty` in text mode. False, with `why`, when it cannot.
bool restore_console_text_mode(const std::filesystem::path& tty, std::string& why);

class ConsoleTakeover {
 public:
  // Takes the first VT of: standard input (a service started with
  // TTYPath= and StandardInput=tty has its VT there, which it may switch
  // without privileges), then `fallback` (/dev/tty0: the foreground VT,
  // root or the tty group). When none is a VT that can be switched,
  // taken() is false and why() says so: a UI without a console (a
  // headless board, a terminal, a test) is not an error. One takeover at a
  // time per process; a second one takes nothing.
  explicit ConsoleTakeover(const std::filesystem::path& fallback = "/dev/tty0");
  ~ConsoleTakeover();
  ConsoleTakeover(const ConsoleTakeover&) = delete;
  ConsoleTakeover& operator=(const ConsoleTakeover&) = delete;

  bool taken() const { return fd_ >= 0; }
  // The VT taken ("standard input" or the path), or why none was.
  const std::string& description() const { return description_; }
  // Back to text mode now (idempotent).
  void release() noexcept;

 private:
  bool take(int fd, bool owns_fd, const std::string& what);
  int fd_ = -1;
  bool owns_fd_ = false;
  std::string description_;
};

}  // namespace propcam::ui_fb
