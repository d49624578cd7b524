// Export to the stick and the spool on healthy storage: what lands on the
// stick, under which names, and how the spool waits for a stick. The faults
// are in storage_fault_test.cpp.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sys/wait.h>
#include <thread>

#include "cli_run.h"
#include "propcam/capture/image_file.h"
#include "storage/storage_names.h"
#include "storage_test_support.h"

namespace {

using namespace storage_test;
using nlohmann::json;

const std::string kStem = item_stem();

TEST(StorageNames, SanitiseKeepsASafeAlphabetOnly) {
  EXPECT_EQ(sanitise_name("chair"), "chair");
  EXPECT_EQ(sanitise_name("Chair 2.0"), "Chair_2_0");
  EXPECT_EQ(sanitise_name("../../etc/passwd"), "etc_passwd");
  EXPECT_EQ(sanitise_name("a/b\\c"), "a_b_c");
  EXPECT_EQ(sanitise_name(""), "composite");
  EXPECT_EQ(sanitise_name(".."), "composite");
  EXPECT_EQ(sanitise_name("\n\t"), "composite");
  EXPECT_EQ(sanitise_name("--x--"), "x");
  EXPECT_EQ(sanitise_name("Stuhl f\xc3\xbcr K\xc3\xbc" "che"), "Stuhl_f_r_K_che");
  const std::string long_name = sanitise_name(std::string(300, 'a') + "/..");
  EXPECT_EQ(long_name.size(), kMaxPropNameChars);
  const std::regex safe("[A-Za-z0-9][A-Za-z0-9_-]*");
  for (const std::string name : {"\xff\xfe", "CON", "a:b*c?d", "x\0y", " spaced out "})
    EXPECT_TRUE(std::regex_match(sanitise_name(name), safe)) << sanitise_name(name);
}

TEST(StorageNames, StemsAreDatedAndIdsValid) {
  EXPECT_EQ(dated_stem(make_item(0).taken, "chair"), kStem);
  EXPECT_EQ(numbered_stem("s", 1), "s");
  EXPECT_EQ(numbered_stem("s", 3), "s_3");
  const std::string id = new_entry_id(std::chrono::system_clock::now());
  EXPECT_TRUE(is_entry_id(id)) << id;
  EXPECT_NE(id, new_entry_id(std::chrono::system_clock::now()));
  EXPECT_FALSE(is_entry_id("../20261201T230112-1a2b3c4d"));
  EXPECT_FALSE(is_entry_id(".incoming-20261201T230112-1a2b3c4d"));
}

TEST(StorageExport, WritesThePngPixelForPixelTheJpegAndTheSidecar) {
  const fs::path usb = fresh_dir("usb"), spool = fresh_dir("spool");
  Exporter exporter(spool, UsbTarget::folder(usb));
  const ExportItem item = make_item(7);
  const ExportOutcome outcome = exporter.export_composite(item);
  ASSERT_EQ(outcome.kind, ExportOutcome::Kind::Written) << outcome.message;
  EXPECT_EQ(outcome.message, "saved to USB as " + kStem + ".png");
  const fs::path dir = usb / kStickFolder;
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{std::string(kStem) + ".jpg", std::string(kStem) + ".json",
                                                     std::string(kStem) + ".png"}));
  const auto png = decode(dir / (std::string(kStem) + ".png"));
  ASSERT_TRUE(png);
  EXPECT_TRUE(same_pixels(png->pixels, item.composite_srgb8));
  EXPECT_EQ(png->text.at("Software"), "PropCam");
  EXPECT_EQ(png->text.at("PropCam:export_id"), outcome.entry_id);
  EXPECT_NE(png->text.at("ImageDescription").find("chair"), std::string::npos);
  EXPECT_EQ(json::parse(png->text.at("PropCam:metadata"))["index"], 7);
  const auto jpeg = decode(dir / (std::string(kStem) + ".jpg"));
  ASSERT_TRUE(jpeg);
  EXPECT_EQ(jpeg->pixels.size(), item.composite_srgb8.size());
  EXPECT_EQ(jpeg->text.at("Software"), "PropCam");
  EXPECT_FALSE(jpeg->text.at("DateTime").empty());
  EXPECT_LT(cv::norm(jpeg->pixels, item.composite_srgb8, cv::NORM_L1) / jpeg->pixels.total() / 3, 8.0);
  std::ifstream sidecar(dir / (std::string(kStem) + ".json"));
  const json doc = json::parse(sidecar);
  EXPECT_EQ(doc["export_id"], outcome.entry_id);
  EXPECT_EQ(doc["metadata"]["prop"], "chair");
  EXPECT_TRUE(exporter.spool().empty());
  EXPECT_EQ(check_stick(dir), (std::vector<int>{7}));
}

