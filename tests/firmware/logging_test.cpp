// Where the programs' logs go: the journal only when stderr is its stream.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "common/logging.h"

namespace {

namespace fs = std::filesystem;
using propcam::firmware::stderr_is_journal;

// stderr pointed at a file for the test's life, restored after.
class StderrToFile {
 public:
  explicit StderrToFile(const fs::path& file) : saved_(dup(STDERR_FILENO)) {
    std::fflush(stderr);
    const int fd = open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    dup2(fd, STDERR_FILENO);
    close(fd);
  }
  ~StderrToFile() {
    std::fflush(stderr);
    dup2(saved_, STDERR_FILENO);
    close(saved_);
  }

 private:
  int saved_;
};

std::string stream_of(const fs::path& file) {
  struct stat st {};
  stat(file.c_str(), &st);
  return std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
}

TEST(Logging, StderrIsTheJournalOnlyWhenJournalStreamNamesIt) {
  const fs::path dir = fs::path(::testing::TempDir()) / "propcam_logging";
  fs::create_directories(dir);
  const fs::path journal = dir / "journal_stream", other = dir / "other";
  std::FILE* f = std::fopen(other.c_str(), "w");
  std::fclose(f);

  unsetenv("JOURNAL_STREAM");
  {
    StderrToFile redirect(journal);
    EXPECT_FALSE(stderr_is_journal()) << "no JOURNAL_STREAM: a terminal or a pipe";
    setenv("JOURNAL_STREAM", stream_of(journal).c_str(), 1);
    EXPECT_TRUE(stderr_is_journal());
    setenv("JOURNAL_STREAM", stream_of(other).c_str(), 1);
    EXPECT_FALSE(stderr_is_journal()) << "stderr redirected away from the journal";
    setenv("JOURNAL_STREAM", "not:a:stream", 1);
    EXPECT_FALSE(stderr_is_journal());
    setenv("JOURNAL_STREAM", "", 1);
    EXPECT_FALSE(stderr_is_journal());
  }
  unsetenv("JOURNAL_STREAM");
  fs::remove_all(dir);
}

TEST(Logging, VerbositySetsTheLevel) {
  using propcam::firmware::Verbosity;
  propcam::firmware::set_up_logging("propcam_test", Verbosity::Quiet);
  EXPECT_EQ(spdlog::default_logger()->level(), spdlog::level::warn);
  propcam::firmware::set_up_logging("propcam_test", Verbosity::Verbose);
  EXPECT_EQ(spdlog::default_logger()->level(), spdlog::level::debug);
  propcam::firmware::set_up_logging("propcam_test", Verbosity::Normal);
  EXPECT_EQ(spdlog::default_logger()->level(), spdlog::level::info);
}

}  // namespace
