#include "propcam/render/mesh.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace propcam::render {

const char* to_string(Material::Type type) {
  switch (type) {
    case Material::Type::Diffuse: return "diffuse";
    case Material::Type::Plastic: return "plastic";
    case Material::Type::Metal: return "metal";
    case Material::Type::Emissive: return "emissive";
    case Material::Type::Dielectric: return "dielectric";
  }
  return "diffuse";
}

Material::Type material_type_from_string(const std::string& name) {
  if (name == "diffuse") return Material::Type::Diffuse;
  if (name == "plastic" || name == "glossy") return Material::Type::Plastic;
  if (name == "metal" || name == "conductor") return Material::Type::Metal;
  if (name == "dielectric" || name == "glass") return Material::Type::Dielectric;
  if (name == "emissive") return Material::Type::Emissive;
  throw std::invalid_argument("unknown material '" + name +
                              "' (expected diffuse|plastic|glossy|metal|dielectric|glass|emissive)");
}

float Material::coat_ior() const {
  const float f0 = std::isfinite(specular) ? std::clamp(specular, 0.f, kMaxCoatSpecular) : 0.04f;
  const float r = std::sqrt(f0);
  return (1.f + r) / (1.f - r);
}

Eigen::AlignedBox3f Mesh::bounds() const {
  Eigen::AlignedBox3f box;
  for (const auto& p : positions) box.extend(p);
  return box;
}

void Mesh::append(const Mesh& other) {
  const int vertex_offset = static_cast<int>(positions.size());
  const int material_offset = static_cast<int>(materials.size());
  const bool had_normals = !normals.empty() || positions.empty();
  const bool had_uvs = !uvs.empty() || positions.empty();
  // Keep per-vertex arrays aligned: fill missing attributes with neutral values.
  if (!other.normals.empty() && !had_normals) normals.assign(positions.size(), Eigen::Vector3f::Zero());
  if (!other.uvs.empty() && !had_uvs) uvs.assign(positions.size(), Eigen::Vector2f::Zero());
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  if (!normals.empty() || !other.normals.empty()) {
    if (other.normals.empty()) normals.resize(positions.size(), Eigen::Vector3f::Zero());
    else normals.insert(normals.end(), other.normals.begin(), other.normals.end());
  }
  if (!uvs.empty() || !other.uvs.empty()) {
    if (other.uvs.empty()) uvs.resize(positions.size(), Eigen::Vector2f::Zero());
    else uvs.insert(uvs.end(), other.uvs.begin(), other.uvs.end());
  }
  for (const auto& t : other.triangles) triangles.push_back(t + Eigen::Vector3i::Constant(vertex_offset));
  for (int id : other.material_ids) material_ids.push_back(id + material_offset);
  materials.insert(materials.end(), other.materials.begin(), other.materials.end());
}

void Mesh::transform(const Eigen::Affine3f& xf) {
  const Eigen::Matrix3f normal_matrix = xf.linear().inverse().transpose();
  for (auto& p : positions) p = xf * p;
  for (auto& n : normals) {
    n = normal_matrix * n;
    const float len = n.norm();
    if (len > 0.f) n /= len;
  }
}

void Mesh::validate() const {
  const auto nv = static_cast<int>(positions.size());
  if (!normals.empty() && static_cast<int>(normals.size()) != nv)
    throw std::runtime_error("mesh: normals count differs from positions count");
  if (!uvs.empty() && static_cast<int>(uvs.size()) != nv)
    throw std::runtime_error("mesh: uvs count differs from positions count");
  if (material_ids.size() != triangles.size())
    throw std::runtime_error("mesh: material_ids count differs from triangle count");
  for (const auto& p : positions)
    if (!p.allFinite()) throw std::runtime_error("mesh: non-finite vertex position");
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k)
      if (t[k] < 0 || t[k] >= nv) throw std::runtime_error("mesh: triangle index out of range");
  for (int id : material_ids)
    if (id < 0 || id >= static_cast<int>(materials.size()))
      throw std::runtime_error("mesh: material id out of range");
}

void Mesh::compute_vertex_normals() {
  normals.assign(positions.size(), Eigen::Vector3f::Zero());
  for (const auto& t : triangles) {
    const Eigen::Vector3f n = (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]);
    for (int k = 0; k < 3; ++k) normals[t[k]] += n;  // |n| = 2*area: area weighting
  }
  for (auto& n : normals) {
    const float len = n.norm();
    n = len > 1e-20f ? Eigen::Vector3f(n / len) : Eigen::Vector3f(0.f, 1.f, 0.f);
  }
}

}  // namespace propcam::render
