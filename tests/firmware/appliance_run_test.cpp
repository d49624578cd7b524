// System tests of the appliance: `propcam run` on the virtual board (the real
// replay camera and pixel-format code, the real debouncer and state machine,
// the file framebuffer with the real packing, the real export), driven by
// button scripts, asserted on what a user would see: the screen snapshots
// and the files on the stick.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>

#include "cli_run.h"
#include "propcam/ui_fb/screens.h"

namespace {
namespace fs = std::filesystem;
using nlohmann::json;

struct SessionRun {
  int exit_code = -1;
  json summary;
  std::string log;
};

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / "propcam_appliance" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Thumbnails and the measured throughput are kept between runs, as on a device.
fs::path shared_data_dir() {
  const fs::path dir = fs::path(PROPCAM_BINARY_DIR) / "test-data" / "appliance";
  fs::create_directories(dir);
  return dir;
}

SessionRun run_appliance(const std::string& args, const fs::path& work) {
  const fs::path log = work / "run.log";
  const std::string cmd = std::string(PROPCAM_CLI) + " run --json --threads 2 --data " + shared_data_dir().string() +
                          " " + args + " 2>" + log.string();
  SessionRun r;
  const propcam::test::CliRun run = propcam::test::run_shell(cmd);
  r.exit_code = run.exit_code;
  std::ifstream in(log);
  r.log.assign(std::istreambuf_iterator<char>(in), {});
  if (r.exit_code == 0) r.summary = json::parse(run.out);
  return r;
}

fs::path write_script(const fs::path& dir, const std::string& text) {
  const fs::path file = dir / "session.buttons";
  std::ofstream(file) << text;
  return file;
}

cv::Mat read_rgb(const fs::path& file) {
  cv::Mat bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
  cv::Mat rgb;
  if (!bgr.empty()) cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

// The snapshot whose label (after the "NNN-" number) is `label`; the last one if several.
fs::path snapshot(const json& summary, const std::string& label) {
  fs::path found;
  for (const auto& s : summary["snapshots"]) {
    const fs::path p = s.get<std::string>();
    const std::string stem = p.stem().string();
    if (stem.size() > 4 && stem.substr(4) == label) found = p;
  }
  return found;
}

double mean_abs_diff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  const cv::Scalar m = cv::mean(d);
  return (m[0] + m[1] + m[2]) / 3.0;
}

// The picture region of a snapshot, and an image scaled the way the screen shows it.
cv::Rect picture(const cv::Mat& screen, const propcam::ui_fb::ScreenView& view) {
  const propcam::ui_fb::Rect r = propcam::ui_fb::screen_image_area({screen.cols, screen.rows}, view);
  return {r.x, r.y, r.width, r.height};
}

const fs::path kPhoto = fs::path(PROPCAM_SOURCE_DIR) / "board/virtual/photos/living_room.png";

// Shoot, pick the cube (three PREVs from the chair), the first spot, draft, render, export.
constexpr const char* kCubeSession = R"(
at 1s press SHOOT
await placing 300s
+300ms press PREV
+300ms press PREV
+300ms press PREV
+300ms press OK
+300ms press OK
+300ms press PREV
+300ms press OK
await adjusting 900s
+300ms hold OK 1200ms
await adjusting 120s
+300ms wait 0s
)";

// One scripted session (a run takes a while) checked the way a user would
// look at it; each check is its own function so a failure says which.
void check_the_session_ends_where_the_script_leaves_it(const SessionRun& run) {
  EXPECT_EQ(run.summary["final_state"], "adjusting");
  EXPECT_EQ(run.summary["rejected_inputs"], 0) << "every scripted press was meaningful";
  for (const char* label : {"viewfinder", "captured", "analysing", "placing-prop", "placing-spot", "placing-tier",
                            "rendering", "adjusting", "exporting", "end"})
    EXPECT_FALSE(snapshot(run.summary, label).empty()) << "no snapshot of " << label;
  for (const auto& ms : run.summary["input_to_screen_ms"]) EXPECT_GE(ms.get<double>(), 0.0);
}

void check_the_viewfinder_shows_the_camera(const SessionRun& run) {
  const cv::Mat screen = read_rgb(snapshot(run.summary, "viewfinder"));
  ASSERT_FALSE(screen.empty());
  propcam::ui_fb::ScreenView view;
  view.kind = propcam::ui_fb::ScreenKind::Viewfinder;
  view.image = cv::Mat(480, 640, CV_8UC3);
  const cv::Rect area = picture(screen, view);
  ASSERT_GT(area.area(), 0);
  cv::Mat photo = read_rgb(kPhoto), scaled;
  cv::resize(photo, scaled, area.size(), 0, 0, cv::INTER_AREA);
  // The top three quarters (the caption strip, if any, is at the bottom).
  const cv::Rect upper(0, 0, area.width, area.height * 3 / 4);
  EXPECT_LT(mean_abs_diff(screen(area)(upper), scaled(upper)), 6.0) << "the recorded room is on screen";
}

