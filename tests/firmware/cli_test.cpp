// Runs the real `propcam` executable as a user would.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <csignal>
#include <sys/wait.h>
#include <unistd.h>

#include "cli_run.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/depth_transfer.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/render/camera.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using propcam::test::CliRun;
using propcam::test::propcam;

json json_tail(const std::string& text) {
  // The JSON document is the last thing printed (progress goes before it).
  const auto start = text.find_first_of("[{");
  return json::parse(text.substr(start));
}

// ctest runs each test in its own process, two at a time: every process gets
// its own folder, so one test's fixture photo is never rewritten under another
// test's composite. The folder goes when the process ends.
const fs::path& process_temp_root() {
  struct Root {
    fs::path path = fs::path(::testing::TempDir()) / ("propcam_cli_" + std::to_string(::getpid()));
    ~Root() {
      std::error_code ignored;
      fs::remove_all(path, ignored);
    }
  };
  static const Root root;
  return root.path;
}

std::string temp(const std::string& name) {
  const fs::path p = process_temp_root() / name;
  fs::create_directories(p.parent_path());
  return p.string();
}

// A small photo made by the project itself (synthetic room).
const std::string& fixture_photo() {
  static const std::string dir = [] {
    const std::string d = temp("room");
    const CliRun r = propcam("synth -o " + d + " --seed 4 --size 160x120 --spp 8");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    return d;
  }();
  static const std::string photo = dir + "/photo.png";
  return photo;
}

