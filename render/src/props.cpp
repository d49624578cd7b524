#include "propcam/render/props.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace propcam::render {
namespace {

using Eigen::Vector2f;
using Eigen::Vector3f;

constexpr float kPi = 3.14159265358979323846f;

// ---------------------------------------------------------------------------
// Geometry builders. Each returns a closed part (positions, normals, triangles
// only); PropBuilder attaches the material.

int add_vertex(Mesh& mesh, const Vector3f& position, const Vector3f& normal) {
  mesh.positions.push_back(position);
  mesh.normals.push_back(normal.normalized());
  return static_cast<int>(mesh.positions.size()) - 1;
}

void add_triangle(Mesh& mesh, int a, int b, int c) { mesh.triangles.emplace_back(a, b, c); }

// Axis-aligned box with 4 vertices per face so the faces shade flat.
Mesh make_box(const Vector3f& lo, const Vector3f& hi) {
  Mesh box;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3;
    const int v = (axis + 2) % 3;  // (axis, u, v) is cyclic, so e_u x e_v = +e_axis
    for (const bool positive_side : {false, true}) {
      Vector3f normal = Vector3f::Zero();
      normal[axis] = positive_side ? 1.f : -1.f;
      int corner[4];
      const int corner_uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
      for (int k = 0; k < 4; ++k) {
        Vector3f p;
        p[axis] = positive_side ? hi[axis] : lo[axis];
        p[u] = corner_uv[k][0] ? hi[u] : lo[u];
        p[v] = corner_uv[k][1] ? hi[v] : lo[v];
        corner[k] = add_vertex(box, p, normal);
      }
      if (positive_side) {
        add_triangle(box, corner[0], corner[1], corner[2]);
        add_triangle(box, corner[0], corner[2], corner[3]);
      } else {
        add_triangle(box, corner[0], corner[2], corner[1]);
        add_triangle(box, corner[0], corner[3], corner[2]);
      }
    }
  }
  return box;
}

// A lathe profile in the (radius, height) half plane. Walking the points in
// order, the solid lies on the left, so (dy, -dr) points out of the surface:
// go outwards along the bottom, up the outside, and back down any inside.
class Profile {
 public:
  struct Point {
    Vector2f position;
    bool crease = false;      // hard edge: each side keeps its own segment normal
    bool has_normal = false;  // exact normal known (arcs); else adjacent segments are averaged
    Vector2f normal = Vector2f::Zero();
  };

  void add(const Vector2f& radius_height, bool crease = false) { add_point({radius_height, crease}); }
  void add(float radius, float height, bool crease = false) { add(Vector2f(radius, height), crease); }
  // Circular arc, angles in radians measured from +radius towards +height. Its
  // exact normals keep the shading smooth where it meets a straight piece.
  void add_arc(const Vector2f& centre, float radius, float from_angle, float to_angle, int steps) {
    const float side = to_angle > from_angle ? 1.f : -1.f;  // solid inside a counter-clockwise arc
    for (int k = 0; k <= steps; ++k) {
      const float a = from_angle + (to_angle - from_angle) * static_cast<float>(k) / static_cast<float>(steps);
      const Vector2f radial(std::cos(a), std::sin(a));
      add_point({centre + radius * radial, false, true, side * radial});
    }
  }
  const std::vector<Point>& points() const { return points_; }

 private:
  void add_point(const Point& point) {
    if (!points_.empty() && (points_.back().position - point.position).norm() < 1e-6f) {
      Point& joint = points_.back();  // pieces share their end points
      joint.crease = joint.crease || point.crease;
      if (!joint.has_normal && point.has_normal) {
        joint.has_normal = true;
        joint.normal = point.normal;
      }
      return;
    }
    points_.push_back(point);
  }

  std::vector<Point> points_;
};

