#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "common/board_config.h"

namespace propcam::firmware {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kBoardRoot = fs::path(PROPCAM_SOURCE_DIR) / "board";

TEST(BoardConfig, ListsTheCommittedBoards) {
  EXPECT_EQ(list_boards(kBoardRoot), (std::vector<std::string>{"qemu", "rpi", "usb-webcam", "virtual"}));
  EXPECT_TRUE(list_boards("/nonexistent/propcam/boards").empty());
}

TEST(BoardConfig, RaspberryPiBoard) {
  const BoardConfig b = load_board(kBoardRoot, "rpi");
  EXPECT_EQ(b.name, "rpi");
  EXPECT_EQ(b.dir, (kBoardRoot / "rpi").lexically_normal());
  EXPECT_EQ(b.buttons.backend, ButtonBackend::Gpiod);
  EXPECT_EQ(b.buttons.gpio_chip, "gpiochip0");
  EXPECT_EQ(b.buttons.gpio_lines.at(Button::Shoot), "GPIO5");
  EXPECT_EQ(b.buttons.gpio_lines.at(Button::Back), "GPIO26");
  EXPECT_EQ(b.buttons.gpio_lines.size(), 5u);
  EXPECT_LT(b.buttons.debounce_ms, b.buttons.long_press_ms);
  EXPECT_EQ(b.display.backend, DisplayBackend::Fbdev);
  EXPECT_EQ(b.display.device, "/dev/fb0");
  EXPECT_EQ(b.camera.backend, CameraBackend::Libcamera);
  EXPECT_EQ(b.camera.id, "libcamera:auto");
  EXPECT_DOUBLE_EQ(b.camera_mount_height_m, 1.4);
  EXPECT_EQ(b.storage.usb.kind, StorageLocation::Kind::Auto);
  EXPECT_EQ(b.storage.spool_dir.path, "/var/spool/propcam");
  EXPECT_EQ(b.budgets.working_pixels, 1024L * 768L);
  EXPECT_EQ(b.budgets.memory_mb, 768);
}

TEST(BoardConfig, QemuBoard) {
  const BoardConfig b = load_board(kBoardRoot, "qemu");
  EXPECT_EQ(b.buttons.backend, ButtonBackend::Gpiod);
  EXPECT_EQ(b.buttons.gpio_chip, "propcam-buttons");  // gpio-sim's bank label (board/qemu/guest/lib.sh)
  EXPECT_EQ(b.buttons.gpio_lines.at(Button::Shoot), "propcam-shoot");
  EXPECT_EQ(b.buttons.gpio_lines.at(Button::Back), "propcam-back");
  EXPECT_EQ(b.buttons.gpio_lines.size(), 5u);
  EXPECT_EQ(b.display.backend, DisplayBackend::Fbdev);
  EXPECT_EQ(b.display.device, "/dev/fb0");
  EXPECT_EQ(b.camera.backend, CameraBackend::V4l2);
  EXPECT_EQ(b.camera.id, "v4l2:/dev/video0");
  EXPECT_EQ(b.storage.usb.kind, StorageLocation::Kind::Auto);
}

TEST(BoardConfig, UsbWebcamBoard) {
  const BoardConfig b = load_board(kBoardRoot, "usb-webcam");
  EXPECT_EQ(b.buttons.backend, ButtonBackend::Evdev);
  EXPECT_EQ(b.buttons.evdev_device_name, "gpio-keys");
  EXPECT_TRUE(b.buttons.evdev_device.empty());
  EXPECT_EQ(b.buttons.evdev_keys.at(Button::Ok), 28);  // KEY_ENTER
  EXPECT_EQ(b.camera.backend, CameraBackend::V4l2);
  EXPECT_EQ(b.camera.id, "v4l2:/dev/video0");
  EXPECT_EQ(b.camera.viewfinder_format, "YUYV");
  EXPECT_EQ(b.camera.viewfinder_size, (Size{640, 480}));
  EXPECT_EQ(b.display.backend, DisplayBackend::Fbdev);
}

TEST(BoardConfig, VirtualBoardResolvesItsPathsInsideItsFolder) {
  const BoardConfig b = load_board(kBoardRoot, "virtual");
  const fs::path dir = (kBoardRoot / "virtual").lexically_normal();
  EXPECT_EQ(b.buttons.backend, ButtonBackend::Script);
  EXPECT_EQ(b.buttons.script, dir / "demo_session.buttons");  // need not exist yet
  EXPECT_EQ(b.camera.backend, CameraBackend::Replay);
  EXPECT_EQ(b.camera.replay_dir, dir / "recordings/living_room");
  EXPECT_EQ(b.camera.id, "replay:" + (dir / "recordings/living_room").string());
  EXPECT_TRUE(fs::is_regular_file(b.camera.replay_dir / "recording.json"));
  EXPECT_EQ(b.display.backend, DisplayBackend::File);
  EXPECT_TRUE(b.display.device.empty()) << "runtime: the screen file goes into the data folder";
  EXPECT_EQ(b.display.width, 640);
  EXPECT_EQ(b.display.height, 480);
  EXPECT_EQ(b.storage.usb.kind, StorageLocation::Kind::Runtime);
  EXPECT_DOUBLE_EQ(b.camera_mount_height_m, 1.5);  // the synthetic room's camera
}

TEST(BoardConfig, UnknownOrUnsafeBoardNames) {
  try {
    load_board(kBoardRoot, "beaglebone");
    FAIL();
  } catch (const BoardConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("no board \"beaglebone\" (boards: qemu, rpi, usb-webcam, virtual)"),
              std::string::npos) << e.what();
  }
  for (const char* bad : {"", "../board", "rpi/..", "/etc", "RPI", "-x"})
    EXPECT_THROW(load_board(kBoardRoot, bad), BoardConfigError) << bad;
}

