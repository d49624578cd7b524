#include "propcam/render/placement.h"

#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace propcam::render {
namespace {
// Lifts the prop off its support so its base does not z-fight with it.
constexpr float kBaseClearanceM = 1e-3f;
constexpr double kDegToRad = std::numbers::pi / 180.0;
// Sub-pixel offset of the retries after a miss (see place_prop).
constexpr double kMissRetryOffsetPx = 0.25;
}  // namespace

PlacedProp place_prop(const Mesh& prop, const PinholeCamera& camera, const Scene& background,
                      const PropPlacement& placement) {
  std::ostringstream where;
  where << "(" << placement.pixel_u << "," << placement.pixel_v << ")";
  if (!(placement.pixel_u >= -0.5 && placement.pixel_u <= camera.width - 0.5 && placement.pixel_v >= -0.5 &&
        placement.pixel_v <= camera.height - 0.5))
    throw std::invalid_argument("placement pixel " + where.str() + " is outside the " +
                                std::to_string(camera.width) + "x" + std::to_string(camera.height) + " photo");
  if (prop.empty()) throw std::invalid_argument("the prop mesh is empty");
  const Eigen::Vector3f origin = camera.center_world.cast<float>();
  Eigen::Vector3f dir = camera.ray_direction(placement.pixel_u, placement.pixel_v).cast<float>();
  RayHit hit;
  bool seen = background.intersect(origin, dir, std::numeric_limits<float>::infinity(), false, hit);
  // A ray through a vertex or an edge of the depth mesh (its vertices sit on
  // pixel centres) can slip through Embree's fast, not watertight, test: on a
  // miss, look a little off the pixel centre.
  for (int k = 0; !seen && k < 4; ++k) {
    const double du = (k & 1 ? 1 : -1) * kMissRetryOffsetPx, dv = (k & 2 ? 1 : -1) * kMissRetryOffsetPx;
    dir = camera.ray_direction(placement.pixel_u + du, placement.pixel_v + dv).cast<float>();
    seen = background.intersect(origin, dir, std::numeric_limits<float>::infinity(), false, hit);
  }
  if (!seen) throw std::invalid_argument("no surface is seen at pixel " + where.str() + " to stand the prop on");
  const SurfacePoint sp = background.surface(hit, origin, dir);
  const double tilt_deg = std::acos(std::clamp<double>(sp.geometric_normal.y(), -1.0, 1.0)) / kDegToRad;
  if (tilt_deg > kMaxSupportTiltDeg) {
    std::ostringstream msg;
    msg << "the surface at pixel " << where.str() << " is tilted " << static_cast<int>(std::lround(tilt_deg))
        << " degrees from horizontal (a wall?); place the prop on the floor or a table top";
    throw TiltedSupportError(msg.str());
  }

  const Eigen::AlignedBox3f box = prop.bounds();
  const float natural_height = box.sizes().y();
  if (!(natural_height > 0.f)) throw std::invalid_argument("the prop has no height");
  const float scale = placement.height_m > 0 ? static_cast<float>(placement.height_m) / natural_height : 1.f;
  // The base centre of the prop's bounding box goes to the support point.
  const Eigen::Vector3f base_prop(box.center().x(), box.min().y(), box.center().z());

  // At yaw 0 the prop's +z points horizontally toward the camera.
  Eigen::Vector3f to_camera = origin - sp.position;
  to_camera.y() = 0.f;
  const float facing = to_camera.norm() > 1e-6f ? std::atan2(to_camera.x(), to_camera.z()) : 0.f;
  const float angle = facing + static_cast<float>(placement.yaw_deg * kDegToRad);

  PlacedProp placed;
  placed.base_world = sp.position + Eigen::Vector3f::UnitY() * kBaseClearanceM;
  placed.support_normal = sp.geometric_normal;
  placed.world_from_prop = Eigen::Translation3f(placed.base_world) *
                           Eigen::AngleAxisf(angle, Eigen::Vector3f::UnitY()) * Eigen::Scaling(scale) *
                           Eigen::Translation3f(-base_prop);
  return placed;
}

}  // namespace propcam::render