// Surface of revolution about +y. The profile must start and end on the axis
// (radius 0, within kOnAxis) so the result is closed; those ends become single
// pole vertices.
Mesh make_lathe(const Profile& profile, int segments) {
  const auto& pts = profile.points();
  const int n = static_cast<int>(pts.size());
  constexpr float kOnAxis = 1e-6f;
  if (n < 3 || pts.front().position.x() > kOnAxis || pts.back().position.x() > kOnAxis)
    throw std::logic_error("make_lathe: profile must start and end on the axis");

  std::vector<Vector2f> segment_normal(n - 1);
  for (int k = 0; k + 1 < n; ++k) {
    const Vector2f d = pts[k + 1].position - pts[k].position;
    segment_normal[k] = Vector2f(d.y(), -d.x()).normalized();
  }

  Mesh lathe;
  // A ring is the circle of vertices of one profile point with one normal;
  // creases get two rings (one per side), poles a single vertex.
  struct Ring {
    int first;
    bool pole;
  };
  const auto make_ring = [&](const Vector2f& p, const Vector2f& normal2d) {
    if (p.x() <= kOnAxis) {
      const float up = normal2d.y() >= 0.f ? 1.f : -1.f;  // smooth pole: normal along the axis
      return Ring{add_vertex(lathe, Vector3f(0.f, p.y(), 0.f), Vector3f(0.f, up, 0.f)), true};
    }
    const int first = static_cast<int>(lathe.positions.size());
    for (int j = 0; j < segments; ++j) {
      const float angle = 2.f * kPi * static_cast<float>(j) / static_cast<float>(segments);
      const float c = std::cos(angle), s = std::sin(angle);
      add_vertex(lathe, Vector3f(p.x() * c, p.y(), p.x() * s),
                 Vector3f(normal2d.x() * c, normal2d.y(), normal2d.x() * s));
    }
    return Ring{first, false};
  };

  std::vector<Ring> ring_below(n), ring_above(n);  // used by segment i-1 and segment i
  for (int i = 0; i < n; ++i) {
    const Vector2f& p = pts[i].position;
    if (i == 0) {
      ring_above[i] = make_ring(p, segment_normal[0]);
    } else if (i == n - 1) {
      ring_below[i] = make_ring(p, segment_normal[n - 2]);
    } else if (pts[i].crease) {
      ring_below[i] = make_ring(p, segment_normal[i - 1]);
      ring_above[i] = make_ring(p, segment_normal[i]);
    } else {
      const Vector2f normal =
          pts[i].has_normal ? pts[i].normal : Vector2f((segment_normal[i - 1] + segment_normal[i]).normalized());
      ring_below[i] = ring_above[i] = make_ring(p, normal);
    }
  }

  for (int i = 0; i + 1 < n; ++i) {
    const Ring a = ring_above[i];
    const Ring b = ring_below[i + 1];
    if (a.pole && b.pole) continue;  // a segment along the axis sweeps no area
    for (int j = 0; j < segments; ++j) {
      const int j1 = (j + 1) % segments;
      if (a.pole) {
        add_triangle(lathe, a.first, b.first + j, b.first + j1);
      } else if (b.pole) {
        add_triangle(lathe, a.first + j, b.first, a.first + j1);
      } else {
        add_triangle(lathe, a.first + j, b.first + j, b.first + j1);
        add_triangle(lathe, a.first + j, b.first + j1, a.first + j1);
      }
    }
  }
  return lathe;
}

// UV sphere centred at the origin: a lathe of a half circle.
Mesh make_uv_sphere(float radius, int segments, int rings) {
  Profile half_circle;
  // The arc's ends are a float rounding off the axis; make_lathe snaps them onto it.
  half_circle.add_arc(Vector2f::Zero(), radius, -kPi / 2.f, kPi / 2.f, rings);
  return make_lathe(half_circle, segments);
}

