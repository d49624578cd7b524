#include "storage/storage_usb.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace propcam::firmware {

namespace fs = std::filesystem;

namespace {

// mountinfo escapes space, tab, newline and backslash as \ooo (octal).
std::string unescape_mount_field(const std::string& field) {
  std::string out;
  for (std::size_t i = 0; i < field.size(); ++i) {
    if (field[i] == '\\' && i + 3 < field.size() && std::isdigit(static_cast<unsigned char>(field[i + 1])) && std::isdigit(static_cast<unsigned char>(field[i + 2])) &&
        std::isdigit(static_cast<unsigned char>(field[i + 3]))) {
      out += static_cast<char>(std::stoi(field.substr(i + 1, 3), nullptr, 8));
      i += 3;
    } else {
      out += field[i];
    }
  }
  return out;
}

bool has_option(const std::string& options, const std::string& option) {
  std::istringstream in(options);
  std::string item;
  while (std::getline(in, item, ','))
    if (item == option) return true;
  return false;
}

bool reads_one(const fs::path& file) {
  std::ifstream in(file);
  int value = 0;
  return static_cast<bool>(in >> value) && value == 1;
}

UsbStatus absent(std::string message) {
  UsbStatus s;
  s.state = UsbStatus::State::Absent;
  s.message = std::move(message);
  return s;
}

}  // namespace

const char* to_string(UsbStatus::State state) {
  switch (state) {
    case UsbStatus::State::Ready: return "ready";
    case UsbStatus::State::Absent: return "absent";
    case UsbStatus::State::ReadOnly: return "read-only";
    case UsbStatus::State::Full: return "full";
  }
  return "?";
}

std::string human_bytes(std::uintmax_t bytes) {
  constexpr double kKilo = 1000.0;
  const char* units[] = {"B", "kB", "MB", "GB", "TB"};
  double value = static_cast<double>(bytes);
  int unit = 0;
  while (value >= kKilo && unit < 4) {
    value /= kKilo;
    ++unit;
  }
  char text[32];
  if (unit == 0) std::snprintf(text, sizeof text, "%ju B", bytes);
  else std::snprintf(text, sizeof text, value < 10 ? "%.1f %s" : "%.0f %s", value, units[unit]);
  return text;
}

std::vector<MountInfo> parse_mountinfo(const std::string& text) {
  std::vector<MountInfo> mounts;
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    // id parent MAJ:MIN root mount_point options [optional...] - fstype source super_options
    std::istringstream in(line);
    std::vector<std::string> fields;
    for (std::string f; in >> f;) fields.push_back(f);
    std::size_t dash = 6;
    while (dash < fields.size() && fields[dash] != "-") ++dash;
    if (fields.size() < 6 || dash + 2 >= fields.size()) continue;
    MountInfo m;
    m.device = fields[2];
    m.mount_point = unescape_mount_field(fields[4]);
    m.read_only = has_option(fields[5], "ro");
    m.fs_type = fields[dash + 1];
    m.source = unescape_mount_field(fields[dash + 2]);
    mounts.push_back(std::move(m));
  }
  return mounts;
}

bool is_removable_block_device(const fs::path& sys_dev_block, const std::string& device) {
  std::error_code ec;
  const fs::path link = sys_dev_block / device;
  const fs::path real = fs::canonical(link, ec);
  if (ec) return false;
  if (real.string().find("/usb") != std::string::npos) return true;
  if (reads_one(real / "removable")) return true;
  return fs::exists(real / "partition", ec) && reads_one(real.parent_path() / "removable");
}

UsbTarget UsbTarget::folder(fs::path path) {
  UsbTarget t;
  t.folder_ = std::move(path);
  return t;
}

UsbTarget UsbTarget::automatic(fs::path mountinfo, fs::path sys_dev_block) {
  UsbTarget t;
  t.automatic_ = true;
  t.mountinfo_ = std::move(mountinfo);
  t.sys_dev_block_ = std::move(sys_dev_block);
  return t;
}

UsbTarget UsbTarget::from_config(const StorageLocation& usb, const std::optional<fs::path>& runtime_path) {
  if (runtime_path) return folder(*runtime_path);
  switch (usb.kind) {
    case StorageLocation::Kind::Path: return folder(usb.path);
    case StorageLocation::Kind::Auto: return automatic();
    case StorageLocation::Kind::Runtime: break;
  }
  throw std::invalid_argument("the board's storage.usb is \"runtime\": give the stick's folder with --usb DIR");
}

std::optional<fs::path> UsbTarget::find_mount() const {
  if (!automatic_) return folder_;
  std::ifstream in(mountinfo_);
  if (!in) return std::nullopt;
  std::stringstream text;
  text << in.rdbuf();
  std::optional<fs::path> read_only_match;
  for (const MountInfo& m : parse_mountinfo(text.str())) {
    if (!is_removable_block_device(sys_dev_block_, m.device)) continue;
    if (!m.read_only) return m.mount_point;
    if (!read_only_match) read_only_match = m.mount_point;  // reported as read-only if nothing better
  }
  return read_only_match;
}

UsbStatus UsbTarget::status() const {
  const std::optional<fs::path> root = find_mount();
  if (!root) return absent("no stick");
  std::error_code ec;
  if (!fs::is_directory(*root, ec)) return absent("no stick");
  UsbStatus s;
  s.root = *root;
  struct statvfs vfs{};
  if (::statvfs(root->c_str(), &vfs) != 0) return absent("no stick");
  s.free_bytes = static_cast<std::uintmax_t>(vfs.f_bavail) * vfs.f_frsize;
  if ((vfs.f_flag & ST_RDONLY) || ::access(root->c_str(), W_OK) != 0) {
    s.state = UsbStatus::State::ReadOnly;
    s.message = "stick read-only";
  } else if (s.free_bytes < kStickFullBelowBytes) {
    s.state = UsbStatus::State::Full;
    s.message = "stick full";
  } else {
    s.state = UsbStatus::State::Ready;
    s.message = "USB " + human_bytes(s.free_bytes) + " free";
  }
  return s;
}

std::string UsbTarget::describe() const {
  return automatic_ ? "auto (removable mounts in " + mountinfo_.string() + ")" : "folder " + folder_.string();
}

MountWatcher::MountWatcher(const fs::path& mountinfo) : fd_(::open(mountinfo.c_str(), O_RDONLY | O_CLOEXEC)) {}

MountWatcher::~MountWatcher() {
  if (fd_ >= 0) ::close(fd_);
}

bool MountWatcher::wait(std::chrono::milliseconds timeout) {
  if (fd_ < 0) return false;
  pollfd p{fd_, POLLPRI, 0};
  int n;
  do n = ::poll(&p, 1, static_cast<int>(timeout.count()));
  while (n < 0 && errno == EINTR);
  // The kernel reports a changed mount table as POLLERR | POLLPRI and re-arms.
  return n > 0 && (p.revents & (POLLPRI | POLLERR));
}

}  // namespace propcam::firmware