void check_the_carousel_is_not_the_photo(const SessionRun& run) {
  const cv::Mat viewfinder = read_rgb(snapshot(run.summary, "viewfinder"));
  const cv::Mat carousel = read_rgb(snapshot(run.summary, "placing-prop"));
  ASSERT_FALSE(carousel.empty());
  EXPECT_GT(mean_abs_diff(viewfinder, carousel), 5.0) << "the carousel shows the props, not the camera";
}

void check_the_export_is_the_composite_with_the_prop_in_it(const SessionRun& run, const fs::path& work) {
  std::vector<fs::path> pngs;
  for (const auto& e : run.summary["exported"])
    if (fs::path(e.get<std::string>()).extension() == ".png") pngs.push_back(e.get<std::string>());
  ASSERT_EQ(pngs.size(), 1u) << run.summary.dump(2);
  EXPECT_TRUE(fs::exists(pngs[0]));
  EXPECT_EQ(pngs[0].parent_path().parent_path(), work / "usb") << "on the stick";
  const cv::Mat composite = read_rgb(pngs[0]);
  ASSERT_EQ(composite.cols, 640);
  ASSERT_EQ(composite.rows, 480);
  // The sidecar says where the cube stands.
  fs::path sidecar = pngs[0];
  sidecar.replace_extension(".json");
  ASSERT_TRUE(fs::exists(sidecar));
  const json meta = json::parse(std::ifstream(sidecar));
  const json base = meta.contains("metadata") ? meta["metadata"]["base_pixel"] : meta["base_pixel"];
  ASSERT_TRUE(base.is_array()) << meta.dump(2);
  const int u = static_cast<int>(base[0].get<double>()), v = static_cast<int>(base[1].get<double>());
  const cv::Mat photo = read_rgb(kPhoto);
  // Just above the base the cube covers the photo; far above it nothing changed.
  const cv::Rect cube = cv::Rect(u - 6, v - 14, 12, 10) & cv::Rect(0, 0, 640, 480);
  const cv::Rect far(0, 0, 640, 100);
  EXPECT_GT(mean_abs_diff(composite(cube), photo(cube)), 8.0) << "the cube is in the composite at " << u << "," << v;
  EXPECT_LT(mean_abs_diff(composite(far), photo(far)), 3.0) << "far from the cube the photo is as shot";

  // The exported file is the composite the screen showed last.
  const cv::Mat screen = read_rgb(snapshot(run.summary, "end"));
  propcam::ui_fb::ScreenView view;
  view.kind = propcam::ui_fb::ScreenKind::Adjusting;
  view.image = composite;
  view.sliders.resize(4);
  const cv::Rect area = picture(screen, view);
  ASSERT_GT(area.area(), 0);
  cv::Mat scaled;
  cv::resize(composite, scaled, area.size(), 0, 0, cv::INTER_AREA);
  const cv::Rect upper(0, 0, area.width, area.height * 3 / 4);
  EXPECT_LT(mean_abs_diff(screen(area)(upper), scaled(upper)), 2.0);
}

TEST(ApplianceRun, AScriptedSessionShowsWhatTheUserDidAndExportsWhatTheScreenShowed) {
  const fs::path work = temp_dir("cube_session");
  const fs::path script = write_script(work, kCubeSession);
  fs::create_directories(work / "usb");
  const SessionRun run = run_appliance("--board virtual --script " + script.string() + " --snapshots " +
                                           (work / "snapshots").string() + " --usb " + (work / "usb").string(),
                                       work);
  ASSERT_EQ(run.exit_code, 0) << run.log;
  {
    SCOPED_TRACE("states");
    check_the_session_ends_where_the_script_leaves_it(run);
  }
  {
    SCOPED_TRACE("viewfinder");
    check_the_viewfinder_shows_the_camera(run);
  }
  {
    SCOPED_TRACE("carousel");
    check_the_carousel_is_not_the_photo(run);
  }
  {
    SCOPED_TRACE("export");
    check_the_export_is_the_composite_with_the_prop_in_it(run, work);
  }
}

TEST(ApplianceFaults, AMissingCameraShowsAFaultAndTheApplianceRecovers) {
  const fs::path work = temp_dir("no_camera");
  // A board like the virtual one whose recording is not there.
  const fs::path board_dir = work / "nocam";
  fs::create_directories(board_dir);
  std::ifstream in(fs::path(PROPCAM_SOURCE_DIR) / "board/virtual/board.json");
  json board = json::parse(in);
  board["name"] = "nocam";
  board["camera"]["id"] = "replay:recordings/none";
  std::ofstream(board_dir / "board.json") << board.dump(2);
  const fs::path script = write_script(work, R"(
at 1s press SHOOT
await fault 30s
+300ms press OK
await viewfinder 10s
+300ms wait 0s
)");
  fs::create_directories(work / "usb");
  const SessionRun r = run_appliance("--board " + (board_dir / "board.json").string() + " --script " + script.string() +
                                  " --snapshots " + (work / "snapshots").string() + " --usb " + (work / "usb").string(),
                              work);
  ASSERT_EQ(r.exit_code, 0) << r.log;
  EXPECT_EQ(r.summary["final_state"], "viewfinder");
  EXPECT_FALSE(snapshot(r.summary, "fault").empty());
}

