// The camera commands, in rpicam style: list the cameras, record raw frames,
// shoot a still, time the capture daemon, and calibrate the lens's
// vignetting from flat-field photos (for board.json).
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

// The recordings `propcam cameras` lists beside the live cameras when no
// --recordings is given: the virtual board's (board/virtual/recordings).
std::string bundled_recordings_dir();

struct CameraChoice {
  std::string camera;     // an id from `propcam cameras`; empty: the first camera found
  std::string format;     // empty: the camera's choice
  std::string size;       // WxH; empty: the camera's choice
  double fps = 0;
  std::vector<std::string> recordings;  // replay folders to look in for the default camera
};

struct CamerasArgs {
  std::vector<std::string> recordings;
  bool json_out = false;
};
void add_cameras_options(CLI::App& command, CamerasArgs& args);
int run_cameras_command(const CamerasArgs& args);

struct RecordArgs {
  CameraChoice choice;
  std::string from_photo;  // a still photo packed as the camera would deliver it, instead of a camera
  int frames = 30;
  double noise = 1.5;      // sensor noise (8-bit levels) of --from-photo frames
  std::string out;
  bool json_out = false;
};
void add_record_options(CLI::App& command, RecordArgs& args);
int run_record_command(const RecordArgs& args);

struct ShootArgs {
  CameraChoice choice;
  std::string daemon_socket;  // through propcamd instead of opening the camera
  std::string still_size;     // WxH of the still; empty: the largest
  int settle_frames = 5;      // viewfinder frames before the shot (auto exposure settles)
  double exposure_us = 0, gain = 0;
  std::string out;
  bool json_out = false;
};
void add_shoot_options(CLI::App& command, ShootArgs& args);
int run_shoot_command(const ShootArgs& args);

// `propcam bench capture`: frames per second and frame-to-client latency
// through propcamd (server and client in this process, a real socket), on
// replayed frames, paced as recorded and as fast as the daemon goes.
struct CaptureBenchArgs {
  std::string recording;  // empty: the first bundled recording
  int frames = 300;
  bool json_out = false;
};
void add_bench_capture_options(CLI::App& command, CaptureBenchArgs& args);
int run_bench_capture_command(const CaptureBenchArgs& args);

// The lens's fall-off from flat-field photos: prints what board.json's
// camera.vignetting and `propcam composite --vignetting` take.
struct CalibrateVignettingArgs {
  std::vector<std::string> frames;  // flat-field photos, the camera's still framing
  bool json_out = false;
};

void add_calibrate_vignetting_options(CLI::App& cmd, CalibrateVignettingArgs& args);
int run_calibrate_vignetting_command(const CalibrateVignettingArgs& args);

}  // namespace propcam::firmware
