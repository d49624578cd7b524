// `propcam bench camera --nyu DIR`: the camera stage on real indoor line data.
// NYU-VP (Kluger et al. 2020, CONSAC; NYU Depth v2) gives LSD segments of real
// 640x480 photos, ground-truth vanishing points and the Kinect intrinsics; the
// bench runs `estimate_camera` on every image and reports focal-length and
// Manhattan-axis errors, the case counts and the time per image, plus a sweep
// of the quality knobs (error against time).
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>

namespace propcam::firmware {

// The Kinect RGB camera of NYU Depth v2 (the dataset's README).
struct TrueIntrinsics {
  double fx = 518.8579, fy = 519.4696, cx = 325.5824, cy = 253.7362;
};

struct CameraBenchOptions {
  std::string nyu_dir;     // lsd_lines_NNNN.csv + vps_NNNN.csv
  int width = 640, height = 480;
  TrueIntrinsics truth;
  int max_images = 0;      // 0: every image in the folder
  double prior_focal_px = 0;  // CameraOptions::prior_focal_px (0: the stage's default prior)
  bool fixed_focal = false;   // CameraOptions::fixed_focal (a calibrated lens: rotation only)
  bool centre_principal_point = false;  // CameraOptions::estimate_principal_point off
  int sweep_images = 300;  // images (evenly spaced) per sweep point; 0: no sweep
  std::string plot_dir;    // empty: no plots
  bool quiet = false;
};

nlohmann::json run_camera_bench(const CameraBenchOptions& options);
std::string format_camera_bench(const nlohmann::json& result);
// PNG plots with gnuplot: for the sweep, the share of focal lengths within 10%
// and the 90th-percentile axis error against seconds per image; and the
// cumulative distribution of the focal error. Throws if gnuplot is missing.
void plot_camera_bench(const nlohmann::json& result, const std::string& dir);

// `propcam bench camera`: its options and its run, a row of the command table
// (cli/command_table.cpp).
struct CameraBenchArgs {
  CameraBenchOptions options;
  std::string size = "640x480";
  std::string intrinsics;  // "FX,FY,CX,CY"; empty: the Kinect's
  bool json_out = false;
};
void add_bench_camera_options(CLI::App& command, CameraBenchArgs& args);
int run_bench_camera_command(CameraBenchArgs args);

}  // namespace propcam::firmware
