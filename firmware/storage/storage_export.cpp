#include "storage/storage_export.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>

#include "storage/storage_names.h"

namespace propcam::firmware {

namespace fs = std::filesystem;

namespace {

enum class Presence { Absent, Ours, Other };

Presence file_presence(const fs::path& path, const Fingerprint& print) {
  std::error_code ec;
  const auto status = fs::symlink_status(path, ec);
  if (ec || !fs::exists(status)) return Presence::Absent;
  if (!fs::is_regular_file(status)) return Presence::Other;
  return fingerprint_file(path) == print ? Presence::Ours : Presence::Other;
}

// A folder part is published by one rename, so it is all there or absent.
Presence folder_presence(const fs::path& path, const std::vector<SpoolFile>& files) {
  std::error_code ec;
  const auto status = fs::symlink_status(path, ec);
  if (ec || !fs::exists(status)) return Presence::Absent;
  if (!fs::is_directory(status)) return Presence::Other;
  for (const auto& f : files)
    if (file_presence(path / f.path, f.print) != Presence::Ours) return Presence::Other;
  return Presence::Ours;
}

bool is_under(const fs::path& path, const fs::path& dir) {
  const std::string p = path.lexically_normal().string(), d = dir.lexically_normal().string();
  return p.size() > d.size() && p.compare(0, d.size(), d) == 0 && (p[d.size()] == '/' || d.back() == '/');
}

// The spool's copy, checked against its manifest (a damaged spool file must
// never become a "complete" file on the stick).
std::vector<std::uint8_t> verified_bytes(const fs::path& path, const Fingerprint& print) {
  std::vector<std::uint8_t> bytes = read_file_bytes(path);
  if (fingerprint(bytes) != print) throw StorageFailure(EBADMSG, "verify", path);
  return bytes;
}

// What an interrupted move left on the stick: temporaries are never a final
// name, so all of them can go before the next attempt.
void remove_stick_temporaries(StorageIo& io, const fs::path& stick_dir) {
  std::error_code ec;
  std::vector<fs::path> stale;
  for (fs::directory_iterator it(stick_dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->path().filename().string().rfind(kStickTempPrefix, 0) == 0) stale.push_back(it->path());
  for (const auto& path : stale) remove_tree(io, path);
}

std::string waiting_text(std::size_t waiting) { return std::to_string(waiting) + " waiting"; }

}  // namespace

const char* to_string(ExportOutcome::Kind kind) {
  switch (kind) {
    case ExportOutcome::Kind::Written: return "written";
    case ExportOutcome::Kind::Spooled: return "spooled";
    case ExportOutcome::Kind::Failed: return "failed";
  }
  return "?";
}

Exporter::Exporter(fs::path spool_dir, UsbTarget usb, ExportOptions options, std::shared_ptr<StorageIo> io)
    : io_(io ? std::move(io) : system_storage_io()),
      spool_(std::move(spool_dir), io_),
      usb_(std::move(usb)),
      options_(options) {}

void Exporter::publish_folder(const SpoolEntry& entry, const fs::path& temp, const fs::path& final_path) {
  check_io(io_->make_dir(temp), "mkdir", temp);
  std::vector<fs::path> dirs{temp};
  for (const auto& f : entry.folder_files) {
    // Sub-folders as needed (the manifest lists files only).
    fs::path sub = temp;
    for (const auto& part : fs::path(f.path).parent_path()) {
      sub /= part;
      if (std::find(dirs.begin(), dirs.end(), sub) != dirs.end()) continue;
      check_io(io_->make_dir(sub), "mkdir", sub);
      dirs.push_back(sub);
    }
    write_new_file(*io_, temp / f.path, verified_bytes(entry.dir / entry.folder_path / f.path, f.print));
  }
  for (auto d = dirs.rbegin(); d != dirs.rend(); ++d) check_io(io_->sync_dir(*d), "fsync folder", *d);
  check_io(io_->rename_new(temp, final_path), "rename", final_path);
  check_io(io_->sync_dir(final_path.parent_path()), "fsync folder", final_path.parent_path());
}

std::string Exporter::failure_reason(const StorageFailure& failure) const {
  if (is_under(failure.path(), spool_.dir())) return std::string("spool failed (") + failure.what() + ")";
  switch (failure.error()) {
    case ENOSPC:
    case EDQUOT: return "stick full";
    case EROFS:
    case EACCES:
    case EPERM: return "stick read-only";
    case ENOTDIR: return "stick's PropCam is not a folder";
    default: return "stick removed or failing";
  }
}

std::vector<fs::path> Exporter::move_to_stick(const SpoolEntry& entry, const UsbStatus& usb) {
  const fs::path stick_dir = usb.root / kStickFolder;
  ensure_dir(*io_, stick_dir);
  // A stick is foreign data: its PropCam may be a symlink to anywhere
  // (/etc, the spool). Exports go only into a real folder on the stick.
  std::error_code ec;
  if (!fs::is_directory(fs::symlink_status(stick_dir, ec)))
    throw StorageFailure(ENOTDIR, "use (not a plain folder)", stick_dir);

  // The first stem under which nothing belongs to another export.
  std::string stem;
  std::vector<Presence> files_present;
  Presence folder_present = Presence::Ours;
  for (int index = 1; index <= kMaxNameCollisions && stem.empty(); ++index) {
    const std::string candidate = numbered_stem(entry.stem, index);
    files_present.clear();
    bool taken = false;
    for (const auto& f : entry.files) {
      files_present.push_back(file_presence(stick_dir / (candidate + f.stick_suffix), f.print));
      taken = taken || files_present.back() == Presence::Other;
    }
    if (!entry.folder_path.empty()) {
      folder_present = folder_presence(stick_dir / (candidate + entry.folder_stick_suffix), entry.folder_files);
      taken = taken || folder_present == Presence::Other;
    }
    if (!taken) stem = candidate;
  }
  if (stem.empty()) throw StorageFailure(EEXIST, "find a free name", stick_dir / entry.stem);

  const std::string temp_prefix = std::string(kStickTempPrefix) + entry.id + "-";
  std::vector<fs::path> written;
  for (std::size_t i = 0; i < entry.files.size(); ++i) {
    const SpoolFile& f = entry.files[i];
    const fs::path final_path = stick_dir / (stem + f.stick_suffix);
    if (files_present[i] == Presence::Absent)
      publish_file(*io_, stick_dir / (temp_prefix + std::to_string(i) + ".tmp"), final_path,
                   verified_bytes(entry.dir / f.path, f.print));
    written.push_back(final_path);
  }
  if (!entry.folder_path.empty()) {
    const fs::path final_path = stick_dir / (stem + entry.folder_stick_suffix);
    if (folder_present == Presence::Absent) {
      const fs::path temp = stick_dir / (temp_prefix + "folder.tmp");
      try {
        publish_folder(entry, temp, final_path);
      } catch (const StorageFailure&) {
        try {
          remove_tree(*io_, temp);
        } catch (const StorageFailure&) {  // a pulled stick: removed at the next flush
        }
        throw;
      }
    }
    written.push_back(final_path);
  }
  spool_.remove(entry);
  return written;
}

ExportOutcome Exporter::export_composite(const ExportItem& item) {
  const std::string id = new_entry_id(std::chrono::system_clock::now());
  const std::vector<EncodedFile> files = encode_export(item, options_, id);
  // A missing scene folder costs the scene copy, never the composite.
  std::error_code ec;
  const bool with_scene = options_.scene && !item.scene_dir.empty();
  if (with_scene && !fs::is_directory(item.scene_dir, ec))
    spdlog::warn("export: no scene folder {}: exporting without it", item.scene_dir.string());
  const fs::path scene = with_scene && fs::is_directory(item.scene_dir, ec) ? item.scene_dir : fs::path();
  ExportOutcome outcome;
  outcome.entry_id = id;
  SpoolEntry entry;
  try {
    entry = spool_.add(id, dated_stem(item.taken, item.prop_name), item.prop_name, item.taken, files, scene);
  } catch (const StorageFailure& e) {
    outcome.kind = ExportOutcome::Kind::Failed;
    outcome.message = std::string("not saved: ") + e.what();
    spdlog::error("export: {}", outcome.message);
    return outcome;
  }
  const UsbStatus usb = usb_.status();
  std::string reason = usb.message;
  if (usb.usable()) {
    try {
      remove_stick_temporaries(*io_, usb.root / kStickFolder);
      outcome.files = move_to_stick(entry, usb);
      outcome.kind = ExportOutcome::Kind::Written;
      outcome.message = "saved to USB as " + outcome.files.front().filename().string();
      return outcome;
    } catch (const StorageFailure& e) {
      reason = failure_reason(e);
      spdlog::warn("export: {} ({})", reason, e.what());
    }
  }
  outcome.kind = ExportOutcome::Kind::Spooled;
  outcome.files = {entry.dir};
  outcome.message = reason + ": kept in the spool (" + waiting_text(spool_.entries().size()) + ")";
  return outcome;
}

FlushReport Exporter::flush_spool() {
  FlushReport report;
  report.usb = usb_.status();
  const std::vector<SpoolEntry> entries = spool_.entries();
  if (entries.empty()) {
    report.message = "spool empty";
    return report;
  }
  std::string reason = report.usb.message;
  if (report.usb.usable()) {
    try {
      remove_stick_temporaries(*io_, report.usb.root / kStickFolder);
    } catch (const StorageFailure& e) {
      spdlog::warn("flush: {}", e.what());
    }
  }
  bool stick_failed = !report.usb.usable();
  for (const SpoolEntry& entry : entries) {
    if (stick_failed) break;
    try {
      const auto files = move_to_stick(entry, report.usb);
      report.files.insert(report.files.end(), files.begin(), files.end());
      ++report.moved;
    } catch (const StorageFailure& e) {
      reason = failure_reason(e);
      spdlog::warn("flush {}: {} ({})", entry.id, reason, e.what());
      // A damaged spool entry is skipped; a failing stick ends the flush.
      stick_failed = !is_under(e.path(), spool_.dir());
    }
  }
  report.waiting = static_cast<int>(spool_.entries().size());
  const std::string moved = "moved " + std::to_string(report.moved) + " to USB";
  if (report.waiting == 0) report.message = moved;
  else report.message = (report.moved > 0 ? moved + "; " : "") + reason + ": " + waiting_text(report.waiting) + " in the spool";
  return report;
}

}  // namespace propcam::firmware