// Without --snapshots, a file display whose path is "runtime" (the virtual
// board's) writes its screen into the data folder, never beside the board.
TEST(ApplianceRun, WithoutSnapshotsTheScreenFileIsInTheDataFolder) {
  const fs::path work = temp_dir("screen_in_data");
  const fs::path board_dir = work / "virtual";  // a board is named after its folder
  fs::create_directories(board_dir);
  std::ifstream in(fs::path(PROPCAM_SOURCE_DIR) / "board/virtual/board.json");
  json board = json::parse(in);
  ASSERT_EQ(board["display"]["path"], "runtime");
  fs::create_directory_symlink(fs::path(PROPCAM_SOURCE_DIR) / "board/virtual/recordings", board_dir / "recordings");
  std::ofstream(board_dir / "board.json") << board.dump(2);
  const fs::path script = write_script(work, "at 500ms wait 0s\n");
  fs::create_directories(work / "usb");
  // (run_appliance names the suite's shared data folder: the screen goes there.)
  const fs::path screen = shared_data_dir() / "screen.png";
  fs::remove(screen);
  const SessionRun r = run_appliance("--board " + (board_dir / "board.json").string() + " --script " + script.string() +
                                         " --usb " + (work / "usb").string(),
                                     work);
  ASSERT_EQ(r.exit_code, 0) << r.log;
  EXPECT_TRUE(fs::is_regular_file(screen)) << r.log;
  std::vector<std::string> beside_the_board;
  for (const auto& e : fs::directory_iterator(board_dir)) beside_the_board.push_back(e.path().filename().string());
  std::sort(beside_the_board.begin(), beside_the_board.end());
  EXPECT_EQ(beside_the_board, (std::vector<std::string>{"board.json", "recordings"}));
}

TEST(ApplianceRun, PropsOnTheStickJoinTheCarousel) {
  const fs::path work = temp_dir("usb_props");
  fs::create_directories(work / "usb/props");
  // A 30 cm box, and a file that is no mesh (left out, not fatal).
  std::ofstream(work / "usb/props/box.obj") << R"(v -0.15 0 -0.15
v 0.15 0 -0.15
v 0.15 0 0.15
v -0.15 0 0.15
v -0.15 0.3 -0.15
v 0.15 0.3 -0.15
v 0.15 0.3 0.15
v -0.15 0.3 0.15
f 1 2 3 4
f 8 7 6 5
f 1 5 6 2
f 2 6 7 3
f 3 7 8 4
f 4 8 5 1
)";
  std::ofstream(work / "usb/props/broken.obj") << "this is not a mesh\nf 1 2 3\n";
  const fs::path script = write_script(work, "wait 1s\n");
  const SessionRun r = run_appliance("--board virtual --script " + script.string() + " --usb " + (work / "usb").string(),
                                     work);
  ASSERT_EQ(r.exit_code, 0) << r.log;
  const auto props = r.summary["props"].get<std::vector<std::string>>();
  ASSERT_EQ(props.size(), 9u) << r.summary.dump(2);
  EXPECT_EQ(props.back(), "box");
  EXPECT_NE(r.log.find("broken.obj"), std::string::npos) << "the bad file is named in the log";
}

TEST(ApplianceFaults, AScriptWaitingForAStateThatNeverComesFailsClearly) {
  const fs::path work = temp_dir("await_timeout");
  const fs::path script = write_script(work, "await rendering 2s\n");
  fs::create_directories(work / "usb");
  const SessionRun r = run_appliance("--board virtual --script " + script.string() + " --usb " + (work / "usb").string(),
                              work);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.log.find("timed out"), std::string::npos) << r.log;
  EXPECT_NE(r.log.find("rendering"), std::string::npos) << r.log;
}

TEST(ApplianceFaults, WithoutAStickTheCompositeWaitsInTheSpoolUntilOneIsThere) {
  const fs::path work = temp_dir("spool");
  const fs::path stick = work / "usb";  // not there during the first run
  const fs::path spool = work / "spool";
  const fs::path script = write_script(work, kCubeSession);
  const SessionRun first = run_appliance("--board virtual --script " + script.string() + " --usb " + stick.string() +
                                      " --spool " + spool.string(),
                                  work);
  ASSERT_EQ(first.exit_code, 0) << first.log;
  EXPECT_EQ(first.summary["spooled"], 1);
  EXPECT_TRUE(first.summary["exported"].empty());
  ASSERT_FALSE(fs::exists(stick));
  // The stick arrives: the next run moves the composite over without a button press.
  fs::create_directories(stick);
  const fs::path wait = write_script(work, "wait 5s\n");
  const SessionRun second = run_appliance("--board virtual --script " + wait.string() + " --usb " + stick.string() +
                                       " --spool " + spool.string(),
                                   work);
  ASSERT_EQ(second.exit_code, 0) << second.log;
  int pngs = 0;
  for (const auto& e : fs::recursive_directory_iterator(stick))
    if (e.path().extension() == ".png") ++pngs;
  EXPECT_EQ(pngs, 1) << second.log;
}

}  // namespace
