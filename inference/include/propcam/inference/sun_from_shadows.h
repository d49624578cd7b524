// Outdoors: the sun's direction and its strength against the sky, from the
// shadows the scene's own geometry casts.
//
// Within one surface orientation (the ground, one facade) a distant sun
// shades every point alike, so what varies there is its cast shadow, the
// sky's visibility and the albedo's texture. A sun hypothesis predicts the
// shading sky + r * sun at every pixel; the right one leaves the photo's log
// luminance with the least variance inside each orientation group once each
// group's mean (its albedo) is taken out. The photo's shadow contrast then
// also fixes r, the sun's irradiance per unit of sky: the quantity the
// intensity fit cannot find when the estimated albedo carries the shadows.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/scene.h"

namespace propcam::inference {

struct SunFromShadowsOptions {
  int azimuths = 16;  // coarse grid: every 22.5 degrees
  std::vector<double> elevations_deg = {10, 20, 30, 40, 50, 60, 70};
  int refine_rounds = 3;  // each halves the grid's step around the best sun
  int max_pixels = 2048;  // evenly spread over the usable ones
  // Which pixels share an albedo offset: each orientation (ground, ceilings,
  // slopes, facades by azimuth), ground against the rest, or all alike.
  enum class Groups { Orientation, GroundAndWalls, One };
  Groups groups = Groups::GroundAndWalls;
  // Search the photo over the albedo (its shading) rather than the photo:
  // the albedo's texture (windows, bricks) is then gone, and so are the
  // shadows smaller than the albedo's blur; the larger ones stay.
  bool shading_only = true;
  // Sun irradiance per unit sky radiance that the search tries: 0 and a
  // geometric ladder up to max_ratio.
  double min_ratio = 0.05, max_ratio = 60.0;
  int ratio_steps = 24;
  // A hypothesis must leave this much less of the grouped variance than a
  // shadowless ambient light does, or no sun is found (overcast, or nothing
  // casts a shadow).
  double min_variance_explained = 0.15;
};

struct SunFromShadows {
  bool found = false;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitY();  // world, toward the sun
  // Irradiance on a surface facing the sun, per unit weight of the sky's
  // environment (both in the renderer's units).
  double irradiance_per_sky = 0.0;
  // The best hypothesis whether or not it passed the test: its direction
  // and ratio (UnitY and 0 when nothing could be scored).
  Eigen::Vector3d best_direction = Eigen::Vector3d::UnitY();
  double best_irradiance_per_sky = 0.0;
  // Grouped log-luminance variance left with no sun, with the best ambient
  // light (SunFromShadowsOptions::min_variance_explained) and with the sun found.
  double variance_no_sun = 0.0, variance_ambient = 0.0, variance = 0.0;
  int pixels = 0, groups = 0, hypotheses = 0;
};

// `photo`, `albedo` and `sky_basis` (the sky's environment rendered alone at
// unit weight with `albedo`) are CV_32FC3 at the camera's resolution; the
// scene holds the empty scene's mesh (committed). `usable` (CV_8U, 0: skip)
// drops sources, clipped and sky pixels. `more_directions` (world, toward
// the light: e.g. the ranked panoramas' suns) are tried beside the grid.
SunFromShadows sun_from_shadows(const render::Scene& scene, const render::PinholeCamera& camera, const cv::Mat& photo,
                                const cv::Mat& albedo, const cv::Mat& sky_basis, const cv::Mat& usable,
                                const SunFromShadowsOptions& options = {},
                                const std::vector<Eigen::Vector3d>& more_directions = {});

}  // namespace propcam::inference
