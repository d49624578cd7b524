#include "light_stand_ins.h"

#include <array>

namespace propcam::render::detail {
namespace {

using Eigen::Vector3f;

// Relative slack on a light's outline: a panel cut to the light's size stays inside.
constexpr float kOutlineSlack = 1e-3f;

bool behind_area_light(const AreaLight& light, const Vector3f& v) {
  const Vector3f n = light.normal(), q = v - light.corner;
  const float depth = -q.dot(n);
  const float s = q.dot(light.edge_u) / light.edge_u.squaredNorm(), t = q.dot(light.edge_v) / light.edge_v.squaredNorm();
  return depth >= 0.f && depth <= kStandInDepth && s >= -kOutlineSlack && s <= 1.f + kOutlineSlack &&
         t >= -kOutlineSlack && t <= 1.f + kOutlineSlack;
}

bool behind_disc_light(const DiscLight& light, const Vector3f& v) {
  const Vector3f n = light.normal.normalized(), q = v - light.centre;
  const float depth = -q.dot(n);
  return depth >= 0.f && depth <= kStandInDepth && (q + depth * n).norm() <= light.radius * (1.f + kOutlineSlack);
}

// Some light of the rig holds every point of `points` (a sphere light: inside it).
template <typename Points>
bool one_light_holds(const LightRig& rig, const Points& points) {
  const auto all = [&](const auto& holds) {
    for (const Vector3f& v : points)
      if (!holds(v)) return false;
    return true;
  };
  for (const SphereLight& light : rig.sphere_lights)
    if (light.emits() && all([&](const Vector3f& v) { return (v - light.center).norm() <= light.radius; })) return true;
  for (const AreaLight& light : rig.area_lights)
    if (light.emits() && all([&](const Vector3f& v) { return behind_area_light(light, v); })) return true;
  for (const DiscLight& light : rig.disc_lights)
    if (light.emits() && all([&](const Vector3f& v) { return behind_disc_light(light, v); })) return true;
  return false;
}

bool sphere_light_holds(const LightRig& rig, const EmitterGroup& group) {
  for (const SphereLight& light : rig.sphere_lights)
    if (light.emits() && (group.centre - light.center).norm() + group.radius <= light.radius) return true;
  return false;
}

}  // namespace

bool rig_stands_for_every_emitter(const LightRig& rig, const EmissiveLights& emitters) {
  for (const EmitterGroup& group : emitters.groups()) {
    if (sphere_light_holds(rig, group)) continue;
    std::array<Vector3f, 8> corners;
    for (int c = 0; c < 8; ++c) corners[c] = group.box.corner(static_cast<Eigen::AlignedBox3f::CornerType>(c));
    if (one_light_holds(rig, corners)) continue;
    for (int i = group.first; i < group.end; ++i) {
      const EmissiveTriangle& t = emitters.triangle(i);
      if (!one_light_holds(rig, std::array<Vector3f, 3>{t.a, t.b, t.c})) return false;
    }
  }
  return true;
}

}  // namespace propcam::render::detail
