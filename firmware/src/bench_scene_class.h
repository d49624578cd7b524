// `propcam bench scene-class`: indoor/outdoor accuracy and time of the k-NN
// classifier (scene_class_knn.h) beside the sky-based rule inference uses
// (sky.h classify_indoor), on held-out generator scenes and real photos.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

namespace propcam::firmware {

struct SceneClassBenchArgs {
  int rooms = 30, streets = 30;
  uint64_t first_seed = 5001;  // disjoint from the depth database (1001..) and tests (1..99)
  int width = 320, height = 240, spp = 16;
  int k = 7;
};

CLI::App* add_bench_scene_class_command(CLI::App& bench, SceneClassBenchArgs& args);
int run_bench_scene_class_command(const SceneClassBenchArgs& args);

}  // namespace propcam::firmware