// Board files written to a per-test temporary folder.
class BoardFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("propcam_board_test_" + std::to_string(getpid()) + "_" + info->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path write_text(const std::string& text, const std::string& name = "b") {
    fs::create_directories(root_ / name);
    const fs::path file = root_ / name / "board.json";
    std::ofstream(file, std::ios::binary) << text;
    return file;
  }
  fs::path write(const json& j, const std::string& name = "b") { return write_text(j.dump(2), name); }

  fs::path root_;
};

json gpiod_board() {
  return json::parse(R"({
    "name": "b",
    "buttons": {"backend": "gpiod", "chip": "gpiochip0", "debounce_ms": 20, "long_press_ms": 800,
                "lines": {"shoot": "GPIO5", "next": "GPIO6", "prev": "GPIO13", "ok": "GPIO19", "back": "GPIO26"}},
    "display": {"backend": "fbdev", "device": "/dev/fb0", "rotation": 90},
    "camera": {"id": "v4l2:/dev/video0",
               "viewfinder": {"format": "YUYV", "size": "640x480", "fps": 30},
               "still": {"size": "1280x720"}},
    "camera_mount_height_m": 1.4,
    "storage": {"usb": "/media/stick", "spool_dir": "spool", "data_dir": "/var/lib/propcam"}
  })");
}

json evdev_board() {
  json j = gpiod_board();
  j["buttons"] = json::parse(R"({"backend": "evdev", "device": "/dev/input/event3", "debounce_ms": 5,
    "long_press_ms": 700, "keys": {"shoot": 212, "next": 106, "prev": 105, "ok": 28, "back": 1}})");
  return j;
}

json file_board() {
  json j = gpiod_board();
  j["buttons"] = json::parse(R"({"backend": "script", "script": "s.buttons", "debounce_ms": 0, "long_press_ms": 500})");
  j["display"] = json::parse(R"({"backend": "file", "path": "shots", "size": "320x240"})");
  j["camera"]["id"] = "replay:rec/one";
  return j;
}

