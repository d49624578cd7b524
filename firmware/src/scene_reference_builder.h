// `propcam build-scene-refs`: the k-NN scene classifier's references — the
// depth database's rendered rooms and streets plus rectilinear views cut
// from the CC0 HDR panoramas of Debian's blender-data, exposed as a camera
// would (real_views.h), each labelled by its panorama's class.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "propcam/inference/scene_class_knn.h"

namespace propcam::firmware {

struct LabelledPanorama {
  std::string name;  // blender-data file stem (panorama_path)
  bool indoor = true;
};

// The blender-data panoramas and their classes (the labels of ibl_library.cpp).
const std::vector<LabelledPanorama>& blender_panoramas();

// Where the views of a panorama look. Two of the eight panoramas are indoor,
// so indoor ones are cut `indoor_turn_factor` times as densely in yaw: both
// classes then bring as many real views.
struct RealViewGrid {
  int views_per_turn = 12;
  int indoor_turn_factor = 3;
  std::vector<double> pitches_deg = {-10, 0, 10};
  std::vector<double> fovs_deg = {50, 70};
  int width = 160, height = 120;  // the depth database's photo size
};

// A panorama file as a linear RGB latlong (CV_32FC3). Throws std::runtime_error.
cv::Mat load_panorama_rgb(const std::string& path);

// Descriptors of the grid's views of one panorama (linear HDR latlong).
std::vector<std::vector<float>> panorama_view_descriptors(const cv::Mat& latlong, const RealViewGrid& grid, bool indoor);

struct SceneReferenceSpec {
  std::string depth_database;  // empty: default_depth_database_path()
  std::string panorama_dir;    // empty: kBlenderWorldDir
  RealViewGrid grid;
  bool quiet = false;
};

// Throws std::runtime_error when the depth database or a panorama cannot be read.
inference::SceneReferenceSet build_scene_references(const SceneReferenceSpec& spec);

struct SceneReferenceArgs {
  SceneReferenceSpec spec;
  std::string output;
};
CLI::App* add_build_scene_refs_command(CLI::App& app, SceneReferenceArgs& args);
int run_build_scene_refs_command(const SceneReferenceArgs& args);

}  // namespace propcam::firmware
