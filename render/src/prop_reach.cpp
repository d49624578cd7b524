#include "propcam/render/prop_reach.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

#include "luminance.h"

namespace propcam::render {
namespace {

using Eigen::Vector3f;

constexpr float kPi = std::numbers::pi_v<float>;
// A box with any extent below this is treated as empty (no prop).
constexpr float kMinBoundsExtent = 1e-6f;
// Luminance of a light below this is off.
constexpr float kMinLightLuminance = 1e-12f;

using detail::luminance;

// Slab test: does origin + t*dir, t > 0, meet the box?
bool ray_hits_box(const Vector3f& origin, const Vector3f& dir, const Eigen::AlignedBox3f& box) {
  float t0 = 0.f, t1 = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (std::abs(dir[a]) < 1e-12f) {
      if (origin[a] < box.min()[a] || origin[a] > box.max()[a]) return false;
      continue;
    }
    float ta = (box.min()[a] - origin[a]) / dir[a], tb = (box.max()[a] - origin[a]) / dir[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

// Angular radius of a sphere of radius r at distance d (pi/2 when inside).
float angular_radius(float r, float d) { return d <= r ? kPi / 2 : std::asin(std::clamp(r / d, 0.f, 1.f)); }

float angle_between(const Vector3f& a, const Vector3f& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.f, 1.f));
}

// The environment's brightest direction and the share of its light (solid
// angle weighted) within `cone` radians of it.
struct EnvironmentPeak {
  Vector3f direction = Vector3f::UnitY();
  double share = 0.0;
};

EnvironmentPeak environment_peak(const EnvironmentLight& env, double cone) {
  EnvironmentPeak peak;
  const cv::Mat& img = env.image();
  if (img.empty()) return peak;
  double total = 0.0, best = -1.0;
  std::vector<std::pair<Vector3f, double>> texels;
  texels.reserve(img.total());
  for (int y = 0; y < img.rows; ++y) {
    const float v = (y + 0.5f) / img.rows;
    const double solid = std::sin(v * kPi);
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3f c = img.at<cv::Vec3f>(y, x);
      const double power = std::max(0.f, luminance(Vector3f(c[0], c[1], c[2]))) * solid;
      const Vector3f d = EnvironmentLight::uv_to_direction((x + 0.5f) / img.cols, v);
      texels.push_back({d, power});
      total += power;
      if (power > best) {
        best = power;
        peak.direction = d;
      }
    }
  }
  if (!(total > 0)) return peak;
  const float cos_cone = static_cast<float>(std::cos(cone));
  double inside = 0.0;
  for (const auto& [d, power] : texels)
    if (d.dot(peak.direction) >= cos_cone) inside += power;
  peak.share = inside / total;
  return peak;
}

// Which area lights matter at the prop: radiance x solid angle, relative to the strongest.
std::vector<bool> significant_area_lights(const LightRig& lights, const Vector3f& centre, float radius,
                                          double min_light_share) {
  const int n_area = static_cast<int>(lights.area_lights.size());
  std::vector<float> strength(n_area, 0.f);
  float strongest = 0.f;
  for (int i = 0; i < n_area; ++i) {
    const AreaLight& l = lights.area_lights[i];
    const float d = std::max((l.centre() - centre).norm(), radius);
    strength[i] = luminance(l.radiance) * l.area() / (d * d);
    strongest = std::max(strongest, strength[i]);
  }
  std::vector<bool> significant(n_area, false);
  for (int i = 0; i < n_area; ++i)
    significant[i] = strength[i] > kMinLightLuminance && strength[i] >= min_light_share * strongest;
  return significant;
}

// Occlusion and bounce reach: the prop's bounding sphere subtends solid
// angle 2pi(1 - cos a); its share of the cosine-weighted hemisphere is at
// most sin^2 a. Points with sin^2 a below the threshold are out of reach.
// The sphere overstates a box's occlusion: use the sphere of the box's mean
// projected area (a convex body's mean shadow is a quarter of its surface).
float occlusion_reach_distance(const Eigen::AlignedBox3f& prop_bounds, double min_hemisphere_share) {
  const Vector3f e = prop_bounds.sizes();
  const float mean_projected_area = 0.5f * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
  const float effective_radius = std::sqrt(mean_projected_area / kPi);
  return effective_radius / std::sqrt(static_cast<float>(std::max(min_hemisphere_share, 1e-9)));
}

// The sampled rays are up to 1.5 pixels apart, so a prop projecting to less
// than that (far away, at the horizon) can slip between them. Every camera
// ray through a box in front of the camera passes within the rectangle
// around its projected corners: the pixels whose jittered rays can meet the
// box (half a pixel around it) count as seeing it. Empty when a corner is
// behind the camera.
cv::Rect projected_bounds_rect(const PinholeCamera& camera, const Eigen::AlignedBox3f& prop_bounds) {
  double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
  for (int c = 0; c < 8; ++c) {
    Eigen::Vector2d px = Eigen::Vector2d::Zero();
    if (!camera.project(prop_bounds.corner(static_cast<Eigen::AlignedBox3f::CornerType>(c)).cast<double>(), px))
      return {};
    u0 = std::min(u0, px.x()), u1 = std::max(u1, px.x()), v0 = std::min(v0, px.y()), v1 = std::max(v1, px.y());
  }
  const auto clamp_to = [](double value, int size) {
    return static_cast<int>(std::clamp(value, -1.0, static_cast<double>(size)));
  };
  const int x_lo = clamp_to(std::floor(u0 - 0.5), camera.width), x_hi = clamp_to(std::ceil(u1 + 0.5), camera.width);
  const int y_lo = clamp_to(std::floor(v0 - 0.5), camera.height), y_hi = clamp_to(std::ceil(v1 + 0.5), camera.height);
  return cv::Rect(x_lo, y_lo, x_hi - x_lo + 1, y_hi - y_lo + 1) & cv::Rect(0, 0, camera.width, camera.height);
}

// A block of step x step pixels (clipped to the image) and the pixel at its centre.
struct PixelBlock {
  cv::Rect rect;
  int x, y;
};

// Seen through the prop's bounds (prop visible, or hiding what is behind):
// tested at the block's corners too, so thin props are not missed.
bool sees_prop_bounds(const PinholeCamera& camera, const Eigen::AlignedBox3f& prop_bounds, const cv::Rect& seen_rect,
                      const PixelBlock& block, int step) {
  if ((seen_rect & block.rect).area() > 0) return true;
  const Vector3f origin = camera.center_world.cast<float>();
  for (int corner = 0; corner < 5; ++corner) {
    const double u = corner == 0 ? block.x : block.rect.x - 0.5 + (corner & 1 ? step : 0);
    const double v = corner == 0 ? block.y : block.rect.y - 0.5 + (corner & 2 ? step : 0);
    const Vector3f dir = camera.ray_direction(u, v).cast<float>();
    if (ray_hits_box(origin, dir, prop_bounds)) return true;
  }
  return false;
}

// A surface point seen at a pixel, as the prop's shadow cones see it.
struct PointNearProp {
  Vector3f p, to_prop;
  float prop_distance, prop_radius, prop_angle;

