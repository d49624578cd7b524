// A lamp out of view, read from the light it throws on the walls
// (docs/lit_wall_lamp.md). A lamp near a wall lights it in a pool that
// falls off with distance as cos / d^2; the position whose falloff best
// explains the walls' shading (the photo over its albedo) is where the lamp
// stands. It becomes a small spherical light, a candidate the intensity
// fit weighs beside the others: the fit, not this module, says how much of
// the room's light it gives.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

struct LitWallLampOptions {
  // Seen points this close to a wall or ceiling plane (m) are that surface.
  double max_plane_distance_m = 0.08;
  // The surfaces are sampled on a grid this many columns wide.
  int sample_width = 96;
  // Too few wall samples to read a falloff from.
  int min_samples = 60;
  // A channel this bright (linear, the photo's 0..1) is clipped: its
  // shading is not known.
  double clipped_level = 0.98;
  // The lamp is searched on a grid over the room's box, this many steps
  // along each horizontal axis and the height, then refined around the best
  // in rounds whose step halves from one grid cell.
  int grid_xz = 14, grid_y = 6, refine_rounds = 5;
  // The room's box, where the layout has no wall: this far around the camera.
  double default_half_extent_m = 4.0;
  // The lamp stands at least this far from every sampled surface point and
  // from the camera (a lamp on a wall would be seen in its own pool).
  double min_clearance_m = 0.25;
  // The share of the shading's variance around its mean the lamp must
  // explain, after the worst `trim_share` of the samples (furniture,
  // shadows, texture) are left out.
  double min_explained = 0.35;
  double trim_share = 0.1;
  // Where it lights the walls most, the lamp gives at least this share of
  // their light.
  double min_lamp_share = 0.3;
  // The lamp's bulb (m): a small sphere, so its shadows stay sharp.
  double bulb_radius_m = kDefaultPointLightRadiusM;
};

struct LitWallLamp {
  bool found = false;
  std::string why;                                   // why found or not
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world
  double explained = 0.0;     // the share of the shading's variance the lamp explains (trimmed)
  double lamp_share = 0.0;    // its share of the light where it lights the walls most
  int samples = 0;            // wall and ceiling samples read
  nlohmann::json details = nlohmann::json::object();
};

// Where a lamp out of view stands, from the shading of the walls and the
// ceiling an indoor photo shows. `photo_linear` CV_32FC3, `depth` CV_32F
// along z and `albedo` CV_32FC3 at the photo's size (empty albedo: the
// walls are taken as evenly painted), `planes` the layout's planes (walls
// named wall*, the ceiling `ceiling`; normals facing the camera),
// `sources` CV_8U 255 on visible sources (or empty). The lamp is never
// where the photo would show it. Deterministic; not found (with the
// reason) on any input it cannot judge, never non-finite.
LitWallLamp find_lit_wall_lamp(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                               const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                               const cv::Mat& sources = {}, const LitWallLampOptions& options = {});

}  // namespace propcam::inference
