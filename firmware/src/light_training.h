// `propcam train-light-classifier` and `propcam bench lights`: the visible
// light classifier trained on views of the CC0 HDR panoramas Debian installs
// (blender-data), emitters labelled from radiance; and its leave-one-panorama-
// out evaluation against the threshold detector it replaces.
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
  bool quiet = false;
};

// The 8 panoramas of blender-data.
std::vector<std::string> default_training_panoramas();

inference::LightClassifier train_light_classifier(const LightTrainingSpec& spec);

// Leave one panorama out: per held-out panorama, pixel precision, recall and
// F1 of the classifier (trained on the others) and of the threshold detector,
// with milliseconds per view.
nlohmann::json evaluate_light_classifier(const LightTrainingSpec& spec);
std::string format_light_evaluation(const nlohmann::json& result);

struct LightTrainingArgs {
  LightTrainingSpec spec;
  std::string output;
  bool json_out = false;
};
CLI::App* add_train_light_classifier_command(CLI::App& app, LightTrainingArgs& args);
int run_train_light_classifier_command(const LightTrainingArgs& args);
CLI::App* add_bench_lights_command(CLI::App& bench, LightTrainingArgs& args);
int run_bench_lights_command(LightTrainingArgs args);

}  // namespace propcam::firmware
