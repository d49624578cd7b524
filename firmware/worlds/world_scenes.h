// The scenes `propcam bench worlds` measures on, each with the truth its
// world can give, in one form: our own generator's rooms and streets
// (rendered by our path tracer) and the Blender world (scenes made and
// rendered by Blender Cycles, scripts/make_blender_world.sh,
// docs/blender_world.md). The panorama world has its own form
// (panorama_world.h): its truth is light, not a scene.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "worlds/light_probe.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"
#include "propcam/render/placement.h"

namespace propcam::firmware {

// Where the light a prop receives is measured: this far above its base.
constexpr double kProbeLiftM = 0.05;

struct WorldScene {
  std::string world;   // "own" | "blender"
  std::string name;    // "room 3", "scene_0012"
  std::string split;   // "tune" | "held" (Blender world); "" (own world)
  std::string kind;    // room, corridor, street, courtyard, ...
  // The camera's output, display-encoded in [0, 1] (CV_32FC3: an 8-bit
  // file's values over 255), and what the appliance infers from: the same
  // decoded with the sRGB curve (capture::load_photo_linear).
  cv::Mat photo_display, photo_linear;
  // The truth: camera, depth (metres along z, sky >= kSkyDepthM), albedo,
  // normals, lights, indoor/outdoor. Maps may be empty where a world has none.
  inference::SceneModel truth;
  render::PinholeCamera true_camera;  // truth.camera() with the true height
  cv::Mat emitters;                   // CV_8U: where the camera sees a light (empty: unknown)
  // The true insertion: the prop, where it stands, and the photo with the
  // prop truly in the scene (display-encoded, as photo_display).
  std::string prop;
  render::PropPlacement placement;
  cv::Mat insertion_display;
  cv::Mat prop_mask;  // CV_8U: where the camera sees the prop (empty: unknown)
  // The light at the prop's base (kProbeLiftM above it), in the truth's world.
  std::optional<LightMoments> true_light;
  // Scene-referred linear radiance times this is the photo's linear value
  // before the camera's tone curve (1 for our own world).
  double exposure = 1;
  // The truth's own render noise: the photo's RMSE in 8-bit levels against a
  // render at 4x the samples, as the Blender world predicts it from pilot
  // renders (NaN: unknown; our own world's differences cancel by shared
  // random streams outside the prop's paths).
  double render_noise_8bit = std::nan("");
};

// `propcam synth`-style scenes: rooms seeds 1..rooms, streets 1..streets,
// rendered at `spp` with the prop `prop` (natural height unless
// height_m > 0) at the generator's free floor point and turned by yaw_deg;
// photo and insertion share their random streams, so pixels the prop does
// not touch are identical. Quantised to 8 bits like a camera's file.
struct OwnWorldOptions {
  int rooms = 4, streets = 4;
  int width = 320, height = 240;
  int spp = 64;
  std::string prop = "cube";
  double height_m = 0;
  double yaw_deg = 30;
  int probe_face_px = 24, probe_spp = 16;
};
std::vector<WorldScene> make_own_world(const OwnWorldOptions& options);

// Where scripts/make_blender_world.sh writes the Blender world by default.
inline constexpr const char* kDefaultBlenderWorldDir = "build/worlds/blender";

// Reads the Blender world's scene folders under `dir` (world.json lists
// them) of `split` ("tune", "held" or "" for both). Throws
// std::runtime_error naming the folder and the file for a missing or bad
// file, and when the world does not exist (saying how to make it).
std::vector<WorldScene> load_blender_world(const std::string& dir, const std::string& split);

// One Blender scene folder (`name` is its folder name).
WorldScene load_blender_scene(const std::string& folder);

}  // namespace propcam::firmware
