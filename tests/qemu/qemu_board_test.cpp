// System tests on the qemu board (board/qemu/): a real Linux kernel in QEMU
// (TCG) with vivid as the camera, gpio-sim lines as the buttons, bochs-drm's
// /dev/fb0 as the screen and a QEMU usb-storage FAT image as the stick. One
// boot (board/qemu/guest/system_test.sh) runs propcamd on vivid and the
// appliance (`propcam run --daemon`, board/qemu/board.json) driven by gpio-sim
// line pulls; the host takes screendumps when the guest asks and pulls the
// stick mid-export. Each TEST checks one part of what that boot left behind.
// Skipped, with the reason, only when QEMU or the Debian kernel cannot be had.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "../firmware/cli_run.h"
#include "propcam/ui_fb/screens.h"

namespace {
namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kQemuBoard = fs::path(PROPCAM_SOURCE_DIR) / "board/qemu";
const std::string kBin = PROPCAM_BINARY_DIR;

std::string slurp(const fs::path& file) {
  std::ifstream in(file);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

cv::Mat read_rgb(const fs::path& file) {
  cv::Mat bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
  cv::Mat rgb;
  if (!bgr.empty()) cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

double mean_abs_diff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  const cv::Scalar m = cv::mean(d);
  return (m[0] + m[1] + m[2]) / 3.0;
}

// What the one boot left behind, shared by every test.
struct Boot {
  bool skipped = false;
  std::string skip_reason;
  int vm_exit = -1;
  std::string vm_log;
  fs::path out;    // the guest's /run/vm
  fs::path stick;  // the stick's PropCam/ folder, copied out of the image after the run
  std::string guest_log() const { return vm_log + "\n--- console\n" + slurp(out / "console.log"); }
};

Boot boot_once() {
  Boot b;
  if (propcam::test::run_shell("qemu-system-x86_64 --version >/dev/null 2>&1").exit_code != 0) {
    b.skipped = true;
    b.skip_reason = "qemu-system-x86_64 cannot run here (apt-get install qemu-system-x86: scripts/setup.sh)";
    return b;
  }
  const fs::path work = fs::path(kBin) / "test-data/qemu";
  fs::remove_all(work);
  fs::create_directories(work);
  // The kernel and its sources come from Debian's archive (cached under build/qemu).
  const auto prepared = propcam::test::run_shell(shell_quote((kQemuBoard / "prepare.sh").string()) + " 2>" +
                                                 shell_quote((work / "prepare.log").string()));
  std::istringstream lines(prepared.out);
  std::string kernel_dir, initrd;
  std::getline(lines, kernel_dir);
  std::getline(lines, initrd);
  if (prepared.exit_code != 0 || initrd.empty()) {
    const std::string log = slurp(work / "prepare.log");
    if (log.find("fetch:") != std::string::npos || log.find("apt-cache") != std::string::npos) {
      b.skipped = true;
      b.skip_reason = "no Debian kernel to boot (board/qemu/fetch.sh failed):\n" + log;
      return b;
    }
    b.vm_log = "board/qemu/prepare.sh failed:\n" + log;
    return b;
  }
  // The device's data folder as a device keeps it: the preset thumbnails and the
  // measured throughput, made here by a short run on the virtual board (the
  // guest is emulated, rendering eight thumbnails there would take minutes).
  b.out = work / "vm";
  fs::create_directories(b.out / "data");
  fs::create_directories(work / "warm_usb");
  std::ofstream(work / "warm.buttons") << "wait 0s\n";
  const auto warm = propcam::test::run_shell(std::string(PROPCAM_CLI) + " run --board virtual --script " +
                                             (work / "warm.buttons").string() + " --usb " +
                                             (work / "warm_usb").string() + " --spool " + (work / "warm_spool").string() +
                                             " --data " + (b.out / "data").string() + " >/dev/null 2>&1");
  if (warm.exit_code != 0) {
    b.vm_log = "warming the data folder on the virtual board failed";
    return b;
  }
  std::ofstream(b.out / "env.sh") << "PROPCAM_BIN=" << kBin << "\nPROPCAM_DATA=/run/vm/data\n";
  // A 64 MB FAT stick.
  const fs::path image = work / "stick.img";
  if (propcam::test::run_shell("truncate -s 64M " + image.string() + " && mkfs.vfat -n PROPCAM " + image.string() +
                               " >/dev/null 2>&1")
          .exit_code != 0) {
    b.vm_log = "mkfs.vfat failed (apt-get install dosfstools)";
    return b;
  }
  // The stick's writes are throttled (20 kB/s) so the export is still writing when it is pulled.
  const char* timeout = std::getenv("PROPCAM_QEMU_TIMEOUT");
  const auto vm = propcam::test::run_shell(
      "python3 " + shell_quote((kQemuBoard / "vm.py").string()) + " --kernel-dir " + shell_quote(kernel_dir) +
      " --initrd " + shell_quote(initrd) + " --out " + b.out.string() + " --run " +
      shell_quote((kQemuBoard / "guest/system_test.sh").string()) + " --stick " + image.string() +
      " --stick-write-bps 8000 --quiet --timeout " + (timeout ? timeout : "1500") + " 2>&1");
  b.vm_exit = vm.exit_code;
  b.vm_log = vm.out;
  b.stick = work / "stick";
  propcam::test::run_shell("mcopy -s -n -i " + image.string() + " ::PropCam " + b.stick.string() + " 2>/dev/null");
  return b;
}

const Boot& the_boot() {
  static const Boot boot = boot_once();
  return boot;
}

class QemuBoard : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { (void)the_boot(); }
  void SetUp() override {
    if (the_boot().skipped) GTEST_SKIP() << the_boot().skip_reason;
  }
  const Boot& boot() const { return the_boot(); }
  json read_json(const std::string& name) const {
    const std::string text = slurp(boot().out / name);
    return json::parse(text, nullptr, false);
  }
};

TEST_F(QemuBoard, TheGuestRanTheWholeSession) {
  EXPECT_EQ(boot().vm_exit, 0) << boot().guest_log();
  EXPECT_NE(slurp(boot().out / "steps.txt").find("done ok=1"), std::string::npos) << slurp(boot().out / "steps.txt");
}

// (1) vivid through the V4L2 backend and propcamd: a still through the daemon's socket.
TEST_F(QemuBoard, AStillFromVividThroughPropcamdShowsItsColourBars) {
  ASSERT_EQ(slurp(boot().out / "shoot.rc"), "0\n") << slurp(boot().out / "shoot.log");
  EXPECT_NE(slurp(boot().out / "propcamd.log").find("serving v4l2:/dev/video0"), std::string::npos)
      << slurp(boot().out / "propcamd.log");
  EXPECT_NE(slurp(boot().out / "cameras.json").find("v4l2:/dev/video0"), std::string::npos)
      << slurp(boot().out / "cameras.json");
  const cv::Mat shot = read_rgb(boot().out / "shot.png");
  ASSERT_EQ(shot.cols, 320);
  ASSERT_EQ(shot.rows, 180);
  // vivid's default pattern, 75% colour bars, left to right; the middle row of each bar.
  const cv::Vec3b bars[8] = {{191, 191, 191}, {191, 191, 0}, {0, 191, 191}, {0, 191, 0},
                             {191, 0, 191},   {191, 0, 0},   {0, 0, 191},   {0, 0, 0}};
  for (int i = 0; i < 8; ++i) {
    const cv::Vec3b got = shot.at<cv::Vec3b>(90, i * 40 + 20);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(got[c], bars[i][c], 24) << "bar " << i << " channel " << c;
  }
}

// (1b) vimc (built out of tree) through the libcamera backend: a second
// propcamd on libcamera:auto, as the Pi's propcamd.service runs, and a still
// through its socket. vimc's sensor draws the same 75% colour bars as vivid,
// with its settings written in the top left corner (white on a black box);
// the still is 1920x1080, from libcamera's vimc pipeline (sensor 640x360,
// debayer, x3 scaler), not a V4L2 node.
TEST_F(QemuBoard, ALibcameraStillFromVimc) {
  const std::string logs = slurp(boot().out / "shoot_vimc.log") + "\n--- propcamd\n" +
                           slurp(boot().out / "propcamd_vimc.log") + "\n--- udev\n" + slurp(boot().out / "udev.log");
  ASSERT_EQ(slurp(boot().out / "shoot_vimc.rc"), "0\n") << logs;
  EXPECT_EQ(slurp(boot().out / "propcamd_vimc.rc"), "0\n") << logs;
  EXPECT_NE(slurp(boot().out / "propcamd_vimc.log").find("serving libcamera:auto"), std::string::npos) << logs;
  const json shoot = read_json("shoot_vimc.json");
  ASSERT_TRUE(shoot.is_object()) << slurp(boot().out / "shoot_vimc.json");
  const std::string camera = shoot.value("camera", "");
  EXPECT_EQ(camera.rfind("libcamera:", 0), 0u) << camera;
  EXPECT_NE(camera.find("vimc"), std::string::npos) << camera;
  EXPECT_EQ(shoot["format"], "RGB24");
  EXPECT_EQ(shoot["size"], json::array({1920, 1080}));
  // `propcam cameras` (run beside propcamd) lists it too, as a libcamera camera.
  const json cameras = read_json("cameras.json");
  bool listed = false;
  for (const auto& c : cameras.is_array() ? cameras : json::array())
    listed |= c.value("backend", "") == "libcamera" && c.value("id", "").find("vimc") != std::string::npos;
  EXPECT_TRUE(listed) << slurp(boot().out / "cameras.json");

  const cv::Mat still = read_rgb(boot().out / "vimc.png");
  ASSERT_EQ(still.cols, 1920);
  ASSERT_EQ(still.rows, 1080);
  cv::Scalar mean, stddev;
  cv::meanStdDev(still, mean, stddev);
  EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 150.0) << "not a black or constant frame";
  // Eight vertical bars, left to right, below the text and at the bottom.
  const cv::Vec3b bars[8] = {{191, 191, 191}, {191, 191, 0}, {0, 191, 191}, {0, 191, 0},
                             {191, 0, 191},   {191, 0, 0},   {0, 0, 191},   {0, 0, 0}};
  for (const int y : {400, 700, 1040})
    for (int i = 0; i < 8; ++i) {
      const cv::Vec3b got = still.at<cv::Vec3b>(y, i * 240 + 120);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(got[c], bars[i][c], 24) << "bar " << i << " row " << y << " channel " << c;
    }
  // The text's black box covers much of the white bar's top (vivid's text is off).
  cv::Mat grey, dark;
  cv::cvtColor(still(cv::Rect(60, 60, 170, 160)), grey, cv::COLOR_RGB2GRAY);
  cv::threshold(grey, dark, 64, 255, cv::THRESH_BINARY_INV);
  EXPECT_GT(cv::countNonZero(dark), grey.total() / 3) << "vimc's sensor text in the top left corner";
}

