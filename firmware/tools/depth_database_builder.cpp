#include "tools/depth_database_builder.h"

#include <opencv2/imgproc.hpp>

#include <cstdio>

#include "common/progress.h"
#include "propcam/render/depth_mesh.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {

inference::DepthDatabase build_depth_database(const DepthDatabaseSpec& spec) {
  Progress progress(spec.quiet);
  inference::DepthDatabase db;
  render::RenderSettings settings;
  settings.samples_per_pixel = spec.spp;
  const int total = spec.rooms + spec.streets;
  for (int i = 0; i < total; ++i) {
    const bool street = i >= spec.rooms;
    const uint64_t seed = spec.first_seed + static_cast<uint64_t>(street ? i - spec.rooms : i);
    if (i % 20 == 0) progress.stage("scene " + std::to_string(i + 1) + " of " + std::to_string(total));
    const SyntheticShot shot =
        street ? shoot_synthetic_street({spec.photo_width, spec.photo_height, seed, 0.0, 1.5}, settings)
               : shoot_synthetic_room({spec.photo_width, spec.photo_height, seed, 0.0, 1.5}, settings);
    inference::DepthExample e;
    e.descriptor = inference::appearance_descriptor(shot.photo_linear);
    // Resampled by area in inverse depth (affine over planes); nothing hit is sky.
    cv::Mat inv(shot.truth.depth.size(), CV_32F);
    for (int y = 0; y < inv.rows; ++y)
      for (int x = 0; x < inv.cols; ++x) {
        const float d = shot.truth.depth.at<float>(y, x);
        inv.at<float>(y, x) = d > 0 && d < render::kSkyDepthM ? 1.f / d : static_cast<float>(1.0 / render::kSkyDepthM);
      }
    cv::resize(inv, inv, cv::Size(spec.depth_width, spec.depth_height), 0, 0, cv::INTER_AREA);
    cv::divide(1.0 / shot.truth.camera_height_m, inv, e.depth);
    e.fx_over_width = shot.truth.fx / shot.truth.width;
    e.horizon = inference::horizon_frame(shot.truth.R_world_from_cam);
    e.indoor = shot.truth.indoor;
    db.add(std::move(e));
  }
  return db;
}

void add_build_depth_db_options(CLI::App& cmd, DepthDatabaseArgs& a) {
  cmd.add_option("-o,--output", a.output, "Database file to write")->required();
  cmd.add_option("--rooms", a.spec.rooms, "Rooms")->check(CLI::NonNegativeNumber);
  cmd.add_option("--streets", a.spec.streets, "Streets")->check(CLI::NonNegativeNumber);
  cmd.add_option("--first-seed", a.spec.first_seed, "First generator seed");
  cmd.add_option("--spp", a.spec.spp, "Samples per pixel of the photos")->check(CLI::PositiveNumber);
}

int run_build_depth_db_command(const DepthDatabaseArgs& a) {
  const inference::DepthDatabase db = build_depth_database(a.spec);
  db.save(a.output);
  std::fprintf(stderr, "wrote %zu examples to %s\n", db.size(), a.output.c_str());
  return 0;
}

}  // namespace propcam::firmware
