// An area light with what its sampling needs derived once (internal to
// render/): the path tracer samples every light at every vertex, and deriving
// the light's frame, normal and area there cost more than the sampling itself.
// AreaLight::sample and intersect are this over a single call.
#pragma once

#include <Eigen/Core>
#include <optional>

#include "propcam/render/lights.h"
#include "spherical_rectangle.h"

namespace propcam::render::detail {

class AreaLightSampler {
 public:
  explicit AreaLightSampler(const AreaLight& light);

  // As AreaLight::sample and AreaLight::intersect.
  LightSample sample(const Eigen::Vector3f& from, float u1, float u2) const;
  bool intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float& t, float& pdf) const;

 private:
  // The solid-angle parametrisation seen from `from`, where it holds.
  std::optional<SphericalRectangle> seen_from(const Eigen::Vector3d& from) const;

  Eigen::Vector3d corner_, edge_u_, edge_v_;
  Eigen::Vector3d area_normal_;  // edge_u x edge_v: the emitting side, length = area
  double area_ = 0.0;
  // The edges' Gram matrix and its determinant (= area^2), for a hit's
  // parallelogram coordinates.
  double uu_ = 0.0, uv_ = 0.0, vv_ = 0.0, gram_det_ = 0.0;
  std::optional<RectangleFrame> rectangle_;  // empty for a skewed parallelogram
  Eigen::Vector3f radiance_;
  bool emits_ = false;
};

}  // namespace propcam::render::detail