// (2) gpio-sim line pulls through libgpiod reach the state machine: the
// session walks every state the presses lead to, none rejected.
TEST_F(QemuBoard, GpioSimPressesDriveTheAppliance) {
  ASSERT_EQ(slurp(boot().out / "run.rc"), "0\n") << slurp(boot().out / "run.log");
  const std::string log = slurp(boot().out / "run.log");
  EXPECT_NE(log.find("buttons gpiod propcam-buttons (5 lines)"), std::string::npos) << log;
  EXPECT_NE(log.find("display fbdev /dev/fb0"), std::string::npos) << log;
  // While the appliance ran, its five lines were held by it (gpioinfo in the guest).
  const std::string info = slurp(boot().out / "gpioinfo.txt");
  for (const char* line : {"propcam-shoot", "propcam-next", "propcam-prev", "propcam-ok", "propcam-back"}) {
    const auto at = info.find(line);
    ASSERT_NE(at, std::string::npos) << info;
    const std::string row = info.substr(at, info.find('\n', at) - at);
    EXPECT_NE(row.find("used"), std::string::npos) << row;
    EXPECT_EQ(row.find("unused"), std::string::npos) << row;
  }
  const json run = read_json("run.json");
  ASSERT_TRUE(run.is_object()) << slurp(boot().out / "run.json");
  EXPECT_EQ(run["rejected_inputs"], 0) << "every press was meaningful";
  EXPECT_EQ(run["final_state"], "adjusting");
  std::map<std::string, int> seen;
  for (const auto& s : run["snapshots"]) {
    const std::string stem = fs::path(s.get<std::string>()).stem().string();
    if (stem.size() > 4) ++seen[stem.substr(4)];
  }
  for (const char* label : {"viewfinder", "captured", "analysing", "placing-prop", "placing-spot", "placing-tier",
                            "rendering", "adjusting", "exporting"})
    EXPECT_GT(seen[label], 0) << "never in " << label << ": " << run["snapshots"].dump();
  EXPECT_GE(seen["exporting"], 1);
}

