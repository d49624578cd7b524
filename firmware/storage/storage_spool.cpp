#include "storage/storage_spool.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "storage/storage_names.h"

namespace propcam::firmware {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int kManifestFormat = 1;

json file_json(const SpoolFile& f, bool with_suffix) {
  json j = {{"path", f.path}, {"size", f.print.size}, {"fnv1a64", to_hex(f.print.hash)}};
  if (with_suffix) j["suffix"] = f.stick_suffix;
  return j;
}

// A relative path that stays inside its folder.
bool is_contained(const std::string& relative) {
  const fs::path p(relative);
  if (relative.empty() || p.is_absolute()) return false;
  for (const auto& part : p)
    if (part == ".." || part == ".") return false;
  return true;
}

SpoolFile file_from_json(const json& j, bool with_suffix) {
  SpoolFile f;
  f.path = j.at("path").get<std::string>();
  if (!is_contained(f.path)) throw std::runtime_error("path \"" + f.path + "\" leaves the entry");
  f.print.size = j.at("size").get<std::uintmax_t>();
  f.print.hash = std::stoull(j.at("fnv1a64").get<std::string>(), nullptr, 16);
  if (with_suffix) {
    f.stick_suffix = j.at("suffix").get<std::string>();
    if (f.stick_suffix.find('/') != std::string::npos) throw std::runtime_error("suffix holds a '/'");
  }
  return f;
}

json manifest_json(const SpoolEntry& e) {
  json files = json::array(), folder_files = json::array();
  for (const auto& f : e.files) files.push_back(file_json(f, true));
  for (const auto& f : e.folder_files) folder_files.push_back(file_json(f, false));
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(e.taken.time_since_epoch()).count();
  json j = {{"format", kManifestFormat}, {"id", e.id},       {"stem", e.stem},
            {"prop", e.prop_name},       {"taken_unix_ms", ms}, {"files", files}};
  if (!e.folder_path.empty())
    j["folder"] = {{"path", e.folder_path}, {"suffix", e.folder_stick_suffix}, {"files", folder_files}};
  return j;
}

SpoolEntry entry_from_manifest(const fs::path& dir) {
  const auto bytes = read_file_bytes(dir / kSpoolManifest);
  const json j = json::parse(bytes.begin(), bytes.end());
  if (j.at("format").get<int>() != kManifestFormat) throw std::runtime_error("unknown manifest format");
  SpoolEntry e;
  e.id = j.at("id").get<std::string>();
  if (e.id != dir.filename().string()) throw std::runtime_error("id does not match the folder");
  e.stem = j.at("stem").get<std::string>();
  if (e.stem.empty() || e.stem.find('/') != std::string::npos || e.stem[0] == '.')
    throw std::runtime_error("bad stem \"" + e.stem + "\"");
  e.prop_name = j.at("prop").get<std::string>();
  e.taken = std::chrono::system_clock::time_point(std::chrono::milliseconds(j.at("taken_unix_ms").get<long long>()));
  e.dir = dir;
  for (const auto& f : j.at("files")) e.files.push_back(file_from_json(f, true));
  if (j.contains("folder")) {
    const json& folder = j["folder"];
    e.folder_path = folder.at("path").get<std::string>();
    e.folder_stick_suffix = folder.at("suffix").get<std::string>();
    if (!is_contained(e.folder_path) || e.folder_stick_suffix.find('/') != std::string::npos)
      throw std::runtime_error("bad folder part");
    for (const auto& f : folder.at("files")) e.folder_files.push_back(file_from_json(f, false));
  }
  return e;
}

bool starts_with(const std::string& text, const std::string& prefix) { return text.rfind(prefix, 0) == 0; }

}  // namespace

// flock(2) on the spool folder: the kernel drops it when its holder dies,
// so a killed exporter's leftovers become removable and a live one's never are.
SpoolFolderLock::SpoolFolderLock(const fs::path& dir, Mode mode) {
  fd_ = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0) return;  // no folder to lock: nothing to share it with
  const int operation = mode == Mode::Writing ? LOCK_SH : LOCK_EX | LOCK_NB;
  int rc;
  do rc = ::flock(fd_, operation);
  while (rc != 0 && errno == EINTR);
  held_ = rc == 0;
}

SpoolFolderLock::~SpoolFolderLock() {
  if (fd_ >= 0) ::close(fd_);
}

std::uintmax_t SpoolEntry::bytes() const {
  std::uintmax_t total = 0;
  for (const auto& f : files) total += f.print.size;
  for (const auto& f : folder_files) total += f.print.size;
  return total;
}

std::vector<std::uint8_t> read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StorageFailure(errno ? errno : ENOENT, "read", path);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw StorageFailure(EIO, "read", path);
  return bytes;
}

Spool::Spool(fs::path dir, std::shared_ptr<StorageIo> io) : dir_(std::move(dir)), io_(std::move(io)) {
  std::error_code ec;
  if (!fs::is_directory(dir_, ec)) {
    // Parents first (a fresh data partition may hold nothing yet).
    fs::path partial;
    for (const auto& part : dir_) {
      partial /= part;
      if (!fs::exists(partial, ec)) ensure_dir(*io_, partial);
    }
  }
  clean_leftovers();
}

