// `propcam bench worlds`: the whole inference and the composite measured on
// three worlds — our own generator (rendered by our path tracer), the
// Blender world (made and rendered by Blender Cycles, never by our code) and
// views of real HDR panoramas (the panorama is the true light) — so a change
// is judged on scenes that do not share our assumptions. Per scene: the
// indoor/outdoor call, visible lights found, the camera, depth, albedo, the
// dominant light's direction at the prop, and the composite against the
// true insertion beside two baselines (the untouched photo, the Khan-style
// environment); seconds per stage. docs/bench_worlds.md has the metrics.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "world_bench/panorama_world.h"
#include "propcam/render/photo_imaging.h"
#include "worlds/world_scenes.h"

namespace propcam::firmware {

struct WorldsBenchOptions {
  std::vector<std::string> worlds = {"own", "blender", "panorama"};
  std::string blender_dir = kDefaultBlenderWorldDir;
  std::string split = "tune";  // of the Blender world: tune | held | all
  OwnWorldOptions own;
  PanoramaWorldOptions panorama;
  int spp = 64;                 // composite samples per pixel
  int max_scenes = 0;           // of the Blender world (0: all); our own world has rooms and streets
  std::vector<std::string> sweeps;  // extra rows beside the default (see --sweeps)
  std::string plot_dir;
  bool quiet = false;
};

// Scores one scene of the own or Blender world under `options` as given
// (inference and composite at `spp`; run_worlds_bench leaves a tune scene's
// photo out of the models first); a JSON row (worlds.md lists its keys).
nlohmann::json score_world_scene(const WorldScene& scene, const inference::InferenceOptions& options, int spp);
// The same on an estimate already made (in `inference_seconds`); `camera`
// says which of the photo's camera effects the composite matches (null: none).
nlohmann::json score_world_estimate(const WorldScene& scene, const inference::SceneModel& estimate,
                                    double inference_seconds, int spp,
                                    const std::optional<render::CameraMatchOptions>& camera = render::CameraMatchOptions{});
// Medians, rates and mean seconds over a world's rows.
nlohmann::json summarise_world(const nlohmann::json& scene_rows);

nlohmann::json run_worlds_bench(const WorldsBenchOptions& options);
std::string format_worlds_bench(const nlohmann::json& result);
// worlds.png: per world, composite error and light direction against seconds per scene, one point per row.
void plot_worlds_bench(const nlohmann::json& result, const std::string& dir);

struct WorldsBenchArgs {
  WorldsBenchOptions options;
  std::string worlds = "own,blender,panorama";
  std::string own_size = "320x240";
  std::string sweeps;
  bool json_out = false;
};
void add_bench_worlds_options(CLI::App& command, WorldsBenchArgs& args);
int run_bench_worlds_command(WorldsBenchArgs args);

}  // namespace propcam::firmware