TEST(Cli, PropsListsAtLeastFourPresets) {
  const CliRun r = propcam("props --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json list = json::parse(r.out);
  ASSERT_GE(list.size(), 4u);
  for (const auto& p : list) {
    EXPECT_GT(p["height_m"].get<double>(), 0);
    EXPECT_GT(p["triangles"].get<int>(), 0);
  }
}

TEST(Cli, InferWritesTheSceneFolderContract) {
  const std::string out = temp("scene");
  const CliRun r = propcam("infer " + fixture_photo() + " -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::ifstream in(out + "/scene.json");
  const json s = json::parse(in);
  for (const char* k : {"fx", "fy", "cx", "cy"}) EXPECT_TRUE(s["K"][k].is_number()) << k;
  EXPECT_EQ(s["R_world_from_cam"].size(), 3u);
  EXPECT_GT(s["camera_height_m"].get<double>(), 0);
  EXPECT_TRUE(s["gamma"].is_number());
  ASSERT_FALSE(s["lights"].empty());
  for (const auto& l : s["lights"]) {
    EXPECT_TRUE(l["type"] == "area" || l["type"] == "point" || l["type"] == "sun" || l["type"] == "ibl");
    EXPECT_EQ(l["intensity"].size(), 3u);
  }
  for (const auto& rep : s["reports"])
    for (const char* k : {"stage", "usable", "why", "iterations", "seconds"}) EXPECT_TRUE(rep.contains(k)) << k;
  const cv::Mat depth = propcam::capture::read_image_float(out + "/depth.exr");
  EXPECT_EQ(depth.cols, 160);
  EXPECT_EQ(depth.channels(), 1);
  EXPECT_EQ(propcam::capture::read_image_float(out + "/albedo.exr").channels(), 3);
}

TEST(Cli, CompositeWritesAnImageOfThePhotosSize) {
  const std::string out = temp("composite.png");
  const CliRun r = propcam("composite " + fixture_photo() + " --prop vase --at 80,95 --spp 2 --json -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json summary = json_tail(r.out);
  EXPECT_EQ(summary["output"], out);
  const cv::Mat img = propcam::capture::read_image_float(out);
  EXPECT_EQ(img.cols, 160);
  EXPECT_EQ(img.rows, 120);
}

TEST(Cli, CompositeReusesASceneFolderAndAcceptsAMeshFile) {
  const std::string scene = temp("scene2");
  ASSERT_EQ(propcam("infer " + fixture_photo() + " -o " + scene).exit_code, 0);
  const std::string obj = temp("tri.obj");
  std::ofstream(obj) << "v -0.5 0 0\nv 0.5 0 0\nv 0 1 0\nv 0 0 0.5\nf 1 2 3\nf 1 4 2\nf 2 4 3\nf 3 4 1\n";
  const CliRun r = propcam("composite " + fixture_photo() + " --scene " + scene + " --prop " + obj +
                        " --material metal --albedo 0.9,0.6,0.2 --height 0.3 --yaw 45 --at 80,95 --spp 1 -o " +
                        temp("c2.png"));
  EXPECT_EQ(r.exit_code, 0) << r.out;
}

TEST(Cli, CompositeRelightsExplainsAndBlursOnRequest) {
  const std::string out = temp("relit.png");
  CliRun r = propcam("composite " + fixture_photo() + " --prop vase --at 80,95 --spp 2 --light-scale 0=2 --relight-scene"
                     " --aperture 0.02 --explain --json -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json summary = json_tail(r.out);
  EXPECT_TRUE(summary["plan"].contains("tiles_culled"));
  EXPECT_GT(summary["depth_of_field"]["focus_m"].get<double>(), 0.0);
  EXPECT_TRUE(fs::exists(out));
  r = propcam("composite " + fixture_photo() + " --prop vase --at 80,95 --spp 1 --light-scale 99=2 -o " + temp("r2.png"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("--light-scale expects"), std::string::npos) << r.out;
}

TEST(Cli, ViewCutsAPhotoWithAKnownCameraFromAPanorama) {
  // A panorama the test makes: grey everywhere, a bright band above the horizon.
  cv::Mat pano(64, 128, CV_32FC3, cv::Scalar(0.2, 0.2, 0.2));
  pano.rowRange(0, 32).setTo(cv::Scalar(2.0, 2.0, 2.0));
  const std::string pano_path = temp("pano.exr"), out = temp("view.png");
  propcam::capture::write_image(pano_path, pano);
  CliRun r = propcam("view " + pano_path + " --size 80x60 --fov 90 --pitch 10 --json -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json v = json_tail(r.out);
  EXPECT_NEAR(v["K"]["fx"].get<double>(), 40.0, 1e-9) << "90 degrees across 80 pixels";
  EXPECT_GT(v["R_world_from_cam"][1][2].get<double>(), 0.0) << "pitch up: the view axis has a positive world y";
  const cv::Mat img = propcam::capture::read_image_float(out);
  EXPECT_EQ(img.cols, 80);
  EXPECT_EQ(img.rows, 60);
  r = propcam("view " + pano_path + " --fov 200 -o " + temp("bad.png"));
  EXPECT_NE(r.exit_code, 0);
}

// The lens's fall-off from flat-field photos, and a composite given it.
TEST(Cli, CalibrateVignettingFitsAFlatFieldAndCompositeTakesIt) {
  constexpr double kR2 = -0.5;
  cv::Mat flat(240, 320, CV_32FC3);
  for (int r = 0; r < flat.rows; ++r)
    for (int c = 0; c < flat.cols; ++c) {
      const double s2 = (std::pow(c + 0.5 - 160.0, 2) + std::pow(r + 0.5 - 120.0, 2)) / (200.0 * 200.0);
      flat.at<cv::Vec3f>(r, c) = cv::Vec3f::all(static_cast<float>(0.5 * std::exp(kR2 * s2)));
    }
  const std::string frame = temp("flat.png");
  propcam::capture::write_image(frame, flat);
  CliRun r = propcam("calibrate-vignetting " + frame + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json fit = json_tail(r.out);
  EXPECT_NEAR(fit["corner_gain"].get<double>(), std::exp(kR2), 0.01) << r.out;
  r = propcam("calibrate-vignetting " + frame);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("\"vignetting\": {\"r2\""), std::string::npos) << "what board.json takes: " << r.out;
  // A room is no flat field.
  r = propcam("calibrate-vignetting " + fixture_photo());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("not a flat field"), std::string::npos) << r.out;

  r = propcam("composite " + fixture_photo() + " --prop vase --at 80,95 --spp 1 --vignetting=-0.5,0.02 --json -o " +
              temp("vignetted.png"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json match = json_tail(r.out)["camera_match"];
  ASSERT_EQ(match["steps"][1]["effect"], "vignette");
  EXPECT_TRUE(match["steps"][1]["applied"].get<bool>()) << match.dump();
  EXPECT_LT(match["vignette_gain"].get<double>(), 1.0);
  for (const std::string& bad : {"banana", "-0.5,x", "-9", "nan"}) {
    r = propcam("composite " + fixture_photo() + " --prop vase --at 80,95 --spp 1 --vignetting " + bad + " -o " +
                temp("bad_vignetting.png"));
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.out;
    EXPECT_NE(r.out.find("--vignetting"), std::string::npos) << bad << ": " << r.out;
  }
}

TEST(Cli, BadInputIsAClearErrorNotACrash) {
  CliRun r = propcam("composite " + fixture_photo() + " --prop vase --at banana -o " + temp("x.png"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("--at expects U,V"), std::string::npos) << r.out;
  r = propcam("composite " + fixture_photo() + " --prop no_such_prop --at 10,10 -o " + temp("x.png"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("no_such_prop"), std::string::npos) << r.out;
  r = propcam("composite " + fixture_photo() + " --prop vase --at 80,5 --spp 1 -o " + temp("x.png"));
  EXPECT_NE(r.exit_code, 0);  // a wall, not a support
  EXPECT_FALSE(fs::exists(temp("x.png")));
  const std::string junk = temp("junk.png");
  std::ofstream(junk) << "not an image";
  r = propcam("infer " + junk + " -o " + temp("junk_scene"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("junk.png"), std::string::npos) << r.out;
}

// Numbers that would make nonsense are refused where they enter, naming the
// option and its range; NaN included.
TEST(Cli, NumbersOutsideTheirPhysicalRangeAreRefusedNamingTheRange) {
  const std::string out = temp("range.png");
  for (const std::string& bad : {"--height 0", "--height -1", "--height nan", "--aperture nan", "--yaw nan",
                                 "--focal 1e-300", "--camera-height 0", "--camera-height -1.5", "--spp 0",
                                 "--albedo 1e30,0.5,0.5", "--time-budget 0", "--time-budget nan",
                                 "--memory-budget 10"}) {
    const CliRun r = propcam("composite " + fixture_photo() + " --prop vase --at 80,95 " + bad + " -o " + out);
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.out;
    const std::string option = bad.substr(0, bad.find(' '));
    EXPECT_NE(r.out.find(option), std::string::npos) << bad << ": " << r.out;
    EXPECT_TRUE(r.out.find("must be") != std::string::npos || r.out.find("not in range") != std::string::npos ||
                r.out.find("out of range") != std::string::npos)
        << bad << ": " << r.out;
  }
  EXPECT_FALSE(fs::exists(out));
  const CliRun r = propcam("composite " + fixture_photo() + " --prop vase --at 80,95 --spp 1 --light-scale 0=1e38 -o " + out);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--light-scale"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

// A scene folder edited by hand: each field out of its range is named.
TEST(Cli, ASceneFolderWithNonsenseNumbersIsRefusedNamingTheField) {
  const std::string scene = temp("scene_ranges");
  ASSERT_EQ(propcam("infer " + fixture_photo() + " -o " + scene).exit_code, 0);
  json original;
  std::ifstream(scene + "/scene.json") >> original;
  const auto composite_with = [&](const std::function<void(json&)>& edit) {
    json j = original;
    edit(j);
    std::ofstream(scene + "/scene.json") << j.dump(2);
    return propcam("composite " + fixture_photo() + " --scene " + scene + " --prop vase --at 80,95 --spp 1 -o " +
                   temp("ranges.png"));
  };
  CliRun r = composite_with([](json& j) { j["gamma"] = 1e300; });
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("gamma"), std::string::npos) << r.out;
  r = composite_with([](json& j) { j["camera_height_m"] = 0.0; });
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("camera_height_m"), std::string::npos) << r.out;
  r = composite_with([](json& j) { j["lights"][0]["intensity"] = json::array({1e300, 1.0, 1.0}); });
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("intensity"), std::string::npos) << r.out;
  r = composite_with([](json&) {});
  EXPECT_EQ(r.exit_code, 0) << r.out;
  fs::remove(scene + "/depth.exr");
  r = composite_with([](json&) {});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("depth.exr"), std::string::npos) << r.out;
}

// Photos the appliance cannot model say why: a strip, half a JPEG, a folder.
TEST(Cli, UnusablePhotosAreClearErrors) {
  const std::string strip = temp("strip.png");
  propcam::capture::write_image(strip, cv::Mat(16, 1000, CV_8UC3, cv::Scalar(90, 120, 150)));
  CliRun r = propcam("infer " + strip + " -o " + temp("strip_scene"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("long side"), std::string::npos) << r.out;

  const std::string full = temp("whole.jpg"), half = temp("half.jpg");
  propcam::capture::write_image(full, propcam::capture::linear_to_srgb8(propcam::capture::load_photo_linear(fixture_photo())));
  std::ifstream in(full, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(half, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  r = propcam("composite " + half + " --prop vase --at 80,95 --spp 1 -o " + temp("half_out.png"));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("cut short"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(temp("half_out.png")));

  r = propcam("infer " + temp("") + " -o " + temp("folder_scene"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("folder"), std::string::npos) << r.out;
}

// A photo larger than the working size is inferred and rendered reduced and
// delivered at its own size; away from the prop it is the photo.
TEST(Cli, ALargerPhotoIsWorkedReducedAndDeliveredAtItsSize) {
  const std::string scene = temp("scene_working"), out = temp("working_out.png"), again = temp("working_again.png");
  CliRun r = propcam("infer " + fixture_photo() + " --working-size 80x60 --json -o " + scene);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  json j = json_tail(r.out);
  EXPECT_EQ(j["photo_size"], json::array({160, 120}));
  EXPECT_EQ(j["working_size"], json::array({80, 60}));

  r = propcam("composite " + fixture_photo() + " --scene " + scene + " --prop vase --at 80,95 --spp 2 --json -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = json_tail(r.out);
  EXPECT_EQ(j["working_size"], json::array({80, 60}));
  EXPECT_EQ(j["output_size"], json::array({160, 120}));
  EXPECT_EQ(j["samples_per_pixel"], 2);
  EXPECT_EQ(j["time_budget"]["stopped_render"], false);
  const cv::Mat photo = propcam::capture::load_photo_linear(fixture_photo());
  const cv::Mat composite = propcam::capture::load_photo_linear(out);
  ASSERT_EQ(composite.size(), photo.size());
  // The top rows (the far wall, beyond the prop's reach): the photo, up to 8-bit rounding.
  const cv::Rect far(0, 0, 160, 20);
  EXPECT_LT(cv::norm(propcam::capture::linear_to_srgb8(composite(far)), propcam::capture::linear_to_srgb8(photo(far)),
                     cv::NORM_INF),
            2.0);
  // Around the base: the prop is there.
  EXPECT_GT(cv::norm(composite(cv::Rect(70, 70, 20, 25)), photo(cv::Rect(70, 70, 20, 25)), cv::NORM_INF), 0.05);

  // The same without a scene folder: inferred at the working size on the way.
  r = propcam("composite " + fixture_photo() + " --working-size 80x60 --prop vase --at 80,95 --spp 2 --json -o " + again);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(json_tail(r.out)["output_size"], json::array({160, 120}));

  // A scene folder from another photo's size is refused, naming both.
  r = propcam("composite " + fixture_photo() + " --scene " + scene + " --prop vase --at 80,95 --spp 1 -o " + out +
              " --working-size 40x30");
  EXPECT_EQ(r.exit_code, 0) << r.out;  // the scene folder's size wins over --working-size
  const std::string other = temp("other_aspect.png");
  propcam::capture::write_image(other, cv::Mat(120, 120, CV_8UC3, cv::Scalar(100, 100, 100)));
  r = propcam("composite " + other + " --scene " + scene + " --prop vase --at 60,95 --spp 1 -o " + temp("other_out.png"));
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("80x60"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("120x120"), std::string::npos) << r.out;
}

// The working size is checked against the memory budget before the photo is read.
TEST(Cli, AWorkingSizeOverTheMemoryBudgetIsRefusedUpFront) {
  const std::string scene = temp("scene_over_budget");
  fs::remove_all(scene);
  CliRun r = propcam("infer " + fixture_photo() + " --working-size 4000x3000 -o " + scene);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--working-size 4000x3000: a working size of 12.00 megapixels"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("over the memory budget of 512 MB"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(--memory-budget)"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(scene));
  // With the budget raised, the same size is taken (the photo is smaller, so it is worked as it is).
  r = propcam("infer " + fixture_photo() + " --working-size 4000x3000 --memory-budget 8192 --json -o " + scene);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(json_tail(r.out)["working_size"], json::array({160, 120}));
}

TEST(Cli, VersionNamesTheProgramAndItsVersion) {
  CliRun r = propcam("--version");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(r.out, std::string("propcam ") + PROPCAM_VERSION_EXPECTED + "\n");
  r = propcam::test::run_shell(std::string(PROPCAMD) + " --version 2>&1");
  EXPECT_EQ(r.out, std::string("propcamd ") + PROPCAM_VERSION_EXPECTED + "\n");
}

TEST(Cli, QuietLeavesOutProgressAndVerboseIsAccepted) {
  const CliRun normal = propcam("infer " + fixture_photo() + " -o " + temp("loud_scene"));
  ASSERT_EQ(normal.exit_code, 0) << normal.out;
  EXPECT_NE(normal.out.find("s] "), std::string::npos) << "progress lines, e.g. [  0.10s] ...: " << normal.out;
  const CliRun quiet = propcam("-q infer " + fixture_photo() + " -o " + temp("quiet_scene"));
  ASSERT_EQ(quiet.exit_code, 0) << quiet.out;
  EXPECT_EQ(quiet.out.find("s] "), std::string::npos) << quiet.out;
  EXPECT_EQ(quiet.out.find(" ok "), std::string::npos) << "only unusable stages are reported: " << quiet.out;
  EXPECT_TRUE(fs::exists(temp("quiet_scene") + "/scene.json"));
  EXPECT_EQ(propcam("infer -v " + fixture_photo() + " -o " + temp("verbose_scene")).exit_code, 0);
}

// The models are looked up in the data folder (share/propcam beside bin/,
// $PROPCAM_DATA_DIR or --data-dir); one missing or unreadable stops the
// command before any work, naming the file.
TEST(Cli, AMissingOrUnreadableDataFileStopsInferenceNamingIt) {
  const fs::path data = temp("data_dir");
  fs::remove_all(data);
  fs::create_directories(data / "inference");
  const std::string out = temp("data_dir_scene");
  CliRun r = propcam("--data-dir " + data.string() + " infer " + fixture_photo() + " -o " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find((data / "inference/depth_db.bin").string() + " is missing"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out + "/scene.json"));

  // The environment variable, and the flag after the command.
  r = propcam::test::run_shell("PROPCAM_DATA_DIR=" + data.string() + " " + PROPCAM_CLI + " infer " + fixture_photo() +
                               " -o " + out + " 2>&1");
  EXPECT_NE(r.out.find((data / "inference/depth_db.bin").string()), std::string::npos) << r.out;
  r = propcam("composite " + fixture_photo() + " --prop vase --at 80,100 -o " + temp("d.png") + " --data-dir " + data.string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("is missing"), std::string::npos) << r.out;

  // All present but one unreadable (an empty file reads nothing).
  const fs::path shipped = fs::path(PROPCAM_BINARY_DIR) / "share/propcam/inference";
  for (const char* f : {"depth_db.bin", "scene_refs.bin", "scene_classifier.yml.gz", "light_classifier.yml.gz"})
    fs::copy_file(shipped / f, data / "inference" / f, fs::copy_options::overwrite_existing);
  std::ofstream(data / "inference/ibl_ranker.yml.gz").flush();
  r = propcam("--data-dir " + data.string() + " infer " + fixture_photo() + " -o " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find((data / "inference/ibl_ranker.yml.gz").string() + " cannot be read"), std::string::npos) << r.out;

  r = propcam("--data-dir " + (data / "no_such").string() + " infer " + fixture_photo() + " -o " + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("is not a folder"), std::string::npos) << r.out;
  // Commands that load no model do not ask for them.
  EXPECT_EQ(propcam("--data-dir " + data.string() + " props").exit_code, 0);
}

TEST(Cli, InferOnLineSegments) {
  const std::string csv = temp("lines.csv");
  std::ofstream(csv) << "x1,y1,x2,y2\n10,10,100,12\n";
  const CliRun r = propcam("infer --lines " + csv + " --size 640x480");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json j = json::parse(r.out);
  EXPECT_GT(j["K"]["fx"].get<double>(), 0);
  EXPECT_EQ(propcam("infer --lines " + csv).exit_code, 2);
}

TEST(Cli, InferTakesACalibratedFocalLength) {
  // A calibrated lens: fixed, the focal length is exactly the calibration;
  // as a prior on lines that cannot fix it (one family), it is the prior.
  const std::string out = temp("scene_calibrated");
  ASSERT_EQ(propcam("infer " + fixture_photo() + " -o " + out + " --focal 512.5 --fixed-focal").exit_code, 0);
  std::ifstream in(out + "/scene.json");
  const json s = json::parse(in);
  EXPECT_DOUBLE_EQ(s["K"]["fx"].get<double>(), 512.5);
  const std::string csv = temp("lines_prior.csv");
  std::ofstream(csv) << "x1,y1,x2,y2\n10,10,100,12\n";
  const CliRun r = propcam("infer --lines " + csv + " --size 640x480 --focal 700");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_DOUBLE_EQ(json::parse(r.out)["K"]["fx"].get<double>(), 700.0);
  EXPECT_EQ(propcam("infer " + fixture_photo() + " -o " + out + " --fixed-focal").exit_code, 2);
  EXPECT_NE(propcam("infer " + fixture_photo() + " -o " + out + " --focal -3").exit_code, 0);
}

TEST(Cli, InferTakesThePhotosExifFocalLengthAsThePrior) {
  // The fixture photo re-encoded as a JPEG saying "35 mm equivalent".
  auto in = OIIO::ImageInput::open(fixture_photo());
  ASSERT_TRUE(in);
  OIIO::ImageSpec spec = in->spec();
  std::vector<uint8_t> pixels(spec.image_pixels() * spec.nchannels);
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, pixels.data()));
  in->close();
  spec.set_format(OIIO::TypeDesc::UINT8);
  spec.attribute("Exif:FocalLengthIn35mmFilm", 35);
  const std::string jpeg = temp("exif_photo.jpg");
  auto out = OIIO::ImageOutput::create(jpeg);
  ASSERT_TRUE(out && out->open(jpeg, spec) && out->write_image(OIIO::TypeDesc::UINT8, pixels.data()) && out->close());

  const CliRun r = propcam("infer " + jpeg + " -o " + temp("scene_exif") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const double expected = 35.0 * std::hypot(spec.width, spec.height) / 43.2666;
  bool found = false;
  const json reports = json_tail(r.out)["reports"];
  for (const auto& rep : reports) {
    if (rep["stage"] != "camera") continue;
    found = true;
    EXPECT_EQ(rep["details"]["focal_prior_source"], "Exif:FocalLengthIn35mmFilm");
    EXPECT_NEAR(rep["details"]["focal_prior_px"].get<double>(), expected, 0.01);
  }
  EXPECT_TRUE(found) << r.out;
  // A calibration on the command line wins over EXIF.
  const CliRun c = propcam("infer " + jpeg + " -o " + temp("scene_exif2") + " --json --focal 300");
  ASSERT_EQ(c.exit_code, 0) << c.out;
  const json calibrated = json_tail(c.out)["reports"];
  for (const auto& rep : calibrated)
    if (rep["stage"] == "camera") {
      EXPECT_DOUBLE_EQ(rep["details"]["focal_prior_px"].get<double>(), 300.0);
    }
}

TEST(Cli, BenchReportsStagesAndPlots) {
  const std::string plots = temp("plots");
  const CliRun r = propcam("bench --json --size 96x72 --max-spp 2 --reference-spp 8 --plot " + plots);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  EXPECT_FALSE(b["stages"].empty());
  EXPECT_EQ(b["sweeps"]["render_spp"].size(), 2u);
  EXPECT_FALSE(b["sweeps"]["camera_ransac"].empty());
  EXPECT_GT(fs::file_size(plots + "/render_spp.png"), 1000u);
  EXPECT_GT(fs::file_size(plots + "/camera_ransac.png"), 1000u);
}

TEST(Cli, BenchGeometryReportsErrorsAgainstSecondsAndPlots) {
  const std::string plots = temp("geometry_plots");
  const CliRun r = propcam("bench geometry --rooms 1 --streets 0 --size 160x120 --spp 4 --sweeps priors,resolution"
                           " --timing-width 0 --json --plot " + plots);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  ASSERT_GE(b["rows"].size(), 8u);
  for (const auto& row : b["rows"])
    for (const char* k : {"focal_rel_median", "vp_deg_median", "abs_rel_median", "rmse_log_median", "normal_deg_median",
                          "seconds_mean"}) {
      ASSERT_TRUE(row["all"][k].is_number()) << row["label"] << " " << k;
      EXPECT_TRUE(std::isfinite(row["all"][k].get<double>())) << row["label"] << " " << k;
    }
  EXPECT_GT(fs::file_size(plots + "/geometry_rooms.png"), 1000u);
  EXPECT_EQ(propcam("bench geometry --sweeps nonsense").exit_code, 2);
}

TEST(Cli, BenchLightingReportsErrorsAgainstSecondsBesideTheBaseline) {
  const std::string plots = temp("lighting_plots");
  const CliRun r = propcam("bench lighting --rooms 1 --streets 1 --size 128x96 --spp 4 --sweeps response --json --plot " +
                           plots);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  ASSERT_EQ(b["rows"].size(), 4u);  // baseline, default, two response settings
  EXPECT_EQ(b["rows"][0]["sweep"], "baseline");
  for (const auto& row : b["rows"]) {
    for (const char* k : {"direction_deg_median", "composite_rel_rmse_median", "gamma_median", "seconds_mean"}) {
      ASSERT_TRUE(row["all"][k].is_number()) << row["label"] << " " << k;
      EXPECT_TRUE(std::isfinite(row["all"][k].get<double>())) << row["label"] << " " << k;
    }
    EXPECT_TRUE(row.contains("rooms") && row.contains("streets"));
  }
  EXPECT_GT(fs::file_size(plots + "/lighting.png"), 1000u);
  EXPECT_EQ(propcam("bench lighting --sweeps nonsense").exit_code, 2);
}

TEST(Cli, BenchWorldsScoresOurOwnWorldAndSaysHowToMakeTheBlenderOne) {
  const std::string plots = temp("worlds_plots");
  const CliRun r = propcam("bench worlds --worlds own --rooms 1 --streets 1 --own-size 96x72 --own-spp 8 --spp 8 "
                           "--sweeps spp,oracle --json --plot " + plots);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  ASSERT_EQ(b["rows"].size(), 4u);  // default, composites at 16 and 256 spp, the true scene
  EXPECT_EQ(b["rows"][3]["sweep"], "oracle");
  for (const auto& row : b["rows"]) {
    const json& own = row["worlds"]["own"];
    EXPECT_EQ(own["summary"]["scenes"], 2);
    ASSERT_EQ(own["scenes"].size(), 2u);
    for (const auto& scene : own["scenes"]) {
      EXPECT_TRUE(scene["photo"]["rmse"].is_number()) << scene.dump();
      EXPECT_TRUE(scene["composite"]["ssim"].is_number()) << scene.dump();
      EXPECT_TRUE(scene["seconds"].contains("inference"));
    }
    EXPECT_TRUE(own["summary"]["indoor_accuracy"].is_number());
  }
  EXPECT_GT(fs::file_size(plots + "/worlds.png"), 1000u);
  EXPECT_EQ(propcam("bench worlds --worlds nonsense").exit_code, 2);
  const CliRun missing = propcam("bench worlds --worlds blender --dir " + temp("no_world"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.out.find("make_blender_world.sh"), std::string::npos) << missing.out;
}

TEST(Cli, TrainLightClassifierThenBenchLights) {
  const std::string model = temp("light_model") + "/lights.yml.gz";
  const CliRun trained =
      propcam("train-light-classifier -o " + model + " --panoramas interior,sunset --views-per-turn 2 --trees 5");
  ASSERT_EQ(trained.exit_code, 0) << trained.out;
  EXPECT_NO_THROW(propcam::inference::LightClassifier::load(model));
  const CliRun r = propcam("bench lights --panoramas interior,courtyard,sunset --views-per-turn 2 --trees 5 --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  ASSERT_EQ(b["held_out"].size(), 3u);
  for (const char* d : {"classifier", "threshold", "both"})
    for (const char* k : {"precision", "recall", "f1", "ms_per_view"}) EXPECT_TRUE(b["all"][d][k].is_number()) << d << k;
}

TEST(Cli, BuildDepthDbThenBenchTransferOnIt) {
  const std::string db = temp("depth_db") + "/rooms.bin";
  const CliRun built = propcam("build-depth-db -o " + db + " --rooms 3 --streets 0 --spp 2");
  ASSERT_EQ(built.exit_code, 0) << built.out;
  ASSERT_EQ(propcam::inference::DepthDatabase::load(db).size(), 3u);
  const CliRun r = propcam("bench transfer --db " + db + " --rooms 1 --size 96x72 --spp 2 --k 1,3 --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  EXPECT_EQ(b["database_size"].get<int>(), 3);
  ASSERT_EQ(b["rows"].size(), 4u);  // k 1 and 3, with and without the warp
  for (const auto& row : b["rows"])
    for (const char* k : {"abs_rel_median", "rmse_log_median", "seconds_median"}) {
      ASSERT_TRUE(row[k].is_number()) << k;
      EXPECT_TRUE(std::isfinite(row[k].get<double>())) << k;
      EXPECT_GE(row[k].get<double>(), 0.0) << k;
    }
  EXPECT_EQ(propcam("bench transfer --db " + db + " --k 0").exit_code, 2);
  EXPECT_NE(propcam("bench transfer --db " + db + ".missing --rooms 1").exit_code, 0);
}

TEST(Cli, BenchRenderReportsSpeedAndErrorPerSize) {
  const std::string plots = temp("render_plots");
  const CliRun r = propcam("bench render --sizes 96x72 --reference-spp 64 --max-spp 16 --skip-size 64x48 --skip-spp 2"
                           " --skip-reference-spp 8 --json --plot " + plots);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  ASSERT_EQ(b["sizes"].size(), 1u);
  const json& s = b["sizes"][0];
  EXPECT_EQ(s["width"], 96);
  EXPECT_EQ(s["height"], 72);
  const auto finite_positive = [](const json& v) {
    return v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() > 0;
  };
  for (const char* k : {"rays_per_s", "embree_raw_rays_per_s", "efficiency", "scene_build_s", "first_snapshot_s"})
    EXPECT_TRUE(finite_positive(s[k])) << k << " = " << s[k];
  // Null when 1% is not reached within --max-spp.
  ASSERT_TRUE(s.contains("time_to_1pct_s"));
  EXPECT_TRUE(s["time_to_1pct_s"].is_null() || finite_positive(s["time_to_1pct_s"])) << s["time_to_1pct_s"];
  ASSERT_FALSE(s["curve"].empty());
  for (const auto& p : s["curve"])
    for (const char* k : {"spp", "seconds", "rmse_rel"}) EXPECT_TRUE(finite_positive(p[k])) << k << " = " << p[k];
  EXPECT_GT(fs::file_size(plots + "/render_96x72.png"), 1000u);
  // Each skip of the transport plan against simulating everything.
  ASSERT_EQ(b["skips"].size(), 5u);
  for (const auto& k : b["skips"])
    for (const char* key : {"seconds_full", "seconds_with_skip", "rmse_full", "rmse_with_skip"})
      EXPECT_TRUE(finite_positive(k[key])) << k["skip"] << " " << key;
  EXPECT_EQ(propcam("bench render --sizes 96by72").exit_code, 2);
}

// A tiny NYU-VP-format folder (lsd_lines_NNNN.csv, vps_NNNN.csv) of
// segments projected from axis-aligned 3D edges with a known 640x480 camera
// (f = 500, principal point at the centre), 0.4 px noise.
std::string synthetic_nyu_folder() {
  const fs::path dir = temp("nyu_vp");
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> x(-3, 3), y(0, 3), z(-8, -1.5), len(0.5, 1.5);
  std::normal_distribution<double> noise(0, 0.4);
  const std::array<std::pair<double, double>, 3> views = {{{30, -10}, {-40, -5}, {25, 8}}};  // yaw, pitch (deg)
  for (size_t n = 0; n < views.size(); ++n) {
    const double yaw = views[n].first * M_PI / 180, pitch = views[n].second * M_PI / 180;
    propcam::render::PinholeCamera cam;
    cam.width = 640;
    cam.height = 480;
    cam.fx = cam.fy = 500;
    cam.cx = 319.5;
    cam.cy = 239.5;
    const Eigen::Vector3d forward(-std::sin(yaw) * std::cos(pitch), std::sin(pitch), -std::cos(yaw) * std::cos(pitch));
    const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitY()).normalized();
    cam.R_world_from_cam.col(0) = right;
    cam.R_world_from_cam.col(1) = forward.cross(right);
    cam.R_world_from_cam.col(2) = forward;
    cam.center_world = {0, 1.5, 0};
    char id[8];
    std::snprintf(id, sizeof id, "%04zu", n);
    std::ofstream lines(dir / (std::string("lsd_lines_") + id + ".csv"));
    lines << "line_hom_a line_hom_b line_hom_c centroid_x centroid_y centroid_z point1_x point1_y point1_z "
             "point2_x point2_y point2_z\n";
    for (int axis = 0; axis < 3; ++axis)
      for (int made = 0, tries = 0; made < 25 && tries < 1000; ++tries) {
        const Eigen::Vector3d p(x(rng), y(rng), z(rng));
        Eigen::Vector3d q = p;
        q[axis] += len(rng);
        Eigen::Vector2d a, b;
        if (!cam.project(p, a) || !cam.project(q, b) || (a - b).norm() < 25) continue;
        if (a.minCoeff() < 0 || b.minCoeff() < 0 || a.x() > 639 || b.x() > 639 || a.y() > 479 || b.y() > 479) continue;
        a += Eigen::Vector2d(noise(rng), noise(rng));
        b += Eigen::Vector2d(noise(rng), noise(rng));
        const Eigen::Vector3d l = Eigen::Vector3d(a.x(), a.y(), 1).cross(Eigen::Vector3d(b.x(), b.y(), 1));
        lines << l.x() << " " << l.y() << " " << l.z() << " " << (a.x() + b.x()) / 2 << " " << (a.y() + b.y()) / 2
              << " 1 " << a.x() << " " << a.y() << " 1 " << b.x() << " " << b.y() << " 1\n";
        ++made;
      }
    std::ofstream vps(dir / (std::string("vps_") + id + ".csv"));
    vps << "idx X Y\n";
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d d = cam.R_world_from_cam.row(k).transpose();  // world axis k in camera coordinates
      vps << k << " " << cam.fx * d.x() / d.z() + cam.cx << " " << cam.fy * d.y() / d.z() + cam.cy << "\n";
    }
  }
  return dir.string();
}

TEST(Cli, BenchCameraOnANyuFormatFolder) {
  const std::string plots = temp("camera_plots");
  const CliRun r = propcam("bench camera --nyu " + synthetic_nyu_folder() +
                           " --intrinsics 500,500,319.5,239.5 --sweep-images 3 --json --plot " + plots);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json b = json_tail(r.out);
  EXPECT_EQ(b["dataset"]["images"], 3);
  for (const char* k : {"median", "mean", "p90", "within_5", "within_10", "within_20"})
    EXPECT_TRUE(b["focal_rel_error"][k].is_number()) << k;
  for (const char* k : {"median", "p90", "mean", "count", "metric"}) EXPECT_TRUE(b["axis_error_deg"].contains(k)) << k;
  int cases = 0;
  for (const char* k : {"three_vanishing_points", "two_vanishing_points", "vertical_only", "no_vanishing_points"})
    cases += b["cases"][k].get<int>();
  EXPECT_EQ(cases + b["cases"].value("horizontal_only", 0), 3);
  EXPECT_GT(b["seconds_per_image"]["mean"].get<double>(), 0.0);
  ASSERT_EQ(b["images"].size(), 3u);
  EXPECT_EQ(b["images"][0]["id"], "0000");
  ASSERT_FALSE(b["sweep"].empty());
  for (const char* k : {"ransac_iterations", "candidate_vps", "focal_hypotheses", "seconds_per_image",
                        "focal_err_median", "axis_err_median_deg"})
    EXPECT_TRUE(b["sweep"][0].contains(k)) << k;
  // A clean synthetic set: the camera must come out right.
  EXPECT_LT(b["focal_rel_error"]["median"].get<double>(), 0.03);
  EXPECT_LT(b["axis_error_deg"]["median"].get<double>(), 1.0);
  EXPECT_GT(fs::file_size(plots + "/camera_sweep_focal.png"), 1000u);
  EXPECT_GT(fs::file_size(plots + "/camera_focal_cdf.png"), 1000u);
  const CliRun bad = propcam("bench camera --nyu " + temp("no_such_folder"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.out.find("--nyu"), std::string::npos) << bad.out;
}

// The example scene (render/examples/cornell) copied to a temporary folder
// and shrunk to `width` x `height` (intrinsics scaled with it).
std::string example_scene_copy(const std::string& name, int width, int height) {
  const fs::path dir = temp(name);
  fs::remove_all(dir);
  fs::copy(fs::path(PROPCAM_SOURCE_DIR) / "render" / "examples" / "cornell", dir, fs::copy_options::recursive);
  std::ifstream in(dir / "scene.json");
  json scene = json::parse(in);
  const double scale = static_cast<double>(width) / scene["camera"]["width"].get<double>();
  for (const char* k : {"fx", "fy"}) scene["camera"]["K"][k] = scene["camera"]["K"][k].get<double>() * scale;
  scene["camera"]["K"]["cx"] = (width - 1) / 2.0;
  scene["camera"]["K"]["cy"] = (height - 1) / 2.0;
  scene["camera"]["width"] = width;
  scene["camera"]["height"] = height;
  std::ofstream(dir / "scene.json") << scene.dump(2);
  return (dir / "scene.json").string();
}

TEST(Cli, RenderTheExampleScene) {
  const std::string scene = example_scene_copy("cornell_small", 80, 60);
  const std::string out = temp("cornell.exr");
  const CliRun r = propcam("render " + scene + " --spp 4 --bounces 4 --json -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json summary = json_tail(r.out);
  EXPECT_EQ(summary["width"], 80);
  EXPECT_EQ(summary["height"], 60);
  EXPECT_EQ(summary["spp"], 4);
  EXPECT_GT(summary["rays"].get<double>(), 80 * 60 * 4);
  EXPECT_GT(summary["rays_per_s"].get<double>(), 0.0);
  const cv::Mat img = propcam::capture::read_image_float(out);
  ASSERT_EQ(img.cols, 80);
  ASSERT_EQ(img.rows, 60);
  EXPECT_TRUE(cv::checkRange(img));
  const cv::Scalar mean = cv::mean(img);
  EXPECT_GT(mean[0] + mean[1] + mean[2], 0.05) << "not black";
  // A PNG through a time budget (passes of 1, 2, ... spp; at least one).
  const std::string png = temp("cornell.png");
  const CliRun timed = propcam("render " + scene + " --time 0.5 --json -o " + png);
  ASSERT_EQ(timed.exit_code, 0) << timed.out;
  EXPECT_GE(json_tail(timed.out)["spp"].get<int>(), 1);
  EXPECT_EQ(propcam::capture::load_photo_linear(png).cols, 80);
}

TEST(Cli, RenderABrokenSceneIsAClearError) {
  const std::string scene = example_scene_copy("cornell_broken", 16, 12);
  std::ifstream in(scene);
  json broken = json::parse(in);
  broken["camera"]["K"].erase("fy");
  std::ofstream(scene) << broken.dump(2);
  const std::string out = temp("broken.png");
  CliRun r = propcam("render " + scene + " --spp 1 -o " + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("camera.K.fy: missing"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(scene), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
  // A file outside the scene's folder.
  broken = json::parse(std::ifstream(example_scene_copy("cornell_escape", 16, 12)));
  broken["meshes"][0]["file"] = "../cornell_small/box.obj";
  const std::string escape = temp("cornell_escape/scene.json");
  std::ofstream(escape) << broken.dump(2);
  r = propcam("render " + escape + " --spp 1 -o " + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("meshes[0].file"), std::string::npos) << r.out;
  // Not JSON at all, and --spp with --time.
  const std::string junk = temp("junk_scene.json");
  std::ofstream(junk) << "camera: yes";
  r = propcam("render " + junk + " -o " + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("invalid JSON"), std::string::npos) << r.out;
  EXPECT_NE(propcam("render " + scene + " --spp 2 --time 1 -o " + out).exit_code, 0);
  EXPECT_FALSE(fs::exists(out));
}

TEST(Cli, CompositeAcceptsTheNewMaterials) {
  for (const char* material : {"glass", "plastic"}) {
    const CliRun r = propcam("composite " + fixture_photo() + " --prop sphere_plinth --material " +
                             std::string(material) + " --at 80,95 --spp 1 -o " + temp(std::string(material) + ".png"));
    EXPECT_EQ(r.exit_code, 0) << material << ": " << r.out;
  }
}

}  // namespace

namespace {

// A real photograph (OpenCV's sample façade, installed from Debian's opencv-doc).
TEST(CliRealPhoto, InfersAndCompositesOnAStreetFacade) {
  const std::string photo = "/usr/share/doc/opencv-doc/examples/data/building.jpg";
  if (!fs::exists(photo)) GTEST_SKIP() << photo << " missing: install opencv-doc (scripts/setup.sh does)";
  const std::string scene = temp("building_scene");
  CliRun r = propcam("infer " + photo + " -o " + scene + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json reports = json_tail(r.out)["reports"];
  std::string camera_case;
  for (const auto& rep : reports)
    if (rep["stage"] == "camera") camera_case = rep["why"];
  EXPECT_EQ(camera_case, "three_vanishing_points");
  const std::string out = temp("building.png");
  r = propcam("composite " + photo + " --scene " + scene + " --prop chair --at 250,585 --spp 2 -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const cv::Mat before = propcam::capture::load_photo_linear(photo);
  const cv::Mat after = propcam::capture::load_photo_linear(out);
  ASSERT_EQ(after.size(), before.size());
  cv::Mat diff;
  cv::absdiff(before, after, diff);
  EXPECT_GT(cv::countNonZero(diff.reshape(1) > 0.05), 50) << "the prop is visible";
}

}  // namespace

// The camera commands on the virtual board's replay camera and on recordings
// made here: the real replay backend, pixel-format code and propcamd.
namespace {

double mean_abs_difference(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const cv::Scalar m = cv::mean(diff);
  return (m[0] + m[1] + m[2]) / 3.0;
}

TEST(CliCamera, CamerasListsTheVirtualBoardsReplayCamera) {
  const CliRun r = propcam("cameras --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  bool replay = false;
  for (const auto& c : json_tail(r.out))
    if (c["backend"] == "replay" && c["id"].get<std::string>().find("board/virtual/recordings/living_room") != std::string::npos) {
      replay = true;
      EXPECT_EQ(c["formats"][0]["format"], "YUYV");
      EXPECT_EQ(c["formats"][0]["sizes"][0], "640x480");
    }
  EXPECT_TRUE(replay) << r.out;
}

// record packs a photo as a camera would (each format), shoot takes it back
// through the replay camera: the shot is the photo, up to the format's loss.
TEST(CliCamera, RecordFromAPhotoThenShootFromTheRecording) {
  const cv::Mat photo = propcam::capture::linear_to_srgb8(propcam::capture::load_photo_linear(fixture_photo()));
  for (const std::string format : {"YUYV", "NV12", "MJPEG", "RGB24"}) {
    const std::string dir = temp("recording_" + format);
    fs::remove_all(dir);
    CliRun r = propcam("record --from-photo " + fixture_photo() + " --format " + format + " --frames 3 --noise 0 -o " + dir + " --json");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_EQ(json_tail(r.out)["frames"], 3);
    const std::string shot = temp("shot_" + format + ".png");
    r = propcam("shoot --camera replay:" + dir + " --settle-frames 2 -o " + shot + " --json");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_EQ(json_tail(r.out)["format"], format);
    const cv::Mat back = propcam::capture::linear_to_srgb8(propcam::capture::load_photo_linear(shot));
    ASSERT_EQ(back.size(), photo.size());
    EXPECT_LT(mean_abs_difference(back, photo), format == "RGB24" ? 0.01 : 4.0) << format;
  }
}

// With no camera attached, a shot is an error that says how to name one,
// not a silent shot of the bundled recording.
TEST(CliCamera, ShootWithNoCameraAttachedSaysSoAndWritesNothing) {
  const std::string none = temp("no_recordings");
  fs::create_directories(none);
  const json cameras = json_tail(propcam("cameras --recordings " + none + " --json").out);
  if (!cameras.empty()) GTEST_SKIP() << "this machine has a camera: " << cameras.dump();
  const std::string shot = temp("no_camera.png");
  CliRun r = propcam("shoot -o " + shot);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("no camera attached"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--camera replay:"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(shot));
  r = propcam("record --frames 2 -o " + temp("no_camera_rec"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("no camera attached"), std::string::npos) << r.out;
}

TEST(CliCamera, ShootAndRecordRefuseWhatTheyCannotDo) {
  EXPECT_NE(propcam("shoot --camera v4l2:/dev/null -o " + temp("x.png")).exit_code, 0);
  EXPECT_NE(propcam("shoot --camera nowhere:1 -o " + temp("x.png")).exit_code, 0);
  EXPECT_NE(propcam("record --from-photo " + fixture_photo() + " --format XYZ -o " + temp("bad_rec")).exit_code, 0);
  const CliRun r = propcam("shoot --camera replay:/nonexistent/recording -o " + temp("x.png"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("/nonexistent/recording"), std::string::npos) << r.out;
}

// propcamd serves the replay camera; `propcam shoot --daemon` is its client.
TEST(CliCamera, ShootThroughPropcamd) {
  const std::string socket = temp("propcamd.sock");
  const std::string recording = std::string(PROPCAM_SOURCE_DIR) + "/board/virtual/recordings/living_room";
  const pid_t daemon = fork();
  ASSERT_GE(daemon, 0);
  if (daemon == 0) {
    execl(PROPCAMD, PROPCAMD, "--socket", socket.c_str(), "--camera", ("replay:" + recording).c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  for (int i = 0; i < 200 && !fs::exists(socket); ++i) usleep(50 * 1000);  // at most 10 s
  const std::string shot = temp("daemon_shot.png");
  const CliRun r = propcam("shoot --daemon " + socket + " -o " + shot + " --json");
  kill(daemon, SIGTERM);
  int status = 0;
  waitpid(daemon, &status, 0);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "propcamd stops cleanly on SIGTERM";
  EXPECT_FALSE(fs::exists(socket)) << "propcamd removes its socket";
  const cv::Mat back = propcam::capture::load_photo_linear(shot);
  const cv::Mat photo = propcam::capture::load_photo_linear(std::string(PROPCAM_SOURCE_DIR) + "/board/virtual/photos/living_room.png");
  ASSERT_EQ(back.size(), photo.size());
  EXPECT_LT(mean_abs_difference(propcam::capture::linear_to_srgb8(back), propcam::capture::linear_to_srgb8(photo)), 4.0);
}

TEST(CliCamera, BenchCaptureReportsFpsAndLatency) {
  const CliRun r = propcam("bench capture --frames 20 --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json j = json_tail(r.out);
  EXPECT_GT(j["fps"].get<double>(), 0.0);
  EXPECT_GE(j["latency_ms"].get<double>(), 0.0);
  ASSERT_EQ(j["runs"].size(), 2u);
  for (const auto& run : j["runs"]) EXPECT_EQ(run["frames"], 20);
}

}  // namespace
