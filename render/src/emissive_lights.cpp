#include "emissive_lights.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "luminance.h"
#include "propcam/render/scene.h"
#include "spherical_triangle.h"

namespace propcam::render::detail {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

// Nearer than this (m) to a sampled point, or seeing it this edge-on, a
// triangle delivers nothing (its area density d^2 / (cos A) is meaningless).
constexpr double kMinTriangleLightDistance = 1e-6;
constexpr double kMinTriangleLightCosine = 1e-7;
// A node whose bounding sphere subtends less than this sine (about 6 degrees)
// from the receiving point is treated as one light: a triangle in it is
// picked by power alone, without descending further. From there the
// triangles' importances differ little, and the descent cost a third of a
// render of a room lit by a 2208-triangle globe (docs/renderer_vs_cycles.md).
constexpr float kFarClusterSin = 0.1f;
// The largest float below 1: u stays in [0, 1) when it is rescaled per level.
constexpr float kOneMinusEpsilon = 0x1.fffffep-1f;

// What a triangle emits, up to a constant factor: its luminance times its area.
float triangle_power(const EmissiveTriangle& t) { return luminance(t.emission) * t.area; }

float safe_sqrt(float x) { return std::sqrt(std::max(0.f, x)); }

// cos(max(0, a - b)) and sin(max(0, a - b)) from the angles' cosines and sines.
float cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a > cos_b ? 1.f : cos_a * cos_b + sin_a * sin_b;
}
float sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a > cos_b ? 0.f : sin_a * cos_b - cos_a * sin_b;
}

}  // namespace

LightBounds LightBounds::of(const EmissiveTriangle& t) {
  LightBounds b;
  b.box.extend(t.a);
  b.box.extend(t.b);
  b.box.extend(t.c);
  b.w = t.normal;
  b.cos_theta_o = 1.f;
  b.power = triangle_power(t);
  return b;
}

LightBounds LightBounds::merged(const LightBounds& o) const {
  LightBounds m;
  m.box = box.merged(o.box);
  m.power = power + o.power;
  // The smallest cone around both normal cones; normals count up to sign
  // (two-sided emitters), so the other cone is flipped toward this one first.
  const Vector3f ow = w.dot(o.w) < 0.f ? Vector3f(-o.w) : o.w;
  const float theta_a = std::acos(std::clamp(cos_theta_o, -1.f, 1.f));
  const float theta_b = std::acos(std::clamp(o.cos_theta_o, -1.f, 1.f));
  const float theta_d = std::acos(std::clamp(w.dot(ow), -1.f, 1.f));
  const float pi = std::numbers::pi_v<float>;
  if (std::min(theta_d + theta_b, pi) <= theta_a) {
    m.w = w;
    m.cos_theta_o = cos_theta_o;
    return m;
  }
  if (std::min(theta_d + theta_a, pi) <= theta_b) {
    m.w = ow;
    m.cos_theta_o = o.cos_theta_o;
    return m;
  }
  const float theta_o = 0.5f * (theta_a + theta_d + theta_b);
  const Vector3f axis = w.cross(ow);
  if (theta_o >= pi || !(axis.squaredNorm() > 0.f)) {
    m.w = w;
    m.cos_theta_o = -1.f;  // every direction
    return m;
  }
  m.w = (Eigen::AngleAxisf(theta_o - theta_a, axis.normalized()) * w).normalized();
  m.cos_theta_o = std::cos(theta_o);
  return m;
}

ImportanceBound ImportanceBound::of(const LightBounds& b) {
  ImportanceBound out;
  out.centre = b.box.center();
  const float half_diagonal = 0.5f * b.box.diagonal().norm();
  out.radius2 = half_diagonal * half_diagonal;
  out.min_distance2 = half_diagonal;
  out.w = b.w;
  out.cos_theta_o = b.cos_theta_o;
  out.sin_theta_o = safe_sqrt(1.f - b.cos_theta_o * b.cos_theta_o);
  out.power = b.power;
  return out;
}

