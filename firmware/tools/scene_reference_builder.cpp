#include "tools/scene_reference_builder.h"

#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "common/progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/inference/scene_classifier.h"
#include "worlds/real_views.h"
#include "worlds/world_scenes.h"

namespace propcam::firmware {

cv::Mat load_panorama_rgb(const std::string& path) {
  std::vector<cv::Mat> ch;
  cv::split(capture::read_image_float(path), ch);
  // The EXRs may carry alpha; views are cut from RGB.
  if (ch.size() < 3) throw std::runtime_error("panorama '" + path + "' has fewer than three channels");
  cv::Mat rgb;
  cv::merge(std::vector<cv::Mat>{ch[0], ch[1], ch[2]}, rgb);
  return rgb;
}

const std::vector<LabelledPanorama>& blender_panoramas() {
  static const std::vector<LabelledPanorama> list = {
      {"city", false},     {"courtyard", false}, {"forest", false}, {"interior", true},
      {"night", false},    {"studio", true},     {"sunrise", false}, {"sunset", false}};
  return list;
}

const std::vector<LabelledPanorama>& pmndrs_panoramas() {
  static const std::vector<LabelledPanorama> list = {
      {"apartment", true}, {"bridge", true},   {"esplanade", true}, {"hall", true},    {"lab", true},
      {"lobby", true},     {"studio", true},   {"warehouse", true}, {"workshop", true}, {"city", false},
      {"dawn", false},     {"forest", false},  {"night", false},    {"park", false},   {"sky", false},
      {"sunrise", false},  {"sunset", false},  {"venice", false}};
  return list;
}

// scripts/fetch_pmndrs_hdri.sh's folder, run from the checkout's top.
std::string default_pmndrs_dir() { return "build/pmndrs_hdri"; }

// pmndrs' "sunrise" is blender-data's "sunrise" (another file and resolution,
// same scene and yaw): correlating high-passed log luminance over all yaw
// shifts at 128x64 gives this pair 0.91, every other pair of the 26 at most 0.55.
std::string panorama_group(const std::string& catalogue_name) {
  return catalogue_name == "pmndrs_sunrise" ? "sunrise" : catalogue_name;
}

std::string blender_scene_group(const std::string& scene_name) { return "blender/" + scene_name; }

std::vector<std::vector<float>> panorama_view_descriptors(const cv::Mat& latlong, const RealViewGrid& grid, bool indoor) {
  const int per_turn = grid.views_per_turn * (indoor ? grid.indoor_turn_factor : 1);
  std::vector<std::vector<float>> out;
  for (double fov : grid.fovs_deg)
    // panorama_views exposes and quantises each view as real_views.h does.
    for (const auto& view : inference::panorama_views(latlong, per_turn, grid.pitches_deg, fov, grid.width, grid.height))
      out.push_back(inference::appearance_descriptor(view.photo_linear));
  return out;
}

inference::SceneReferenceSet build_scene_references(const SceneReferenceSpec& spec) {
  Progress progress(spec.quiet);
  progress.stage("rendered references");
  const std::string db_path = spec.depth_database.empty() ? inference::default_depth_database_path() : spec.depth_database;
  inference::SceneReferenceSet set = inference::rendered_references(inference::DepthDatabase::load(db_path));
  const std::string dir = spec.panorama_dir.empty() ? std::string(kBlenderWorldDir) : spec.panorama_dir;
  const auto add_views = [&](const std::string& file, const std::string& group_name, bool indoor) {
    progress.stage("views of " + group_name);
    const cv::Mat latlong = load_panorama_rgb(file);
    const int group = set.group(group_name);
    for (auto& d : panorama_view_descriptors(latlong, spec.grid, indoor)) set.add({std::move(d), indoor, group});
  };
  for (const auto& p : blender_panoramas()) add_views(dir + "/" + p.name + ".exr", panorama_group(p.name), p.indoor);
  const std::string pmndrs = spec.pmndrs_dir.empty() ? default_pmndrs_dir() : spec.pmndrs_dir;
  for (const auto& p : pmndrs_panoramas()) {
    const std::string file = pmndrs + "/" + p.name + ".exr";
    if (!std::filesystem::exists(file))
      throw std::runtime_error("no panorama '" + file + "' (scripts/fetch_pmndrs_hdri.sh fetches them)");
    add_views(file, panorama_group("pmndrs_" + p.name), p.indoor);
  }
  if (!spec.blender_world.empty()) {
    progress.stage("photos of the Blender world's tune split");
    // Never the held split: it is the one reported, never learnt from.
    for (const WorldScene& w : load_blender_world(spec.blender_world, "tune")) {
      const int group = set.group(blender_scene_group(w.name));
      cv::Mat mirrored;
      cv::flip(w.photo_linear, mirrored, 1);
      set.add({inference::appearance_descriptor(w.photo_linear), w.truth.indoor, group});
      set.add({inference::appearance_descriptor(mirrored), w.truth.indoor, group});
    }
  }
  return set;
}

void add_build_scene_refs_options(CLI::App& cmd, SceneReferenceArgs& args) {
  cmd.add_option("-o,--output", args.output, "Reference file to write")->required();
  cmd.add_option("--db", args.spec.depth_database, "Depth database whose renders to include (default: the committed one)");
  cmd.add_option("--panorama-dir", args.spec.panorama_dir, "Folder of the blender-data panoramas");
  cmd.add_option("--pmndrs-dir", args.spec.pmndrs_dir,
                  "Folder of the @pmndrs/assets panoramas (default: build/pmndrs_hdri, scripts/fetch_pmndrs_hdri.sh)");
  cmd.add_option("--blender-world", args.spec.blender_world,
                  "A Blender world (scripts/make_blender_world.sh) whose tune split's photos to add");
  cmd.add_option("--views-per-turn", args.spec.grid.views_per_turn, "Yaws per outdoor panorama")
      ->check(CLI::PositiveNumber);
  cmd.add_option("--classifier", args.classifier_output, "Also train the scene classifier (SVM) on them and write it here");
}

int run_build_scene_refs_command(const SceneReferenceArgs& args) {
  const inference::SceneReferenceSet set = build_scene_references(args.spec);
  set.save(args.output);
  std::fprintf(stderr, "wrote %zu references (%zu panoramas) to %s\n", set.size(), set.groups().size(),
               args.output.c_str());
  if (!args.classifier_output.empty()) {
    inference::SceneClassifier::train(set).save(args.classifier_output);
    std::fprintf(stderr, "wrote the scene classifier to %s\n", args.classifier_output.c_str());
  }
  return 0;
}

}  // namespace propcam::firmware