// Sweeps an ellipse along `path` and caps both ends flat. The ellipse's
// half axes lie along the frame normal (half_normal) and binormal (half_binormal);
// the binormal is `binormal_hint` made perpendicular to the path tangent.
Mesh make_tube(const std::vector<Vector3f>& path, const Vector3f& binormal_hint, float half_normal, float half_binormal,
               int segments) {
  const int n = static_cast<int>(path.size());
  if (n < 2) throw std::logic_error("make_tube: path needs at least two points");
  Mesh tube;
  std::vector<Vector3f> tangents(n);
  for (int i = 0; i < n; ++i) tangents[i] = (path[std::min(i + 1, n - 1)] - path[std::max(i - 1, 0)]).normalized();

  // Frame (T, N, B) is right handed: T x N = B, so the section runs
  // counter-clockwise seen from +T.
  std::vector<Vector3f> section_normals(n), section_binormals(n);
  for (int i = 0; i < n; ++i) {
    const Vector3f& t = tangents[i];
    section_binormals[i] = (binormal_hint - binormal_hint.dot(t) * t).normalized();
    section_normals[i] = section_binormals[i].cross(t);
  }
  const auto section_point = [&](int i, int j, Vector3f* normal) {
    const float angle = 2.f * kPi * static_cast<float>(j) / static_cast<float>(segments);
    const float c = std::cos(angle), s = std::sin(angle);
    *normal = (c / half_normal) * section_normals[i] + (s / half_binormal) * section_binormals[i];
    return Vector3f(path[i] + half_normal * c * section_normals[i] + half_binormal * s * section_binormals[i]);
  };

  for (int i = 0; i < n; ++i)
    for (int j = 0; j < segments; ++j) {
      Vector3f normal;
      const Vector3f p = section_point(i, j, &normal);
      add_vertex(tube, p, normal);
    }
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j < segments; ++j) {
      const int j1 = (j + 1) % segments;
      const int a = i * segments + j, b = i * segments + j1;
      const int c = (i + 1) * segments + j, d = (i + 1) * segments + j1;
      add_triangle(tube, a, b, c);
      add_triangle(tube, b, d, c);
    }

  // Flat end caps with their own vertices (hard edge at the rim).
  for (const bool at_end : {false, true}) {
    const int i = at_end ? n - 1 : 0;
    const Vector3f cap_normal = at_end ? tangents[i] : Vector3f(-tangents[i]);
    const int centre = add_vertex(tube, path[i], cap_normal);
    const int first = static_cast<int>(tube.positions.size());
    for (int j = 0; j < segments; ++j) {
      const Vector3f rim = tube.positions[i * segments + j];  // copy: add_vertex grows the array
      add_vertex(tube, rim, cap_normal);
    }
    for (int j = 0; j < segments; ++j) {
      const int j1 = (j + 1) % segments;
      if (at_end)
        add_triangle(tube, centre, first + j, first + j1);
      else
        add_triangle(tube, centre, first + j1, first + j);
    }
  }
  return tube;
}

// Section of a torus in the z = 0 plane: an elliptical tube along a circular
// arc around `centre`, angles in radians from +x towards +y.
Mesh make_torus_arc(const Vector3f& centre, float major_radius, float from_angle, float to_angle, float half_thickness,
                    float half_width, int path_steps, int segments) {
  std::vector<Vector3f> path;
  for (int k = 0; k <= path_steps; ++k) {
    const float a = from_angle + (to_angle - from_angle) * static_cast<float>(k) / static_cast<float>(path_steps);
    path.push_back(centre + major_radius * Vector3f(std::cos(a), std::sin(a), 0.f));
  }
  return make_tube(path, Vector3f::UnitZ(), half_thickness, half_width, segments);
}

// Uniform Catmull-Rom spline through `controls`, `steps` samples per span.
// The end tangents can be pinned (zero vector = natural end).
std::vector<Vector2f> catmull_rom(const std::vector<Vector2f>& controls, int steps, const Vector2f& start_tangent,
                                  const Vector2f& end_tangent) {
  const int n = static_cast<int>(controls.size());
  std::vector<Vector2f> p;
  p.push_back(start_tangent.isZero() ? Vector2f(2.f * controls[0] - controls[1])
                                     : Vector2f(controls[1] - 2.f * start_tangent));
  p.insert(p.end(), controls.begin(), controls.end());
  p.push_back(end_tangent.isZero() ? Vector2f(2.f * controls[n - 1] - controls[n - 2])
                                   : Vector2f(controls[n - 2] + 2.f * end_tangent));
  std::vector<Vector2f> samples;
  for (int span = 0; span + 1 < n; ++span) {
    const Vector2f &p0 = p[span], &p1 = p[span + 1], &p2 = p[span + 2], &p3 = p[span + 3];
    for (int k = 0; k < steps; ++k) {
      const float t = static_cast<float>(k) / static_cast<float>(steps);
      const float t2 = t * t, t3 = t2 * t;
      samples.push_back(0.5f * (2.f * p1 + (p2 - p0) * t + (2.f * p0 - 5.f * p1 + 4.f * p2 - p3) * t2 +
                                (3.f * p1 - p0 - 3.f * p2 + p3) * t3));
    }
  }
  samples.push_back(controls.back());
  return samples;
}