TEST(StorageExport, NoJpegWhenDisabled) {
  const fs::path usb = fresh_dir("usb");
  ExportOptions options;
  options.jpeg = false;
  Exporter exporter(fresh_dir("spool"), UsbTarget::folder(usb), options);
  ASSERT_EQ(exporter.export_composite(make_item(1)).kind, ExportOutcome::Kind::Written);
  for (const auto& name : names_in(usb / kStickFolder)) EXPECT_FALSE(has_suffix(name, ".jpg")) << name;
}

TEST(StorageExport, CollidingNamesGetNumbers) {
  const fs::path usb = fresh_dir("usb");
  Exporter exporter(fresh_dir("spool"), UsbTarget::folder(usb));
  for (int i = 0; i < 3; ++i) ASSERT_EQ(exporter.export_composite(make_item(i)).kind, ExportOutcome::Kind::Written);
  const fs::path dir = usb / kStickFolder;
  const std::string stem = kStem;
  for (const std::string& s : {stem, stem + "_2", stem + "_3"})
    for (const char* ext : {".png", ".jpg", ".json"}) EXPECT_TRUE(fs::exists(dir / (s + ext))) << s << ext;
  EXPECT_EQ(check_stick(dir), (std::vector<int>{0, 1, 2}));
  // A foreign file under the next name is never replaced.
  std::ofstream(dir / (stem + "_4.png")) << "not ours";
  const ExportOutcome outcome = exporter.export_composite(make_item(3));
  EXPECT_EQ(outcome.message, "saved to USB as " + stem + "_5.png");
}

TEST(StorageExport, HostilePropNamesStayInTheExportFolder) {
  const fs::path usb = fresh_dir("usb");
  Exporter exporter(fresh_dir("spool"), UsbTarget::folder(usb));
  const std::regex safe(item_stem("") + "[A-Za-z0-9][A-Za-z0-9_-]*(_\\d+)?\\.(png|jpg|json)");
  for (const std::string& prop : std::vector<std::string>{"../../../evil", "/etc/passwd", "..", "a\nb", std::string(500, 'x'), "\xc3\xa9t\xc3\xa9"}) {
    const ExportOutcome outcome = exporter.export_composite(make_item(2, prop));
    ASSERT_EQ(outcome.kind, ExportOutcome::Kind::Written) << outcome.message;
    for (const auto& f : outcome.files) {
      EXPECT_EQ(f.parent_path(), usb / kStickFolder) << f;
      EXPECT_TRUE(std::regex_match(f.filename().string(), safe)) << f;
    }
  }
  EXPECT_EQ(names_in(usb), (std::vector<std::string>{kStickFolder}));
}

TEST(StorageExport, ASymlinkedExportFolderIsRefused) {
  const fs::path usb = fresh_dir("usb"), elsewhere = fresh_dir("elsewhere");
  fs::create_directory_symlink(elsewhere, usb / kStickFolder);
  Exporter exporter(fresh_dir("spool"), UsbTarget::folder(usb));
  const ExportOutcome outcome = exporter.export_composite(make_item(1));
  EXPECT_EQ(outcome.kind, ExportOutcome::Kind::Spooled);
  EXPECT_EQ(outcome.message, "stick's PropCam is not a folder: kept in the spool (1 waiting)");
  EXPECT_TRUE(names_in(elsewhere).empty());
}

