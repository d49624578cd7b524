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
struct Material {
  enum class Type { Diffuse, Glossy, Metal, Emissive };
  Type type = Type::Diffuse;
  std::string name;
  Eigen::Vector3f albedo{0.8f, 0.8f, 0.8f};  // diffuse colour; base reflectance (F0) for Metal
  float specular = 0.04f;                    // Glossy: reflectance of the clear coat at normal incidence
  float roughness = 0.25f;                   // GGX alpha for Glossy and Metal, clamped to [0.02, 1]
  Eigen::Vector3f emission{0.f, 0.f, 0.f};   // radiance of an Emissive surface (W/sr/m^2, relative)
  // Optional texture (CV_32FC3, linear RGB) multiplying albedo, looked up at the vertex uvs.
  std::shared_ptr<const cv::Mat> texture;
};

const char* to_string(Material::Type type);
Material::Type material_type_from_string(const std::string& name);  // throws on unknown

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