// ---------------------------------------------------------------------------
// Materials (linear albedo).

Material diffuse_material(std::string name, const Vector3f& albedo) {
  Material m;
  m.type = Material::Type::Diffuse;
  m.name = std::move(name);
  m.albedo = albedo;
  m.roughness = 1.f;
  return m;
}

Material glossy_material(std::string name, const Vector3f& albedo, float specular, float roughness) {
  Material m;
  m.type = Material::Type::Glossy;
  m.name = std::move(name);
  m.albedo = albedo;
  m.specular = specular;
  m.roughness = roughness;
  return m;
}

Material metal_material(std::string name, const Vector3f& reflectance, float roughness) {
  Material m;
  m.type = Material::Type::Metal;
  m.name = std::move(name);
  m.albedo = reflectance;
  m.roughness = roughness;
  return m;
}

Material glass_material(std::string name, float ior, float roughness) {
  Material m;
  m.type = Material::Type::Dielectric;
  m.name = std::move(name);
  m.albedo = Vector3f::Ones();
  m.ior = ior;
  m.roughness = roughness;
  return m;
}

Material emissive_material(std::string name, const Vector3f& radiance) {
  Material m;
  m.type = Material::Type::Emissive;
  m.name = std::move(name);
  m.albedo = Vector3f::Zero();
  m.emission = radiance;
  return m;
}

// Collects parts with their materials, then puts the prop on the ground.
class PropBuilder {
 public:
  int add_material(Material material) {
    mesh_.materials.push_back(std::move(material));
    return static_cast<int>(mesh_.materials.size()) - 1;
  }
  void add(const Mesh& part, int material_id) {
    const int offset = static_cast<int>(mesh_.positions.size());
    mesh_.positions.insert(mesh_.positions.end(), part.positions.begin(), part.positions.end());
    mesh_.normals.insert(mesh_.normals.end(), part.normals.begin(), part.normals.end());
    for (const auto& t : part.triangles) {
      mesh_.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
      mesh_.material_ids.push_back(material_id);
    }
  }
  void add_box(const Vector3f& lo, const Vector3f& hi, int material_id) { add(make_box(lo, hi), material_id); }

  // Moves the base centre to the origin and scales to exactly `natural_height`
  // (the designs are drawn to size; the scale only absorbs sampling error).
  Mesh finish(float natural_height) {
    const Eigen::AlignedBox3f box = mesh_.bounds();
    const float height = box.max().y() - box.min().y();
    const float scale = natural_height / height;
    if (std::abs(scale - 1.f) > 0.02f) throw std::logic_error("prop design height disagrees with its preset");
    const Vector3f anchor(box.center().x(), box.min().y(), box.center().z());
    for (auto& p : mesh_.positions) p = (p - anchor) * scale;
    mesh_.validate();
    return std::move(mesh_);
  }

 private:
  Mesh mesh_;
};

// ---------------------------------------------------------------------------
// Presets. Dimensions in metres.

constexpr float kChairHeight = 0.90f;
constexpr float kVaseHeight = 0.35f;
constexpr float kSpherePlinthHeight = 0.50f;
constexpr float kMugHeight = 0.10f;
constexpr float kTableHeight = 0.55f;
constexpr float kCubeHeight = 0.20f;
constexpr float kGlassHeight = 0.15f;
constexpr float kLampHeight = 0.38f;
// The lamp globe's radiance (W/sr/m^2, relative like the lights of a scene):
// a warm ~2700 K white of luminance ~8, the synthetic rooms' ceiling panels'
// order (6-10). Over the 7 cm globe that is a power of ~1/10 of a 0.6 m
// panel's at the same radiance (pi L A), about a 40 W bulb against a panel fitting.
const Vector3f kLampRadiance(10.f, 7.8f, 5.2f);

