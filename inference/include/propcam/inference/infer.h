// Single-photo scene inference: camera, geometry, albedo, lights.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "propcam/inference/camera.h"
#include "propcam/inference/depth_solve.h"
#include "propcam/inference/depth_transfer.h"
#include "propcam/inference/layout.h"
#include "propcam/inference/orientation_map.h"
#include "propcam/inference/lighting.h"
#include "propcam/inference/scene_class_knn.h"
#include "propcam/inference/scene_model.h"
#include "propcam/inference/sky.h"
#include "propcam/inference/support_planes.h"

namespace propcam::inference {

// Dense depth: the paper's energy over data targets (the Manhattan box
// layout, depth transferred from the project's database) and geometric
// priors (Manhattan, orientation map, 3D smoothness).
struct GeometryOptions {
  bool solve = true;              // false: the box layout alone (the first cut)
  bool class_weights = true;      // priors' weights by scene class (DepthPriorWeights::indoor/outdoor)
  double box_weight = 1.0;        // data-term weight of the box layout's depth
  double contact_weight = 2.0;    // data-term weight of the floor-contact depth (contact_depth.h); 0: off
  double transfer_weight = 1.0;   // data-term weight of the depth-transfer median (depth_transfer.h); 0: off
  DepthTransferOptions transfer;
  std::string depth_database;     // empty: default_depth_database_path()
  DepthSolveOptions solver;
  OrientationMapOptions orientation;  // E_o's labels and the floor contacts
  SupportPlaneOptions support;
};

struct InferenceOptions {
  double camera_height_m = 1.5;  // the board's mount height; the paper's scale prior
  LineDetectionOptions lines;
  CameraOptions camera;
  LayoutOptions layout;
  // Indoor/outdoor: the k-NN references (empty: default_scene_reference_path())
  // and the name of a panorama whose references are skipped (benches that
  // score a view of it leave it out; empty: none).
  std::string scene_references;
  std::string scene_class_left_out;
  CombinedSceneClassOptions scene_class;
  GeometryOptions geometry;
  AlbedoOptions albedo;
  LightingOptions lighting;
  // Segments given instead of detected (e.g. `--lines FILE.csv`).
  std::optional<std::vector<LineSegment>> given_lines;
  // Called with each stage's name before it starts.
  std::function<void(const std::string&)> on_stage;
};

// The geometry half of inference: lines, camera, scene class, layout, dense
// depth and support planes (what `propcam bench geometry` sweeps).
struct GeometryEstimate {
  std::vector<LineSegment> lines;
  CameraEstimate camera;
  render::PinholeCamera pinhole;   // the camera as the renderer sees it (height = camera_height_m)
  bool indoor = true;
  SkyEstimate sky;                 // what the scene classifier saw
  cv::Mat sky_mask;                // CV_8U: sky.mask outdoors, empty indoors
  Layout layout;                   // the Manhattan box (a data target)
  cv::Mat orientation;             // CV_8U SurfaceOrientation labels (empty when not computed)
  cv::Mat depth, normals;          // final
  std::vector<SupportPlane> planes;
  std::vector<StageReport> reports;  // lines, camera, camera_height, scene_class, geometry, depth, support_planes
};

// `photo` as infer_scene sanitises it (finite, clipped); same errors as infer_scene.
GeometryEstimate infer_geometry(const cv::Mat& photo, const InferenceOptions& options);

// The rest of inference on a geometry estimate of the same photo: albedo,
// light sources, intensities and camera response (what `propcam bench
// lighting` sweeps without redoing the geometry).
SceneModel complete_scene(const cv::Mat& photo, const GeometryEstimate& geometry, const InferenceOptions& options);

// `photo_linear` is CV_32FC3 linear RGB. Throws std::invalid_argument for an
// empty or too small photo; otherwise always returns a finite model whose
// reports say which fallbacks applied.
SceneModel infer_scene(const cv::Mat& photo_linear, const InferenceOptions& options = {});

constexpr int kMinPhotoSide = 16;
// A strip (a 10000x16 photo) leaves no scene to model at the working size.
constexpr int kMaxPhotoAspect = 8;

// The names InferenceOptions::on_stage is called with, in order (a screen
// lists them as pending before the analysis starts).
inline constexpr const char* kInferenceStages[] = {"lines", "camera", "scene_class", "orientation_map", "geometry",
                                                   "depth_transfer", "depth", "albedo", "lighting"};
// Linear radiance above this is clipped (HDR inputs, and infinities).
constexpr double kMaxPhotoRadiance = 1e4;

}  // namespace propcam::inference