float ImportanceBound::importance(const Vector3f& p, const Vector3f& n) const {
  if (!(power > 0.f)) return 0.f;
  const Vector3f offset = p - centre;
  const float distance2 = offset.squaredNorm();
  const float d2 = std::max(distance2, min_distance2);
  if (!(d2 > 0.f)) return 0.f;
  // Inside the bound's sphere every direction may hold an emitter.
  if (!(distance2 > radius2)) return power / d2;
  const Vector3f wi = offset / std::sqrt(distance2);
  // The angle the bound's sphere subtends from p.
  const float sin2_b = radius2 / distance2;
  const float cos_b = safe_sqrt(1.f - sin2_b), sin_b = std::sqrt(sin2_b);
  // The emitters' normals (either sign) at their best toward p.
  const float cos_w = std::abs(w.dot(wi)), sin_w = safe_sqrt(1.f - cos_w * cos_w);
  const float cos_x = cos_sub_clamped(sin_w, cos_w, sin_theta_o, cos_theta_o);
  const float sin_x = sin_sub_clamped(sin_w, cos_w, sin_theta_o, cos_theta_o);
  const float cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
  if (!(cos_p > 0.f)) return 0.f;  // every emitter edge-on or beyond
  float importance = power * cos_p / d2;
  if (n.x() != 0.f || n.y() != 0.f || n.z() != 0.f) {
    const float cos_i = std::abs(wi.dot(n)), sin_i = safe_sqrt(1.f - cos_i * cos_i);
    importance *= cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
  }
  return std::max(importance, 0.f);
}

EmissiveLights::EmissiveLights(const Scene& scene) {
  for (int m = 0; m < scene.mesh_count(); ++m) {
    EmitterGroup group;
    group.first = static_cast<int>(triangles_.size());
    const Mesh& mesh = scene.mesh(m);
    const Eigen::Affine3f& xf = scene.world_from_mesh(m);
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
      const Material& material = mesh.materials[mesh.material_ids[t]];
      if (material.type != Material::Type::Emissive || !(material.emission.maxCoeff() > 0.f) ||
          !material.emission.allFinite())
        continue;
      EmissiveTriangle e;
      e.a = xf * mesh.positions[mesh.triangles[t][0]];
      e.b = xf * mesh.positions[mesh.triangles[t][1]];
      e.c = xf * mesh.positions[mesh.triangles[t][2]];
      const Vector3f cross = (e.b - e.a).cross(e.c - e.a);
      e.area = 0.5f * cross.norm();
      if (!(e.area > 0.f) || !std::isfinite(e.area)) continue;
      e.normal = cross.normalized();
      e.emission = material.emission.cwiseMax(0.f);
      e.mesh = m;
      e.triangle = static_cast<int>(t);
      e.prop = scene.layer(m) == Layer::Prop;
      index_of_[(static_cast<uint64_t>(m) << 32) | static_cast<uint32_t>(t)] = static_cast<int>(triangles_.size());
      triangles_.push_back(e);
      group.box.extend(e.a);
      group.box.extend(e.b);
      group.box.extend(e.c);
    }
    group.end = static_cast<int>(triangles_.size());
    if (group.end == group.first) continue;
    group.centre = group.box.center();
    for (int i = group.first; i < group.end; ++i)
      for (const Vector3f& v : {triangles_[i].a, triangles_[i].b, triangles_[i].c})
        group.radius = std::max(group.radius, (v - group.centre).norm());
    groups_.push_back(group);
  }
  if (triangles_.empty()) return;
  order_.resize(triangles_.size());
  std::iota(order_.begin(), order_.end(), 0);
  trails_.assign(triangles_.size(), 0);
  nodes_.reserve(2 * triangles_.size());
  build(0, static_cast<int>(triangles_.size()), 0, 0);
  power_.resize(triangles_.size());
  power_prefix_.assign(triangles_.size() + 1, 0.0);
  for (size_t i = 0; i < triangles_.size(); ++i) power_[i] = triangle_power(triangles_[i]);
  for (size_t k = 0; k < order_.size(); ++k) power_prefix_[k + 1] = power_prefix_[k] + power_[order_[k]];
}