// Ladder-back kitchen chair. Joints overlap (rails end inside the legs) so no
// two parts share an edge and no gaps show.
Mesh make_chair() {
  PropBuilder chair;
  const int wood = chair.add_material(glossy_material("varnished_beech", {0.42f, 0.26f, 0.13f}, 0.04f, 0.35f));
  const float seat_top = 0.45f, seat_thickness = 0.03f;
  const float leg = 0.035f, leg_x = 0.1875f, leg_z = 0.1825f;  // leg centres
  chair.add_box({-0.22f, seat_top - seat_thickness, -0.21f}, {0.22f, seat_top, 0.21f}, wood);
  for (const float sx : {-1.f, 1.f}) {
    const float x = sx * leg_x;
    // Front legs stop inside the seat; back legs continue up as the backrest posts.
    chair.add_box({x - leg / 2, 0.f, leg_z - leg / 2}, {x + leg / 2, seat_top - 0.015f, leg_z + leg / 2}, wood);
    chair.add_box({x - leg / 2, 0.f, -leg_z - leg / 2}, {x + leg / 2, kChairHeight, -leg_z + leg / 2}, wood);
    // Side stretcher between front and back leg.
    chair.add_box({x - 0.009f, 0.14f, -leg_z}, {x + 0.009f, 0.165f, leg_z}, wood);
  }
  chair.add_box({-leg_x, 0.20f, leg_z - 0.009f}, {leg_x, 0.225f, leg_z + 0.009f}, wood);  // front stretcher
  // Backrest: two slats and a deeper top rail between the posts, set into them.
  const float slat_half_depth = 0.0075f;
  for (const auto& [bottom, top] : {std::pair{0.56f, 0.61f}, std::pair{0.67f, 0.72f}, std::pair{0.78f, 0.86f}})
    chair.add_box({-leg_x, bottom, -leg_z - slat_half_depth}, {leg_x, top, -leg_z + slat_half_depth}, wood);
  return chair.finish(kChairHeight);
}

// Glazed ceramic vase: a spline outline with a rounded lip, walls of constant
// thickness and a thick floor.
Mesh make_vase() {
  PropBuilder vase;
  const int glaze = vase.add_material(glossy_material("blue_glazed_ceramic", {0.06f, 0.17f, 0.38f}, 0.05f, 0.08f));
  const float wall = 0.006f, floor_top = 0.014f;
  // Outer outline (radius, height); it ends vertical so the rounded lip tops out at the full height.
  const std::vector<Vector2f> outline_controls = {{0.055f, 0.f},
                                                  {0.084f, 0.06f},
                                                  {0.097f, 0.13f},
                                                  {0.076f, 0.22f},
                                                  {0.046f, 0.285f},
                                                  {0.049f, 0.32f},
                                                  {0.058f, kVaseHeight - wall / 2}};
  const std::vector<Vector2f> outer = catmull_rom(outline_controls, 6, Vector2f::Zero(), Vector2f(0.f, 0.03f));

  // Inner wall: the outline offset inwards by the wall thickness along its normals.
  // The top is pinned vertical above, so the offset there is exactly horizontal.
  std::vector<Vector2f> inner;
  for (size_t i = 0; i < outer.size(); ++i) {
    const Vector2f d = i + 1 == outer.size() ? Vector2f(0.f, 1.f) : Vector2f(outer[i + 1] - outer[i == 0 ? 0 : i - 1]);
    const Vector2f outward = Vector2f(d.y(), -d.x()).normalized();
    inner.push_back(outer[i] - wall * outward);
  }

  Profile profile;
  profile.add(0.f, 0.f);
  profile.add(outer.front(), /*crease=*/true);  // sharp foot edge
  for (const auto& p : outer) profile.add(p);
  // Rounded lip: half circle from the outer to the inner wall over the top.
  const Vector2f lip_centre = 0.5f * (outer.back() + inner.back());
  profile.add_arc(lip_centre, wall / 2, 0.f, kPi, 8);
  // Down the inside until the floor, then across it to the axis.
  // The inner wall starts below the floor (the foot is at y = 0), so it crosses it.
  for (size_t i = inner.size() - 1; i > 0; --i) {
    profile.add(inner[i]);
    const Vector2f& next = inner[i - 1];
    if (next.y() < floor_top) {
      const float t = (inner[i].y() - floor_top) / (inner[i].y() - next.y());
      profile.add(inner[i] + t * (next - inner[i]), /*crease=*/true);
      break;
    }
  }
  profile.add(0.f, floor_top);
  vase.add(make_lathe(profile, 64), glaze);
  return vase.finish(kVaseHeight);
}

