// The internal spool: every export lands here first, and stays until it is
// fully and durably on a stick. An entry is a folder named by its id holding
// its files and a manifest.json (written last) with each file's size and hash.
// It is built under ".incoming-<id>" and renamed into place, so an entry
// either exists complete or not at all; deletion renames it to ".done-<id>"
// first. Leftovers of both kinds (a crash mid-way) are removed on start,
// unless another process is exporting into or removing from the same spool
// (it holds the folder's lock shared; see SpoolFolderLock).
//
//   <spool>/20261201T230112-1a2b3c4d/manifest.json, composite.png, composite.jpg,
//                                    metadata.json, layers.exr, scene/...
#pragma once

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "storage/storage_encode.h"
#include "storage/storage_io.h"

namespace propcam::firmware {

// One file of an entry: where it is in the entry, the suffix of its name on
// the stick, and what it must look like there.
struct SpoolFile {
  std::string path;          // relative to the entry (top-level files) or to its folder part
  std::string stick_suffix;  // top-level files only: ".png", "_layers.exr"
  Fingerprint print;
};

struct SpoolEntry {
  std::string id;
  std::string stem;  // the stick name before collision numbering: "2026-12-01_2301_chair"
  std::string prop_name;
  std::chrono::system_clock::time_point taken;
  std::filesystem::path dir;  // the entry's folder in the spool
  std::vector<SpoolFile> files;
  // The optional folder part (the scene model): copied as one folder "<stem>_scene".
  std::string folder_path;          // "scene", empty when none
  std::string folder_stick_suffix;  // "_scene"
  std::vector<SpoolFile> folder_files;
  std::uintmax_t bytes() const;
};

inline constexpr const char* kSpoolManifest = "manifest.json";
inline constexpr const char* kSpoolIncomingPrefix = ".incoming-";
inline constexpr const char* kSpoolDonePrefix = ".done-";
inline constexpr const char* kSceneFolder = "scene";
inline constexpr const char* kSceneStickSuffix = "_scene";

// An advisory lock on the spool folder. Writing (an entry being built or
// removed) holds it shared and waits for a cleaning; cleaning up leftovers
// wants it alone and does not wait: `held()` is false while anyone writes.
class SpoolFolderLock {
 public:
  enum class Mode { Writing, Cleaning };
  SpoolFolderLock(const std::filesystem::path& dir, Mode mode);
  ~SpoolFolderLock();
  SpoolFolderLock(const SpoolFolderLock&) = delete;
  SpoolFolderLock& operator=(const SpoolFolderLock&) = delete;
  bool held() const { return held_; }

 private:
  int fd_ = -1;
  bool held_ = false;
};

class Spool {
 public:
  // Creates the folder if missing and removes what a crash left half-made
  // or half-deleted. Throws StorageFailure when the folder cannot be made.
  Spool(std::filesystem::path dir, std::shared_ptr<StorageIo> io);

  // Writes a new entry durably; returns it. Throws StorageFailure (and leaves
  // no entry) when the spool's disk refuses.
  SpoolEntry add(const std::string& id, const std::string& stem, const std::string& prop_name,
                 std::chrono::system_clock::time_point taken, const std::vector<EncodedFile>& files,
                 const std::filesystem::path& scene_dir);

  // The complete entries, oldest first. An entry whose manifest cannot be read
  // (never made by this code) is skipped with a warning, never deleted.
  std::vector<SpoolEntry> entries() const;

  // Deletes an entry (it is safely on a stick).
  void remove(const SpoolEntry& entry);

  const std::filesystem::path& dir() const { return dir_; }

 private:
  void clean_leftovers();

  std::filesystem::path dir_;
  std::shared_ptr<StorageIo> io_;
};

// A file's bytes (spool files and the scene folder's). Throws StorageFailure.
std::vector<std::uint8_t> read_file_bytes(const std::filesystem::path& path);

}  // namespace propcam::firmware
