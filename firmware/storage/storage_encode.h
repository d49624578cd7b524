// What one export holds, and its files as bytes: the composite as PNG and
// JPEG (metadata in PNG text and EXIF through OpenImageIO), a JSON sidecar,
// and optionally the linear layers as one multi-channel EXR. Encoding happens
// in memory so every byte then reaches the disk through StorageIo.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

struct ExportItem {
  cv::Mat composite_srgb8;                // CV_8UC3 RGB: exactly what the screen showed
  cv::Mat composite_linear;               // optional CV_32FC3 (the EXR's "composite" layer)
  std::map<std::string, cv::Mat> layers;  // optional linear layers (photo, per-light, depth): CV_32FC3 or CV_32FC1, same size
  std::string prop_name;                  // for the file name (sanitised)
  std::chrono::system_clock::time_point taken = std::chrono::system_clock::now();
  nlohmann::json metadata = nlohmann::json::object();  // scene/prop/render settings: in the sidecar and the image text
  std::filesystem::path scene_dir;        // optional: the scene model folder to copy
};

struct ExportOptions {
  bool jpeg = true;     // a JPEG beside the PNG
  bool layers = false;  // the EXR of linear layers (when the item has any)
  bool scene = false;   // a copy of the scene folder (when the item names one)
};

// One encoded file: its name inside a spool entry, the suffix its name on the
// stick gets after the stem ("2026-12-01_2301_chair" + ".png"), its bytes.
struct EncodedFile {
  std::string spool_name;
  std::string stick_suffix;
  std::vector<std::uint8_t> bytes;
};

inline constexpr int kJpegQuality = 95;
inline constexpr const char* kSoftwareName = "PropCam";

// The item's files. `entry_id` goes into every file's metadata, so two
// exports never have identical bytes (the stick copy is recognised by hash).
// Throws std::invalid_argument for an unusable item (no 8-bit RGB composite,
// layers of another size).
std::vector<EncodedFile> encode_export(const ExportItem& item, const ExportOptions& options, const std::string& entry_id);

}  // namespace propcam::firmware