// Polished metal ball resting on a painted square plinth with a wider foot.
Mesh make_sphere_plinth() {
  PropBuilder prop;
  const int paint = prop.add_material(diffuse_material("white_painted_plinth", {0.72f, 0.71f, 0.68f}));
  const int chrome = prop.add_material(metal_material("polished_chrome", {0.55f, 0.56f, 0.55f}, 0.06f));
  const float radius = 0.14f, sink = 0.001f;  // a hair of overlap so no light leaks under the ball
  const float plinth_top = kSpherePlinthHeight - 2.f * radius + sink;
  prop.add_box({-0.14f, 0.f, -0.14f}, {0.14f, 0.02f, 0.14f}, paint);             // foot
  prop.add_box({-0.125f, 0.01f, -0.125f}, {0.125f, plinth_top, 0.125f}, paint);  // column
  Mesh ball = make_uv_sphere(radius, 64, 32);
  ball.transform(Eigen::Affine3f(Eigen::Translation3f(0.f, plinth_top + radius - sink, 0.f)));
  prop.add(ball, chrome);
  return prop.finish(kSpherePlinthHeight);
}

// Stoneware mug: lathe body with walls and a rounded rim, plus a C handle
// whose ends stop inside the wall (never poking into the cup).
Mesh make_mug() {
  PropBuilder mug;
  const int glaze = mug.add_material(glossy_material("white_glazed_stoneware", {0.80f, 0.78f, 0.74f}, 0.05f, 0.10f));
  const float radius = 0.041f, wall = 0.005f, floor_top = 0.008f;
  const float outer_fillet = 0.006f, inner_fillet = 0.004f;
  const int arc_steps = 6;
  Profile body;
  body.add(0.f, 0.f);
  body.add_arc({radius - outer_fillet, outer_fillet}, outer_fillet, -kPi / 2, 0.f, arc_steps);
  body.add_arc({radius - wall / 2, kMugHeight - wall / 2}, wall / 2, 0.f, kPi, 2 * arc_steps);
  body.add_arc({radius - wall - inner_fillet, floor_top + inner_fillet}, inner_fillet, 0.f, -kPi / 2, arc_steps);
  body.add(0.f, floor_top);
  mug.add(make_lathe(body, 64), glaze);

  // The handle's centre line meets the middle of the wall at both ends.
  const float handle_major = 0.026f, handle_centre_x = radius + 0.006f, handle_centre_y = 0.052f;
  const float end_angle = std::acos((radius - wall / 2 - handle_centre_x) / handle_major);
  mug.add(make_torus_arc({handle_centre_x, handle_centre_y, 0.f}, handle_major, -end_angle, end_angle, 0.0035f, 0.0065f,
                         40, 24),
          glaze);
  return mug.finish(kMugHeight);
}

