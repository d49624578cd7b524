// Random numbers, frames and sampling helpers used by the path tracer (internal
// to render/); the BSDFs are in bsdf.h.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

namespace propcam::render::detail {

constexpr float kPi = std::numbers::pi_v<float>;
constexpr float kInvPi = 1.f / kPi;

// PCG32: small state, good statistics, and cheap to copy so that two paths
// can consume identical random streams (the differential render relies on it).
class Rng {
 public:
  Rng(uint64_t seed, uint64_t stream) : inc_((stream << 1u) | 1u) {
    next();
    state_ += seed;
    next();
  }
  uint32_t next() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ULL + inc_;
    const auto xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
    const auto rot = static_cast<uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31u));
  }
  float uniform() { return std::min(static_cast<float>(next() >> 8) * 0x1p-24f, 0x1.fffffep-1f); }

 private:
  uint64_t state_ = 0;
  uint64_t inc_;
};

inline uint64_t mix_seed(uint64_t a, uint64_t b) {
  uint64_t z = a * 0x9E3779B97F4A7C15ULL + b + 0x632BE59BD9B4E019ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Orthonormal frame around a unit normal (Duff et al. 2017).
struct Frame {
  Eigen::Vector3f t, b, n;
  explicit Frame(const Eigen::Vector3f& normal) : n(normal) {
    const float sign = std::copysign(1.f, n.z());
    const float a = -1.f / (sign + n.z());
    const float bb = n.x() * n.y() * a;
    t = {1.f + sign * n.x() * n.x() * a, sign * bb, -sign * n.x()};
    b = {bb, sign + n.y() * n.y() * a, -n.y()};
  }
  Eigen::Vector3f to_local(const Eigen::Vector3f& v) const { return {v.dot(t), v.dot(b), v.dot(n)}; }
  Eigen::Vector3f to_world(const Eigen::Vector3f& v) const { return v.x() * t + v.y() * b + v.z() * n; }
};

inline Eigen::Vector3f cosine_hemisphere(float u1, float u2) {
  const float r = std::sqrt(u1), phi = 2.f * kPi * u2;
  return {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.f, 1.f - u1))};
}

inline float schlick_weight(float cos_theta) {
  const float m = std::clamp(1.f - cos_theta, 0.f, 1.f);
  return (m * m) * (m * m) * m;
}

// MIS weight a^2 / (a^2 + b^2) of the strategy with density a, written as a
// ratio so that large densities (near-delta lobes, the sun) cannot overflow.
inline float power_heuristic(float a, float b) {
  if (std::isinf(a)) return std::isinf(b) ? 0.5f : 1.f;
  if (std::isinf(b)) return 0.f;
  if (!(a > 0.f)) return 0.f;
  if (!(b > 0.f)) return 1.f;
  if (a >= b) {
    const float r = b / a;
    return 1.f / (1.f + r * r);
  }
  const float r = a / b;
  return r * r / (1.f + r * r);
}

}  // namespace propcam::render::detail