bool EmissiveLights::is_far_cluster(const Node& node, const Vector3f& p) const {
  return node.light < 0 && node.bounds.radius2 < kFarClusterSin * kFarClusterSin * (p - node.bounds.centre).squaredNorm();
}

int EmissiveLights::pick_by_power(const Node& node, float u) const {
  const double lo = power_prefix_[node.begin], hi = power_prefix_[node.end];
  const double target = lo + static_cast<double>(u) * (hi - lo);
  const auto first = power_prefix_.begin() + node.begin + 1, last = power_prefix_.begin() + node.end;
  const int k = static_cast<int>(std::upper_bound(first, last, target) - power_prefix_.begin()) - 1;
  return order_[std::clamp(k, node.begin, node.end - 1)];
}

float EmissiveLights::power_fraction(const Node& node, int index) const {
  const double total = power_prefix_[node.end] - power_prefix_[node.begin];
  return total > 0.0 ? static_cast<float>(power_[index] / total) : 0.f;
}

std::pair<int, LightBounds> EmissiveLights::build(int begin, int end, uint64_t trail, int depth) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  nodes_[index].begin = begin;
  nodes_[index].end = end;
  if (end - begin == 1) {
    const int light = order_[begin];
    const LightBounds bounds = LightBounds::of(triangles_[light]);
    nodes_[index].bounds = ImportanceBound::of(bounds);
    nodes_[index].light = light;
    trails_[light] = trail;
    return {index, bounds};
  }
  // A median split along the widest extent of the triangles' centroids: a
  // balanced tree, so a trail of 64 turns covers any scene.
  Eigen::AlignedBox3f centroids;
  const auto centroid = [&](int i) { return Vector3f((triangles_[i].a + triangles_[i].b + triangles_[i].c) / 3.f); };
  for (int i = begin; i < end; ++i) centroids.extend(centroid(order_[i]));
  int axis = 0;
  centroids.diagonal().maxCoeff(&axis);
  const int middle = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + middle, order_.begin() + end,
                   [&](int x, int y) { return centroid(x)[axis] < centroid(y)[axis]; });
  const LightBounds first = build(begin, middle, trail, depth + 1).second;
  const auto [second, second_bounds] = build(middle, end, trail | (uint64_t{1} << depth), depth + 1);
  const LightBounds bounds = first.merged(second_bounds);
  nodes_[index].second_child = second;
  nodes_[index].bounds = ImportanceBound::of(bounds);
  return {index, bounds};
}

int EmissiveLights::index_of(int mesh, int triangle) const {
  if (mesh < 0 || triangle < 0) return -1;
  const auto it = index_of_.find((static_cast<uint64_t>(mesh) << 32) | static_cast<uint32_t>(triangle));
  return it == index_of_.end() ? -1 : it->second;
}

EmissiveLights::Pick EmissiveLights::pick(const Vector3f& p, const Vector3f& n, float u) const {
  if (nodes_.empty()) return {};
  float pmf = 1.f;
  int node = 0;
  u = std::clamp(u, 0.f, kOneMinusEpsilon);
  while (nodes_[node].light < 0) {
    if (is_far_cluster(nodes_[node], p)) {
      const int light = pick_by_power(nodes_[node], u);
      pmf *= power_fraction(nodes_[node], light);
      return pmf > 0.f ? Pick{light, pmf} : Pick{};
    }
    const int first = node + 1, second = nodes_[node].second_child;
    const float i0 = nodes_[first].bounds.importance(p, n), i1 = nodes_[second].bounds.importance(p, n);
    if (!(i0 + i1 > 0.f) || !std::isfinite(i0 + i1)) return {};
    // The same expressions as pmf(), so that the two agree to the bit.
    const float p0 = i0 / (i0 + i1), p1 = i1 / (i0 + i1);
    if (u < p0) {
      node = first;
      pmf *= p0;
      u = std::min(u / p0, kOneMinusEpsilon);
    } else {
      node = second;
      pmf *= p1;
      u = std::min((u - p0) / (1.f - p0), kOneMinusEpsilon);
    }
  }
  // A child picked with a positive probability has a positive importance; a
  // root that is a leaf still needs its own.
  if (!(pmf > 0.f) || (node == 0 && !(nodes_[0].bounds.importance(p, n) > 0.f))) return {};
  return {nodes_[node].light, pmf};
}

