#include "cli/export_commands.h"

#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>

#include "common/board_config.h"
#include "common/board_lookup.h"
#include "propcam/capture/image_file.h"
#include "storage/storage_export.h"
#include "storage/storage_names.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

void add_storage_options(CLI::App& cmd, StorageChoice& s) {
  cmd.add_option("--board", s.board, "Board whose storage to use (board/<NAME>/board.json)");
  cmd.add_option("--usb", s.usb, "The stick's folder (instead of the board's)");
  cmd.add_option("--spool", s.spool, "The spool folder (instead of the board's)");
}

// The spool folder and the stick, from the flags or the board.
struct Storage {
  fs::path spool_dir;
  std::optional<UsbTarget> usb;  // absent: the board says "runtime" and no --usb was given
};

Storage resolve_storage(const StorageChoice& s) {
  std::optional<BoardConfig> board;
  if (s.usb.empty() || s.spool.empty()) board = load_board(installed_board_roots(), s.board);
  Storage out;
  if (!s.spool.empty()) out.spool_dir = s.spool;
  else if (board->storage.spool_dir.kind == StorageLocation::Kind::Path) out.spool_dir = board->storage.spool_dir.path;
  else throw std::invalid_argument("board " + s.board + ": storage.spool_dir is \"runtime\": give --spool DIR");
  if (!s.usb.empty()) out.usb = UsbTarget::folder(s.usb);
  else if (board->storage.usb.kind != StorageLocation::Kind::Runtime)
    out.usb = UsbTarget::from_config(board->storage.usb, std::nullopt);
  return out;
}

UsbTarget require_usb(const Storage& storage, const StorageChoice& s) {
  if (!storage.usb)
    throw std::invalid_argument("board " + s.board + ": storage.usb is \"runtime\": give the stick's folder with --usb DIR");
  return *storage.usb;
}

json usb_json(const UsbStatus& u) {
  return {{"state", to_string(u.state)},
          {"root", u.root.string()},
          {"free_bytes", u.free_bytes},
          {"message", u.message}};
}

json paths_json(const std::vector<fs::path>& paths) {
  json out = json::array();
  for (const auto& p : paths) out.push_back(p.string());
  return out;
}

bool linear_file(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".exr";
}

// An image file as the composite the screen would have shown.
ExportItem item_from_file(const std::string& path, bool with_layers) {
  ExportItem item;
  const cv::Mat linear = capture::load_photo_linear(path);  // throws naming the file
  item.composite_srgb8 = capture::linear_to_srgb8(linear);
  if (with_layers && linear_file(path)) item.composite_linear = linear;
  item.prop_name = fs::path(path).stem().string();
  item.taken = std::chrono::system_clock::now();
  item.metadata = {{"source", fs::path(path).filename().string()}};
  return item;
}

}  // namespace

void add_export_options(CLI::App& cmd, ExportArgs& a) {
  cmd.add_option("files", a.files, "Images (PNG, JPEG, EXR)")->required()->check(CLI::ExistingFile);
  add_storage_options(cmd, a.storage);
  cmd.add_flag("--jpeg,!--no-jpeg", a.jpeg, "A JPEG beside the PNG (default on)");
  cmd.add_flag("--layers", a.layers, "EXR inputs also as a layers EXR");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_export_command(const ExportArgs& a) {
  const Storage storage = resolve_storage(a.storage);
  ExportOptions options;
  options.jpeg = a.jpeg;
  options.layers = a.layers;
  Exporter exporter(storage.spool_dir, require_usb(storage, a.storage), options);
  json results = json::array();
  bool any_spooled = false, any_failed = false;
  for (const auto& file : a.files) {
    // Each file on its own: one that cannot be read is reported and the
    // rest of the batch still goes out.
    ExportOutcome outcome;
    try {
      outcome = exporter.export_composite(item_from_file(file, a.layers));
    } catch (const std::exception& e) {
      outcome.kind = ExportOutcome::Kind::Failed;
      outcome.message = std::string("not exported: ") + e.what();
    }
    any_spooled = any_spooled || outcome.kind == ExportOutcome::Kind::Spooled;
    any_failed = any_failed || outcome.kind == ExportOutcome::Kind::Failed;
    results.push_back({{"input", file},
                       {"kind", to_string(outcome.kind)},
                       {"entry_id", outcome.entry_id},
                       {"files", paths_json(outcome.files)},
                       {"message", outcome.message}});
    if (!a.json_out) std::fprintf(stderr, "%s: %s\n", file.c_str(), outcome.message.c_str());
  }
  if (a.json_out)
    std::cout << json{{"results", results}, {"usb", usb_json(exporter.usb_status())}, {"waiting", exporter.spool().size()}}
                     .dump(2)
              << std::endl;
  return any_failed ? 1 : any_spooled ? kExitSpooled : 0;
}

void add_spool_options(CLI::App& cmd, SpoolArgs& a) {
  add_storage_options(cmd, a.storage);
  cmd.add_flag("--flush", a.flush, "Move what waits to the stick (needs a usable stick)");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_spool_command(const SpoolArgs& a) {
  const Storage storage = resolve_storage(a.storage);
  // Listing needs no stick; a flush does.
  const UsbTarget usb = a.flush ? require_usb(storage, a.storage) : storage.usb.value_or(UsbTarget::folder({}));
  Exporter exporter(storage.spool_dir, usb);
  json out = json::object();
  if (storage.usb || a.flush) out["usb"] = usb_json(exporter.usb_status());
  int code = 0;
  if (a.flush) {
    const FlushReport report = exporter.flush_spool();
    out["flush"] = {{"moved", report.moved}, {"waiting", report.waiting}, {"files", paths_json(report.files)},
                    {"message", report.message}};
    if (!a.json_out) std::fprintf(stderr, "%s\n", report.message.c_str());
    if (report.waiting > 0) code = kExitSpooled;
  }
  json entries = json::array();
  for (const SpoolEntry& e : exporter.spool()) {
    json files = json::array();
    for (const auto& f : e.files) files.push_back(f.path);
    if (!e.folder_path.empty()) files.push_back(e.folder_path + "/");
    entries.push_back({{"id", e.id}, {"name", e.stem}, {"prop", e.prop_name}, {"taken", exif_date_time(e.taken)},
                       {"bytes", e.bytes()}, {"files", files}, {"dir", e.dir.string()}});
    if (!a.json_out)
      std::printf("%s  %-40s %10s  %s\n", e.id.c_str(), e.stem.c_str(), human_bytes(e.bytes()).c_str(),
                  exif_date_time(e.taken).c_str());
  }
  out["entries"] = entries;
  if (a.json_out) std::cout << out.dump(2) << std::endl;
  else if (entries.empty()) std::fprintf(stderr, "spool empty (%s)\n", storage.spool_dir.c_str());
  return code;
}

}  // namespace propcam::firmware
