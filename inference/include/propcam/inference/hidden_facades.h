// The facades beside and behind the camera: outdoors, the buildings that
// shade the street nearest the camera are mostly out of the frame, so a mesh
// of the depth map alone lets the sun light a street the photo shows in
// shade. The vertical planes the depth map does show (a street's two
// facades, a facade seen across) are continued out of the frame, at the
// height they are seen at, as occluders for sun, sky and the prop's light.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/mesh.h"

namespace propcam::inference {

struct HiddenFacadeOptions {
  double max_normal_up = 0.3;          // |n.y| below this: a vertical surface
  double max_axis_deviation_deg = 20;  // a facade faces one of the world's horizontal axes (Manhattan) this closely
  double bin_m = 0.25;                 // plane offsets are histogrammed at this resolution
  double thickness_m = 0.5;            // points this close to a plane belong to it
  double min_area_fraction = 0.03;     // of the sampled frame, for a plane to be a facade
  int max_facades = 4;
  double reach_m = 40.0;  // continued this far each way along the facade from the camera
  double cell_m = 1.0;    // out-of-frame cells of this size; cells that reach into the frame are left out
  double free_space_margin = 0.1;  // a point this share nearer than the depth map's surface stands in seen free space
  int sample_width = 160;  // pixels are sampled on a grid this wide
};

// A facade's extent that a scene file may hold: beyond these it is corrupt
// (and its mesh would not fit in memory).
constexpr double kMaxFacadeSpanM = 1000.0, kMaxFacadeHeightM = 300.0;
constexpr size_t kMaxHiddenFacades = 16;

struct HiddenFacade {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // horizontal, unit, facing the camera
  double offset = 0;                                 // plane: normal . x + offset = 0
  double bottom_m = 0, top_m = 0;                    // heights the facade spans (the top as seen, median over columns)
  double seen_min = 0, seen_max = 0;                 // extent along up x normal where it was seen
  double along_min = 0, along_max = 0;               // and how far it may be continued
  Eigen::Vector3f albedo = Eigen::Vector3f::Constant(0.5f);  // mean estimated albedo of its pixels
  int pixels = 0;                                    // sampled pixels on it

  // Throws std::runtime_error naming what is wrong: a non-finite number, a
  // normal that is not horizontal and unit, an empty or oversized extent.
  void validate() const;
};

// Vertical planes of the depth map with their seen height and colour.
// `normals` are world-space unit normals (SceneModel::normals); depth and
// normals at the camera's size, albedo of any size (resampled). No facade
// when too little of the frame is vertical. Throws std::invalid_argument on
// maps of the wrong type or size.
std::vector<HiddenFacade> find_hidden_facades(const cv::Mat& depth, const cv::Mat& normals, const cv::Mat& albedo,
                                              const render::PinholeCamera& camera, const HiddenFacadeOptions& options = {});

// The parts of the facades out of the camera's view, as a mesh of cells
// (one material per facade, diffuse, its albedo). Cells that reach into the
// frame are left out, so what the camera sees is the depth map's alone. A
// facade is continued from where it was seen outwards only until it would
// stand in space the photo sees through (in front of the depth map): a
// building's side wall is not continued across the street. `depth` is at
// the camera's size (metres along the optical axis).
render::Mesh hidden_facade_mesh(const std::vector<HiddenFacade>& facades, const cv::Mat& depth,
                                const render::PinholeCamera& camera, const HiddenFacadeOptions& options = {});

}  // namespace propcam::inference
