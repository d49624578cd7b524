// The names export gives things: what a file is called on the stick, and the
// spool entries' ids. Prop names come from users' USB props and may hold
// anything ("../../etc", newlines, 300 bytes of UTF-8), so only a safe
// alphabet ever reaches a path.
#pragma once

#include <chrono>
#include <string>

namespace propcam::firmware {

// Longest prop part of a file name, in bytes.
inline constexpr std::size_t kMaxPropNameChars = 40;

// Letters, digits, '-' and '_' kept; every run of anything else becomes one
// '_'; no leading or trailing '_' or '-'; cut to kMaxPropNameChars; "composite"
// when nothing is left. Never "." or "..", never a '/'.
std::string sanitise_name(const std::string& name);

// "2026-12-01_2301_chair": the local date and time the photo was taken (to
// the minute) and the sanitised prop name. Collisions get "_2", "_3", ... later.
std::string dated_stem(std::chrono::system_clock::time_point taken, const std::string& prop_name);

// The stem with its collision index: 1 -> "stem", 2 -> "stem_2".
std::string numbered_stem(const std::string& stem, int index);

// A fresh spool entry id, "20261201T230112-1a2b3c4d" (UTC time and random
// bits): sorts by creation and names the entry's temporary files on the stick.
std::string new_entry_id(std::chrono::system_clock::time_point now);

// True for ids new_entry_id makes (and nothing that could climb a path).
bool is_entry_id(const std::string& text);

// "2026:12:01 23:01:12", the EXIF DateTime form, local time.
std::string exif_date_time(std::chrono::system_clock::time_point t);

}  // namespace propcam::firmware