  // p lies in the prop's shadow cone from a light of this centre and radius.
  bool shadowed_by(const Vector3f& light_centre, float light_radius) const {
    const Vector3f to_light = light_centre - p;
    const float light_distance = to_light.norm();
    return light_distance > prop_distance - prop_radius &&
           angle_between(to_prop, to_light) < prop_angle + angular_radius(light_radius, light_distance);
  }
};

// Spots are taken as whole spheres and points (their cones ignored): a wider
// reach costs tiles, never a missed shadow.
bool in_sphere_point_disc_or_sun_shadow(const PointNearProp& q, const LightRig& lights) {
  for (const SphereLight& l : lights.sphere_lights)
    if (l.emits() && q.shadowed_by(l.center, l.radius)) return true;
  for (const PointLight& l : lights.point_lights)
    if (l.emits() && q.shadowed_by(l.position, 0.f)) return true;
  for (const DiscLight& l : lights.disc_lights) {
    const bool lit_side = l.normal.dot(q.p - l.centre) > 0.f;  // a disc lights one side
    if (l.emits() && lit_side && q.shadowed_by(l.centre, l.radius)) return true;
  }
  for (const SunLight& s : lights.suns)
    if (s.emits() && angle_between(q.to_prop, s.direction) < q.prop_angle + static_cast<float>(s.angular_radius))
      return true;
  return false;
}

// The first significant area light in whose shadow cone of the prop the point lies, or -1.
int area_light_shadowing(const PointNearProp& q, const LightRig& lights, const std::vector<bool>& significant) {
  for (int i = 0; i < static_cast<int>(lights.area_lights.size()); ++i) {
    if (!significant[i]) continue;
    const AreaLight& l = lights.area_lights[i];
    const Vector3f to_light = l.centre() - q.p;
    const float light_distance = to_light.norm();
    if (light_distance <= q.prop_distance - q.prop_radius) continue;  // the light is nearer than the prop
    if (l.normal().dot(-to_light) <= 0.f) continue;                  // p is behind the one-sided light
    const float light_radius = 0.5f * (l.edge_u.norm() + l.edge_v.norm());
    if (angle_between(q.to_prop, to_light) < q.prop_angle + angular_radius(light_radius, light_distance)) return i;
  }
  return -1;
}

// What the prop's shadows and nearness are tested against.
struct ShadowCasters {
  const LightRig& lights;
  Vector3f prop_centre;
  float prop_radius, reach_distance;
  bool environment_has_sun;
  Vector3f environment_sun;
  double environment_sun_cone;
};

// Whether the prop can change the surface seen along `dir` (near it, or in
// one of its shadows), counted in `reach` by the reason found first.
bool surface_within_reach(const Scene& scene, const Vector3f& origin, const Vector3f& dir, const ShadowCasters& casters,
                          PropReach& reach) {
  RayHit hit;
  if (!scene.intersect(origin, dir, std::numeric_limits<float>::infinity(), false, hit)) return false;
  const Vector3f p = origin + dir * hit.t;
  const Vector3f to_prop = casters.prop_centre - p;
  const float prop_distance = to_prop.norm();
  if (prop_distance <= casters.reach_distance) {
    ++reach.pixels_near;
    return true;
  }
  const PointNearProp q{p, to_prop, prop_distance, casters.prop_radius,
                        angular_radius(casters.prop_radius, prop_distance)};
  if (in_sphere_point_disc_or_sun_shadow(q, casters.lights)) {
    ++reach.pixels_in_sphere_or_sun_shadow;
    return true;
  }
  if (casters.environment_has_sun &&
      angle_between(to_prop, casters.environment_sun) < q.prop_angle + static_cast<float>(casters.environment_sun_cone)) {
    ++reach.pixels_in_environment_sun_shadow;
    return true;
  }
  const int area = area_light_shadowing(q, casters.lights, reach.light_significant);
  if (area < 0) return false;
  ++reach.pixels_in_shadow[area];
  return true;
}

}  // namespace

