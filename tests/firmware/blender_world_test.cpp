// The Blender world for real: Debian's blender renders a scene with our
// generator script, the bench reads it, and Cycles and our renderer agree on
// the light units. Skipped (saying why) where blender is not installed;
// scripts/setup.sh installs it, so CI runs these.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "world_bench/bench_worlds.h"
#include "cli_run.h"
#include "tools/light_training.h"
#include "propcam/inference/scene_model.h"
#include "worlds/world_scenes.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using propcam::test::run_shell;

bool have_blender() { return run_shell("command -v blender >/dev/null 2>&1").exit_code == 0; }

std::string source(const std::string& path) { return std::string(PROPCAM_SOURCE_DIR) + "/" + path; }

// scripts/make_blender_world.sh --out DIR ARGS, with this build's propcam; stderr joins stdout.
propcam::test::CliRun make_blender_world(const fs::path& dir, const std::string& args) {
  return run_shell("PROPCAM=" + std::string(PROPCAM_CLI) + " bash " + source("scripts/make_blender_world.sh") + " --out " +
                   dir.string() + " " + args + " 2>&1");
}

fs::path scratch(const std::string& name) {
  const fs::path p = fs::path(PROPCAM_BINARY_DIR) / "test_blender_world" / name;
  fs::remove_all(p);
  fs::create_directories(p.parent_path());
  return p;
}

// --held-only renders the held split's seeds alone: seeds 1 and 2 are both
// tune, so nothing is rendered and the index lists no scene.
TEST(BlenderWorld, HeldOnlySkipsTheTuneSplitsSeeds) {
  if (!have_blender()) GTEST_SKIP() << "blender is not installed (scripts/setup.sh installs it)";
  const fs::path dir = scratch("held_only");
  const auto made = make_blender_world(dir, "--count 2 --seed 1 --held-only");
  ASSERT_EQ(made.exit_code, 0) << made.out;
  EXPECT_NE(made.out.find("0 of 0 scenes complete"), std::string::npos) << made.out;
  EXPECT_FALSE(fs::exists(dir / "scene_1"));
  EXPECT_FALSE(fs::exists(dir / "scene_2"));
  EXPECT_TRUE(fs::exists(dir / "world.json"));
}

// --indoor-plan gives an indoor seed that light plan and skips outdoor
// seeds; a sun through a window reaches the truth as a sun through its window.
TEST(BlenderWorld, AnIndoorPlanIsForcedAndItsWindowsReachTheTruth) {
  if (!have_blender()) GTEST_SKIP() << "blender is not installed (scripts/setup.sh installs it)";
  const fs::path dir = scratch("indoor_plan");
  // Seed 3 is outdoors (skipped), seed 4 indoors.
  const auto made = make_blender_world(dir, "--count 2 --seed 3 --size 64x48 --spp 8 --max-spp 8 --probe-spp 8 "
                                            "--noise-check 0 --threads 2 --indoor-plan window_sun");
  ASSERT_EQ(made.exit_code, 0) << made.out;
  EXPECT_FALSE(fs::exists(dir / "scene_3"));
  std::ifstream meta_file(dir / "scene_4" / "meta.json");
  const json meta = json::parse(meta_file);
  EXPECT_EQ(meta["choices"]["plan"], "window_sun");
  const inference::SceneModel truth = inference::load_scene((dir / "scene_4" / "truth").string());
  ASSERT_FALSE(truth.windows.empty());
  EXPECT_EQ(truth.windows.size(), meta["portals"].size());
  int through = 0;
  for (const auto& light : truth.lights) {
    if (light.type == inference::LightSource::Type::Sun) EXPECT_TRUE(light.through_windows);
    through += light.through_windows;
  }
  EXPECT_GE(through, 1);
  const auto wrong = make_blender_world(scratch("no_such_plan"), "--count 1 --seed 4 --size 64x48 --indoor-plan sunny");
  EXPECT_NE(wrong.exit_code, 0);
}

