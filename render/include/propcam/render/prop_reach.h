// Where a prop can change the photo at all: the pixels that see it, the
// shadows it casts toward each light, and the neighbourhood its occlusion of
// the environment and its bounce light reach. Tiles outside are not traced.
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/scene.h"

namespace propcam::render {

struct ReachOptions {
  // A prop that covers less than this share of a point's cosine-weighted
  // hemisphere changes its environment light and bounce light by less than
  // that share: below the noise of an interactive render.
  double min_hemisphere_share = 0.02;
  // Lights whose radiance times solid angle (seen from the prop) is below this
  // share of the strongest light's cast no shadow worth tracing.
  double min_light_share = 0.01;
  int pixel_step = 2;  // the test runs on every n-th pixel (tiles are larger)
  // An environment whose brightest cone of this half-angle holds at least
  // `environment_peak_share` of its light has a sun in it: it casts a shadow
  // like a sun light does.
  double environment_peak_cone_deg = 5.0;
  double environment_peak_share = 0.2;
};

struct PropReach {
  cv::Mat affected;                 // CV_8U at camera size, 255 where the prop may change the pixel
  int pixels_seen = 0;              // rays through the prop's bounds
  std::vector<int> pixels_in_shadow;  // per area light (same order as the rig)
  int pixels_near = 0;              // within reach of occlusion and bounce light
  std::vector<bool> light_significant;
  bool environment_has_sun = false;  // directional shadows from a peak in the environment
  int pixels_in_environment_sun_shadow = 0;
  // sphere, spot, point and disc lights and suns (all treated as casting shadows)
  int pixels_in_sphere_or_sun_shadow = 0;
  double seconds = 0.0;
};

// `prop_bounds` is the prop's world bounding box; `scene` is committed (its
// background world is used to find the surface seen at each pixel).
PropReach estimate_prop_reach(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                              const Eigen::AlignedBox3f& prop_bounds, const ReachOptions& options = {});

}  // namespace propcam::render
