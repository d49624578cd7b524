// Geometry stage (first cut): a gravity-aligned box of support planes (floor,
// walls, ceiling indoors), each wall at the densest distance of where vertical
// scene edges meet the floor,
// giving depth and normals for every pixel. Pixels of `sky_mask` (CV_8U,
// non-zero on sky) get render::kSkyDepthM: light, not geometry. `seen_floor`
// (world points the orientation map sees as floor) pushes walls behind it;
// `orientation` (CV_8U SurfaceOrientation, any size) says which wall a
// vertical edge stands on.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "propcam/inference/camera.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

struct LayoutOptions {
  double default_wall_distance_indoor_m = 8.0;   // where no edge says otherwise
  double default_wall_distance_outdoor_m = 40.0;
  double min_wall_distance_m = 0.6;
  double ceiling_height_m = 2.7;                 // indoors
  double max_depth_m = 200.0;                    // sky and far background
};

struct Layout {
  cv::Mat depth;    // CV_32F
  cv::Mat normals;  // CV_32FC3 world
  std::vector<SupportPlane> planes;
  StageReport report;
};

Layout estimate_layout(const render::PinholeCamera& camera, const std::vector<LineSegment>& lines,
                       const std::vector<int>& line_labels, bool indoor, const LayoutOptions& options = {},
                       const cv::Mat& sky_mask = cv::Mat(), const std::vector<Eigen::Vector3d>& seen_floor = {},
                       const cv::Mat& orientation = cv::Mat());

}  // namespace propcam::inference