void Spool::clean_leftovers() {
  // Another process mid-export or mid-removal holds the folder shared: its
  // ".incoming-"/".done-" folder is live work, not a leftover. Leftovers wait
  // for a start when nobody is writing.
  const SpoolFolderLock cleaning(dir_, SpoolFolderLock::Mode::Cleaning);
  if (!cleaning.held()) {
    spdlog::info("spool: another export is in progress in {}; leftovers are left for the next start", dir_.string());
    return;
  }
  std::error_code ec;
  std::vector<fs::path> leftovers;
  for (fs::directory_iterator it(dir_, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (starts_with(name, kSpoolIncomingPrefix) || starts_with(name, kSpoolDonePrefix)) leftovers.push_back(it->path());
  }
  check_io(ec.value(), "list", dir_);
  for (const auto& path : leftovers) {
    spdlog::info("spool: removing {} (left by an interrupted export)", path.string());
    remove_tree(*io_, path);
  }
  if (!leftovers.empty()) check_io(io_->sync_dir(dir_), "fsync folder", dir_);
}

SpoolEntry Spool::add(const std::string& id, const std::string& stem, const std::string& prop_name,
                      std::chrono::system_clock::time_point taken, const std::vector<EncodedFile>& files,
                      const fs::path& scene_dir) {
  SpoolEntry entry;
  entry.id = id;
  entry.stem = stem;
  entry.prop_name = prop_name;
  entry.taken = std::chrono::time_point_cast<std::chrono::milliseconds>(taken);
  entry.dir = dir_ / id;
  const fs::path incoming = dir_ / (kSpoolIncomingPrefix + id);
  const SpoolFolderLock writing(dir_, SpoolFolderLock::Mode::Writing);
  try {
    check_io(io_->make_dir(incoming), "mkdir", incoming);
    for (const auto& f : files) {
      write_new_file(*io_, incoming / f.spool_name, f.bytes);
      entry.files.push_back({f.spool_name, f.stick_suffix, fingerprint(f.bytes)});
    }
    if (!scene_dir.empty()) {
      entry.folder_path = kSceneFolder;
      entry.folder_stick_suffix = kSceneStickSuffix;
      const fs::path folder = incoming / kSceneFolder;
      check_io(io_->make_dir(folder), "mkdir", folder);
      std::vector<fs::path> dirs{folder};
      // Regular files and folders only: a symlink in a scene folder is not followed.
      std::error_code ec;
      for (fs::recursive_directory_iterator it(scene_dir, ec), end; !ec && it != end; it.increment(ec)) {
        const fs::path relative = fs::relative(it->path(), scene_dir);
        const auto status = it->symlink_status();
        if (fs::is_directory(status)) {
          check_io(io_->make_dir(folder / relative), "mkdir", folder / relative);
          dirs.push_back(folder / relative);
        } else if (fs::is_regular_file(status)) {
          const auto bytes = read_file_bytes(it->path());
          write_new_file(*io_, folder / relative, bytes);
          entry.folder_files.push_back({relative.string(), "", fingerprint(bytes)});
        }
      }
      if (ec) throw StorageFailure(ec.value(), "read", scene_dir);
      for (auto d = dirs.rbegin(); d != dirs.rend(); ++d) check_io(io_->sync_dir(*d), "fsync folder", *d);
    }
    const std::string manifest = manifest_json(entry).dump(2) + "\n";
    write_new_file(*io_, incoming / kSpoolManifest,
                   std::span(reinterpret_cast<const std::uint8_t*>(manifest.data()), manifest.size()));
    check_io(io_->sync_dir(incoming), "fsync folder", incoming);
    check_io(io_->rename_new(incoming, entry.dir), "rename", entry.dir);
    check_io(io_->sync_dir(dir_), "fsync folder", dir_);
  } catch (const StorageFailure&) {
    try {
      remove_tree(*io_, incoming);
    } catch (const StorageFailure&) {  // removed on the next start
    }
    throw;
  }
  return entry;
}

std::vector<SpoolEntry> Spool::entries() const {
  std::vector<SpoolEntry> entries;
  std::error_code ec;
  for (fs::directory_iterator it(dir_, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!is_entry_id(name) || !it->is_directory()) continue;
    try {
      entries.push_back(entry_from_manifest(it->path()));
    } catch (const std::exception& e) {
      spdlog::warn("spool: skipping {}: {}", it->path().string(), e.what());
    }
  }
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return entries;
}

void Spool::remove(const SpoolEntry& entry) {
  const fs::path done = dir_ / (kSpoolDonePrefix + entry.id);
  const SpoolFolderLock writing(dir_, SpoolFolderLock::Mode::Writing);
  check_io(io_->rename_new(entry.dir, done), "rename", done);
  check_io(io_->sync_dir(dir_), "fsync folder", dir_);
  try {
    remove_tree(*io_, done);
  } catch (const StorageFailure& e) {  // gone from the spool already; the rest goes on the next start
    spdlog::warn("spool: {}", e.what());
  }
}

}  // namespace propcam::firmware
