// BSDFs of the prop and background materials (internal to render/).
//
// Everything is in the local shading frame: z is the shading normal on the
// side the path arrives from, so wo.z > 0 for every valid query. Directions
// are unit vectors pointing away from the surface; wo toward the camera (the
// path's previous vertex), wi toward the light. Reflection has wi.z > 0,
// transmission (Dielectric only) wi.z < 0.
//
// eval() is f(wo, wi) without the cosine; pdf() the solid-angle density of
// sample() for wi; sample() returns a direction with its f and pdf, equal to
// eval() and pdf() for that direction. Transmission is for radiance transport:
// f includes the 1/eta^2 of radiance crossing into another medium, so f is not
// symmetric across the interface (reflection parts are reciprocal).
//
// No method returns NaN or Inf for any unit input: zero cosines, degenerate half
// vectors and pdf 0 give f = 0, pdf = 0, or a failed sample.
#pragma once

#include <Eigen/Core>

#include "propcam/render/mesh.h"

namespace propcam::render::detail {

// Isotropic GGX (Trowbridge-Reitz) with Smith masking, in the local frame.
struct Ggx {
  float alpha = 0.25f;  // >= kMinRoughness

  // Normal distribution for a half vector h (any length-one h; 0 below the surface).
  float D(const Eigen::Vector3f& h) const;
  // Smith Lambda for a direction (masking of the side it looks from).
  float lambda(const Eigen::Vector3f& w) const;
  float G1(const Eigen::Vector3f& w) const { return 1.f / (1.f + lambda(w)); }
  // Height-correlated masking-shadowing.
  float G2(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const {
    return 1.f / (1.f + lambda(wo) + lambda(wi));
  }
  // A microfacet normal visible from wo (wo.z > 0), Heitz 2018; density visible_pdf().
  Eigen::Vector3f sample_visible(const Eigen::Vector3f& wo, float u1, float u2) const;
  float visible_pdf(const Eigen::Vector3f& wo, const Eigen::Vector3f& h) const;
};

// Unpolarised Fresnel reflectance of a dielectric interface for a ray arriving
// with cosine cos_i >= 0 to the normal on the side of index n_i; eta = n_t / n_i.
// Returns 1 under total internal reflection.
float fresnel_dielectric(float cos_i, float eta);

struct BsdfSample {
  Eigen::Vector3f wi = Eigen::Vector3f::Zero();
  Eigen::Vector3f f = Eigen::Vector3f::Zero();
  float pdf = 0.f;
  bool transmitted = false;
};

class Bsdf {
 public:
  // `albedo` is the material's albedo times its texture at the point.
  // `entering`: the path arrives from the side the surface faces (outside);
  // only Dielectric uses it, to choose eta = ior (entering) or 1/ior (leaving).
  Bsdf(const Material& material, const Eigen::Vector3f& albedo, bool entering = true);

  Eigen::Vector3f eval(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const;
  float pdf(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const;
  // Uses three uniform numbers in [0,1); returns false when no direction was produced.
  bool sample(const Eigen::Vector3f& wo, float u0, float u1, float u2, BsdfSample& out) const;

  bool has_transmission() const { return type_ == Material::Type::Dielectric; }
  // Index on the far side over the index on the side of wo (Dielectric), else 1.
  float eta() const { return eta_; }

 private:
  Eigen::Vector3f eval_conductor(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const;
  Eigen::Vector3f eval_plastic(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const;
  Eigen::Vector3f eval_dielectric(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const;
  float pdf_dielectric(const Eigen::Vector3f& wo, const Eigen::Vector3f& wi) const;
  float plastic_specular_probability(const Eigen::Vector3f& wo) const;

  Material::Type type_;
  Eigen::Vector3f albedo_;
  Ggx ggx_;
  float eta_ = 1.f;               // Dielectric: relative index across the surface
  float coat_eta_ = 1.5f;         // Plastic: coat index
  float coat_mean_fresnel_ = 0.f; // Plastic: cosine-weighted hemispherical mean of the coat's Fresnel
};

}  // namespace propcam::render::detail
