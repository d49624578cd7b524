// `propcam infer` and `propcam composite`: a photo's scene model, and a prop
// composited into the photo.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

#include "cli/cli_options.h"
#include "common/job_budget.h"
#include "propcam/inference/infer.h"
#include "propcam/render/vignetting.h"

namespace propcam::firmware {

// The lens: a calibrated focal length in pixels at the photo's size, given on
// the command line, is the camera stage's prior or, fixed, its focal length;
// otherwise the photo's EXIF focal length (if any) is the prior (not fixed:
// the lines may still overrule it). A calibrated vignetting is divided out
// of the photo the scene is inferred from, and given to the prop.
struct LensPrior {
  double focal_px = 0;  // 0: none
  bool fixed = false;
  std::string vignetting;  // "R2[,R4]" (render/vignetting.h); empty: none
  void apply(inference::CameraOptions& o, const std::string& photo_path = {}) const;
  // The parsed vignetting; throws std::invalid_argument naming --vignetting.
  render::Vignetting fall_off() const;
};

struct InferArgs {
  std::string photo, out, lines_csv, size, working_size = "1024x768";
  long memory_mb = firmware::kDefaultMemoryBudgetMb;
  double camera_height = 1.5;
  LensPrior lens;
  bool json_out = false;
};

void add_infer_options(CLI::App& cmd, InferArgs& args);
int run_infer_command(const InferArgs& args);

struct CompositeArgs {
  std::string photo, scene_dir, prop, at, out, material, albedo, save_scene, working_size = "1024x768";
  long memory_mb = firmware::kDefaultMemoryBudgetMb;
  double time_budget = firmware::kDefaultRenderSeconds;
  double height = 0, yaw = 0, camera_height = 1.5;
  LensPrior lens;
  int spp = 16, bounces = kDefaultCliBounces;
  uint64_t seed = 0x5eed;
  bool json_out = false, explain = false, no_cull = false, no_denoise = false, no_camera_match = false;
  double aperture = 0, focus = 0;
  std::string light_scale;  // "I=S,I=S": relight after rendering
  bool relight_scene = false;
};

void add_composite_options(CLI::App& cmd, CompositeArgs& args);
int run_composite_command(const CompositeArgs& args);

}  // namespace propcam::firmware
