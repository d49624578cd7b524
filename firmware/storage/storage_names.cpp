#include "storage/storage_names.h"

#include <cctype>
#include <cstdio>
#include <ctime>
#include <random>

namespace propcam::firmware {
namespace {

constexpr const char* kFallbackName = "composite";
constexpr std::size_t kIdTimeChars = 15;  // "20261201T230112"
constexpr std::size_t kIdRandomChars = 8;

bool is_safe(unsigned char c) { return std::isalnum(c) || c == '-' || c == '_'; }

std::tm local_time(std::chrono::system_clock::time_point t) {
  const std::time_t seconds = std::chrono::system_clock::to_time_t(t);
  std::tm tm{};
  localtime_r(&seconds, &tm);
  return tm;
}

std::string format_time(std::chrono::system_clock::time_point t, const char* format, bool utc) {
  const std::time_t seconds = std::chrono::system_clock::to_time_t(t);
  std::tm tm{};
  if (utc) gmtime_r(&seconds, &tm);
  else tm = local_time(t);
  char text[64];
  const std::size_t n = std::strftime(text, sizeof text, format, &tm);
  return std::string(text, n);
}

}  // namespace

std::string sanitise_name(const std::string& name) {
  std::string out;
  for (const unsigned char c : name) {
    // Plain ASCII test: std::isalnum of a UTF-8 byte depends on the locale.
    const bool ascii_safe = c < 0x80 && is_safe(c);
    if (ascii_safe) out += static_cast<char>(c);
    else if (!out.empty() && out.back() != '_') out += '_';
    if (out.size() >= kMaxPropNameChars) break;
  }
  while (!out.empty() && (out.back() == '_' || out.back() == '-')) out.pop_back();
  std::size_t start = 0;
  while (start < out.size() && (out[start] == '_' || out[start] == '-')) ++start;
  out.erase(0, start);
  return out.empty() ? kFallbackName : out;
}

std::string dated_stem(std::chrono::system_clock::time_point taken, const std::string& prop_name) {
  return format_time(taken, "%Y-%m-%d_%H%M", false) + "_" + sanitise_name(prop_name);
}

std::string numbered_stem(const std::string& stem, int index) {
  return index <= 1 ? stem : stem + "_" + std::to_string(index);
}

std::string new_entry_id(std::chrono::system_clock::time_point now) {
  static std::mt19937_64 random{std::random_device{}()};
  char bits[kIdRandomChars + 1];
  std::snprintf(bits, sizeof bits, "%08x", static_cast<unsigned>(random() & 0xffffffffu));
  return format_time(now, "%Y%m%dT%H%M%S", true) + "-" + bits;
}

bool is_entry_id(const std::string& text) {
  if (text.size() != kIdTimeChars + 1 + kIdRandomChars || text[8] != 'T' || text[kIdTimeChars] != '-') return false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (i == 8 || i == kIdTimeChars) continue;
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (!(i < kIdTimeChars ? std::isdigit(c) : std::isxdigit(c))) return false;
  }
  return true;
}

std::string exif_date_time(std::chrono::system_clock::time_point t) {
  return format_time(t, "%Y:%m:%d %H:%M:%S", false);
}

}  // namespace propcam::firmware