TEST(StorageExport, NoStickSpoolsUntilAStickAppears) {
  const fs::path root = fresh_dir("mnt"), usb = root / "stick", spool = fresh_dir("spool");
  Exporter exporter(spool, UsbTarget::folder(usb));
  EXPECT_EQ(exporter.usb_status().state, UsbStatus::State::Absent);
  EXPECT_EQ(exporter.usb_status().message, "no stick");
  ExportOutcome first = exporter.export_composite(make_item(1));
  EXPECT_EQ(first.kind, ExportOutcome::Kind::Spooled);
  EXPECT_EQ(first.message, "no stick: kept in the spool (1 waiting)");
  EXPECT_EQ(exporter.export_composite(make_item(2)).message, "no stick: kept in the spool (2 waiting)");
  const auto waiting = exporter.spool();
  ASSERT_EQ(waiting.size(), 2u);
  EXPECT_EQ(waiting[0].stem, kStem);
  EXPECT_GT(waiting[0].bytes(), 0u);
  EXPECT_EQ(exporter.flush_spool().message, "no stick: 2 waiting in the spool");

  fs::create_directories(usb);
  EXPECT_TRUE(exporter.usb_status().usable());
  EXPECT_NE(exporter.usb_status().message.find(" free"), std::string::npos) << exporter.usb_status().message;
  // A fresh Exporter (a restart) sees the same spool.
  Exporter restarted(spool, UsbTarget::folder(usb));
  const FlushReport report = restarted.flush_spool();
  EXPECT_EQ(report.moved, 2);
  EXPECT_EQ(report.waiting, 0);
  EXPECT_EQ(report.message, "moved 2 to USB");
  EXPECT_EQ(report.files.size(), 6u);
  EXPECT_TRUE(restarted.spool().empty());
  EXPECT_EQ(check_stick(usb / kStickFolder), (std::vector<int>{1, 2}));
  EXPECT_EQ(restarted.flush_spool().message, "spool empty");
}

TEST(StorageExport, LayersExrAndSceneFolder) {
  const fs::path usb = fresh_dir("usb"), scene = fresh_dir("scene");
  std::ofstream(scene / "scene.json") << "{\"fx\": 500}\n";
  fs::create_directories(scene / "lights");
  std::ofstream(scene / "lights" / "ibl0.bin") << std::string(10000, 'L');
  ExportOptions options;
  options.layers = true;
  options.scene = true;
  Exporter exporter(fresh_dir("spool"), UsbTarget::folder(usb), options);
  ExportItem item = make_layered_item(4);
  item.scene_dir = scene;
  const ExportOutcome outcome = exporter.export_composite(item);
  ASSERT_EQ(outcome.kind, ExportOutcome::Kind::Written) << outcome.message;
  const fs::path dir = usb / kStickFolder;
  auto exr = OIIO::ImageInput::open((dir / (std::string(kStem) + "_layers.exr")).string());
  ASSERT_TRUE(exr);
  const auto& names = exr->spec().channelnames;
  EXPECT_EQ(std::vector<std::string>(names.begin(), names.end()),
            (std::vector<std::string>{"composite.R", "composite.G", "composite.B", "depth.Z", "photo.R", "photo.G",
                                      "photo.B"}));
  std::vector<float> pixels(static_cast<size_t>(kItemWidth) * kItemHeight * 7);
  ASSERT_TRUE(exr->read_image(0, 0, 0, 7, OIIO::TypeDesc::FLOAT, pixels.data()));
  EXPECT_FLOAT_EQ(pixels[3], 2.5f);
  EXPECT_FLOAT_EQ(pixels[4] * 2, pixels[0]);
  const fs::path copied = dir / (std::string(kStem) + "_scene");
  EXPECT_EQ(fingerprint_file(copied / "scene.json"), fingerprint_file(scene / "scene.json"));
  EXPECT_EQ(fingerprint_file(copied / "lights" / "ibl0.bin"), fingerprint_file(scene / "lights" / "ibl0.bin"));
  EXPECT_EQ(check_stick(dir), (std::vector<int>{4}));
}

TEST(StorageExport, AMissingSceneFolderCostsOnlyTheSceneCopy) {
  const fs::path usb = fresh_dir("usb");
  ExportOptions options;
  options.scene = true;
  Exporter exporter(fresh_dir("spool"), UsbTarget::folder(usb), options);
  ExportItem item = make_item(6);
  item.scene_dir = usb / "no-such-scene";
  ASSERT_EQ(exporter.export_composite(item).kind, ExportOutcome::Kind::Written);
  EXPECT_EQ(names_in(usb / kStickFolder), (std::vector<std::string>{kStem + ".jpg", kStem + ".json", kStem + ".png"}));
}

