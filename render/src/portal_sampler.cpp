#include "portal_sampler.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace propcam::render::detail {
namespace {

AreaLight window_as_light(const Portal& p, bool front) {
  AreaLight light;
  light.corner = p.corner;
  // A one-sided light emits toward edge_u x edge_v: swapping the edges turns it.
  light.edge_u = front ? p.edge_u : p.edge_v;
  light.edge_v = front ? p.edge_v : p.edge_u;
  light.radiance = Eigen::Vector3f::Ones();
  return light;
}

}  // namespace

PortalSampler::PortalSampler(const std::vector<Portal>& portals) {
  for (const Portal& p : portals)
    if (p.valid())
      windows_.push_back({p.corner.cast<double>(), p.edge_u.cross(p.edge_v).cast<double>(),
                          AreaLightSampler(window_as_light(p, true)), AreaLightSampler(window_as_light(p, false))});
}

const AreaLightSampler& PortalSampler::Window::seen_from(const Eigen::Vector3f& from) const {
  return (from.cast<double>() - corner).dot(normal) >= 0.0 ? front : back;
}

LightSample PortalSampler::sample(const Eigen::Vector3f& from, float u1, float u2) const {
  LightSample out;
  if (windows_.empty()) return out;
  // The first number picks the window and, rescaled, samples within it.
  const float scaled = u1 * static_cast<float>(windows_.size());
  const size_t pick = std::min(windows_.size() - 1, static_cast<size_t>(std::max(0.f, scaled)));
  const float u1_within = std::clamp(scaled - static_cast<float>(pick), 0.f, std::nextafter(1.f, 0.f));
  const LightSample through = windows_[pick].seen_from(from).sample(from, u1_within, u2);
  if (!(through.pdf > 0.f)) return out;
  out.direction = through.direction;
  out.distance = std::numeric_limits<float>::infinity();
  out.pdf = pdf(from, out.direction);
  return out;
}

float PortalSampler::pdf(const Eigen::Vector3f& from, const Eigen::Vector3f& direction) const {
  if (windows_.empty()) return 0.f;
  double sum = 0.0;
  for (const Window& w : windows_) {
    float t = 0.f, p = 0.f;
    if (w.seen_from(from).intersect(from, direction, t, p)) sum += p;
  }
  const double density = sum / static_cast<double>(windows_.size());
  return std::isfinite(density) ? static_cast<float>(density) : 0.f;
}

}  // namespace propcam::render::detail
