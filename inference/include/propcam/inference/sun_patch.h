// A sun patch on the floor: light through a window the photo does not show
// (docs/sun_patch.md). A patch of floor much brighter than the floor around
// it, with sharp edges, is the sun through an opening; its outline is the
// opening's shadow-projection, a parallelogram whose sides run along the
// wall and along the sun's azimuth. The sun it gives enters the scene only
// through a window placed along the sun above the patch, so it lights the
// patch and whatever stands in it, and nothing else.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/room_enclosure.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

struct SunPatchOptions {
  // Seen points this close to the floor (world y) are floor.
  double max_floor_height_m = 0.08;
  // Too little floor seen to judge: below this share of the frame.
  double min_floor_share = 0.03;
  // The unlit floor's level: this percentile of the floor's luminance.
  double reference_percentile = 0.3;
  // A patch pixel is at least this many times the unlit floor's level...
  double min_brightness_ratio = 2.5;
  // ... and the band just inside its edge is at least this many times
  // brighter than a ring of floor just outside it: a sun patch's edge is
  // sharp, a lamp's pool of light fades.
  double min_edge_contrast = 2.0;
  // The band and the ring: this share of the frame's width each.
  double ring_width_share = 0.015;
  // A patch covers at least this share of the frame, and this much floor.
  double min_area_share = 0.003;
  double min_area_m2 = 0.15;
  // More bright floor regions than this are a pattern (tiles, a checked
  // rug), not light through an opening.
  int max_bright_regions = 3;
  // The outline's sides: one along a wall (a world axis: the camera
  // stage's Manhattan frame), the other turned from the wall's normal by
  // at most this much, searched in steps of kShearStepDeg.
  double max_shear_deg = 70.0;
  // The window's height from sill to top, for the sun's elevation from the
  // patch's length along the sun (a window 1.3 m high, a sun at 35 degrees:
  // a patch 1.9 m long).
  double window_height_m = 1.3;
  double min_elevation_deg = 15.0, max_elevation_deg = 65.0;
  // Where the window would be seen: its centre at this height.
  double window_centre_height_m = 1.5;
  // The window the scene gets: horizontal, this far below the ceiling (or
  // at `default_window_height_m` over the floor when no ceiling was
  // fitted), above any prop, crossed by the sun's rays that make the patch.
  double window_below_ceiling_m = 0.05;
  double default_window_height_m = 2.2;
  // The window is this much wider than the patch's outline on each side:
  // the outline's threshold cuts into the penumbra.
  double window_margin_share = 0.03;
};

struct SunPatch {
  bool found = false;
  std::string why;                 // why found or not
  cv::Mat mask;                    // CV_8U, the photo's size: 255 on the patch
  cv::Mat ring;                    // CV_8U: the unlit floor just around it
  double brightness_ratio = 1.0;   // the patch's luminance over the ring's around it
  double area_m2 = 0.0;
  // The outline on the floor: corner + s*along_wall + t*along_sun, s,t in [0,1].
  Eigen::Vector3d corner = Eigen::Vector3d::Zero(), along_wall = Eigen::Vector3d::Zero(),
                  along_sun = Eigen::Vector3d::Zero();
  Eigen::Vector3d sun_direction = Eigen::Vector3d::UnitY();  // toward the sun, unit
  Window window;                   // where the sun enters
  nlohmann::json details = nlohmann::json::object();
};

// Finds the largest sun patch on the floor of an indoor photo. `photo_linear`
// CV_32FC3, `depth` CV_32F along z at the same size (sky at kSkyDepthM),
// `heights` the layout's floor and ceiling (world y; the floor at 0 when it
// has none), `orientation` the geometry stage's orientation map (CV_8U
// SurfaceOrientation labels at any size; empty: none): a pixel it calls a
// wall is not floor, whatever its depth says. Deterministic; not found
// (with the reason) on any input it cannot judge, never non-finite.
SunPatch find_sun_patch(const cv::Mat& photo_linear, const cv::Mat& depth, const render::PinholeCamera& camera,
                        const RoomHeights& heights, const SunPatchOptions& options = {},
                        const cv::Mat& orientation = {});

// The albedo the patch's light was taken into (a sharp bright patch is
// reflectance to an intrinsic-image method) made continuous with the floor
// around it: the patch's albedo divided by its ratio to the ring's.
// Returns the factor divided by (1 when nothing changed).
double take_sun_patch_out_of_albedo(cv::Mat& albedo, const SunPatch& patch);

}  // namespace propcam::inference
