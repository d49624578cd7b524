// Support surfaces (floor, table tops, shelves) found in the dense depth, and
// the paper's insertion constraint: the depth is flat in a small region
// around the base of an inserted prop, so the prop stands on a plane rather
// than on the noise of the depth map.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "propcam/inference/room_enclosure.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

struct SupportPlaneOptions {
  double max_tilt_deg = 15.0;        // a pixel is on a horizontal surface when its normal is this close to up
  double bin_m = 0.02;               // height histogram resolution
  double thickness_m = 0.04;         // points within this of a plane's height belong to it
  double min_area_fraction = 0.004;  // of the (sampled) frame for a surface to count
  double min_table_height_m = 0.2;   // lower horizontal surfaces are the floor (rugs, steps)
  int max_planes = 6;
  int sample_width = 160;            // pixels are sampled on a grid this wide
};

// Horizontal surfaces facing up, below the camera: the floor (named "floor",
// at the height the floor is seen at, or y = 0 when it is not seen) and raised
// surfaces ("support_1", ...), each with the extents of its pixels. Sky
// (render::kSkyDepthM) is ignored. `report` gets stage "support_planes".
std::vector<SupportPlane> find_support_planes(const cv::Mat& depth, const cv::Mat& normals,
                                              const render::PinholeCamera& camera, const SupportPlaneOptions& options,
                                              StageReport& report);

// The floor's and the ceiling's heights (world y) among `planes`, where
// they are there (the layout names them "floor" and "ceiling").
RoomHeights room_heights(const std::vector<SupportPlane>& planes);

struct InsertionFlattening {
  bool applied = false;
  double plane_height_m = 0;  // world y of the plane the base was flattened onto
  int pixels_changed = 0;
  std::string why;
};

// The insertion constraint: around pixel (u, v), where a prop of footprint
// radius `footprint_radius_m` stands, depth is replaced by the horizontal
// plane the base stands on (a support plane of `planes` within
// `thickness_m`, else the median height of the upward-facing points near the
// base). Only pixels within twice the projected footprint whose points lie
// within `max_offset_m` of the plane change, so walls and objects next to the
// prop keep their depth. Changes `depth` and `normals` in place (sizes must
// match the camera). Never throws for a pixel outside the image or on sky;
// then `applied` is false and `why` says so.
InsertionFlattening flatten_insertion_region(cv::Mat& depth, cv::Mat& normals, const render::PinholeCamera& camera,
                                             const std::vector<SupportPlane>& planes, double u, double v,
                                             double footprint_radius_m, double max_offset_m = 0.1);

}  // namespace propcam::inference
