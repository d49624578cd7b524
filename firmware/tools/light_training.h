// `propcam train-light-classifier` and `propcam bench lights`: the visible
// light classifier trained on views of CC0 HDR panoramas (emitters labelled
// from radiance) and on the Blender world's tune photos (emitters labelled by
// the renderer); and its held-out evaluation against the threshold detector
// it replaces: one panorama left out at a time, the Blender scenes in folds.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "propcam/inference/light_classifier.h"

namespace propcam::firmware {

struct LightTrainingSpec {
  std::vector<std::string> panoramas;  // names under blender-data's world folder, or EXR file paths
  int views_per_turn = 8;
  std::vector<double> pitches_deg = {0.0, 25.0, 50.0};
  double horizontal_fov_deg = 70.0;
  int width = 320, height = 240;
  int negative_stride = 8;  // keep every n-th non-source superpixel (sources are rare)
  int trees = 60, depth = 12;
  inference::LightClassifierOptions classifier;
  // A Blender world (scripts/make_blender_world.sh) whose tune split's
  // photos join the panoramas' views, labelled by its emitter masks; never
  // its held split. Empty: panoramas only.
  std::string blender_world;
  int blender_folds = 4;  // bench lights and bench worlds hold its scenes out in this many folds
  // Each Blender photo's superpixels join the training set this many times:
  // 44 photos among 26 x 24 panorama views would barely move the forest.
  int blender_copies = 20;
  std::string hold_out = "all";  // bench lights: "all", "panoramas" or "blender"
  bool quiet = false;
};

// Labelled superpixels of one held-out unit: a panorama's views or a
// Blender scene's photo.
struct LightTrainingGroup {
  std::string name;  // the panorama entry, or the Blender scene's folder name
  int fold = -1;     // Blender scenes: blender_light_fold(name, folds); panoramas: -1
  inference::LabelledFeatures features;
};

// A panorama entry's file: an entry with a path or an extension is a file
// (e.g. scripts/fetch_pmndrs_hdri.sh's), anything else one of blender-data's.
std::string panorama_entry_file(const std::string& entry);

// The fold a Blender scene (folder scene_<seed>) is held out in: its seed modulo `folds`.
int blender_light_fold(const std::string& scene_name, int folds);

// The Blender world's tune photos as training groups, in the world's order
// (empty when spec.blender_world is). Throws std::runtime_error when the
// world does not exist.
std::vector<LightTrainingGroup> blender_light_groups(const LightTrainingSpec& spec);

// The training set of the groups in order: every source superpixel and every
// negative_stride-th other one, the count running over the groups.
inference::LabelledFeatures light_training_set(const std::vector<const inference::LabelledFeatures*>& groups,
                                                int negative_stride);

// The forest trained on the panoramas' superpixels, in order, then the
// Blender groups but those of `skip_fold` (spec.blender_copies times over);
// `rows`, if given, gets the training set's size. Every model of the
// classifier (committed, leave-one-out, folds) is trained here.
inference::LightClassifier train_light_classifier_on(const std::vector<const inference::LabelledFeatures*>& panoramas,
                                                     const std::vector<LightTrainingGroup>& blender,
                                                     const LightTrainingSpec& spec, int skip_fold = -1, int* rows = nullptr);

// The 8 panoramas of blender-data.
std::vector<std::string> default_training_panoramas();

inference::LightClassifier train_light_classifier(const LightTrainingSpec& spec);

// Per fold of the spec's Blender scenes, the classifier trained as
// train_light_classifier does but without that fold's scenes, cached in
// `cache_dir` under a key of the spec (bench worlds scores a tune scene with
// the model of its fold). Returns the models' paths, indexed by fold.
std::vector<std::string> blender_fold_light_classifiers(const LightTrainingSpec& spec, const std::string& cache_dir);

// train_light_classifier's model for `spec`, cached in `cache_dir` as
// light_classifiers/<name>.yml.gz under a key of the spec. Returns its path.
std::string cached_light_classifier(const LightTrainingSpec& spec, const std::string& cache_dir, const std::string& name);

// Held out in turn: each panorama (the classifier trained on the others and
// every Blender scene), then each fold of the Blender scenes (trained on the
// panoramas and the other folds). Per held-out unit, pixel precision, recall
// and F1 of the classifier and of the threshold detector, with milliseconds
// per view; on Blender scenes also emitters found and detections right, as
// bench worlds counts them.
nlohmann::json evaluate_light_classifier(const LightTrainingSpec& spec);
std::string format_light_evaluation(const nlohmann::json& result);

struct LightTrainingArgs {
  LightTrainingSpec spec;
  std::string output;
  bool json_out = false;
};
void add_train_light_classifier_options(CLI::App& command, LightTrainingArgs& args);
int run_train_light_classifier_command(const LightTrainingArgs& args);
void add_bench_lights_options(CLI::App& command, LightTrainingArgs& args);
int run_bench_lights_command(LightTrainingArgs args);

}  // namespace propcam::firmware