TEST(StorageExport, RelativeFoldersWork) {
  const fs::path base = fresh_dir("cwd");
  const fs::path old_cwd = fs::current_path();
  fs::current_path(base);
  fs::create_directories("usb");
  {
    Exporter exporter("spool", UsbTarget::folder("usb"));
    EXPECT_EQ(exporter.export_composite(make_item(2)).kind, ExportOutcome::Kind::Written);
  }
  fs::current_path(old_cwd);
  EXPECT_EQ(check_stick(base / "usb" / kStickFolder), (std::vector<int>{2}));
}

TEST(StorageExport, RestartRemovesWhatACrashLeft) {
  const fs::path usb = fresh_dir("usb"), spool = fresh_dir("spool");
  fs::create_directories(spool / ".incoming-20261201T230112-00000001");
  std::ofstream(spool / ".incoming-20261201T230112-00000001" / "composite.png") << "half";
  fs::create_directories(spool / ".done-20261201T230112-00000002");
  fs::create_directories(usb / kStickFolder);
  std::ofstream(usb / kStickFolder / ".propcam-20261201T230112-00000003-0.tmp") << "torn";
  std::ofstream(spool / "notes.txt") << "not the spool's: kept";
  Exporter exporter(spool, UsbTarget::folder(usb));
  EXPECT_EQ(names_in(spool), (std::vector<std::string>{"notes.txt"}));
  EXPECT_TRUE(exporter.spool().empty());
  ASSERT_EQ(exporter.export_composite(make_item(5)).kind, ExportOutcome::Kind::Written);
  EXPECT_EQ(check_stick(usb / kStickFolder), (std::vector<int>{5}));
}

// An ".incoming-" folder is a leftover only when nobody is writing: while
// another exporter holds the spool, starting one (even to list) keeps it.
TEST(StorageExport, AnotherProcesssExportInProgressIsNotALeftover) {
  const fs::path spool = fresh_dir("spool");
  const fs::path live = spool / ".incoming-20261201T230112-00000001";
  fs::create_directories(live);
  {
    const SpoolFolderLock writing(spool, SpoolFolderLock::Mode::Writing);
    ASSERT_TRUE(writing.held());
    Exporter lister(spool, UsbTarget::folder(fresh_dir("usb")));
    EXPECT_TRUE(fs::exists(live));
  }
  Exporter after(spool, UsbTarget::folder(fresh_dir("usb")));
  EXPECT_FALSE(fs::exists(live));
}

// Exports and exporters starting beside them, at once: every export lands.
TEST(StorageExport, ConcurrentExportersNeverRemoveEachOthersWork) {
  const fs::path spool = fresh_dir("spool"), no_stick = fresh_dir("usb") / "absent";
  constexpr int kExports = 40;
  std::atomic<bool> done{false};
  std::thread starter([&] {
    while (!done) Exporter(spool, UsbTarget::folder(no_stick)).spool();
  });
  Exporter exporter(spool, UsbTarget::folder(no_stick));
  int spooled = 0;
  for (int i = 0; i < kExports; ++i) spooled += exporter.export_composite(make_item(i)).kind == ExportOutcome::Kind::Spooled;
  done = true;
  starter.join();
  EXPECT_EQ(spooled, kExports);
  EXPECT_EQ(exporter.spool().size(), static_cast<std::size_t>(kExports));
}

TEST(StorageExport, RejectsACompositeThatIsNotRgb8) {
  Exporter exporter(fresh_dir("spool"), UsbTarget::folder(fresh_dir("usb")));
  ExportItem item = make_item(0);
  item.composite_srgb8.convertTo(item.composite_srgb8, CV_32FC3);
  EXPECT_THROW(exporter.export_composite(item), std::invalid_argument);
  EXPECT_TRUE(exporter.spool().empty());
}