TEST_F(BoardFiles, ValidVariantsLoad) {
  const BoardConfig g = load_board_file(write(gpiod_board()));
  EXPECT_EQ(g.display.rotation, 90);
  EXPECT_EQ(g.storage.spool_dir.path, root_ / "b" / "spool");
  EXPECT_EQ(g.camera.still_size, (Size{1280, 720}));
  const BoardConfig e = load_board_file(write(evdev_board()));
  EXPECT_EQ(e.buttons.evdev_device, "/dev/input/event3");
  EXPECT_EQ(e.buttons.evdev_keys.at(Button::Shoot), 212);
  const BoardConfig f = load_board_file(write(file_board()));
  EXPECT_EQ(f.buttons.script, root_ / "b" / "s.buttons");
  EXPECT_EQ(f.camera.replay_dir, root_ / "b" / "rec/one");
  EXPECT_EQ(f.display.device, root_ / "b" / "shots");
  json drm = gpiod_board();
  drm["display"] = json::parse(R"({"backend": "drm", "card": "/dev/dri/card1"})");
  EXPECT_EQ(load_board_file(write(drm)).display.device, "/dev/dri/card1");
  // Budgets default when absent and are read when given.
  EXPECT_EQ(g.budgets.working_pixels, kDefaultWorkingPixels);
  EXPECT_EQ(g.budgets.memory_mb, kDefaultMemoryBudgetMb);
  EXPECT_EQ(g.budgets.render_seconds, kDefaultRenderSeconds);
  json budgeted = gpiod_board();
  budgeted["budgets"] = json::parse(R"({"working_size": "1600x1200", "memory_mb": 1024, "render_seconds": 30})");
  const BoardConfig b = load_board_file(write(budgeted));
  EXPECT_EQ(b.budgets.working_pixels, 1600L * 1200L);
  EXPECT_EQ(b.budgets.memory_mb, 1024);
  EXPECT_EQ(b.budgets.render_seconds, 30.0);
  // The lens's vignetting: none unless calibrated; r4 optional.
  EXPECT_FALSE(g.camera.vignetting.known());
  json vignetted = gpiod_board();
  vignetted["camera"]["vignetting"] = json::parse(R"({"r2": -0.42, "r4": 0.05, "comment": "flat field 2026-12"})");
  const BoardConfig v = load_board_file(write(vignetted));
  EXPECT_EQ(v.camera.vignetting.r2, -0.42);
  EXPECT_EQ(v.camera.vignetting.r4, 0.05);
  vignetted["camera"]["vignetting"] = json::parse(R"({"r2": -0.3})");
  EXPECT_EQ(load_board_file(write(vignetted)).camera.vignetting.r4, 0.0);
  // load_board finds files written under the root too.
  EXPECT_EQ(list_boards(root_), std::vector<std::string>{"b"});
  EXPECT_EQ(load_board(root_, "b").name, "b");
}

struct BadCase {
  std::string label;
  std::function<json()> base;
  std::function<void(json&)> mutate;
  std::string pointer;  // the field the error must name
  std::string problem;  // a part of the message
};

void set(json& j, const std::string& ptr, json value) { j[json::json_pointer(ptr)] = std::move(value); }
void drop(json& j, const std::string& ptr) {
  const json::json_pointer p(ptr);
  j[p.parent_pointer()].erase(p.back());
}

