// `propcam bench scene-class`: indoor/outdoor accuracy and time of the k-NN
// classifier (scene_class_knn.h) beside the sky-based rule (sky.h
// classify_indoor) and their combination, on held-out generator scenes,
// views of real HDR panoramas (leave-one-panorama-out: a view is never
// classified against views of its own panorama) and OpenCV's real photos.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace propcam::firmware {

struct SceneClassBenchArgs {
  int rooms = 30, streets = 30;
  uint64_t first_seed = 5001;  // disjoint from the depth database (1001..) and tests (1..99)
  int width = 320, height = 240, spp = 16;
  int k = 7;
  std::string refs;  // empty: default_scene_reference_path()
  std::vector<double> sky_fractions = {0.0, 0.05, 0.10, 0.20};  // combined: sky decides from this share up
  bool verbose = false;
  bool unbalanced = false;  // plain majority vote instead of class-balanced votes
};

void add_bench_scene_class_options(CLI::App& command, SceneClassBenchArgs& args);
int run_bench_scene_class_command(const SceneClassBenchArgs& args);

}  // namespace propcam::firmware
