// Export to USB, the path the appliance and `propcam export` share. An export
// is first written to the spool (durably, atomically), then moved to the
// stick; it leaves the spool only once every file is durably on the stick.
// A stick that is absent, full, read-only or pulled mid-write leaves the
// export in the spool with a message for the screen; flush_spool() moves what
// waits once a usable stick is there.
//
// On the stick, in <stick>/PropCam/:
//   2026-12-01_2301_chair.png   the composite as shown (metadata in PNG text)
//   2026-12-01_2301_chair.jpg   the same as JPEG (EXIF), unless disabled
//   2026-12-01_2301_chair.json  the sidecar: export id, prop, time, metadata
//   2026-12-01_2301_chair_layers.exr, 2026-12-01_2301_chair_scene/   optional
// Each file is written as ".propcam-<id>-<n>.tmp", fsynced, renamed (never
// replacing) and the folder fsynced. A name taken by another export gets
// "_2", "_3", ...; a file already there with this entry's size and hash is
// this entry's own (a crash after the rename, before the spool forgot it),
// so a re-flush only deletes the spool entry: never a duplicate.
//
// export_composite and flush_spool run on one thread (the appliance's export
// worker), one spool per process; usb_status() and spool() only read and may
// be called from the UI thread meanwhile (an entry being written or deleted is
// not listed).
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "storage/storage_encode.h"
#include "storage/storage_io.h"
#include "storage/storage_spool.h"
#include "storage/storage_usb.h"

namespace propcam::firmware {

struct ExportOutcome {
  enum class Kind {
    Written,  // on the stick (and gone from the spool)
    Spooled,  // kept in the spool: no usable stick, or it failed mid-way
    Failed,   // not even the spool could keep it (its disk full or failing)
  };
  Kind kind = Kind::Failed;
  std::vector<std::filesystem::path> files;  // Written: the stick's files; Spooled: the spool entry's folder
  std::string entry_id;
  // For the screen: "saved to USB as 2026-12-01_2301_chair.png",
  // "no stick: kept in the spool (2 waiting)".
  std::string message;
};
const char* to_string(ExportOutcome::Kind kind);  // "written", "spooled", "failed"

struct FlushReport {
  int moved = 0;    // entries now on the stick
  int waiting = 0;  // entries still in the spool
  std::vector<std::filesystem::path> files;  // what was written to the stick
  UsbStatus usb;
  std::string message;  // "moved 2 to USB", "stick full: 3 waiting in the spool", "spool empty"
};

// The stick's export folder under its root.
inline constexpr const char* kStickFolder = "PropCam";
inline constexpr const char* kStickTempPrefix = ".propcam-";
// How many "_N" collision names are tried before giving up on a stem.
inline constexpr int kMaxNameCollisions = 9999;

class Exporter {
 public:
  // Opens (creates) the spool and cleans what a crash left there. `io` is the
  // write layer (the real syscalls by default; tests inject faults).
  Exporter(std::filesystem::path spool_dir, UsbTarget usb, ExportOptions options = {},
           std::shared_ptr<StorageIo> io = nullptr);

  // Encodes the item, spools it, then tries the stick. Throws
  // std::invalid_argument for an unusable item (see encode_export).
  ExportOutcome export_composite(const ExportItem& item);

  // Moves what waits in the spool (oldest first) to the stick while it works.
  FlushReport flush_spool();

  std::vector<SpoolEntry> spool() const { return spool_.entries(); }
  UsbStatus usb_status() const { return usb_.status(); }
  const ExportOptions& options() const { return options_; }

 private:
  // Copies one entry to the stick and drops it from the spool; returns the
  // stick's files. Throws StorageFailure when the stick (or spool) fails.
  std::vector<std::filesystem::path> move_to_stick(const SpoolEntry& entry, const UsbStatus& usb);
  // The scene folder: built under `temp`, published by one rename.
  void publish_folder(const SpoolEntry& entry, const std::filesystem::path& temp, const std::filesystem::path& final_path);
  std::string failure_reason(const StorageFailure& failure) const;

  std::shared_ptr<StorageIo> io_;
  Spool spool_;
  UsbTarget usb_;
  ExportOptions options_;
};

}  // namespace propcam::firmware
