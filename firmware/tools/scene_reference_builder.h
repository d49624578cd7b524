// `propcam build-scene-refs`: the k-NN scene classifier's references — the
// depth database's rendered rooms and streets, rectilinear views cut from the
// 26 CC0 HDR panoramas (Debian's blender-data and npm's @pmndrs/assets),
// exposed as a camera would (real_views.h), and optionally the photos of the
// Blender world's tune split; each labelled by its class and grouped by
// where it came from, so that a scored scene can leave its own group out.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "propcam/inference/scene_class_knn.h"

namespace propcam::firmware {

struct LabelledPanorama {
  std::string name;  // the file's stem (blender-data: panorama_path; pmndrs: DIR/NAME.exr)
  bool indoor = true;
};

// The blender-data panoramas and their classes (the labels of ibl_library.cpp).
const std::vector<LabelledPanorama>& blender_panoramas();
// The eighteen of @pmndrs/assets (scripts/fetch_pmndrs_hdri.sh; labels as
// scripts/train_ibl_ranker.sh's).
const std::vector<LabelledPanorama>& pmndrs_panoramas();
// Where scripts/fetch_pmndrs_hdri.sh puts them: build/pmndrs_hdri, relative to
// the working folder (the scripts run from the checkout's top).
std::string default_pmndrs_dir();
// The leave-one-out group of a catalogue name ("city", "pmndrs_city"): its
// own name, except where both sources hold one photograph ("pmndrs_sunrise"
// is blender-data's "sunrise").
std::string panorama_group(const std::string& catalogue_name);
// The reference group of a Blender-world scene ("scene_12" -> "blender/scene_12").
std::string blender_scene_group(const std::string& scene_name);

// Where the views of a panorama look. Indoor panoramas may be cut
// `indoor_turn_factor` times as densely in yaw (with blender-data's eight
// alone, two indoor, 3 balanced the classes; with all 26, 11 indoor, 1 does).
struct RealViewGrid {
  int views_per_turn = 12;
  int indoor_turn_factor = 1;
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
  std::string pmndrs_dir;      // empty: default_pmndrs_dir()
  std::string blender_world;   // empty: none; else its tune split's photos (and their mirror images)
  RealViewGrid grid;
  bool quiet = false;
};

// Throws std::runtime_error when the depth database, a panorama or the Blender world cannot be read.
inference::SceneReferenceSet build_scene_references(const SceneReferenceSpec& spec);

struct SceneReferenceArgs {
  SceneReferenceSpec spec;
  std::string output;
  std::string classifier_output;  // empty: no classifier
};
void add_build_scene_refs_options(CLI::App& command, SceneReferenceArgs& args);
int run_build_scene_refs_command(const SceneReferenceArgs& args);

}  // namespace propcam::firmware