// Small scenes, made and rendered by Blender alone, read and scored by the
// bench; the tune one (never the held one) joins the light classifier's training.
TEST(BlenderWorld, AGeneratedSceneLoadsWithItsTruthAndIsScored) {
  if (!have_blender()) GTEST_SKIP() << "blender is not installed (scripts/setup.sh installs it)";
  const fs::path dir = scratch("world");
  // Seed 2: an indoor scene of the tune split, with a table lamp; seed 3: one of the held split.
  const auto made = make_blender_world(
      dir, "--count 2 --seed 2 --size 96x72 --spp 16 --max-spp 16 --probe-spp 16 --noise-check 0 --threads 2");
  ASSERT_EQ(made.exit_code, 0) << made.out;
  const std::vector<WorldScene> scenes = load_blender_world(dir.string(), "tune");
  ASSERT_EQ(scenes.size(), 1u);
  ASSERT_EQ(load_blender_world(dir.string(), "held").size(), 1u);
  const WorldScene& w = scenes[0];

  // The light classifier learns from the tune photo with its true emitters, never from the held one.
  LightTrainingSpec spec;
  spec.blender_world = dir.string();
  spec.classifier.superpixel_px = 4;  // the lamp's shade is 9x6 pixels at 96x72
  spec.quiet = true;
  const std::vector<LightTrainingGroup> groups = blender_light_groups(spec);
  ASSERT_EQ(groups.size(), 1u);
  EXPECT_EQ(groups[0].name, "scene_2");
  EXPECT_EQ(groups[0].fold, 2 % spec.blender_folds);
  EXPECT_GT(cv::countNonZero(w.emitters), 0) << "the lamp's shade is seen";
  EXPECT_GT(cv::countNonZero(groups[0].features.labels), 0) << "its superpixels are labelled sources";
  EXPECT_EQ(w.world, "blender");
  EXPECT_EQ(w.split, "tune");
  EXPECT_EQ(w.photo_display.size(), cv::Size(96, 72));
  EXPECT_EQ(w.truth.depth.size(), w.photo_display.size());
  EXPECT_FALSE(w.truth.lights.empty()) << "every light that lights the scene is listed";
  // The truth folder's lights are in Blender's units; the scene model's in
  // the photo's, which the exposure scaled.
  const inference::SceneModel in_blender_units = inference::load_scene((dir / "scene_2" / "truth").string());
  ASSERT_EQ(in_blender_units.lights.size(), w.truth.lights.size());
  EXPECT_GT(w.exposure, 0.0);
  EXPECT_TRUE(w.truth.lights[0].intensity.isApprox(in_blender_units.lights[0].intensity * w.exposure, 1e-9));
  EXPECT_GT(cv::countNonZero(w.prop_mask), 0) << "the prop is seen";
  ASSERT_TRUE(w.true_light);
  EXPECT_TRUE(w.true_light->vector.allFinite());
  EXPECT_GT(w.true_light->total, 0.0);
  // The truth's camera sees the prop's base where placement.json says.
  Eigen::Vector2d at(w.placement.pixel_u, w.placement.pixel_v);
  EXPECT_GE(at.x(), 0);
  EXPECT_LT(at.x(), 96);

  const json row = score_world_estimate(w, w.truth, 0.0, 8);
  EXPECT_TRUE(row["indoor_right"].get<bool>());
  EXPECT_NEAR(row["depth"]["abs_rel"].get<double>(), 0.0, 1e-6);
  ASSERT_TRUE(row["photo"]["rmse"].is_number());
  EXPECT_GT(row["photo"]["rmse"].get<double>(), 0.0) << "the insertion differs from the photo";
  EXPECT_TRUE(row["composite"]["rmse"].is_number());
}

// The conversion from Blender's light units to ours, proved by rendering the
// same scene with Cycles and with `propcam render` (docs/blender_world.md).
TEST(BlenderWorld, CyclesAndOurRendererAgreeOnEveryLightType) {
  if (!have_blender()) GTEST_SKIP() << "blender is not installed (scripts/setup.sh installs it)";
  const fs::path dir = scratch("units");
  const auto r = run_shell("PROPCAM=" + std::string(PROPCAM_CLI) + " bash " + source("scripts/blender_units_check.sh") +
                           " --out " + dir.string() + " --size 64x48 --spp 128 --threads 2 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  for (const char* light : {"area", "point", "sun", "environment"})
    EXPECT_NE(r.out.find(light), std::string::npos) << light << " was checked\n" << r.out;
}

}  // namespace
}  // namespace propcam::firmware
