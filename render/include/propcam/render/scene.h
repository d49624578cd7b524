// The Embree scene: background geometry (the reconstructed photo, or a
// synthetic room) and prop geometry, kept so that rays can be traced with or
// without the props. Differential rendering needs both worlds.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "propcam/render/mesh.h"

namespace propcam::render {

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

  // Adds a mesh (validated) before commit(); returns its index.
  int add_mesh(Mesh mesh, Layer layer);
  // Builds the acceleration structures. Must be called before tracing.
  void commit();

  bool has_props() const { return prop_count_ > 0; }
  const Mesh& mesh(int index) const { return meshes_[index].mesh; }
  Layer layer(int index) const { return meshes_[index].layer; }
  Eigen::AlignedBox3f bounds() const { return bounds_; }

  // Closest hit along origin + t*direction, t in (0, t_max). `with_props`
  // selects the world with or without the props.
  bool intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
                 bool with_props, RayHit& hit) const;
  bool occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
                bool with_props) const;
  SurfacePoint surface(const RayHit& hit, const Eigen::Vector3f& origin, const Eigen::Vector3f& direction) const;

 private:
  struct Entry {
    Mesh mesh;
    Layer layer;
  };
  struct EmbreeState;
  std::vector<Entry> meshes_;
  std::unique_ptr<EmbreeState> embree_;
  Eigen::AlignedBox3f bounds_;
  int prop_count_ = 0;
  bool committed_ = false;
};

}  // namespace propcam::render
