// Emissive triangles as lights (internal to render/): every triangle of an
// Emissive material in the scene, sampled by next-event estimation like the
// rig's lights. One triangle is picked per shading point from a light BVH
// (as pbrt-v4's BVHLightSampler): each node bounds its triangles' positions,
// normals and power, and a point descends toward the child whose bound
// promises the more light (power over squared distance, shrunk by the angles
// at which the bound can face the point and the point's normal can face the
// bound); from a node that looks small from the point (a far cluster) the
// triangle is picked by power alone. The picked triangle is sampled by solid
// angle (spherical_triangle.h) where that is accurate, else by area.
//
// Emission is two-sided (as the path tracer counts an emissive surface met
// from either side).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "propcam/render/lights.h"

namespace propcam::render {
class Scene;
}

namespace propcam::render::detail {

struct EmissiveTriangle {
  Eigen::Vector3f a, b, c;  // world space
  Eigen::Vector3f normal;   // unit, of the winding a -> b -> c
  float area = 0.f;
  Eigen::Vector3f emission = Eigen::Vector3f::Zero();  // radiance, both sides
  int mesh = -1, triangle = -1;
  bool prop = false;  // a prop's: it exists only in the world with props
};

// What bounds a set of two-sided emitters: where they are, how much they
// emit, and the cone (axis w, half-angle theta_o) holding their normals up to
// sign.
struct LightBounds {
  Eigen::AlignedBox3f box;
  Eigen::Vector3f w = Eigen::Vector3f::UnitZ();
  float cos_theta_o = 1.f;
  float power = 0.f;

  static LightBounds of(const EmissiveTriangle& t);
  LightBounds merged(const LightBounds& other) const;
};

// A LightBounds as the traversal reads it, with what does not depend on the
// receiving point worked out once (the traversal evaluates two per level).
struct ImportanceBound {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();  // of the box
  float radius2 = 0.f;        // squared radius of the box's bounding sphere
  Eigen::Vector3f w = Eigen::Vector3f::UnitZ();
  float cos_theta_o = 1.f, sin_theta_o = 0.f;
  float power = 0.f;
  float min_distance2 = 0.f;  // the box's half diagonal: nearer, distance says nothing (as pbrt)

  static ImportanceBound of(const LightBounds& b);
  // An estimate of the light reaching a point at p with normal n (a zero n:
  // any orientation) that is never 0 where some emitter inside could reach
  // it: power / distance^2, times the cosines at the emitters and at p at the
  // most favourable angles the bounds allow.
  float importance(const Eigen::Vector3f& p, const Eigen::Vector3f& n) const;
};

// The emissive triangles of one mesh: a range of EmissiveLights' triangles
// and a sphere around them.
struct EmitterGroup {
  int first = 0, end = 0;  // triangle indices
  Eigen::AlignedBox3f box;
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  float radius = 0.f;  // no triangle corner is further from the centre
};

class EmissiveLights {
 public:
  EmissiveLights() = default;
  // Every emissive triangle (emission > 0, area > 0) of the scene's meshes at
  // their current places.
  explicit EmissiveLights(const Scene& scene);

  bool empty() const { return triangles_.empty(); }
  int size() const { return static_cast<int>(triangles_.size()); }
  const EmissiveTriangle& triangle(int index) const { return triangles_[index]; }
  const std::vector<EmitterGroup>& groups() const { return groups_; }
  // The light index of a mesh's triangle; -1 when it is not one.
  int index_of(int mesh, int triangle) const;

  struct Pick {
    int index = -1;  // -1: no triangle can reach the point
    float pmf = 0.f;
  };
  // One triangle for the point p (normal n, or zero) from u in [0,1), with
  // the probability of that pick.
  Pick pick(const Eigen::Vector3f& p, const Eigen::Vector3f& n, float u) const;
  // The probability that pick(p, n, .) returns `index`.
  float pmf(const Eigen::Vector3f& p, const Eigen::Vector3f& n, int index) const;

  // A direction from `from` toward triangle `index` (LightSample: its solid-angle
  // density, distance and radiance; pdf 0 when nothing arrives).
  LightSample sample(int index, const Eigen::Vector3f& from, float u1, float u2) const;
  // The density sample(index, from, ...) has for the direction that meets the
  // triangle at distance t.
  float pdf(int index, const Eigen::Vector3f& from, const Eigen::Vector3f& direction, float t) const;

 private:
  struct Node {
    ImportanceBound bounds;
    int second_child = -1;  // interior: the first child is the next node
    int light = -1;         // leaf: the triangle
    int begin = 0, end = 0;  // its triangles: order_[begin, end)
  };
  // True when the node is so small from p that the descent stops there and
  // a triangle is picked by power alone (pick_by_power).
  bool is_far_cluster(const Node& node, const Eigen::Vector3f& p) const;
  // Triangle order_[k] of the node's range with probability power / node power.
  int pick_by_power(const Node& node, float u) const;
  float power_fraction(const Node& node, int index) const;
  // Builds the subtree of order_[begin, end) and returns its root's index and bounds.
  std::pair<int, LightBounds> build(int begin, int end, uint64_t trail, int depth);

  std::vector<EmissiveTriangle> triangles_;
  std::vector<EmitterGroup> groups_;
  std::vector<Node> nodes_;
  // Per triangle, the turns from the root to its leaf (bit d: second child at depth d).
  std::vector<uint64_t> trails_;
  std::vector<int> order_;  // triangle indices in leaf order (every node's triangles are a range)
  std::vector<double> power_prefix_;  // power of order_[0, k), size + 1
  std::vector<float> power_;          // per triangle
  std::unordered_map<uint64_t, int> index_of_;  // (mesh << 32 | triangle) -> index
};

}  // namespace propcam::render::detail
