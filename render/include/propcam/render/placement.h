// Placing a prop in the world: on the support surface seen at a pixel,
// scaled to a height and turned about the up axis.
#pragma once

#include <Eigen/Geometry>
#include <stdexcept>
#include <string>

#include "propcam/render/camera.h"
#include "propcam/render/mesh.h"
#include "propcam/render/scene.h"

namespace propcam::render {

struct PropPlacement {
  double pixel_u = 0, pixel_v = 0;
  double height_m = 0;   // bounding-box height; <= 0 keeps the mesh's own size
  double yaw_deg = 0;    // counter-clockwise seen from above; 0: the prop's +z faces the camera
};

struct PlacedProp {
  Eigen::Affine3f world_from_prop = Eigen::Affine3f::Identity();
  Eigen::Vector3f base_world = Eigen::Vector3f::Zero();
  Eigen::Vector3f support_normal = Eigen::Vector3f::UnitY();
};

// Largest tilt of a surface from horizontal that still counts as a support.
constexpr double kMaxSupportTiltDeg = 30.0;

// The surface seen at the placement pixel is steeper than kMaxSupportTiltDeg.
struct TiltedSupportError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

// Finds the support point seen at the placement pixel in `background` (a
// committed scene) and returns the prop's transform. Throws
// std::invalid_argument with a user-facing message when the pixel is outside
// the image or sees nothing, and TiltedSupportError when it sees a surface
// that is not horizontal.
PlacedProp place_prop(const Mesh& prop, const PinholeCamera& camera, const Scene& background,
                      const PropPlacement& placement);

}  // namespace propcam::render
