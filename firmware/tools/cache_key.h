// Models and features the benches train are cached on disk beside a JSON key
// of what made them; a cached file is used only when its key matches.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

namespace propcam::firmware {

// The file's size in bytes as text, or "missing": a cheap stamp for a key.
std::string file_stamp(const std::string& path);
// True when `key_file` holds exactly `key`.
bool key_matches(const std::filesystem::path& key_file, const nlohmann::json& key);
// Writes `key` to `key_file` atomically (temporary name, rename).
void write_key(const std::filesystem::path& key_file, const nlohmann::json& key);

}  // namespace propcam::firmware