// Small side table: top, four legs with an apron, and a lower shelf.
Mesh make_table() {
  PropBuilder table;
  const int oak = table.add_material(glossy_material("oiled_oak", {0.45f, 0.30f, 0.17f}, 0.04f, 0.30f));
  const int frame = table.add_material(glossy_material("dark_stained_oak", {0.16f, 0.09f, 0.05f}, 0.04f, 0.40f));
  const float half_top = 0.225f, top_thickness = 0.025f;
  const float leg = 0.035f, leg_c = 0.185f;  // leg centres at (+-leg_c, +-leg_c)
  const float top_bottom = kTableHeight - top_thickness;
  table.add_box({-half_top, top_bottom, -half_top}, {half_top, kTableHeight, half_top}, oak);
  for (const float sx : {-1.f, 1.f})
    for (const float sz : {-1.f, 1.f})
      table.add_box({sx * leg_c - leg / 2, 0.f, sz * leg_c - leg / 2},
                    {sx * leg_c + leg / 2, top_bottom + 0.01f, sz * leg_c + leg / 2}, frame);
  // Apron boards run from leg centre to leg centre, thinner than the legs.
  const float apron_bottom = top_bottom - 0.07f, apron_top = top_bottom + 0.005f, apron_half = 0.01f;
  const float apron_c = leg_c - 0.005f;
  for (const float s : {-1.f, 1.f}) {
    table.add_box({-leg_c, apron_bottom, s * apron_c - apron_half}, {leg_c, apron_top, s * apron_c + apron_half},
                  frame);
    table.add_box({s * apron_c - apron_half, apron_bottom, -leg_c}, {s * apron_c + apron_half, apron_top, leg_c},
                  frame);
  }
  table.add_box({-leg_c, 0.10f, -leg_c}, {leg_c, 0.118f, leg_c}, oak);  // shelf, corners set into the legs
  return table.finish(kTableHeight);
}

// 18% grey cube: a known size and reflectance for checking scale and exposure.
Mesh make_cube() {
  PropBuilder cube;
  const int grey = cube.add_material(diffuse_material("grey_card_18_percent", {0.18f, 0.18f, 0.18f}));
  const float h = kCubeHeight / 2;
  cube.add_box({-h, 0.f, -h}, {h, kCubeHeight, h}, grey);
  return cube.finish(kCubeHeight);
}

// Clear tumbler: a solid of glass with 3 mm walls, a thick base and a rounded
// rim, one closed outward-wound lathe (the dielectric's inside is the glass).
Mesh make_glass() {
  PropBuilder glass;
  const int clear = glass.add_material(glass_material("clear_glass", 1.5f, 0.02f));
  const float bottom_radius = 0.031f, top_radius = 0.038f, wall = 0.003f, base_top = 0.012f;
  const float rim_y = kGlassHeight - wall / 2;
  Profile profile;
  profile.add(0.f, 0.f);
  profile.add(bottom_radius - 0.002f, 0.f, /*crease=*/true);
  profile.add_arc({bottom_radius - 0.002f, 0.002f}, 0.002f, -kPi / 2, 0.f, 4);  // softened foot edge
  profile.add(top_radius, rim_y);
  profile.add_arc({top_radius - wall / 2, rim_y}, wall / 2, 0.f, kPi, 8);
  // The inside wall is parallel to the outside (same taper), down to the base.
  const float taper = (top_radius - bottom_radius) / rim_y;
  profile.add(top_radius - wall, rim_y);
  profile.add(top_radius - wall - taper * (rim_y - base_top), base_top, /*crease=*/true);
  profile.add(0.f, base_top);
  glass.add(make_lathe(profile, 64), clear);
  return glass.finish(kGlassHeight);
}

// Table lamp: brushed brass base and stem holding an opal glass globe that
// glows (Emissive; prop_lights turns it into the light it casts).
Mesh make_lamp() {
  PropBuilder lamp;
  const int brass = lamp.add_material(metal_material("brushed_brass", {0.80f, 0.60f, 0.30f}, 0.30f));
  const int opal = lamp.add_material(emissive_material("opal_glass_globe", kLampRadiance));
  Profile base;
  base.add(0.f, 0.f);
  base.add(0.07f, 0.f, /*crease=*/true);
  base.add(0.07f, 0.012f, /*crease=*/true);
  base.add(0.05f, 0.022f, /*crease=*/true);
  base.add(0.f, 0.022f);
  lamp.add(make_lathe(base, 48), brass);
  const float globe_radius = 0.07f, globe_y = kLampHeight - globe_radius;
  // Stem and socket run up into the globe (no gap at the joints).
  const float stem_top = globe_y - globe_radius + 0.015f;
  Profile stem;
  stem.add(0.f, 0.015f);
  stem.add(0.008f, 0.015f, /*crease=*/true);
  stem.add(0.008f, stem_top - 0.03f, /*crease=*/true);
  stem.add(0.018f, stem_top - 0.03f, /*crease=*/true);
  stem.add(0.018f, stem_top, /*crease=*/true);
  stem.add(0.f, stem_top);
  lamp.add(make_lathe(stem, 24), brass);
  Mesh globe = make_uv_sphere(globe_radius, 48, 24);
  globe.transform(Eigen::Affine3f(Eigen::Translation3f(0.f, globe_y, 0.f)));
  lamp.add(globe, opal);
  return lamp.finish(kLampHeight);
}