// The picture region of a screendump of the real screen.
cv::Rect picture(const cv::Mat& screen, propcam::ui_fb::ScreenKind kind, const cv::Mat& image) {
  propcam::ui_fb::ScreenView view;
  view.kind = kind;
  view.image = image;
  if (kind == propcam::ui_fb::ScreenKind::Adjusting) view.sliders.resize(4);
  const propcam::ui_fb::Rect r = propcam::ui_fb::screen_image_area({screen.cols, screen.rows}, view);
  return {r.x, r.y, r.width, r.height};
}

// (3) what the screen showed (QEMU screendumps of bochs-drm's framebuffer).
TEST_F(QemuBoard, TheScreenShowsTheViewfinderTheCarouselAndTheComposite) {
  const cv::Mat shot = read_rgb(boot().out / "shot.png");
  const cv::Mat viewfinder = read_rgb(boot().out / "viewfinder.png");
  const cv::Mat carousel = read_rgb(boot().out / "carousel.png");
  const cv::Mat composite_screen = read_rgb(boot().out / "composite.png");
  ASSERT_FALSE(shot.empty());
  ASSERT_FALSE(viewfinder.empty()) << boot().guest_log();
  ASSERT_FALSE(carousel.empty());
  ASSERT_FALSE(composite_screen.empty());
  EXPECT_EQ(viewfinder.cols, 1280);
  EXPECT_EQ(viewfinder.rows, 800);

  // The viewfinder: vivid's frames, as the still shows them, fitted to the screen.
  const cv::Rect area = picture(viewfinder, propcam::ui_fb::ScreenKind::Viewfinder, shot);
  ASSERT_GT(area.area(), 0);
  cv::Mat scaled;
  cv::resize(shot, scaled, area.size(), 0, 0, cv::INTER_AREA);
  const cv::Rect upper(0, 0, area.width, area.height * 3 / 4);
  EXPECT_LT(mean_abs_diff(viewfinder(area)(upper), scaled(upper)), 8.0) << "vivid's bars are on screen";
  EXPECT_GT(mean_abs_diff(viewfinder, carousel), 5.0) << "the carousel shows the props, not the camera";

  // The converged composite: where the sidecar says the cube stands the screen
  // differs from the photo; far above it, it is the photo.
  std::vector<fs::path> sidecars;
  if (fs::exists(boot().stick))
    for (const auto& e : fs::directory_iterator(boot().stick))
      if (e.path().extension() == ".json") sidecars.push_back(e.path());
  ASSERT_EQ(sidecars.size(), 1u) << "the export's sidecar on the stick";
  const json meta = json::parse(slurp(sidecars[0]), nullptr, false);
  const json base = meta.contains("metadata") ? meta["metadata"]["base_pixel"] : meta["base_pixel"];
  ASSERT_TRUE(base.is_array()) << meta.dump(2);
  const double u = base[0].get<double>(), v = base[1].get<double>();
  const json& fields = meta.contains("metadata") ? meta["metadata"] : meta;
  EXPECT_EQ(fields.value("converged_fraction", 0.0), 1.0) << "the render had converged: " << meta.dump(2);
  const cv::Rect carea = picture(composite_screen, propcam::ui_fb::ScreenKind::Adjusting, shot);
  ASSERT_GT(carea.area(), 0);
  cv::Mat photo_on_screen;
  cv::resize(shot, photo_on_screen, carea.size(), 0, 0, cv::INTER_AREA);
  const cv::Mat on_screen = composite_screen(carea);
  const double sx = static_cast<double>(carea.width) / shot.cols, sy = static_cast<double>(carea.height) / shot.rows;
  const cv::Rect bounds(0, 0, carea.width, carea.height);
  const cv::Rect cube = cv::Rect(static_cast<int>((u - 4) * sx), static_cast<int>((v - 10) * sy),
                                 static_cast<int>(8 * sx), static_cast<int>(7 * sy)) & bounds;
  const cv::Rect far = cv::Rect(0, 0, carea.width, static_cast<int>(carea.height * 0.2)) & bounds;
  ASSERT_GT(cube.area(), 0);
  EXPECT_GT(mean_abs_diff(on_screen(cube), photo_on_screen(cube)), 8.0) << "the cube at " << u << "," << v;
  EXPECT_LT(mean_abs_diff(on_screen(far), photo_on_screen(far)), 4.0) << "far from the cube the photo is as shot";
}

