// Indoors, the room's surfaces outside the frame — the ceiling above the
// camera, the wall behind it, the side walls it does not see — are not in the
// depth map. Rendered from the depth map alone, a room is open at the back
// and the top, and an environment map lights the prop through the open side
// behind the camera. (On the Blender world's tune rooms the estimated light
// came from behind the camera in 29 of 31; the true one from ahead in 15.)
// The enclosure closes the room: an axis-aligned box in the layout's
// Manhattan frame around everything seen and every light the fit may use,
// with the seen surfaces' mean albedo. Its cells the photo sees through (in
// front of the depth map) are left out, so what the camera sees is still the
// depth map's alone. Used when LightingOptions::enclose_room is on (off by
// default: docs/room_enclosure.md has the figures).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/mesh.h"

namespace propcam::inference {

// An enclosure larger than this on any side is a corrupt scene's.
constexpr double kMaxEnclosureExtentM = 200.0;

struct RoomEnclosure {
  Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();  // world corners
  Eigen::Vector3f albedo = Eigen::Vector3f::Constant(0.5f);                      // linear RGB
  // No box: the room stays open (outdoors, or switched off).
  bool empty() const { return !(max.array() > min.array()).all(); }
  // Throws std::runtime_error for non-finite corners, a side over
  // kMaxEnclosureExtentM or an albedo outside [0, 1].
  void validate() const;
};

struct RoomEnclosureOptions {
  double percentile = 0.01;     // the seen points' extent, robust to a few wild depths: [p, 1 - p]
  double margin_m = 0.1;        // the box stands this far beyond the seen extent and the lights
  double behind_camera_m = 1.0; // a wall the camera does not see stands at least this far from it
  double cell_m = 0.25;         // mesh cells (at most kMaxEnclosureCellsPerSide per side)
  double free_space_margin = 0.05;  // a cell counts as seen through when nearer than (1 - this) x the seen depth
  int sample_width = 160;       // depth pixels are sampled on a grid this wide
};

constexpr int kMaxEnclosureCellsPerSide = 64;

// The heights (world y) of the layout's floor and ceiling, where it has them.
struct RoomHeights {
  std::optional<double> floor_y, ceiling_y;
};

// The box around the seen points (depth below render::kSkyDepthM), the
// camera (behind_camera_m each way), the layout's floor and ceiling and the
// points in `light_positions` (the lights' centres). `albedo` (CV_32FC3 at
// the depth's size) gives its mean colour. Empty when the depth sees no
// surface. Throws std::invalid_argument when depth is not CV_32F at the
// camera's size or albedo not CV_32FC3 at the depth's.
RoomEnclosure enclose_room(const cv::Mat& depth, const cv::Mat& albedo, const render::PinholeCamera& camera,
                           const RoomHeights& heights, const std::vector<Eigen::Vector3d>& light_positions,
                           const RoomEnclosureOptions& options = {});

// The box's six inward faces as cells, less the cells the photo sees
// through. `depth` is at the camera's size. Empty for an empty box.
render::Mesh room_enclosure_mesh(const RoomEnclosure& box, const cv::Mat& depth, const render::PinholeCamera& camera,
                                 const RoomEnclosureOptions& options = {});

}  // namespace propcam::inference