struct PresetEntry {
  PropPreset preset;
  Mesh (*make)();
};

const std::vector<PresetEntry>& preset_entries() {
  static const std::vector<PresetEntry> entries = {
      {{"chair", "Wooden ladder-back chair", kChairHeight}, make_chair},
      {{"vase", "Blue glazed ceramic vase", kVaseHeight}, make_vase},
      {{"sphere_plinth", "Chrome sphere on a white plinth", kSpherePlinthHeight}, make_sphere_plinth},
      {{"mug", "White stoneware mug, handle to the right", kMugHeight}, make_mug},
      {{"table", "Small oak side table with a shelf", kTableHeight}, make_table},
      {{"cube", "20 cm cube in 18% grey (scale and exposure reference)", kCubeHeight}, make_cube},
      {{"glass", "Clear drinking glass (dielectric, IOR 1.5)", kGlassHeight}, make_glass},
      {{"lamp", "Brass table lamp with a glowing opal globe (lights the scene)", kLampHeight}, make_lamp},
  };
  return entries;
}

}  // namespace

std::vector<SphereLight> prop_lights(const Mesh& prop, const Eigen::Affine3f& world_from_prop) {
  std::vector<SphereLight> lights;
  for (int material = 0; material < static_cast<int>(prop.materials.size()); ++material) {
    const Material& m = prop.materials[material];
    if (m.type != Material::Type::Emissive || !(m.emission.maxCoeff() > 0.f)) continue;
    double area = 0.0;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    std::vector<Vector3f> vertices;
    for (size_t t = 0; t < prop.triangles.size(); ++t) {
      if (prop.material_ids[t] != material) continue;
      const Vector3f a = world_from_prop * prop.positions[prop.triangles[t][0]];
      const Vector3f b = world_from_prop * prop.positions[prop.triangles[t][1]];
      const Vector3f c = world_from_prop * prop.positions[prop.triangles[t][2]];
      const double triangle_area = 0.5 * (b - a).cross(c - a).norm();
      area += triangle_area;
      centroid += triangle_area * ((a + b + c) / 3.f).cast<double>();
      vertices.insert(vertices.end(), {a, b, c});
    }
    if (!(area > 0.0)) continue;
    SphereLight light;
    light.center = (centroid / area).cast<float>();
    float radius = 0.f;
    for (const Vector3f& v : vertices) radius = std::max(radius, (v - light.center).norm());
    light.radius = radius * 1.01f;  // just outside the triangles, which would block its shadow rays
    light.radiance = m.emission * static_cast<float>(area / (4.0 * kPi * light.radius * light.radius));
    light.prop_only = true;
    lights.push_back(light);
  }
  return lights;
}

const std::vector<PropPreset>& prop_presets() {
  static const std::vector<PropPreset> presets = [] {
    std::vector<PropPreset> list;
    for (const auto& entry : preset_entries()) list.push_back(entry.preset);
    return list;
  }();
  return presets;
}

Mesh make_prop(const std::string& name) {
  for (const auto& entry : preset_entries())
    if (entry.preset.name == name) return entry.make();
  std::string valid;
  for (const auto& entry : preset_entries()) valid += (valid.empty() ? "" : ", ") + entry.preset.name;
  throw std::invalid_argument("unknown prop '" + name + "' (valid: " + valid + ")");
}

}  // namespace propcam::render
