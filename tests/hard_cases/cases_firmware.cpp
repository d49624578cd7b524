// firmware: corrupt board configs, exports to a missing or read-only stick,
// hostile prop names, empty composites, a scene with nowhere to stand a
// prop, a missing prop mesh, and a short composite render of a tiny room.
#include <cerrno>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "appliance/appliance_shot.h"
#include "common/board_config.h"
#include "catalogue.h"
#include "common/compositor.h"
#include "propcam/capture/image_file.h"
#include "storage/storage_export.h"
#include "worlds/synthetic_truth.h"

namespace propcam::hard_cases {
namespace {

namespace fs = std::filesystem;
using namespace propcam::firmware;

// The virtual board's board.json in <dir>/virtual/, with `edit` applied.
fs::path board_copy(const ScratchDir& dir, const std::function<void(nlohmann::json&)>& edit) {
  nlohmann::json j;
  std::ifstream(std::string(PROPCAM_SOURCE_DIR) + "/board/virtual/board.json") >> j;
  edit(j);
  fs::create_directories(dir / "virtual");
  write_text_file(dir / "virtual" / "board.json", j.dump(2));
  return dir / "virtual" / "board.json";
}

ExportItem small_item(const std::string& prop_name) {
  ExportItem item;
  item.composite_srgb8 = cv::Mat(12, 16, CV_8UC3, cv::Scalar(40, 90, 200));
  item.prop_name = prop_name;
  // A fixed time, so both runs make the same names.
  item.taken = std::chrono::system_clock::time_point(std::chrono::seconds(1'796'000'000));
  item.metadata = {{"prop", prop_name}};
  return item;
}

// The stick as a read-only filesystem: every write under it fails with EROFS
// (the real export code runs above this layer; root ignores chmod, so a
// read-only folder cannot stand in for it here).
class ReadOnlyStickIo : public StorageIo {
 public:
  explicit ReadOnlyStickIo(fs::path stick) : stick_(std::move(stick)) {}
  int create_file(const fs::path& path, int& fd) override {
    return under_stick(path) ? EROFS : StorageIo::create_file(path, fd);
  }
  int rename_new(const fs::path& from, const fs::path& to) override {
    return under_stick(to) ? EROFS : StorageIo::rename_new(from, to);
  }
  int make_dir(const fs::path& dir) override { return under_stick(dir) ? EROFS : StorageIo::make_dir(dir); }
  int remove(const fs::path& path) override { return under_stick(path) ? EROFS : StorageIo::remove(path); }

 private:
  bool under_stick(const fs::path& p) const {
    const std::string s = p.lexically_normal().string(), root = stick_.lexically_normal().string();
    return s.rfind(root, 0) == 0;
  }
  fs::path stick_;
};

void add_outcome(Digest& d, const ExportOutcome& o, const fs::path& base) {
  d.text(to_string(o.kind));
  d.text(o.message);
  for (const fs::path& f : o.files) d.text(f.lexically_relative(base).string());
}

// A tiny synthetic room and its exact scene, as the appliance's analysis holds it.
std::shared_ptr<const Analysis> tiny_room_analysis() {
  render::SyntheticRoomSpec spec;
  spec.width = 48;
  spec.height = 36;
  spec.seed = 4;
  render::RenderSettings settings;
  settings.samples_per_pixel = 2;
  settings.threads = 2;
  const SyntheticShot shot = shoot_synthetic_room(spec, settings);
  auto a = std::make_shared<Analysis>();
  a->photo_linear = shot.photo_linear;
  a->scene = shot.truth;
  a->scene_photo = capture::srgb_linear_to_response_linear(shot.photo_linear, a->scene.gamma);
  a->photo_rgb8 = capture::linear_to_srgb8(shot.photo_linear);
  return a;
}

}  // namespace

void add_firmware_cases(std::vector<HardCase>& cases) {
  const std::string m = "firmware";
  cases.push_back({"BoardJsonTruncated", m, "the virtual board's board.json cut in half", "error naming board.json",
                   Expect::Error, {"board.json"}, [](Digest&) {
                     ScratchDir dir("BoardJsonTruncated");
                     const fs::path file = board_copy(dir, [](nlohmann::json&) {});
                     std::ifstream in(file);
                     const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
                     write_text_file(file, text.substr(0, text.size() / 2));
                     load_board_file(file);
                   }});
  cases.push_back({"BoardNegativeMountHeight", m, "the virtual board with camera_mount_height_m = -1.5",
                   "error naming camera_mount_height_m", Expect::Error, {"camera_mount_height_m"}, [](Digest&) {
                     ScratchDir dir("BoardNegativeMountHeight");
                     load_board_file(board_copy(dir, [](nlohmann::json& j) { j["camera_mount_height_m"] = -1.5; }));
                   }});
  cases.push_back({"BoardUnknownField", m, "the virtual board with an extra top-level field \"wifi\"",
                   "error naming wifi", Expect::Error, {"wifi"}, [](Digest&) {
                     ScratchDir dir("BoardUnknownField");
                     load_board_file(board_copy(dir, [](nlohmann::json& j) { j["wifi"] = {{"ssid", "x"}}; }));
                   }});
  cases.push_back({"ExportToAMissingStick", m, "export a 16x12 composite with no stick (the mount folder absent)",
                   "spooled, with a message saying so", Expect::Result, {}, [](Digest& d) {
                     ScratchDir dir("ExportToAMissingStick");
                     Exporter exporter(dir / "spool", UsbTarget::folder(dir / "no_stick"));
                     const ExportOutcome o = exporter.export_composite(small_item("chair"));
                     check(o.kind == ExportOutcome::Kind::Spooled, "kept in the spool");
                     check(exporter.spool().size() == 1, "one entry waits");
                     check(!fs::exists(dir / "no_stick"), "no stick folder was made up");
                     d.text(to_string(exporter.usb_status().state));
                     d.text(o.message);
                   }});
  cases.push_back({"ExportToAReadOnlyStick", m, "export a 16x12 composite to a stick whose writes fail with EROFS",
                   "spooled, nothing left on the stick", Expect::Result, {}, [](Digest& d) {
                     ScratchDir dir("ExportToAReadOnlyStick");
                     fs::create_directories(dir / "stick");
                     Exporter exporter(dir / "spool", UsbTarget::folder(dir / "stick"), {},
                                       std::make_shared<ReadOnlyStickIo>(dir / "stick"));
                     const ExportOutcome o = exporter.export_composite(small_item("chair"));
                     check(o.kind == ExportOutcome::Kind::Spooled, "kept in the spool");
                     check(exporter.spool().size() == 1, "one entry waits");
                     check(fs::is_empty(dir / "stick"), "nothing torn on the stick");
                     d.text(to_string(o.kind));
                     d.text(o.message);
                   }});
  cases.push_back({"ExportWithAHostilePropName", m,
                   "export with the prop name \"../../etc/passwd\\n*?\" to a working stick",
                   "written, under a sanitised name inside <stick>/PropCam", Expect::Result, {}, [](Digest& d) {
                     ScratchDir dir("ExportWithAHostilePropName");
                     fs::create_directories(dir / "stick");
                     Exporter exporter(dir / "spool", UsbTarget::folder(dir / "stick"));
                     const ExportOutcome o = exporter.export_composite(small_item("../../etc/passwd\n*?"));
                     check(o.kind == ExportOutcome::Kind::Written, "written to the stick");
                     for (const fs::path& f : o.files) {
                       check(f.parent_path() == dir / "stick" / kStickFolder, "inside the stick's folder: " + f.string());
                       check(f.filename().string().find_first_of("/\n*?") == std::string::npos, "sanitised");
                     }
                     add_outcome(d, o, dir.path());
                   }});
  cases.push_back({"ExportAnEmptyComposite", m, "export an item whose composite image is empty",
                   "error naming the composite", Expect::Error, {"composite"}, [](Digest&) {
                     ScratchDir dir("ExportAnEmptyComposite");
                     Exporter exporter(dir / "spool", UsbTarget::folder(dir / "stick"));
                     ExportItem item = small_item("chair");
                     item.composite_srgb8 = cv::Mat();
                     exporter.export_composite(item);
                   }});
  cases.push_back({"SpotsWhenNothingFacesUp", m, "find_spots on a 32x24 scene whose every normal faces the camera",
                   "no spots (the appliance says: shoot again)", Expect::Result, {}, [](Digest& d) {
                     inference::SceneModel s;
                     s.width = 32;
                     s.height = 24;
                     s.fx = s.fy = 30;
                     s.cx = 15.5;
                     s.cy = 11.5;
                     s.depth = cv::Mat(24, 32, CV_32F, cv::Scalar(3.f));
                     s.albedo = cv::Mat(24, 32, CV_32FC3, cv::Scalar::all(0.5));
                     s.normals = cv::Mat(24, 32, CV_32FC3, cv::Scalar(0, 0, -1));
                     const auto spots = find_spots(s, 12);
                     check(spots.empty(), "no surface to stand on");
                     d.integer(static_cast<std::int64_t>(spots.size()));
                   }});
  cases.push_back({"MissingPropMesh", m, "load_prop of a mesh file that does not exist", "error naming the file",
                   Expect::Error, {"no_such_prop.obj"}, [](Digest&) {
                     load_prop("/nonexistent/no_such_prop.obj");
                   }});
  cases.push_back({"DraftRenderOfATinyRoom", m,
                   "a 48x36 synthetic room: find_spots, then a CompositeRender of the cube at the first spot, 2 spp per pass, to the end",
                   "a finite composite and depth, converged", Expect::Result, {}, [](Digest& d) {
                     const auto analysis = tiny_room_analysis();
                     const auto spots = find_spots(analysis->scene, 12);
                     check(!spots.empty(), "the room's floor is in view");
                     PropEntry cube;
                     cube.name = cube.source = "cube";
                     TierSpec tier = tier_spec(appliance::Tier::Draft);
                     tier.max_samples_per_pixel = 2;
                     CompositeRender render(analysis, cube, spots.front(), tier, 2);
                     int passes = 0;
                     while (!render.finished() && passes++ < 50) render.run_pass(nullptr);
                     check(render.finished(), "the render ends");
                     const auto snap = render.snapshot(true);
                     d.mat(snap->composite);
                     d.mat(snap->depth);
                     d.number(snap->converged_fraction);
                     d.mat(adjusted_composite(*analysis, *snap, Adjustment{}));
                   }});
}

}  // namespace propcam::hard_cases
