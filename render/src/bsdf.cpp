#include "bsdf.h"

#include <algorithm>
#include <cmath>

#include "sampling.h"

namespace propcam::render::detail {
namespace {

using Eigen::Vector3f;

// Microfacet terms divide by both cosines; below this they overflow before
// the masking term brings them to 0. Directions this close to the tangent
// plane (a set of measure ~1e-6) get f = 0 and pdf = 0 instead.
constexpr float kMinCosine = 1e-6f;
// wo + wi (or wo + eta*wi) shorter than this has no meaningful direction: the
// half vector is undefined, the configuration gets f = 0.
constexpr float kMinHalfLength = 1e-6f;
// An index-matched interface (ior = 1) makes the refraction half vector
// wo + eta*wi vanish; indices closer to 1 than this are moved to 1 +/- it.
constexpr float kMinIorContrast = 1e-3f;
// Plastic picks its coat lobe with a probability from the Fresnel and base
// weights, kept within these bounds so neither lobe is ever starved (MIS
// then covers whichever estimate is poor).
constexpr float kMinCoatProbability = 0.25f;
constexpr float kMaxCoatProbability = 0.9f;
// Midpoint steps for the hemispherical mean of the coat's Fresnel (smooth in
// the cosine; 64 steps are accurate to ~1e-4).
constexpr int kMeanFresnelSteps = 64;
// Smith Lambda is capped here for directions in the tangent plane (G -> 0).
constexpr float kMaxLambda = 1e12f;

float finite_or(float v, float fallback) { return std::isfinite(v) ? v : fallback; }

Vector3f reflect(const Vector3f& wo, const Vector3f& h) { return 2.f * wo.dot(h) * h - wo; }

// The cosine-weighted mean over the hemisphere, 2 * integral F(mu) mu dmu.
float mean_fresnel(float eta) {
  thread_local float cached_eta = -1.f;
  thread_local float cached_mean = 0.f;
  if (eta == cached_eta) return cached_mean;
  double sum = 0.0;
  for (int i = 0; i < kMeanFresnelSteps; ++i) {
    const double mu = (i + 0.5) / kMeanFresnelSteps;
    sum += fresnel_dielectric(static_cast<float>(mu), eta) * mu;
  }
  cached_eta = eta;
  cached_mean = static_cast<float>(2.0 * sum / kMeanFresnelSteps);
  return cached_mean;
}

Vector3f schlick(const Vector3f& f0, float cos_theta) {
  return f0 + (Vector3f::Ones() - f0) * schlick_weight(cos_theta);
}

}  // namespace

float Ggx::D(const Vector3f& h) const {
  if (!(h.z() > 0.f)) return 0.f;
  // alpha^2 / (pi (alpha^2 cos^2 + sin^2)^2): with sin^2 taken from x and y
  // directly, precise even for near-delta lobes where 1 - cos^2 would cancel.
  const float a2 = alpha * alpha;
  const float s2 = h.x() * h.x() + h.y() * h.y();
  const float d = a2 * h.z() * h.z() + s2;
  return d > 0.f ? a2 / (kPi * d * d) : 0.f;
}

float Ggx::lambda(const Vector3f& w) const {
  const float c2 = w.z() * w.z();
  const float s2 = w.x() * w.x() + w.y() * w.y();
  if (!(c2 > 0.f)) return kMaxLambda;
  const float t = alpha * alpha * s2 / c2;  // alpha^2 tan^2
  if (!(t < kMaxLambda)) return kMaxLambda;
  return 0.5f * t / (std::sqrt(1.f + t) + 1.f);  // (sqrt(1 + t) - 1) / 2 without cancellation
}

Vector3f Ggx::sample_visible(const Vector3f& wo, float u1, float u2) const {
  // Stretch to the unit-roughness configuration, sample the projected
  // hemisphere seen from there, unstretch.
  const Vector3f v = Vector3f(alpha * wo.x(), alpha * wo.y(), wo.z()).normalized();
  const float len2 = v.x() * v.x() + v.y() * v.y();
  const Vector3f t1 = len2 > 0.f ? Vector3f(-v.y(), v.x(), 0.f) / std::sqrt(len2) : Vector3f(1.f, 0.f, 0.f);
  const Vector3f t2 = v.cross(t1);
  const float r = std::sqrt(u1), phi = 2.f * kPi * u2;
  const float p1 = r * std::cos(phi);
  const float s = 0.5f * (1.f + v.z());
  const float p2 = (1.f - s) * std::sqrt(std::max(0.f, 1.f - p1 * p1)) + s * r * std::sin(phi);
  const Vector3f n = p1 * t1 + p2 * t2 + std::sqrt(std::max(0.f, 1.f - p1 * p1 - p2 * p2)) * v;
  return Vector3f(alpha * n.x(), alpha * n.y(), std::max(n.z(), 0.f)).normalized();
}

float Ggx::visible_pdf(const Vector3f& wo, const Vector3f& h) const {
  if (!(wo.z() > 0.f)) return 0.f;
  return G1(wo) * std::max(0.f, wo.dot(h)) * D(h) / wo.z();
}

float fresnel_dielectric(float cos_i, float eta) {
  cos_i = std::clamp(finite_or(cos_i, 0.f), 0.f, 1.f);
  const float sin2_t = (1.f - cos_i * cos_i) / (eta * eta);
  if (!(sin2_t < 1.f)) return 1.f;  // total internal reflection
  const float cos_t = std::sqrt(1.f - sin2_t);
  const float r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const float r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return std::clamp(0.5f * (r_parallel * r_parallel + r_perpendicular * r_perpendicular), 0.f, 1.f);
}

Bsdf::Bsdf(const Material& material, const Vector3f& albedo, bool entering) : type_(material.type) {
  for (int c = 0; c < 3; ++c) albedo_[c] = std::clamp(finite_or(albedo[c], 0.f), 0.f, 1.f);
  ggx_.alpha = std::clamp(finite_or(material.roughness, 1.f), kMinRoughness, 1.f);
  if (type_ == Material::Type::Dielectric) {
    float ior = finite_or(material.ior, 1.5f);
    if (!(ior > 0.f)) ior = 1.5f;
    if (std::abs(ior - 1.f) < kMinIorContrast) ior = ior < 1.f ? 1.f - kMinIorContrast : 1.f + kMinIorContrast;
    eta_ = entering ? ior : 1.f / ior;
  } else if (type_ == Material::Type::Plastic) {
    coat_eta_ = std::max(material.coat_ior(), 1.f);
    coat_mean_fresnel_ = mean_fresnel(coat_eta_);
  }
}

Vector3f Bsdf::eval(const Vector3f& wo, const Vector3f& wi) const {
  if (!(wo.z() > 0.f) || !wo.allFinite() || !wi.allFinite()) return Vector3f::Zero();
  switch (type_) {
    case Material::Type::Diffuse: return wi.z() > 0.f ? Vector3f(albedo_ * kInvPi) : Vector3f::Zero();
    case Material::Type::Plastic: return eval_plastic(wo, wi);
    case Material::Type::Metal: return eval_conductor(wo, wi);
    case Material::Type::Dielectric: return eval_dielectric(wo, wi);
    case Material::Type::Emissive: break;
  }
  return Vector3f::Zero();
}

float Bsdf::pdf(const Vector3f& wo, const Vector3f& wi) const {
  if (!(wo.z() > 0.f) || !wo.allFinite() || !wi.allFinite()) return 0.f;
  const auto specular_pdf = [&]() -> float {
    if (wo.z() < kMinCosine || wi.z() < kMinCosine) return 0.f;
    const Vector3f sum = wo + wi;
    const float len = sum.norm();
    if (len < kMinHalfLength) return 0.f;
    const Vector3f h = sum / len;
    const float cos_oh = wo.dot(h);
    return cos_oh > 0.f ? ggx_.visible_pdf(wo, h) / (4.f * cos_oh) : 0.f;
  };
  switch (type_) {
    case Material::Type::Diffuse: return wi.z() > 0.f ? wi.z() * kInvPi : 0.f;
    case Material::Type::Plastic: {
      if (!(wi.z() > 0.f)) return 0.f;
      const float p = plastic_specular_probability(wo);
      return p * specular_pdf() + (1.f - p) * wi.z() * kInvPi;
    }
    case Material::Type::Metal: return specular_pdf();
    case Material::Type::Dielectric: return pdf_dielectric(wo, wi);
    case Material::Type::Emissive: break;
  }
  return 0.f;
}

bool Bsdf::sample(const Vector3f& wo, float u0, float u1, float u2, BsdfSample& out) const {
  if (!(wo.z() > 0.f) || !wo.allFinite()) return false;
  Vector3f wi = Vector3f::Zero();
  bool refracted = false;
  switch (type_) {
    case Material::Type::Diffuse: wi = cosine_hemisphere(u1, u2); break;
    case Material::Type::Plastic:
      if (u0 < plastic_specular_probability(wo)) wi = reflect(wo, ggx_.sample_visible(wo, u1, u2));
      else wi = cosine_hemisphere(u1, u2);
      break;
    case Material::Type::Metal: wi = reflect(wo, ggx_.sample_visible(wo, u1, u2)); break;
    case Material::Type::Dielectric: {
      const Vector3f h = ggx_.sample_visible(wo, u1, u2);
      const float cos_oh = wo.dot(h);
      if (!(cos_oh > 0.f)) return false;
      if (u0 < fresnel_dielectric(cos_oh, eta_)) {
        wi = reflect(wo, h);
      } else {
        const float sin2_t = (1.f - cos_oh * cos_oh) / (eta_ * eta_);
        if (!(sin2_t < 1.f)) return false;
        const float cos_t = std::sqrt(1.f - sin2_t);
        wi = -wo / eta_ + (cos_oh / eta_ - cos_t) * h;
        refracted = true;
      }
      break;
    }
    case Material::Type::Emissive: return false;
  }
  const float len = wi.norm();
  if (!(len > 0.f) || !std::isfinite(len)) return false;
  wi /= len;
  // A reflection that ends below the surface (or a refraction above it) is a
  // lost sample: its direction would be counted under the other lobe's pdf.
  if (refracted ? !(wi.z() < 0.f) : !(wi.z() > 0.f)) return false;
  out.wi = wi;
  out.pdf = pdf(wo, wi);
  if (!(out.pdf > 0.f) || !std::isfinite(out.pdf)) return false;
  out.f = eval(wo, wi);
  out.transmitted = wi.z() < 0.f;
  return out.f.allFinite();
}

float Bsdf::plastic_specular_probability(const Vector3f& wo) const {
  const float coat = fresnel_dielectric(wo.z(), coat_eta_);
  const float base = (1.f - coat) * albedo_.mean();
  const float p = coat + base > 0.f ? coat / (coat + base) : 1.f;
  return std::clamp(p, kMinCoatProbability, kMaxCoatProbability);
}

Vector3f Bsdf::eval_conductor(const Vector3f& wo, const Vector3f& wi) const {
  if (wo.z() < kMinCosine || wi.z() < kMinCosine) return Vector3f::Zero();
  const Vector3f sum = wo + wi;
  const float len = sum.norm();
  if (len < kMinHalfLength) return Vector3f::Zero();
  const Vector3f h = sum / len;
  const float scale = ggx_.D(h) * ggx_.G2(wo, wi) / (4.f * wo.z() * wi.z());
  return schlick(albedo_, wo.dot(h)) * scale;
}

Vector3f Bsdf::eval_plastic(const Vector3f& wo, const Vector3f& wi) const {
  if (!(wi.z() > 0.f)) return Vector3f::Zero();
  // Base: light enters through the coat (1 - F), scatters diffusely and
  // leaves through it (1 - F); dividing by 1 - mean F makes a white base
  // under a smooth coat reflect exactly 1 - F(wo) (symmetric in wo, wi).
  const float into = 1.f - fresnel_dielectric(wi.z(), coat_eta_);
  const float out = 1.f - fresnel_dielectric(wo.z(), coat_eta_);
  Vector3f f = albedo_ * (kInvPi * into * out / (1.f - coat_mean_fresnel_));
  if (wo.z() < kMinCosine || wi.z() < kMinCosine) return f;
  const Vector3f sum = wo + wi;
  const float len = sum.norm();
  if (len < kMinHalfLength) return f;
  const Vector3f h = sum / len;
  const float coat = fresnel_dielectric(wo.dot(h), coat_eta_) * ggx_.D(h) * ggx_.G2(wo, wi) / (4.f * wo.z() * wi.z());
  return f + Vector3f::Constant(coat);
}

Vector3f Bsdf::eval_dielectric(const Vector3f& wo, const Vector3f& wi) const {
  if (wo.z() < kMinCosine || std::abs(wi.z()) < kMinCosine) return Vector3f::Zero();
  if (wi.z() > 0.f) {
    const Vector3f sum = wo + wi;
    const float len = sum.norm();
    if (len < kMinHalfLength) return Vector3f::Zero();
    const Vector3f h = sum / len;
    const float value = fresnel_dielectric(wo.dot(h), eta_) * ggx_.D(h) * ggx_.G2(wo, wi) / (4.f * wo.z() * wi.z());
    return Vector3f::Constant(value);
  }
  // Refraction (Walter et al. 2007, eq. 21, for radiance): with eta = n_i/n_o,
  // f = (1-F) D G |wi.h| |wo.h| / (|wi.n| |wo.n| (wo.h + eta wi.h)^2).
  Vector3f h = wo + eta_ * wi;
  const float len = h.norm();
  if (len < kMinHalfLength) return Vector3f::Zero();
  h /= len;
  if (h.z() < 0.f) h = -h;
  const float cos_oh = wo.dot(h), cos_ih = wi.dot(h);
  if (!(cos_oh > 0.f) || !(cos_ih < 0.f)) return Vector3f::Zero();
  const float fresnel = fresnel_dielectric(cos_oh, eta_);
  const float denom = cos_oh + eta_ * cos_ih;
  const float denom2 = denom * denom;
  if (!(denom2 > 0.f)) return Vector3f::Zero();
  const float value =
      (1.f - fresnel) * ggx_.D(h) * ggx_.G2(wo, wi) * std::abs(cos_ih) * cos_oh / (wo.z() * std::abs(wi.z()) * denom2);
  return Vector3f::Constant(value);
}

float Bsdf::pdf_dielectric(const Vector3f& wo, const Vector3f& wi) const {
  if (wo.z() < kMinCosine || std::abs(wi.z()) < kMinCosine) return 0.f;
  if (wi.z() > 0.f) {
    const Vector3f sum = wo + wi;
    const float len = sum.norm();
    if (len < kMinHalfLength) return 0.f;
    const Vector3f h = sum / len;
    const float cos_oh = wo.dot(h);
    if (!(cos_oh > 0.f)) return 0.f;
    return ggx_.visible_pdf(wo, h) / (4.f * cos_oh) * fresnel_dielectric(cos_oh, eta_);
  }
  Vector3f h = wo + eta_ * wi;
  const float len = h.norm();
  if (len < kMinHalfLength) return 0.f;
  h /= len;
  if (h.z() < 0.f) h = -h;
  const float cos_oh = wo.dot(h), cos_ih = wi.dot(h);
  if (!(cos_oh > 0.f) || !(cos_ih < 0.f)) return 0.f;
  const float denom = cos_oh + eta_ * cos_ih;
  const float denom2 = denom * denom;
  if (!(denom2 > 0.f)) return 0.f;
  const float dh_dwi = eta_ * eta_ * std::abs(cos_ih) / denom2;
  return ggx_.visible_pdf(wo, h) * (1.f - fresnel_dielectric(cos_oh, eta_)) * dh_dwi;
}

}  // namespace propcam::render::detail
