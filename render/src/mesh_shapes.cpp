#include "propcam/render/mesh_shapes.h"

namespace propcam::render {

void add_quad(Mesh& mesh, const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
              const Eigen::Vector3f& d, int material, float metres_per_tile) {
  const int base = static_cast<int>(mesh.positions.size());
  const Eigen::Vector3f eu = (b - a), ev = (d - a);
  const float lu = eu.norm() / metres_per_tile, lv = ev.norm() / metres_per_tile;
  mesh.positions.insert(mesh.positions.end(), {a, b, c, d});
  mesh.uvs.insert(mesh.uvs.end(), {{0.f, lv}, {lu, lv}, {lu, 0.f}, {0.f, 0.f}});
  mesh.triangles.emplace_back(base, base + 1, base + 2);
  mesh.triangles.emplace_back(base, base + 2, base + 3);
  mesh.material_ids.insert(mesh.material_ids.end(), {material, material});
}

void add_box(Mesh& mesh, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, int material) {
  const float x0 = lo.x(), y0 = lo.y(), z0 = lo.z(), x1 = hi.x(), y1 = hi.y(), z1 = hi.z();
  using V = Eigen::Vector3f;
  add_quad(mesh, V(x0, y0, z1), V(x1, y0, z1), V(x1, y1, z1), V(x0, y1, z1), material, 1.f);  // +z
  add_quad(mesh, V(x1, y0, z0), V(x0, y0, z0), V(x0, y1, z0), V(x1, y1, z0), material, 1.f);  // -z
  add_quad(mesh, V(x1, y0, z1), V(x1, y0, z0), V(x1, y1, z0), V(x1, y1, z1), material, 1.f);  // +x
  add_quad(mesh, V(x0, y0, z0), V(x0, y0, z1), V(x0, y1, z1), V(x0, y1, z0), material, 1.f);  // -x
  add_quad(mesh, V(x0, y1, z1), V(x1, y1, z1), V(x1, y1, z0), V(x0, y1, z0), material, 1.f);  // +y
}

}  // namespace propcam::render
