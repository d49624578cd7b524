#pragma once
// Where PropCam's shipped data lives: the models inference loads (depth
// database, scene and light classifiers, IBL ranker), the boards and the
// virtual board's recordings. Never a source path: an installed PropCam
// finds it beside its executable (<prefix>/bin -> <prefix>/share/propcam),
// a build tree finds the share/propcam folder CMake links at its top.

#include <filesystem>
#include <string>
#include <vector>

namespace propcam::inference {

// Environment variable that overrides the folder (a flag overrides both).
inline constexpr const char* kDataDirEnv = "PROPCAM_DATA_DIR";

// The folder, in this order: set_data_dir() (the --data-dir flag), then
// $PROPCAM_DATA_DIR, then <the executable's folder>/../share/propcam.
// Throws std::runtime_error naming what was tried when none exists.
std::filesystem::path data_dir();

// The --data-dir flag; an empty path restores the default order.
void set_data_dir(const std::filesystem::path& dir);

// The administrator's folder (boards of their own, the services' settings):
// $PROPCAM_CONFIG_DIR, else beside the prefix as GNU install dirs put it
// (<root>/usr/bin -> <root>/etc/propcam, <prefix>/bin -> <prefix>/etc/propcam).
// It may not exist; nothing there is required.
inline constexpr const char* kConfigDirEnv = "PROPCAM_CONFIG_DIR";
std::filesystem::path config_dir();

// data_dir() / relative.
std::filesystem::path data_file(const std::filesystem::path& relative);

// The files inference loads by default, relative to data_dir().
std::vector<std::filesystem::path> inference_data_files();

// Throws std::runtime_error naming the first of `files` (relative to
// data_dir()) that is missing or cannot be read, and how to point PropCam
// at its data. Programs call it at start, before any work.
void require_data_files(const std::vector<std::filesystem::path>& files);

}  // namespace propcam::inference