TEST(StorageUsb, AutoFindsTheWritableRemovableMount) {
  const fs::path root = fresh_dir("sys"), stick = fresh_dir("media stick"), ro = fresh_dir("ro");
  // sysfs: /sys/dev/block/MAJ:MIN links into /sys/devices; sda is a USB disk,
  // mmcblk0 a removable card reader, nvme0n1 neither.
  const fs::path devices = root / "devices", dev_block = root / "dev" / "block";
  fs::create_directories(devices / "pci0/usb1/1-1/block/sda/sda1");
  std::ofstream(devices / "pci0/usb1/1-1/block/sda/sda1/partition") << "1\n";
  fs::create_directories(devices / "platform/mmc/block/mmcblk0/mmcblk0p1");
  std::ofstream(devices / "platform/mmc/block/mmcblk0/removable") << "1\n";
  std::ofstream(devices / "platform/mmc/block/mmcblk0/mmcblk0p1/partition") << "1\n";
  fs::create_directories(devices / "pci0/nvme/block/nvme0n1/nvme0n1p2");
  std::ofstream(devices / "pci0/nvme/block/nvme0n1/removable") << "0\n";
  std::ofstream(devices / "pci0/nvme/block/nvme0n1/nvme0n1p2/partition") << "2\n";
  fs::create_directories(dev_block);
  fs::create_symlink(devices / "pci0/usb1/1-1/block/sda/sda1", dev_block / "8:1");
  fs::create_symlink(devices / "platform/mmc/block/mmcblk0/mmcblk0p1", dev_block / "179:1");
  fs::create_symlink(devices / "pci0/nvme/block/nvme0n1/nvme0n1p2", dev_block / "259:2");
  EXPECT_TRUE(is_removable_block_device(dev_block, "8:1"));
  EXPECT_TRUE(is_removable_block_device(dev_block, "179:1"));
  EXPECT_FALSE(is_removable_block_device(dev_block, "259:2"));
  EXPECT_FALSE(is_removable_block_device(dev_block, "0:42"));

  std::string escaped = stick.string();
  escaped.replace(escaped.find("media stick"), 11, "media\\040stick");
  const fs::path mountinfo = root / "mountinfo";
  std::ofstream(mountinfo) << "22 1 259:2 / / rw,relatime shared:1 - ext4 /dev/nvme0n1p2 rw\n"
                           << "40 22 179:1 / " << ro.string() << " ro,nosuid shared:7 - vfat /dev/mmcblk0p1 ro\n"
                           << "41 22 8:1 / " << escaped << " rw,nosuid,nodev shared:9 - vfat /dev/sda1 rw,fmask=0022\n";
  std::ifstream mountinfo_in(mountinfo);
  const auto mounts = parse_mountinfo(std::string(std::istreambuf_iterator<char>(mountinfo_in), {}));
  ASSERT_EQ(mounts.size(), 3u);
  EXPECT_EQ(mounts[2].mount_point, stick);
  EXPECT_EQ(mounts[2].source, "/dev/sda1");
  EXPECT_TRUE(mounts[1].read_only);
  const UsbStatus status = UsbTarget::automatic(mountinfo, dev_block).status();
  EXPECT_EQ(status.state, UsbStatus::State::Ready) << status.message;
  EXPECT_EQ(status.root, stick);
  EXPECT_TRUE(UsbTarget::automatic(root / "no-such-mountinfo", dev_block).status().state == UsbStatus::State::Absent);
}

