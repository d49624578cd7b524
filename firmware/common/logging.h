// Where propcam's and propcamd's logs go: the journal, with each message's
// priority, when systemd connected stderr to it; stderr otherwise.
// Header-only: propcamd includes it without linking the firmware library.
#pragma once

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>

namespace propcam::firmware {

enum class Verbosity { Quiet, Normal, Verbose };

// True when stderr is the journal's stream: systemd sets $JOURNAL_STREAM to
// its "device:inode", and a redirected stderr (a pipe, a file) no longer
// matches it (systemd.exec(5)).
inline bool stderr_is_journal() {
  const char* stream = std::getenv("JOURNAL_STREAM");
  if (!stream) return false;
  unsigned long long device = 0, inode = 0;
  if (std::sscanf(stream, "%llu:%llu", &device, &inode) != 2) return false;
  struct stat st {};
  if (fstat(STDERR_FILENO, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == device && static_cast<unsigned long long>(st.st_ino) == inode;
}

inline spdlog::level::level_enum log_level(Verbosity v) {
  return v == Verbosity::Quiet ? spdlog::level::warn : v == Verbosity::Verbose ? spdlog::level::debug : spdlog::level::info;
}

// The default logger, named after the program: the journal's sink (info,
// warning, error as the journal's priorities) or coloured stderr.
inline void set_up_logging(const std::string& program, Verbosity verbosity) {
  spdlog::drop(program);
  std::shared_ptr<spdlog::logger> logger;
  if (stderr_is_journal())
    logger = std::make_shared<spdlog::logger>(program, std::make_shared<spdlog::sinks::systemd_sink_mt>(program));
  else
    logger = spdlog::stderr_color_mt(program);
  logger->set_level(log_level(verbosity));
  spdlog::set_default_logger(logger);
}

}  // namespace propcam::firmware
