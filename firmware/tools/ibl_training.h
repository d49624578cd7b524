// `propcam train-ibl-ranker` and `propcam bench ibl-ranking`: the IBL
// ranking function (ibl_ranking.h) trained on rectilinear views of the IBL
// library's panoramas, with the rendering-based IBL distance as margin, and
// its leave-one-panorama-out evaluation.
#pragma once

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "propcam/inference/ibl_library.h"
#include "propcam/inference/ibl_ranking.h"
#include "propcam/inference/infer.h"
#include "propcam/inference/light_classifier.h"

namespace propcam::firmware {

struct IblTrainingSpec {
  // Built in memory, wide enough that 60-90 degree views at 320 px keep their lines.
  inference::IblLibraryOptions library = [] {
    inference::IblLibraryOptions o;
    o.width = 1024;
    return o;
  }();
  // The paper's sampling: N stratified views per panorama, azimuth all
  // around, elevation within +-30 degrees, field of view 60-90 degrees.
  int views_per_entry = 10;
  double max_abs_pitch_deg = 30, min_fov_deg = 60, max_fov_deg = 90;
  int width = 320, height = 240;
  uint64_t seed = 7;
  int pairs_per_query = 400;
  // The better view of each pair is one of the query's this many nearest
  // candidates (by IBL distance; 0: any candidate): what matters is the top.
  int better_from_nearest = 5;
  inference::SvmRankOptions svm;
  bool quiet = false;
};

// Every library view with its features, the pairwise similarities and the
// view-frame IBL distances between them.
struct IblTrainingSet {
  inference::IblRanker ranker;  // entries and views; weights still ones
  std::vector<std::vector<inference::IblSimilarity>> similarity;  // [query view][candidate view]
  Eigen::MatrixXd distance;                                       // [query view][candidate view]
  double seconds = 0;
};
IblTrainingSet build_ibl_training_set(const IblTrainingSpec& spec);
// The same with other models (a leave-one-out run's): the views' features
// from `options` (e.g. scene_class_left_out) and `classifier`; the library
// entries named in `drop_entries` are left out (the others' views are
// sampled as there, so with no drops and the committed models it is the
// same set).
IblTrainingSet build_ibl_training_set_with(const IblTrainingSpec& spec, const inference::InferenceOptions& options,
                                           const inference::LightClassifier& classifier,
                                           const std::set<std::string>& drop_entries = {});

// Trains on the queries of all entries but `held_out` (-1: none); candidates
// are views of other entries of the query's kind, never of `held_out`.
inference::SvmRankResult train_ibl_weights(const IblTrainingSet& set, int held_out, const IblTrainingSpec& spec);

nlohmann::json evaluate_ibl_ranking(const IblTrainingSet& set, const IblTrainingSpec& spec);
std::string format_ibl_evaluation(const nlohmann::json& result);

struct IblTrainingArgs {
  IblTrainingSpec spec;
  // bench: a grid of training settings on one training set (empty: spec's).
  std::vector<double> C_values;
  std::vector<int> nearest_values;
  std::string output;
  bool json_out = false;
};
void add_train_ibl_ranker_options(CLI::App& command, IblTrainingArgs& args);
int run_train_ibl_ranker_command(const IblTrainingArgs& args);
void add_bench_ibl_ranking_options(CLI::App& command, IblTrainingArgs& args);
int run_bench_ibl_ranking_command(const IblTrainingArgs& args);

// `propcam build-ibl-library`: the annotated panorama library the ranker
// ranks; a row of the command table (cli/command_table.cpp).
struct IblLibraryArgs {
  inference::IblLibraryOptions options;
  std::string output;
};
void add_build_ibl_library_options(CLI::App& cmd, IblLibraryArgs& args);
int run_build_ibl_library_command(const IblLibraryArgs& args);

}  // namespace propcam::firmware
