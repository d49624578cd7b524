// The inferred 3D model of a photographed scene, and its folder format:
// scene.json + depth.exr + albedo.exr + normals.exr + lights/*.exr.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/room_enclosure.h"
#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/photo_imaging.h"

namespace propcam::inference {

// What every stage returns, so the CLI, UI and bench can show cost and quality.
struct StageReport {
  std::string stage;
  bool usable = true;
  std::string why;         // the case that applied, or why it is unusable
  int iterations = 0;
  double seconds = 0.0;
  double error = -1.0;     // the stage's own error estimate; < 0 when it has none
  nlohmann::json details = nlohmann::json::object();
};

// A point light's bulb radius when the scene does not give one.
constexpr double kDefaultPointLightRadiusM = 0.05;
// Bounds on a point light's radius in a scene file: a bulb, not a room.
constexpr double kMinPointLightRadiusM = 1e-4, kMaxPointLightRadiusM = 2.0;

struct LightSource {
  enum class Type { Area, Point, Sun, Ibl };
  Type type = Type::Area;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();   // area/point: centre (world)
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();  // sun: toward the light
  // Linear RGB: radiance for area, point (a sphere of `radius`) and IBL
  // lights (a scale of the map); for a sun, the irradiance it gives a
  // surface facing it.
  Eigen::Vector3d intensity = Eigen::Vector3d::Ones();
  double radius = kDefaultPointLightRadiusM;  // point: the bulb's radius (m)
  // Area: the quad (world), emitting on the side of edge_u x edge_v.
  Eigen::Vector3d corner = Eigen::Vector3d::Zero(), edge_u = Eigen::Vector3d::Zero(),
                  edge_v = Eigen::Vector3d::Zero();
  cv::Mat environment;  // Ibl: equirectangular CV_32FC3, unit scale
  std::string file;     // Ibl: file name inside the scene folder
  // Sun, Ibl: light from outside a room, which reaches it only through the
  // scene's windows (SceneModel::windows).
  bool through_windows = false;
};

// An opening in a room's walls, which the scene does not hold as geometry:
// the parallelogram corner + s*edge_u + t*edge_v (world), s,t in [0,1].
struct Window {
  Eigen::Vector3d corner = Eigen::Vector3d::Zero(), edge_u = Eigen::Vector3d::Zero(),
                  edge_v = Eigen::Vector3d::Zero();
};
// At most this many windows in a scene file.
constexpr size_t kMaxWindows = 64;

const char* to_string(LightSource::Type type);

// Area lights at least this far away stand for distant light (the lighting
// places suns and sky patches as quads 1 km out; room lights lie within
// metres): they give a direction, not a place.
constexpr double kDistantLightM = 100.0;

// The unit direction from `from` toward a distant light: a sun's, or a far
// area light's centre. None for the lights in the scene (and for a sun with
// no direction).
std::optional<Eigen::Vector3d> distant_light_direction(const LightSource& light, const Eigen::Vector3d& from);

// The irradiance a distant light gives a surface at `from` facing it (linear
// RGB): a sun's intensity, or a far area light's radiance times the solid
// angle it subtends. None for the lights distant_light_direction refuses.
std::optional<Eigen::Vector3d> distant_light_irradiance(const LightSource& light, const Eigen::Vector3d& from);

struct SupportPlane {
  std::string name;       // floor, wall_front, table_1, ...
  Eigen::Vector3d normal;  // world, unit, facing the camera
  double offset = 0.0;     // plane: normal . x + offset = 0
  // Where the plane was seen (world, axis-aligned box of its pixels' points);
  // unbounded planes (the layout's walls, hypotheses) have pixels == 0.
  Eigen::Vector3d extent_min = Eigen::Vector3d::Zero(), extent_max = Eigen::Vector3d::Zero();
  int pixels = 0;
};

struct SceneModel {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Eigen::Matrix3d R_world_from_cam = Eigen::Matrix3d::Identity();
  double camera_height_m = 1.5;
  double gamma = 2.2;         // camera response exponent the photo was linearised with
  bool indoor = true;
  cv::Mat depth;    // CV_32F metres along camera z
  cv::Mat albedo;   // CV_32FC3 linear RGB
  cv::Mat normals;  // CV_32FC3 world unit normals
  // CV_8U, 255 on the pixels the lighting took for visible light sources
  // (in memory only: benches score it; the folder does not keep it).
  cv::Mat light_source_mask;
  std::vector<LightSource> lights;
  // Where the lights marked `through_windows` enter (render::Portal).
  std::vector<Window> windows;
  std::vector<SupportPlane> planes;
  // Outdoors: the seen facades continued out of the frame, occluders for the
  // lights (hidden_facades.h); the compositor adds them as the lighting did.
  std::vector<HiddenFacade> hidden_facades;
  // Indoors: the room closed around what the photo shows (room_enclosure.h);
  // the compositor adds it as the lighting did. Empty: open.
  RoomEnclosure enclosure;
  // What the photo's camera did beyond light (blur, noise), for the
  // composite to do the same to the prop (render/photo_imaging.h).
  render::PhotoImaging imaging;
  std::vector<StageReport> reports;
  std::string source_photo;

  render::PinholeCamera camera() const;
  render::LightRig light_rig() const;
  // Throws std::runtime_error when a number is non-finite or a size disagrees.
  void validate() const;
};

// The renderer's view of a list of lights: area quads, then at most one
// environment, the windows as the rig's portals. With `unit_intensity`
// every light gets intensity 1 (basis renders).
render::LightRig make_light_rig(const std::vector<LightSource>& lights, bool unit_intensity = false,
                                const std::vector<Window>& windows = {});

void save_scene(const SceneModel& scene, const std::string& folder);
SceneModel load_scene(const std::string& folder);

nlohmann::json to_json(const StageReport& report);

}  // namespace propcam::inference