// (4) the stick was pulled while the export was writing to it; the export was
// kept in the spool and, once the stick was back, flushed onto it whole.
TEST_F(QemuBoard, PullingTheStickMidExportLosesNothing) {
  // When the stick went, the export was under way: a temporary was being
  // written, or not all of the composite's three files had arrived yet. (The
  // guest lists the folder a moment after it saw the temporary; under load a
  // small file can be renamed in between, so either is "mid-export".)
  const std::string at_unplug = slurp(boot().out / "stick_at_unplug.txt");
  const bool writing = at_unplug.find(".propcam-") != std::string::npos;
  const bool incomplete = at_unplug.find(".png") == std::string::npos || at_unplug.find(".jpg") == std::string::npos ||
                          at_unplug.find(".json") == std::string::npos;
  EXPECT_TRUE(writing || incomplete) << "the stick was pulled mid-export: " << at_unplug;
  // Meanwhile the composite waited in the spool (ls -R of it).
  const std::string spooled = slurp(boot().out / "spool_unplugged.txt");
  EXPECT_NE(spooled.find("composite.png"), std::string::npos) << spooled;
  EXPECT_NE(spooled.find("manifest.json"), std::string::npos) << spooled;
  ASSERT_TRUE(fs::exists(boot().stick)) << "nothing on the stick\n" << boot().guest_log();
  std::map<std::string, int> by_ext;
  std::vector<fs::path> pngs;
  for (const auto& e : fs::directory_iterator(boot().stick)) {
    const std::string name = e.path().filename().string();
    EXPECT_NE(name.rfind(".propcam-", 0), 0u) << "a temporary left on the stick: " << name;
    // (vfat writes a renamed file's size with its inode: publish_file fsyncs it after the rename.)
    EXPECT_GT(fs::file_size(e.path()), 0u) << "an empty file under a final name: " << name;
    ++by_ext[e.path().extension().string()];
    if (e.path().extension() == ".png") pngs.push_back(e.path());
  }
  EXPECT_EQ(by_ext[".png"], 1) << slurp(boot().out / "stick.txt");
  EXPECT_EQ(by_ext[".jpg"], 1) << slurp(boot().out / "stick.txt");
  EXPECT_EQ(by_ext[".json"], 1) << slurp(boot().out / "stick.txt");
  EXPECT_TRUE(slurp(boot().out / "spool.txt").empty()) << "the spool is empty: " << slurp(boot().out / "spool.txt");
  ASSERT_EQ(pngs.size(), 1u);
  const cv::Mat composite = read_rgb(pngs[0]);
  ASSERT_EQ(composite.cols, 320);
  ASSERT_EQ(composite.rows, 180);
  // The file on the stick is what the screen showed when it was exported.
  const cv::Mat screen = read_rgb(boot().out / "composite.png");
  ASSERT_FALSE(screen.empty());
  const cv::Rect area = picture(screen, propcam::ui_fb::ScreenKind::Adjusting, composite);
  cv::Mat scaled;
  cv::resize(composite, scaled, area.size(), 0, 0, cv::INTER_AREA);
  const cv::Rect upper(0, 0, area.width, area.height * 3 / 4);
  EXPECT_LT(mean_abs_diff(screen(area)(upper), scaled(upper)), 3.0);
}

// (5) The appliance puts the VT under its fbdev display in graphics mode and
// gives it back in text mode on SIGTERM; ui_fb's Console tests, run after
// it on the same real VT, begin by requiring text mode, then take the VT
// and crash a child holding it.
TEST_F(QemuBoard, TheUiTakesTheConsoleAndGivesItBackEvenAfterACrash) {
  const std::string log = slurp(boot().out / "run.log");
  EXPECT_NE(log.find("console in graphics mode"), std::string::npos) << log;
  const std::string tests = slurp(boot().out / "console_tests.txt");
  EXPECT_EQ(slurp(boot().out / "console_tests.rc"), "0\n") << tests;
  EXPECT_NE(tests.find("[       OK ] Console.AVirtualTerminalGoesToGraphicsAndBackEvenAfterACrash"), std::string::npos)
      << "not run on a VT in text mode: " << tests;
}

}  // namespace
