// Triangle meshes with per-triangle materials: the currency between prop
// generators, mesh loaders, the scene reconstruction and the path tracer.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace propcam::render {

// Surface reflectance model. All colours are linear RGB in [0,1].
//   Diffuse     Lambertian: albedo / pi.
//   Plastic     (alias Glossy) a diffuse base under a smooth-to-rough GGX
//               dielectric coat: the coat reflects F(theta) (exact dielectric
//               Fresnel of the coat IOR), the base receives what it transmits.
//               `specular` is the coat's reflectance at normal incidence
//               (0.04 is IOR 1.5; see coat_ior()).
//   Metal       rough conductor: GGX with Schlick's Fresnel, F0 = albedo (colour).
//   Dielectric  rough glass (Walter et al. 2007): GGX reflection and
//               refraction with index `ior` inside relative to outside, total
//               internal reflection; clear (albedo ignored). The side a ray
//               enters from is the one the triangle winding faces
//               (counter-clockwise = outside), so meshes must be closed and
//               outward-wound.
//   Emissive    a light's visible surface: emission radiance, no reflection.
// Roughness is the GGX alpha, clamped to [kMinRoughness, 1]; 0 gives a
// near-mirror lobe (never NaN).
struct Material {
  enum class Type { Diffuse, Plastic, Metal, Emissive, Dielectric, Glossy = Plastic };
  Type type = Type::Diffuse;
  std::string name;
  Eigen::Vector3f albedo{0.8f, 0.8f, 0.8f};  // diffuse colour; base reflectance (F0) for Metal
  float specular = 0.04f;                    // Plastic: reflectance of the clear coat at normal incidence
  float roughness = 0.25f;                   // GGX alpha for Plastic, Metal and Dielectric
  float ior = 1.5f;                          // Dielectric: index of refraction (inside / outside)
  Eigen::Vector3f emission{0.f, 0.f, 0.f};   // radiance of an Emissive surface (W/sr/m^2, relative)
  // Optional texture (CV_32FC3, linear RGB) multiplying albedo, looked up at the vertex uvs.
  std::shared_ptr<const cv::Mat> texture;

  // The plastic coat's index of refraction, from `specular` = ((n-1)/(n+1))^2.
  float coat_ior() const;
};

// The smallest GGX alpha the BSDFs use: below it the lobe is narrower than
// float precision resolves in a half vector, and D's peak 1/(pi alpha^2) grows
// toward overflow. Shared by every microfacet material.
constexpr float kMinRoughness = 1e-3f;
// Coat reflectance at normal incidence is kept below this (an IOR of ~37):
// a coat that reflects everything would hide its base and make coat_ior() infinite.
constexpr float kMaxCoatSpecular = 0.9f;

// "Plastic" for both Plastic and Glossy (the same type).
const char* to_string(Material::Type type);
// diffuse | plastic | glossy (= plastic) | metal | conductor (= metal) |
// dielectric | glass (= dielectric) | emissive; throws std::invalid_argument on unknown.
Material::Type material_type_from_string(const std::string& name);

struct Mesh {
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3f> normals;  // per vertex; empty means flat shading
  std::vector<Eigen::Vector2f> uvs;      // per vertex; empty means no texture lookup
  std::vector<Eigen::Vector3i> triangles;
  std::vector<int> material_ids;         // per triangle, index into materials
  std::vector<Material> materials;

  bool empty() const { return triangles.empty(); }
  Eigen::AlignedBox3f bounds() const;
  // Appends `other`, remapping its material ids after this mesh's materials.
  void append(const Mesh& other);
  // Applies an affine transform to positions and (inverse-transpose) to normals.
  void transform(const Eigen::Affine3f& xf);
  // Throws std::runtime_error naming the first inconsistency (index out of range,
  // non-finite position, array sizes that disagree).
  void validate() const;
  // Fills per-vertex normals by area-weighted averaging of face normals.
  void compute_vertex_normals();
};

}  // namespace propcam::render
