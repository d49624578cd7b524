#pragma once

// What differs per board, read from board/<name>/board.json and validated
// before anything touches a device. Every error names the file and the JSON
// path of the field ("board/rpi/board.json: /buttons/map/ok: missing ..."), so
// a wrong board file is fixed without reading code. Relative paths are
// resolved against the board folder and may not climb out of it (".."). Paths
// are checked for form only: whether a device, script or recording exists is
// for the backend that opens it (the script of the virtual board, say, may be
// written after the board is loaded).
//
// The schema, field by field, is in board/README.md.

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/job_budget.h"
#include "propcam/render/vignetting.h"
#include "propcam/ui_fb/buttons.h"

namespace propcam::firmware {

// A board file that cannot be used. what() is "<file>: <json path>: <problem>".
class BoardConfigError : public std::runtime_error {
 public:
  BoardConfigError(std::filesystem::path file, std::string json_path, const std::string& problem);
  const std::filesystem::path& file() const { return file_; }
  const std::string& json_path() const { return json_path_; }  // a JSON pointer, "" for the file itself

 private:
  std::filesystem::path file_;
  std::string json_path_;
};

// The five buttons are ui_fb's (the input backends deliver them).
using Button = ui_fb::Button;
using ui_fb::kAllButtons;
const char* to_string(Button button);  // "shoot", "next", ... as in board.json

enum class ButtonBackend { Gpiod, Evdev, Script };

struct ButtonsConfig {
  ButtonBackend backend = ButtonBackend::Script;
  int debounce_ms = 0;     // every backend goes through the same debouncer
  int long_press_ms = 0;   // OK held this long is a long press (export)
  // gpiod: lines by name on one chip, active-low with pull-up.
  std::string gpio_chip;                        // "gpiochip0"
  std::map<Button, std::string> gpio_lines;     // all five, distinct
  // evdev: one input device, by path or by name, and a key code per button.
  std::filesystem::path evdev_device;           // "/dev/input/by-path/..." or empty
  std::string evdev_device_name;                // "gpio-keys" or empty (exactly one of the two is set)
  std::map<Button, int> evdev_keys;             // Linux KEY_* codes, all five, distinct
  // script: timed presses from a file (resolved; need not exist at load time).
  std::filesystem::path script;
};

enum class DisplayBackend { Fbdev, Drm, File };

struct DisplayConfig {
  DisplayBackend backend = DisplayBackend::File;
  std::filesystem::path device;  // fbdev: /dev/fbN; drm: /dev/dri/cardN; file: the snapshot folder (resolved)
  int rotation = 0;              // fbdev: 0, 90, 180 or 270
  int width = 0, height = 0;     // file only
};

enum class CameraBackend { V4l2, Libcamera, Replay };

struct Size {
  int width = 0, height = 0;
  bool operator==(const Size&) const = default;
};

struct CameraConfig {
  CameraBackend backend = CameraBackend::Replay;
  // The id to open (capture/camera_registry.h); a replay's folder is made
  // absolute. "libcamera:auto" means the first camera libcamera lists.
  std::string id;
  std::filesystem::path replay_dir;  // replay only (resolved)
  std::string viewfinder_format;     // a capture pixel format name, "YUYV"
  Size viewfinder_size;
  double viewfinder_fps = 0.0;
  Size still_size;
  // The lens's fall-off at the still's framing, from its calibration
  // (optional; unknown: the composite applies none).
  render::Vignetting vignetting;
};

// Where a storage folder lives: a path, found at run time by looking at the
// mounts ("auto", USB only), or given on the command line ("runtime").
struct StorageLocation {
  enum class Kind { Path, Auto, Runtime };
  Kind kind = Kind::Path;
  std::filesystem::path path;  // Kind::Path only (resolved)
};

struct StorageConfig {
  StorageLocation usb;
  StorageLocation spool_dir;  // exports wait here when no stick is in
  StorageLocation data_dir;   // the device's own state (throughput, thumbnails)
};

struct BoardConfig {
  std::string name;  // equals the board folder's name
  std::string description;
  std::filesystem::path dir;   // the board folder
  std::filesystem::path file;  // its board.json
  ButtonsConfig buttons;
  DisplayConfig display;
  CameraConfig camera;
  double camera_mount_height_m = 0.0;  // lens above the floor, for the inference's scale
  StorageConfig storage;
  JobBudget budgets;  // "budgets", optional: the working size, memory and render seconds of a shot
};

// The boards under board_root (folders holding a board.json), sorted by name.
std::vector<std::string> list_boards(const std::filesystem::path& board_root);

// Loads and validates board_root/name/board.json. Throws BoardConfigError
// (an unknown name lists the boards there).
BoardConfig load_board(const std::filesystem::path& board_root, const std::string& name);

// load_board over several roots: the first that holds the name wins; an
// unknown name lists the boards of all of them and, if several, the roots.
BoardConfig load_board(const std::vector<std::filesystem::path>& board_roots, const std::string& name);

// Loads and validates one board file; its folder is the board folder.
BoardConfig load_board_file(const std::filesystem::path& board_json);

// Board files larger than this are refused before parsing.
inline constexpr std::uintmax_t kMaxBoardFileBytes = 1 << 20;

}  // namespace propcam::firmware
