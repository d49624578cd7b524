// The console takeover: graphics mode on a virtual terminal, left alone on
// anything else (a pseudo-terminal, a file, a missing device).
#include <gtest/gtest.h>

#include <fcntl.h>
#include <linux/kd.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <string>

#include "propcam/ui_fb/console.h"

namespace {

using propcam::ui_fb::console_mode;
using propcam::ui_fb::ConsoleMode;
using propcam::ui_fb::ConsoleTakeover;
using propcam::ui_fb::restore_console_text_mode;

// A pseudo-terminal: a terminal, but not a VT (KDGETMODE fails on it).
struct Pty {
  Pty() : master(posix_openpt(O_RDWR | O_NOCTTY)) {
    grantpt(master);
    unlockpt(master);
    path = ptsname(master);
  }
  ~Pty() { close(master); }
  int master;
  std::string path;
};

TEST(Console, APseudoTerminalIsNotAVirtualTerminal) {
  Pty pty;
  std::string why;
  EXPECT_EQ(console_mode(pty.path, why), ConsoleMode::Unknown);
  EXPECT_NE(why.find("not a virtual terminal"), std::string::npos) << why;
  EXPECT_FALSE(restore_console_text_mode(pty.path, why));
  EXPECT_EQ(console_mode("/nonexistent/tty", why), ConsoleMode::Unknown);
  EXPECT_NE(why.find("cannot open /nonexistent/tty"), std::string::npos) << why;
}

TEST(Console, WithoutAVirtualTerminalTheTakeoverTakesNothingAndSaysWhy) {
  Pty pty;
  // Standard input is a pseudo-terminal too, as under a terminal emulator.
  const int saved_stdin = dup(STDIN_FILENO);
  const int slave = open(pty.path.c_str(), O_RDWR | O_NOCTTY);
  ASSERT_GE(slave, 0);
  dup2(slave, STDIN_FILENO);
  {
    ConsoleTakeover takeover(pty.path);
    EXPECT_FALSE(takeover.taken());
    EXPECT_NE(takeover.description().find("console left alone"), std::string::npos) << takeover.description();
    EXPECT_NE(takeover.description().find("not a virtual terminal"), std::string::npos) << takeover.description();
    takeover.release();  // nothing taken: nothing to do
  }
  ConsoleTakeover missing("/nonexistent/tty");
  EXPECT_FALSE(missing.taken());
  EXPECT_NE(missing.description().find("cannot open /nonexistent/tty"), std::string::npos) << missing.description();
  dup2(saved_stdin, STDIN_FILENO);
  close(saved_stdin);
  close(slave);
}

// Only where a real VT can be switched (root on a machine with a console,
// the qemu board): taken, released, and restored after a crash.
TEST(Console, AVirtualTerminalGoesToGraphicsAndBackEvenAfterACrash) {
  std::string why;
  if (console_mode("/dev/tty0", why) != ConsoleMode::Text) GTEST_SKIP() << "no VT in text mode here: " << why;
  {
    ConsoleTakeover takeover("/dev/tty0");
    ASSERT_TRUE(takeover.taken()) << takeover.description();
    EXPECT_EQ(console_mode("/dev/tty0", why), ConsoleMode::Graphics);
  }
  EXPECT_EQ(console_mode("/dev/tty0", why), ConsoleMode::Text);

  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ConsoleTakeover takeover("/dev/tty0");
    if (!takeover.taken()) _exit(3);
    ConsoleTakeover* volatile leaked = new ConsoleTakeover("/dev/tty0");  // a second takes nothing
    if (leaked->taken()) _exit(4);
    raise(SIGABRT);
    _exit(5);
  }
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "exit " << WEXITSTATUS(status);
  EXPECT_EQ(WTERMSIG(status), SIGABRT);
  EXPECT_EQ(console_mode("/dev/tty0", why), ConsoleMode::Text) << "the fatal signal left the VT in graphics mode";
}

}  // namespace
