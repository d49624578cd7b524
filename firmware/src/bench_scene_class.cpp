#include "bench_scene_class.h"

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "propcam/capture/image_file.h"
#include "propcam/inference/scene_class_knn.h"
#include "propcam/inference/sky.h"
#include "propcam/render/panorama.h"
#include "synthetic_truth.h"

namespace propcam::firmware {
namespace {

constexpr const char* kOpenCvExamples = "/usr/share/doc/opencv-doc/examples/data";

struct Tally {
  int correct = 0, total = 0;
  double seconds = 0;
  void add(bool ok, double s) {
    correct += ok;
    ++total;
    seconds += s;
  }
  double accuracy() const { return total ? static_cast<double>(correct) / total : 0; }
  double ms() const { return total ? 1000 * seconds / total : 0; }
};

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

CLI::App* add_bench_scene_class_command(CLI::App& bench, SceneClassBenchArgs& args) {
  auto* cmd = bench.add_subcommand("scene-class", "Indoor/outdoor: k-NN on the appearance descriptor vs the sky rule");
  cmd->add_option("--rooms", args.rooms, "Held-out rooms")->check(CLI::NonNegativeNumber);
  cmd->add_option("--streets", args.streets, "Held-out streets")->check(CLI::NonNegativeNumber);
  cmd->add_option("--first-seed", args.first_seed, "First generator seed (keep clear of the database's 1001..)");
  cmd->add_option("--spp", args.spp, "Samples per pixel")->check(CLI::PositiveNumber);
  cmd->add_option("--k", args.k, "Neighbours")->check(CLI::PositiveNumber);
  return cmd;
}

int run_bench_scene_class_command(const SceneClassBenchArgs& args) {
  const inference::DepthDatabase db = inference::DepthDatabase::load(inference::default_depth_database_path());
  render::RenderSettings settings;
  settings.samples_per_pixel = args.spp;
  Tally knn[2], sky[2];  // [0] synthetic rooms, [1] synthetic streets
  auto evaluate = [&](const cv::Mat& photo, const render::PinholeCamera& camera, bool truth_indoor, Tally& k_tally,
                      Tally& s_tally, const char* name) {
    auto t0 = std::chrono::steady_clock::now();
    const inference::KnnSceneClass k = inference::classify_indoor_knn(photo, db, args.k);
    k_tally.add(k.indoor == truth_indoor, seconds_since(t0));
    inference::StageReport report;
    t0 = std::chrono::steady_clock::now();
    const bool s = inference::classify_indoor(photo, camera, report);
    s_tally.add(s == truth_indoor, seconds_since(t0));
    if (name)
      std::printf("%-14s truth %-7s  knn %-7s (indoor share %.2f)  sky rule %s\n", name,
                  truth_indoor ? "indoor" : "outdoor", k.indoor ? "indoor" : "outdoor", k.indoor_share,
                  s ? "indoor" : "outdoor");
  };
  for (int i = 0; i < args.rooms + args.streets; ++i) {
    const bool street = i >= args.rooms;
    const uint64_t seed = args.first_seed + static_cast<uint64_t>(street ? i - args.rooms : i);
    const SyntheticShot shot =
        street ? shoot_synthetic_street({args.width, args.height, seed, 0.0, 1.5}, settings)
               : shoot_synthetic_room({args.width, args.height, seed, 0.0, 1.5}, settings);
    evaluate(shot.photo_linear, shot.truth.camera(), shot.truth.indoor, knn[street], sky[street], nullptr);
  }
  Tally knn_real, sky_real;
  for (const auto& [file, indoor] : {std::pair{"building.jpg", false}, std::pair{"home.jpg", true}}) {
    const std::string path = std::string(kOpenCvExamples) + "/" + file;
    if (!std::filesystem::exists(path)) continue;
    const cv::Mat photo = capture::load_photo_linear(path);
    render::ViewSpec spec;
    spec.width = photo.cols;
    spec.height = photo.rows;
    evaluate(photo, render::view_camera(spec), indoor, knn_real, sky_real, file);
  }
  std::printf("\n%-22s %12s %12s %12s %10s\n", "classifier", "rooms", "streets", "real photos", "ms/photo");
  auto row = [](const char* name, const Tally* t, const Tally& real) {
    const double ms = (t[0].seconds + t[1].seconds + real.seconds) * 1000 / std::max(1, t[0].total + t[1].total + real.total);
    std::printf("%-22s %5d/%-3d %3.0f%% %5d/%-3d %3.0f%% %7d/%-3d %9.2f\n", name, t[0].correct, t[0].total,
                100 * t[0].accuracy(), t[1].correct, t[1].total, 100 * t[1].accuracy(), real.correct, real.total, ms);
  };
  row("k-NN (appearance)", knn, knn_real);
  row("sky rule (current)", sky, sky_real);
  return 0;
}

}  // namespace propcam::firmware
