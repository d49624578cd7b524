#include "scene_reference_builder.h"

#include <cstdio>
#include <stdexcept>

#include "progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/light_classifier.h"
#include "real_views.h"

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
  for (const auto& p : blender_panoramas()) {
    progress.stage("views of " + p.name);
    const cv::Mat latlong = load_panorama_rgb(dir + "/" + p.name + ".exr");
    const int group = set.group(p.name);
    for (auto& d : panorama_view_descriptors(latlong, spec.grid, p.indoor)) set.add({std::move(d), p.indoor, group});
  }
  return set;
}

CLI::App* add_build_scene_refs_command(CLI::App& app, SceneReferenceArgs& args) {
  auto* cmd = app.add_subcommand("build-scene-refs",
                                 "Build the k-NN scene-class references: depth-database renders + real panorama views "
                                 "(scripts/build_scene_refs.sh)");
  cmd->add_option("-o,--output", args.output, "Reference file to write")->required();
  cmd->add_option("--db", args.spec.depth_database, "Depth database whose renders to include (default: the committed one)");
  cmd->add_option("--panorama-dir", args.spec.panorama_dir, "Folder of the blender-data panoramas");
  cmd->add_option("--views-per-turn", args.spec.grid.views_per_turn, "Yaws per outdoor panorama")
      ->check(CLI::PositiveNumber);
  return cmd;
}

int run_build_scene_refs_command(const SceneReferenceArgs& args) {
  const inference::SceneReferenceSet set = build_scene_references(args.spec);
  set.save(args.output);
  std::fprintf(stderr, "wrote %zu references (%zu panoramas) to %s\n", set.size(), set.groups().size(),
               args.output.c_str());
  return 0;
}

}  // namespace propcam::firmware
