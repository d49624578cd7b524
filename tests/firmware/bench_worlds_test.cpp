// The instrument of `propcam bench worlds`: our own world's scenes carry a
// usable truth, and scoring rewards the right scene (the truth scored as an
// estimate beats the untouched photo and gets the light's direction).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "world_bench/bench_worlds.h"
#include "propcam/capture/image_file.h"
#include "worlds/world_scenes.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

OwnWorldOptions tiny_own_world() {
  OwnWorldOptions o;
  o.rooms = 1;
  o.streets = 0;
  o.width = 128;
  o.height = 96;
  o.spp = 16;
  return o;
}

TEST(BenchWorlds, OurOwnWorldsSceneCarriesItsTruth) {
  const std::vector<WorldScene> scenes = make_own_world(tiny_own_world());
  ASSERT_EQ(scenes.size(), 1u);
  const WorldScene& w = scenes[0];
  EXPECT_EQ(w.world, "own");
  ASSERT_EQ(w.photo_display.size(), cv::Size(128, 96));
  EXPECT_EQ(w.insertion_display.size(), w.photo_display.size());
  EXPECT_GT(cv::countNonZero(w.prop_mask), 20) << "the prop is seen";
  // Photo and insertion share their random streams: a pixel whose paths
  // never meet the prop comes out identical, and most of them do.
  cv::Mat diff;
  cv::absdiff(w.photo_display, w.insertion_display, diff);
  cv::Mat grey;
  cv::transform(diff, grey, cv::Matx13f(1.f, 1.f, 1.f));
  const double identical = static_cast<double>(cv::countNonZero(grey == 0)) / grey.total();
  EXPECT_GT(identical, 0.5);
  ASSERT_TRUE(w.true_light);
  EXPECT_TRUE(w.true_light->vector.allFinite());
  EXPECT_GT(w.true_light->irradiance_up, 0.0);
  EXPECT_TRUE(w.truth.indoor);
}

TEST(BenchWorlds, TheTruthScoredAsAnEstimateBeatsThePhoto) {
  const WorldScene w = make_own_world(tiny_own_world()).at(0);
  inference::SceneModel truth = w.truth;
  const json row = score_world_estimate(w, truth, 0.0, 16);
  ASSERT_TRUE(row.value("placed", false)) << row.dump(2);
  EXPECT_GT(row["region_pixels"].get<int>(), 20);
  EXPECT_LT(row["composite"]["rmse"].get<double>(), 0.7 * row["photo"]["rmse"].get<double>()) << row.dump(2);
  EXPECT_GT(row["composite"]["ssim"].get<double>(), row["photo"]["ssim"].get<double>());
  EXPECT_LT(row["direction_deg"].get<double>(), 15.0) << "the same scene's light, measured twice";
  EXPECT_NEAR(row["camera"]["focal_rel"].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(row["depth"]["abs_rel"].get<double>(), 0.0, 1e-6);
  EXPECT_NEAR(row["albedo_lmse"].get<double>(), 0.0, 1e-9);
  EXPECT_TRUE(row["indoor_right"].get<bool>());
  EXPECT_LT(row["changed_outside_share"].get<double>(), 0.01);
}

TEST(BenchWorlds, SummariesCountRatesAndMedians) {
  const json rows = json::array(
      {{{"indoor_right", true}, {"indoor_true", true}, {"emitters", {{"truth", 2}, {"found", 1}, {"detected", 2}, {"right", 2}}},
        {"direction_deg", 10.0}, {"region_pixels", 5}, {"placed", true},
        {"composite", {{"rmse", 0.1}, {"ssim", 0.9}}}, {"photo", {{"rmse", 0.2}, {"ssim", 0.8}}},
        {"khan", {{"rmse", 0.3}, {"ssim", 0.7}}}, {"seconds", {{"inference", 2.0}}}},
       {{"indoor_right", false}, {"indoor_true", false}, {"emitters", {{"truth", 0}, {"found", 0}, {"detected", 1}, {"right", 0}}},
        {"direction_deg", nullptr}, {"region_pixels", 5}, {"placed", false},
        {"composite", {{"rmse", 0.3}, {"ssim", 0.5}}}, {"photo", {{"rmse", 0.2}, {"ssim", 0.8}}},
        {"khan", {{"rmse", 0.3}, {"ssim", 0.7}}}, {"seconds", {{"inference", 4.0}}}}});
  const json s = summarise_world(rows);
  EXPECT_DOUBLE_EQ(s["indoor_accuracy"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(s["emitters"]["recall"].get<double>(), 0.5);
  EXPECT_NEAR(s["emitters"]["precision"].get<double>(), 2.0 / 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(s["direction_deg_median"].get<double>(), 10.0) << "a missing direction is left out";
  EXPECT_DOUBLE_EQ(s["composite_beats_photo_share"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(s["placed_share"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(s["seconds_mean"]["inference"].get<double>(), 3.0);
}

class BlenderWorldFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("propcam_blender_world_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string error_of(const std::function<void()>& f) {
    try {
      f();
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "(no error)";
  }
  fs::path dir_;
};

TEST_F(BlenderWorldFiles, AMissingWorldSaysHowToMakeOne) {
  const std::string e = error_of([&] { load_blender_world((dir_ / "nothing").string(), "tune"); });
  EXPECT_NE(e.find("make_blender_world.sh"), std::string::npos) << e;
}

TEST_F(BlenderWorldFiles, ASceneNameLeavingTheWorldIsRefused) {
  std::ofstream(dir_ / "world.json") << R"({"scenes": [{"name": "../etc", "split": "tune"}]})";
  EXPECT_NE(error_of([&] { load_blender_world(dir_.string(), "tune"); }).find("bad name"), std::string::npos);
}

TEST_F(BlenderWorldFiles, AnIncompleteSceneNamesTheMissingFile) {
  std::ofstream(dir_ / "world.json") << R"({"scenes": [{"name": "scene_1", "split": "tune"}]})";
  fs::create_directories(dir_ / "scene_1");
  std::ofstream(dir_ / "scene_1" / "meta.json") << R"({"split": "tune", "kind": "room"})";
  const std::string e = error_of([&] { load_blender_world(dir_.string(), "tune"); });
  EXPECT_NE(e.find("photo.png"), std::string::npos) << e;
  EXPECT_TRUE(load_blender_world(dir_.string(), "held").empty()) << "the other split has no scene";
}

}  // namespace
}  // namespace propcam::firmware