std::vector<BadCase> bad_cases() {
  auto set_to = [](std::string ptr, json v) { return [=](json& j) { set(j, ptr, v); }; };
  auto without = [](std::string ptr) { return [=](json& j) { drop(j, ptr); }; };
  const auto G = gpiod_board, E = evdev_board, F = file_board;
  return {
      {"missing name", G, without("/name"), "/name", "missing"},
      {"name not the folder", G, set_to("/name", "other"), "/name", "must be the board folder's name, \"b\""},
      {"name a number", G, set_to("/name", 5), "/name", "must be a string, not an integer"},
      {"unknown top field", G, set_to("/pins", json::object()), "/pins", "unknown field"},
      {"comment not a string", G, set_to("/buttons/comment", 3), "/buttons/comment", "must be a string"},
      {"missing buttons", G, without("/buttons"), "/buttons", "missing"},
      {"buttons an array", G, set_to("/buttons", json::array()), "/buttons", "must be an object, not an array"},
      {"unknown button backend", G, set_to("/buttons/backend", "i2c"), "/buttons/backend",
       "unknown backend \"i2c\" (backends: gpiod, evdev, script)"},
      {"missing debounce", G, without("/buttons/debounce_ms"), "/buttons/debounce_ms", "missing"},
      {"debounce a string", G, set_to("/buttons/debounce_ms", "20"), "/buttons/debounce_ms", "must be an integer, not a string"},
      {"debounce fractional", G, set_to("/buttons/debounce_ms", 20.5), "/buttons/debounce_ms", "must be an integer, not a number"},
      {"debounce negative", G, set_to("/buttons/debounce_ms", -1), "/buttons/debounce_ms", "out of range [0, 200]"},
      {"long press too short", G, [](json& j) { set(j, "/buttons/debounce_ms", 200); set(j, "/buttons/long_press_ms", 150); },
       "/buttons/long_press_ms", "must be longer than debounce_ms (200)"},
      {"long press huge", G, set_to("/buttons/long_press_ms", 1000000), "/buttons/long_press_ms", "out of range"},
      {"misspelt field", G, set_to("/buttons/debounce", 20), "/buttons/debounce", "unknown field"},
      {"evdev field on gpiod", G, set_to("/buttons/keys", json::object()), "/buttons/keys", "unknown field"},
      {"missing chip", G, without("/buttons/chip"), "/buttons/chip", "missing"},
      {"missing ok line", G, without("/buttons/lines/ok"), "/buttons/lines/ok", "all five buttons are required: shoot, next, prev, ok, back"},
      {"duplicate line", G, set_to("/buttons/lines/prev", "GPIO6"), "/buttons/lines/prev", "\"GPIO6\" is already the next button"},
      {"unknown button", G, set_to("/buttons/lines/menu", "GPIO4"), "/buttons/lines/menu", "unknown field"},
      {"empty line name", G, set_to("/buttons/lines/shoot", ""), "/buttons/lines/shoot", "must not be empty"},
      {"line a number", G, set_to("/buttons/lines/shoot", 5), "/buttons/lines/shoot", "must be a string"},
      {"evdev device and name", E, set_to("/buttons/device_name", "gpio-keys"), "/buttons", "exactly one of"},
      {"evdev neither", E, without("/buttons/device"), "/buttons", "exactly one of"},
      {"evdev device outside /dev/input", E, set_to("/buttons/device", "/tmp/event0"), "/buttons/device", "under /dev/input/"},
      {"evdev device climbing", E, set_to("/buttons/device", "/dev/input/../sda"), "/buttons/device", "under /dev/input/"},
      {"key code zero", E, set_to("/buttons/keys/ok", 0), "/buttons/keys/ok", "out of range [1, 767]"},
      {"key code huge", E, set_to("/buttons/keys/ok", 4096), "/buttons/keys/ok", "out of range [1, 767]"},
      {"duplicate key code", E, set_to("/buttons/keys/back", 28), "/buttons/keys/back", "\"28\" is already the ok button"},
      {"missing keys", E, without("/buttons/keys"), "/buttons/keys", "missing"},
      {"script climbing", F, set_to("/buttons/script", "../../etc/passwd"), "/buttons/script", "leaves the board folder"},
      {"script absolute", F, set_to("/buttons/script", "/etc/passwd"), "/buttons/script", "must be relative to the board folder"},
      {"unknown display backend", G, set_to("/display/backend", "vga"), "/display/backend", "unknown backend \"vga\""},
      {"rotation 45", G, set_to("/display/rotation", 45), "/display/rotation", "must be 0, 90, 180 or 270"},
      {"rotation 360", G, set_to("/display/rotation", 360), "/display/rotation", "out of range [0, 270]"},
      {"fbdev relative", G, set_to("/display/device", "fb0"), "/display/device", "must be a device path under /dev/"},
      {"drm not dri", G, set_to("/display", json{{"backend", "drm"}, {"card", "/dev/fb0"}}), "/display/card", "under /dev/dri/"},
      {"file size no height", F, set_to("/display/size", "640x"), "/display/size", "must be WIDTHxHEIGHT"},
      {"file size negative", F, set_to("/display/size", "-640x480"), "/display/size", "must be WIDTHxHEIGHT"},
      {"file size tiny", F, set_to("/display/size", "10x10"), "/display/size", "each side must be in [32, 8192]"},
      {"file size huge", F, set_to("/display/size", "100000x480"), "/display/size", "each side must be in [32, 8192]"},
      {"file size number", F, set_to("/display/size", 640), "/display/size", "must be a string"},
      {"file path climbing", F, set_to("/display/path", "../shots"), "/display/path", "leaves the board folder"},
      {"missing camera", G, without("/camera"), "/camera", "missing"},
      {"unknown camera backend", G, set_to("/camera/id", "usb:0"), "/camera/id", "unknown camera \"usb:0\""},
      {"camera id without colon", G, set_to("/camera/id", "video0"), "/camera/id", "unknown camera"},
      {"replay of nothing", G, set_to("/camera/id", "replay:"), "/camera/id", "names no camera"},
      {"replay climbing", G, set_to("/camera/id", "replay:rec/../../x"), "/camera/id", "leaves the board folder"},
      {"replay absolute", G, set_to("/camera/id", "replay:/srv/rec"), "/camera/id", "must be relative"},
      {"v4l2 not a device", G, set_to("/camera/id", "v4l2:video0"), "/camera/id", "device path under /dev/"},
      {"unknown pixel format", G, set_to("/camera/viewfinder/format", "H264"), "/camera/viewfinder/format", "unknown pixel format \"H264\""},
      {"fps zero", G, set_to("/camera/viewfinder/fps", 0), "/camera/viewfinder/fps", "out of range (0, 240]"},
      {"fps huge", G, set_to("/camera/viewfinder/fps", 1000), "/camera/viewfinder/fps", "out of range"},
      {"fps a string", G, set_to("/camera/viewfinder/fps", "30"), "/camera/viewfinder/fps", "must be a number, not a string"},
      {"missing still", G, without("/camera/still"), "/camera/still", "missing"},
      {"still size tiny", G, set_to("/camera/still/size", "8x8"), "/camera/still/size", "each side must be in [16, 16384]"},
      {"vignetting r2 missing", G, set_to("/camera/vignetting", json{{"r4", 0.1}}), "/camera/vignetting/r2", "missing"},
      {"vignetting misspelt", G, set_to("/camera/vignetting", json{{"r2", -0.3}, {"k1", 0.1}}), "/camera/vignetting/k1",
       "unknown field"},
      {"vignetting a string", G, set_to("/camera/vignetting", json{{"r2", "-0.3"}}), "/camera/vignetting/r2",
       "must be a number, not a string"},
      {"vignetting huge", G, set_to("/camera/vignetting", json{{"r2", -50}}), "/camera/vignetting/r2", "out of range [-5, 5]"},
      {"vignetting black corners", G, set_to("/camera/vignetting", json{{"r2", -4.0}}), "/camera/vignetting",
       "outside [0.05, 1.50]"},
      {"missing height", G, without("/camera_mount_height_m"), "/camera_mount_height_m", "missing"},
      {"negative height", G, set_to("/camera_mount_height_m", -1.4), "/camera_mount_height_m", "out of range (0, 10]"},
      {"zero height", G, set_to("/camera_mount_height_m", 0), "/camera_mount_height_m", "out of range"},
      {"height in feet", G, set_to("/camera_mount_height_m", 55), "/camera_mount_height_m", "out of range"},
      // JSON has no NaN: a NaN written by a tool comes out as null.
      {"NaN height", G, set_to("/camera_mount_height_m", std::nan("")), "/camera_mount_height_m", "must be a number, not null"},
      {"height a string", G, set_to("/camera_mount_height_m", "1.4"), "/camera_mount_height_m", "must be a number, not a string"},
      {"empty usb", G, set_to("/storage/usb", ""), "/storage/usb", "must not be empty"},
      {"spool auto", G, set_to("/storage/spool_dir", "auto"), "/storage/spool_dir", "\"auto\" is for the USB mount only"},
      {"data climbing", G, set_to("/storage/data_dir", "x/../../y"), "/storage/data_dir", "leaves the board folder"},
      {"absolute with dots", G, set_to("/storage/usb", "/media/../etc"), "/storage/usb", "must not contain \"..\""},
      {"control character", G, set_to("/storage/usb", "/media/a\nb"), "/storage/usb", "control characters"},
      {"missing storage usb", G, without("/storage/usb"), "/storage/usb", "missing"},
      {"unknown budget", G, set_to("/budgets/seconds", 10), "/budgets/seconds", "unknown field"},
      {"working size text", G, set_to("/budgets/working_size", "big"), "/budgets/working_size", "must be WIDTHxHEIGHT"},
      {"memory a fraction", G, set_to("/budgets/memory_mb", 512.5), "/budgets/memory_mb", "must be an integer"},
      {"memory tiny", G, set_to("/budgets/memory_mb", 64), "/budgets/memory_mb", "out of range [256, 1048576]"},
      {"render seconds zero", G, set_to("/budgets/render_seconds", 0), "/budgets/render_seconds", "out of range (0, 86400]"},
      {"working size over memory", G, set_to("/budgets", json{{"working_size", "2048x1536"}}), "/budgets/working_size",
       "over the memory budget of 512 MB"},
      {"memory under the default size", G, set_to("/budgets", json{{"memory_mb", 300}}), "/budgets/memory_mb",
       "needs about 439 MB at its peak with the full-size photo held"},
  };
}

