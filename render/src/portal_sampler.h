// The sky seen through a room's windows, sampled through the windows (internal
// to render/). An environment marked `through_portals` reaches a point only
// through the portals, so sampling it over the whole sphere wastes every
// sample that misses them; as Cycles' light portals, the path tracer instead
// picks a window uniformly and a direction uniformly in the solid angle it
// subtends. The density of a direction sums every window it crosses, so BSDF
// rays that escape through one are weighted against the same density.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "area_light_sampler.h"
#include "propcam/render/lights.h"

namespace propcam::render::detail {

class PortalSampler {
 public:
  explicit PortalSampler(const std::vector<Portal>& portals);

  bool empty() const { return windows_.empty(); }
  // A direction from `from` through one window: `direction`, `distance`
  // (infinite) and `pdf` set, `radiance` left zero for the caller's sky; pdf 0
  // when the window is seen edge-on or from its plane.
  LightSample sample(const Eigen::Vector3f& from, float u1, float u2) const;
  // The solid-angle density sample(from, ...) has for `direction`.
  float pdf(const Eigen::Vector3f& from, const Eigen::Vector3f& direction) const;

 private:
  struct Window {
    Eigen::Vector3d corner, normal;  // normal: edge_u x edge_v
    AreaLightSampler front, back;    // seen from the side of `normal`, and from the other
    const AreaLightSampler& seen_from(const Eigen::Vector3f& from) const;
  };
  std::vector<Window> windows_;
};

}  // namespace propcam::render::detail