PropReach estimate_prop_reach(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                              const Eigen::AlignedBox3f& prop_bounds, const ReachOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  PropReach reach;
  reach.affected = cv::Mat::zeros(camera.height, camera.width, CV_8U);
  const int n_area = static_cast<int>(lights.area_lights.size());
  reach.pixels_in_shadow.assign(n_area, 0);
  reach.light_significant.assign(n_area, false);
  if (prop_bounds.isEmpty() || prop_bounds.sizes().maxCoeff() < kMinBoundsExtent || camera.width <= 0) return reach;

  const Vector3f centre = prop_bounds.center();
  const float radius = 0.5f * prop_bounds.sizes().norm();
  reach.light_significant = significant_area_lights(lights, centre, radius, options.min_light_share);
  ShadowCasters casters{lights, centre, radius, occlusion_reach_distance(prop_bounds, options.min_hemisphere_share),
                        false, Vector3f::UnitY(), options.environment_peak_cone_deg * kPi / 180.0};
  if (lights.environment) {
    const EnvironmentPeak sun = environment_peak(*lights.environment, casters.environment_sun_cone);
    reach.environment_has_sun = sun.share >= options.environment_peak_share;
    casters.environment_has_sun = reach.environment_has_sun;
    casters.environment_sun = sun.direction;
  }
  const Vector3f origin = camera.center_world.cast<float>();
  const int step = std::max(1, options.pixel_step);
  const cv::Rect seen_rect = projected_bounds_rect(camera, prop_bounds);
  for (int y0 = 0; y0 < camera.height; y0 += step)
    for (int x0 = 0; x0 < camera.width; x0 += step) {
      const PixelBlock block{
          cv::Rect(x0, y0, std::min(step, camera.width - x0), std::min(step, camera.height - y0)),
          std::min(x0 + step / 2, camera.width - 1), std::min(y0 + step / 2, camera.height - 1)};
      bool affected = sees_prop_bounds(camera, prop_bounds, seen_rect, block, step);
      if (affected) ++reach.pixels_seen;
      if (!affected)
        affected = surface_within_reach(scene, origin, camera.ray_direction(block.x, block.y).cast<float>(), casters,
                                        reach);
      if (affected) reach.affected(block.rect).setTo(255);
    }
  reach.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return reach;
}

}  // namespace propcam::render