TEST_F(BoardFiles, EveryValidationErrorNamesTheFileAndTheField) {
  for (const BadCase& c : bad_cases()) {
    SCOPED_TRACE(c.label);
    json j = c.base();
    c.mutate(j);
    const fs::path file = write(j);
    try {
      load_board_file(file);
      ADD_FAILURE() << "loaded";
    } catch (const BoardConfigError& e) {
      const std::string what = e.what();
      EXPECT_EQ(e.file(), file);
      EXPECT_EQ(e.json_path(), c.pointer) << what;
      EXPECT_EQ(what.rfind(file.string() + ": " + c.pointer + ": ", 0), 0u) << what;
      EXPECT_NE(what.find(c.problem), std::string::npos) << what;
    }
  }
}

TEST_F(BoardFiles, ADoubledKeyIsAnErrorNotASilentOverride) {
  const std::string text = gpiod_board().dump();
  const std::string doubled = std::string(text).replace(text.find("\"ok\":"), 0, "\"ok\":\"GPIO4\",");
  const fs::path file = write_text(doubled);
  try {
    load_board_file(file);
    FAIL();
  } catch (const BoardConfigError& e) {
    EXPECT_EQ(e.json_path(), "/buttons/lines/ok") << e.what();
    EXPECT_NE(std::string(e.what()).find("appears twice"), std::string::npos);
  }
}

TEST_F(BoardFiles, FileLevelErrors) {
  auto message = [](const fs::path& f) {
    try {
      load_board_file(f);
    } catch (const BoardConfigError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(f.string() + ": ", 0), 0u) << e.what();
      return std::string(e.what());
    }
    return std::string("loaded");
  };
  EXPECT_NE(message(root_ / "none" / "board.json").find("no such board file"), std::string::npos);
  EXPECT_NE(message(write_text("")).find("not valid JSON"), std::string::npos);
  EXPECT_NE(message(write_text("{\"name\": \"b\",")).find("not valid JSON"), std::string::npos);
  EXPECT_NE(message(write_text("[1, 2]")).find("/: must be a JSON object, not an array"), std::string::npos);
  EXPECT_NE(message(write_text("\"b\"")).find("must be a JSON object, not a string"), std::string::npos);
  EXPECT_NE(message(write_text("{\"camera_mount_height_m\": NaN}")).find("not valid JSON"), std::string::npos);
}

}  // namespace
}  // namespace propcam::firmware
