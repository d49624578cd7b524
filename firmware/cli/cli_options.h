// Limits and parsers the `propcam` commands share.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace propcam::firmware {

// Every bad argument exits 2: CLI11's parse errors and the checks after
// parsing alike (CLI11's own codes run from 101 to 116).
inline constexpr int kExitBadArguments = 2;

// `--bounces` counts as Blender Cycles' max_bounces does (0: direct light
// only); the renderer's max_bounces is one more (path_tracer.h).
inline constexpr int kDefaultCliBounces = 3;
inline constexpr int kMaxCliBounces = 63;
inline constexpr int kMaxCliSpp = 65536;
inline constexpr int kMaxCliThreads = 1024;

inline int renderer_bounces(int cli_bounces) {
  if (cli_bounces < 0 || cli_bounces > kMaxCliBounces)
    throw std::invalid_argument("--bounces must be in 0.." + std::to_string(kMaxCliBounces));
  return cli_bounces + 1;
}

// Parses "A,B" or "AxB" into two numbers; nothing may follow.
template <typename T>
bool parse_pair(const std::string& text, T& a, T& b, char separator) {
  std::istringstream in(text);
  char sep = 0;
  return static_cast<bool>(in >> a >> sep >> b) && sep == separator && in.peek() == EOF;
}

}  // namespace propcam::firmware
