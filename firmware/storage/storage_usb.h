// Where exports go: the USB stick. A board names it as a folder (the virtual
// board, `--usb DIR`) or as "auto": the first writable mount of a removable
// block device, found in /proc/self/mountinfo and sysfs each time it is asked
// (a stick comes and goes while the appliance runs).
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/board_config.h"

namespace propcam::firmware {

struct UsbStatus {
  enum class State { Ready, Absent, ReadOnly, Full };
  State state = State::Absent;
  std::filesystem::path root;      // the stick's folder (mount point), when one was found
  std::uintmax_t free_bytes = 0;
  std::string message;             // for the status line: "USB 3.1 GB free", "no stick", "stick read-only", "stick full"
  bool usable() const { return state == State::Ready; }
};

const char* to_string(UsbStatus::State state);  // "ready", "absent", "read-only", "full"

// Below this much free space a stick counts as full (a composite's PNG, JPEG
// and sidecar need more).
inline constexpr std::uintmax_t kStickFullBelowBytes = 1 << 20;

// "3.1 GB", "512 MB", "12 kB" (decimal units, as sticks are sold).
std::string human_bytes(std::uintmax_t bytes);

// One mount from /proc/self/mountinfo.
struct MountInfo {
  std::string device;                // "8:1" (major:minor)
  std::filesystem::path mount_point; // unescaped (\040 -> ' ')
  std::string source;                // "/dev/sda1"
  std::string fs_type;
  bool read_only = false;            // the mount's own "ro" option
};
std::vector<MountInfo> parse_mountinfo(const std::string& text);

// Whether block device "MAJ:MIN" is removable: sysfs says so for it or its
// disk (<sys_dev_block>/MAJ:MIN/removable, or ../removable for a partition), or
// it hangs under a USB controller (its sysfs path holds "/usb").
bool is_removable_block_device(const std::filesystem::path& sys_dev_block, const std::string& device);

class UsbTarget {
 public:
  // A fixed folder: present when it is a folder.
  static UsbTarget folder(std::filesystem::path path);
  // Found among the mounts (the files are parameters for tests).
  static UsbTarget automatic(std::filesystem::path mountinfo = "/proc/self/mountinfo",
                             std::filesystem::path sys_dev_block = "/sys/dev/block");
  // The board's storage.usb; `runtime_path` (--usb) wins over the board and is
  // required for a "runtime" location (std::invalid_argument otherwise).
  static UsbTarget from_config(const StorageLocation& usb, const std::optional<std::filesystem::path>& runtime_path);

  // Looks now: present, writable, how much free space.
  UsbStatus status() const;
  // "folder /media/stick" or "auto (removable mounts)".
  std::string describe() const;

 private:
  UsbTarget() = default;
  std::optional<std::filesystem::path> find_mount() const;

  bool automatic_ = false;
  std::filesystem::path folder_;
  std::filesystem::path mountinfo_;
  std::filesystem::path sys_dev_block_;
};

// Wakes when the mount table changes (a stick mounted or unmounted: the
// kernel flags /proc/self/mountinfo to poll()), so the appliance re-reads
// UsbTarget::status() and flushes the spool then instead of polling.
class MountWatcher {
 public:
  explicit MountWatcher(const std::filesystem::path& mountinfo = "/proc/self/mountinfo");
  ~MountWatcher();
  MountWatcher(const MountWatcher&) = delete;
  MountWatcher& operator=(const MountWatcher&) = delete;
  // True when the mounts changed since the watcher was made or since the last
  // true; false when `timeout` passed first (or mountinfo cannot be watched).
  bool wait(std::chrono::milliseconds timeout);

 private:
  int fd_ = -1;
};

}  // namespace propcam::firmware
