// Random numbers and BSDFs used by the path tracer (internal to render/).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "propcam/render/mesh.h"

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

// Isotropic GGX (Trowbridge-Reitz) in the local frame (z = normal).
struct Ggx {
  float alpha;
  float D(const Eigen::Vector3f& h) const {
    const float c2 = h.z() * h.z();
    const float a2 = alpha * alpha;
    const float d = c2 * (a2 - 1.f) + 1.f;
    return a2 / (kPi * d * d);
  }
  float G1(const Eigen::Vector3f& v) const {
    const float c = std::abs(v.z());
    const float a2 = alpha * alpha;
    return 2.f * c / (c + std::sqrt(a2 + (1.f - a2) * c * c));
  }
  Eigen::Vector3f sample_half(float u1, float u2) const {
    const float tan2 = alpha * alpha * u1 / std::max(1.f - u1, 1e-7f);
    const float cos_t = 1.f / std::sqrt(1.f + tan2);
    const float sin_t = std::sqrt(std::max(0.f, 1.f - cos_t * cos_t));
    const float phi = 2.f * kPi * u2;
    return {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t};
  }
};

// A material evaluated at one point, in the local shading frame.
class Bsdf {
 public:
  Bsdf(const Material& m, const Eigen::Vector3f& albedo) : type_(m.type), albedo_(albedo) {
    ggx_.alpha = std::clamp(m.roughness, 0.02f, 1.f);
    specular_ = std::clamp(m.specular, 0.f, 1.f);
    // Probability of sampling the specular lobe: always some, more for shiny bases.
    spec_prob_ = type_ == Material::Type::Metal ? 1.f
                 : type_ == Material::Type::Glossy ? std::clamp(0.15f + 2.f * specular_, 0.15f, 0.6f)
                                                   : 0.f;
  }

  Eigen::Vector3f eval(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const {
    if (wo.z() <= 0.f || wi.z() <= 0.f) return Eigen::Vector3f::Zero();
    Eigen::Vector3f f = Eigen::Vector3f::Zero();
    if (type_ != Material::Type::Metal) {
      const float coat = type_ == Material::Type::Glossy ? 1.f - specular_ : 1.f;
      f += albedo_ * (kInvPi * coat);
    }
    if (spec_prob_ > 0.f) f += specular(wo, wi);
    return f;
  }

  float pdf(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const {
    if (wo.z() <= 0.f || wi.z() <= 0.f) return 0.f;
    float p = (1.f - spec_prob_) * wi.z() * kInvPi;
    if (spec_prob_ > 0.f) {
      const Eigen::Vector3f h = (wo + wi).normalized();
      p += spec_prob_ * ggx_.D(h) * h.z() / (4.f * std::max(wo.dot(h), 1e-7f));
    }
    return p;
  }

  // Returns false when no direction was produced.
  bool sample(const Eigen::Vector3f& wo, float u0, float u1, float u2, Eigen::Vector3f& wi) const {
    if (wo.z() <= 0.f) return false;
    if (u0 < spec_prob_) {
      const Eigen::Vector3f h = ggx_.sample_half(u1, u2);
      wi = 2.f * wo.dot(h) * h - wo;
    } else {
      wi = cosine_hemisphere(u1, u2);
    }
    return wi.z() > 0.f;
  }

 private:
  Eigen::Vector3f specular(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const {
    const Eigen::Vector3f h = (wo + wi).normalized();
    const float fw = schlick_weight(wo.dot(h));
    const Eigen::Vector3f f0 = type_ == Material::Type::Metal ? albedo_ : Eigen::Vector3f::Constant(specular_);
    const Eigen::Vector3f fresnel = f0 + (Eigen::Vector3f::Ones() - f0) * fw;
    const float g = ggx_.G1(wo) * ggx_.G1(wi);
    return fresnel * (ggx_.D(h) * g / (4.f * wo.z() * wi.z()));
  }

  Material::Type type_;
  Eigen::Vector3f albedo_;
  Ggx ggx_{0.25f};
  float specular_ = 0.04f;
  float spec_prob_ = 0.f;
};

inline float power_heuristic(float a, float b) {
  const float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0.f ? a2 / (a2 + b2) : 0.f;
}

}  // namespace propcam::render::detail