float EmissiveLights::pmf(const Vector3f& p, const Vector3f& n, int index) const {
  if (index < 0 || index >= size()) return 0.f;
  float pmf = 1.f;
  int node = 0;
  for (int depth = 0; nodes_[node].light < 0; ++depth) {
    if (is_far_cluster(nodes_[node], p)) return pmf * power_fraction(nodes_[node], index);
    const int first = node + 1, second = nodes_[node].second_child;
    const float i0 = nodes_[first].bounds.importance(p, n), i1 = nodes_[second].bounds.importance(p, n);
    if (!(i0 + i1 > 0.f) || !std::isfinite(i0 + i1)) return 0.f;
    const bool take_second = (trails_[index] >> depth) & 1u;
    pmf *= take_second ? i1 / (i0 + i1) : i0 / (i0 + i1);
    node = take_second ? second : first;
  }
  if (node == 0 && !(nodes_[0].bounds.importance(p, n) > 0.f)) return 0.f;
  return pmf;
}

LightSample EmissiveLights::sample(int index, const Vector3f& from, float u1, float u2) const {
  LightSample out;
  if (index < 0 || index >= size()) return out;
  const EmissiveTriangle& t = triangles_[index];
  const Vector3d o = from.cast<double>(), a = t.a.cast<double>(), b = t.b.cast<double>(), c = t.c.cast<double>();
  const Vector3d normal = t.normal.cast<double>();
  const auto spherical = SphericalTriangle::seen_from(o, a, b, c);
  Vector3d to;
  double dist = 0.0;
  if (spherical) {
    to = spherical->sample(u1, u2);
    dist = (a - o).dot(normal) / to.dot(normal);  // where the direction meets the triangle's plane
  } else {
    const double su = std::sqrt(static_cast<double>(u1));
    const Vector3d point = (1.0 - su) * a + (u2 * su) * b + (su - u2 * su) * c;
    to = point - o;
    dist = to.norm();
    to /= dist;
  }
  if (!(dist > kMinTriangleLightDistance) || !std::isfinite(dist) || !to.allFinite()) return out;
  const double cos_light = std::abs(to.dot(normal));
  if (!(cos_light > kMinTriangleLightCosine)) return out;
  out.direction = to.cast<float>();
  out.distance = static_cast<float>(dist);
  out.radiance = t.emission;
  out.pdf = static_cast<float>(spherical ? 1.0 / spherical->solid_angle() : dist * dist / (cos_light * t.area));
  if (!std::isfinite(out.pdf)) out.pdf = 0.f;
  return out;
}

float EmissiveLights::pdf(int index, const Vector3f& from, const Vector3f& direction, float t) const {
  if (index < 0 || index >= size()) return 0.f;
  const EmissiveTriangle& tri = triangles_[index];
  const auto spherical = SphericalTriangle::seen_from(from.cast<double>(), tri.a.cast<double>(),
                                                      tri.b.cast<double>(), tri.c.cast<double>());
  if (spherical) return static_cast<float>(1.0 / spherical->solid_angle());
  const double cos_light = std::abs(static_cast<double>(direction.normalized().dot(tri.normal)));
  if (!(cos_light > kMinTriangleLightCosine)) return 0.f;
  const double pdf = static_cast<double>(t) * t / (cos_light * tri.area);
  return std::isfinite(pdf) ? static_cast<float>(pdf) : 0.f;
}

}  // namespace propcam::render::detail