TEST(StorageUsb, ConfigLocations) {
  StorageLocation runtime;
  runtime.kind = StorageLocation::Kind::Runtime;
  EXPECT_THROW(UsbTarget::from_config(runtime, std::nullopt), std::invalid_argument);
  EXPECT_EQ(UsbTarget::from_config(runtime, fs::path("/x")).describe(), "folder /x");
  StorageLocation path;
  path.path = "/media/stick";
  EXPECT_EQ(UsbTarget::from_config(path, std::nullopt).describe(), "folder /media/stick");
  EXPECT_EQ(human_bytes(3'100'000'000), "3.1 GB");
  EXPECT_EQ(human_bytes(512'000'000), "512 MB");
  EXPECT_EQ(human_bytes(12), "12 B");
}

// ---- the CLI, end to end ----

using propcam::test::CliRun;
using propcam::test::propcam;

json json_of(const std::string& text) { return json::parse(text.substr(text.find('{'))); }

TEST(StorageCli, ExportAndSpoolEndToEnd) {
  const fs::path inputs = fresh_dir("in"), spool = fresh_dir("spool"), mnt = fresh_dir("mnt"), usb = mnt / "stick";
  const fs::path photo = inputs / "my lamp.png";
  propcam::capture::write_image(photo.string(), item_pixels(9));
  const std::string storage = " --spool '" + spool.string() + "' --usb '" + usb.string() + "'";

  // No stick yet: spooled (exit 3).
  CliRun r = propcam("export '" + photo.string() + "'" + storage + " --json");
  ASSERT_EQ(r.exit_code, 3) << r.out;
  json out = json_of(r.out);
  EXPECT_EQ(out["results"][0]["kind"], "spooled");
  EXPECT_EQ(out["results"][0]["message"], "no stick: kept in the spool (1 waiting)");
  EXPECT_EQ(out["usb"]["state"], "absent");

  r = propcam("spool --spool '" + spool.string() + "' --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  out = json_of(r.out);
  ASSERT_EQ(out["entries"].size(), 1u);
  EXPECT_EQ(out["entries"][0]["prop"], "my lamp");

  fs::create_directories(usb);
  r = propcam("spool --flush" + storage + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  out = json_of(r.out);
  EXPECT_EQ(out["flush"]["moved"], 1);
  EXPECT_TRUE(out["entries"].empty());
  EXPECT_EQ(check_stick(usb / kStickFolder), (std::vector<int>{9}));
  std::string flushed;  // the spooled composite's name on the stick
  for (const auto& e : fs::directory_iterator(usb / kStickFolder))
    if (e.path().extension() == ".png") flushed = e.path().filename().string();
  ASSERT_FALSE(flushed.empty());

  // With a stick: written at once, the PNG equal to the input. Names carry
  // the minute: within the same minute as the first, the name is taken and
  // this one is numbered (the two exports may straddle a minute).
  r = propcam("export '" + photo.string() + "'" + storage + " --no-jpeg --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  out = json_of(r.out);
  ASSERT_EQ(out["results"][0]["kind"], "written");
  const fs::path png = out["results"][0]["files"][0].get<std::string>();
  const std::string dated = "YYYY-MM-DD_HHMM";
  const bool same_minute = png.filename().string().substr(0, dated.size()) == flushed.substr(0, dated.size());
  EXPECT_TRUE(has_suffix(png.filename().string(), same_minute ? "_my_lamp_2.png" : "_my_lamp.png")) << png << " after " << flushed;
  EXPECT_NE(png.filename().string(), flushed);
  const auto decoded = decode(png);
  ASSERT_TRUE(decoded);
  EXPECT_TRUE(same_pixels(decoded->pixels, item_pixels(9)));
  for (const auto& f : out["results"][0]["files"]) EXPECT_FALSE(has_suffix(f.get<std::string>(), ".jpg"));
}

// One unreadable file in a batch is reported; the others are exported.
TEST(StorageCli, ABatchReportsEachFileAndKeepsGoingPastABadOne) {
  const fs::path inputs = fresh_dir("in"), spool = fresh_dir("spool"), usb = fresh_dir("stick");
  const fs::path a = inputs / "a.png", bad = inputs / "bad.png", c = inputs / "c.png";
  propcam::capture::write_image(a.string(), item_pixels(1));
  propcam::capture::write_image(c.string(), item_pixels(3));
  std::ofstream(bad) << "not an image";
  const std::string storage = " --spool '" + spool.string() + "' --usb '" + usb.string() + "'";
  CliRun r = propcam("export '" + a.string() + "' '" + bad.string() + "' '" + c.string() + "'" + storage + " --json");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  const json out = json_of(r.out);
  ASSERT_EQ(out["results"].size(), 3u) << r.out;
  EXPECT_EQ(out["results"][0]["kind"], "written");
  EXPECT_EQ(out["results"][1]["kind"], "failed");
  EXPECT_NE(out["results"][1]["message"].get<std::string>().find("bad.png"), std::string::npos) << r.out;
  EXPECT_EQ(out["results"][2]["kind"], "written");
  EXPECT_EQ(check_stick(usb / kStickFolder).size(), 2u);

  r = propcam("export '" + a.string() + "' '" + bad.string() + "'" + storage);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("bad.png: not exported"), std::string::npos) << r.out;
}

TEST(StorageCli, RuntimeLocationsNeedTheFlags) {
  const fs::path photo = fresh_dir("in") / "a.png";
  propcam::capture::write_image(photo.string(), item_pixels(1));
  CliRun r = propcam("export " + photo.string() + " --board virtual");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--spool"), std::string::npos) << r.out;
  r = propcam("export " + photo.string() + " --board virtual --spool " + fresh_dir("spool").string());
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--usb"), std::string::npos) << r.out;
  r = propcam("spool --board virtual --flush --spool " + fresh_dir("spool2").string());
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--usb"), std::string::npos) << r.out;
  r = propcam("export " + photo.string() + " --board no-such-board --usb /tmp");
  EXPECT_NE(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("no-such-board"), std::string::npos) << r.out;
}

}  // namespace
