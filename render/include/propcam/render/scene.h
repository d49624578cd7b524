// The Embree scene: background geometry (the reconstructed photo, or a
// synthetic room) and prop geometry, kept so that rays can be traced with or
// without the props. Differential rendering needs both worlds.
//
// Two levels: the background's BVH is built once; the world with props
// instances it next to one instance per prop. Moving a prop
// (set_prop_transform) rebuilds only the top level, never the background.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "propcam/render/mesh.h"

namespace propcam::render {

namespace detail {
class EmissiveLights;  // emissive_lights.h (internal)
}

enum class Layer { Background, Prop };

struct RayHit {
  float t = 0.f;
  int mesh = -1;      // index into Scene meshes
  int triangle = -1;
  float u = 0.f, v = 0.f;  // barycentrics of vertices 1 and 2
};

// What a shader needs at a hit point.
struct SurfacePoint {
  Eigen::Vector3f position;
  Eigen::Vector3f geometric_normal;  // unit, facing the incoming ray
  Eigen::Vector3f shading_normal;    // unit, same hemisphere as geometric_normal
  // The ray arrived on the side the triangle's counter-clockwise winding faces
  // (outside of a closed, outward-wound mesh); dielectrics refract with ior
  // when true, with 1/ior when false.
  bool front_face = true;
  const Material* material = nullptr;
  Eigen::Vector3f albedo;            // material albedo times texture
  Layer layer = Layer::Background;
};

class Scene {
 public:
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  // Adds a mesh (validated) before commit(); returns its index. A prop added
  // this way is an instance with the identity transform.
  int add_mesh(Mesh mesh, Layer layer);
  // Adds a prop given in its own coordinates, placed by `world_from_prop`.
  int add_prop(Mesh mesh_in_prop_space, const Eigen::Affine3f& world_from_prop);
  // Builds the acceleration structures. Must be called before tracing.
  void commit();
  // Moves a prop after commit (not while rendering): only the top level is rebuilt.
  void set_prop_transform(int mesh_index, const Eigen::Affine3f& world_from_prop);

  bool has_props() const { return prop_count_ > 0; }
  int mesh_count() const { return static_cast<int>(meshes_.size()); }
  // A mesh in its own coordinates (props: prop space) and where it is.
  const Mesh& mesh(int index) const { return meshes_[index].mesh; }
  const Eigen::Affine3f& world_from_mesh(int index) const { return meshes_[index].world_from_local; }
  Eigen::AlignedBox3f world_bounds(int index) const;
  Layer layer(int index) const { return meshes_[index].layer; }
  Eigen::AlignedBox3f bounds() const { return bounds_; }

  // Closest hit along origin + t*direction, t in (0, t_max). `with_props`
  // selects the world with or without the props.
  bool intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
                 bool with_props, RayHit& hit) const;
  bool occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
                bool with_props) const;
  SurfacePoint surface(const RayHit& hit, const Eigen::Vector3f& origin, const Eigen::Vector3f& direction) const;

  // The emissive triangles as lights, at the meshes' current places: made by
  // commit() and remade when a prop with emissive triangles moves.
  const detail::EmissiveLights& emissive_lights() const { return *emissive_lights_; }

 private:
  struct Entry {
    Mesh mesh;
    Layer layer;
    Eigen::Affine3f world_from_local = Eigen::Affine3f::Identity();
    Eigen::Matrix3f normal_matrix = Eigen::Matrix3f::Identity();  // inverse transpose of the linear part
    unsigned instance_id = 0;  // in the world with props (props only)
  };
  void update_bounds();
  struct EmbreeState;
  std::vector<Entry> meshes_;
  std::unique_ptr<EmbreeState> embree_;
  std::unique_ptr<detail::EmissiveLights> emissive_lights_;
  Eigen::AlignedBox3f bounds_;
  int prop_count_ = 0;
  bool committed_ = false;
};

}  // namespace propcam::render
