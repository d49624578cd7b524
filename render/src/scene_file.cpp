#include "propcam/render/scene_file.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "propcam/capture/image_file.h"
#include "propcam/render/mesh_io.h"

namespace propcam::render {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;
using Eigen::Vector3f;
using nlohmann::json;

// Largest image side a scene may ask for.
constexpr int kMaxImageSide = 16384;
// R_world_from_cam must be orthonormal to this tolerance (entries of R^T R - I):
// loose enough for rotations written with 6 decimals, tight enough to catch a
// scaled or transposed-and-scaled matrix.
constexpr double kRotationTolerance = 1e-4;
// A transform's last row must be (0, 0, 0, 1) to this tolerance.
constexpr double kAffineTolerance = 1e-9;
// A transform whose linear part has |det| below this flattens the mesh.
constexpr double kMinTransformDeterminant = 1e-12;
// Sun cones wider than this (degrees, angular radius) are not suns.
constexpr double kMaxSunAngleDeg = 30.0;
// A direction or normal shorter than this has none.
constexpr double kMinDirectionLength = 1e-9;
// Largest light intensity (any unit) and light radius (m) a scene may give.
constexpr double kMaxIntensity = 1e9;
constexpr double kMaxLightRadius = 1e6;
// A rectangle's turn about its normal, in degrees, lies within +-this.
constexpr double kMaxRotationDeg = 360.0;
// A spot's full cone angle is at most this (Blender's spot_size range).
constexpr double kMaxSpotConeDeg = 180.0;

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw std::runtime_error("scene file '" + file_ + "': " + (field.empty() ? "top level" : field) + ": " + what);
  }

  // Refuses keys other than `allowed` (keys starting with '_' are comments).
  void only_fields(const json& object, const std::string& field, std::initializer_list<const char*> allowed) const {
    if (!object.is_object()) fail(field, std::string("expected an object, got ") + object.type_name());
    for (const auto& item : object.items()) {
      const std::string& key = item.key();  // a plain name: clang 14's lambdas cannot capture structured bindings
      if (!key.empty() && key[0] == '_') continue;
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; }))
        fail(join(field, key), "unknown field");
    }
  }

  static std::string join(const std::string& field, const std::string& key) {
    return field.empty() ? key : field + "." + key;
  }
  static std::string index(const std::string& field, size_t i) { return field + "[" + std::to_string(i) + "]"; }

  const json& required(const json& object, const std::string& field, const char* key) const {
    if (!object.is_object()) fail(field, std::string("expected an object, got ") + object.type_name());
    const auto it = object.find(key);
    if (it == object.end()) fail(join(field, key), "missing");
    return *it;
  }
  static const json* optional(const json& object, const char* key) {
    const auto it = object.find(key);
    return it == object.end() ? nullptr : &*it;
  }

  double number(const json& j, const std::string& field) const {
    if (!j.is_number()) fail(field, std::string("expected a number, got ") + j.type_name());
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(field, "not a finite number");
    return v;
  }
  double number(const json& j, const std::string& field, double lo, double hi) const {
    const double v = number(j, field);
    if (v < lo || v > hi) fail(field, out_of_range(v, lo, hi));
    return v;
  }
  int integer(const json& j, const std::string& field, int lo, int hi) const {
    const double v = number(j, field);
    if (v != std::floor(v)) fail(field, "expected an integer");
    if (v < lo || v > hi) fail(field, out_of_range(v, lo, hi));
    return static_cast<int>(v);
  }
  bool boolean(const json& j, const std::string& field) const {
    if (!j.is_boolean()) fail(field, std::string("expected true or false, got ") + j.type_name());
    return j.get<bool>();
  }
  std::string string(const json& j, const std::string& field) const {
    if (!j.is_string()) fail(field, std::string("expected a string, got ") + j.type_name());
    return j.get<std::string>();
  }
  const json& array(const json& j, const std::string& field) const {
    if (!j.is_array()) fail(field, std::string("expected an array, got ") + j.type_name());
    return j;
  }
  Eigen::VectorXd numbers(const json& j, const std::string& field, size_t n) const {
    if (!j.is_array() || j.size() != n)
      fail(field, "expected an array of " + std::to_string(n) + " numbers, got " +
                      (j.is_array() ? "an array of " + std::to_string(j.size()) : std::string(j.type_name())));
    Eigen::VectorXd v(static_cast<Eigen::Index>(n));
    for (size_t i = 0; i < n; ++i) v[static_cast<Eigen::Index>(i)] = number(j[i], index(field, i));
    return v;
  }
  Vector3d vec3(const json& j, const std::string& field) const { return numbers(j, field, 3); }
  // A unit direction from any non-zero vector.
  Vector3d direction(const json& j, const std::string& field) const {
    const Vector3d v = vec3(j, field);
    if (v.norm() < kMinDirectionLength) fail(field, "a direction cannot be zero");
    return v.normalized();
  }
  // [r, g, b] or one number for grey, each within [lo, hi].
  Vector3f rgb(const json& j, const std::string& field, double lo, double hi) const {
    const Vector3d v = j.is_number() ? Vector3d::Constant(number(j, field)) : vec3(j, field);
    for (int c = 0; c < 3; ++c)
      if (v[c] < lo || v[c] > hi) fail(field, out_of_range(v[c], lo, hi));
    return v.cast<float>();
  }

  // A file named relative to the scene file's folder, which it must not leave.
  std::string file(const json& j, const std::string& field) const {
    const std::string name = string(j, field);
    if (name.empty()) fail(field, "empty file name");
    const fs::path relative(name);
    if (relative.is_absolute() || relative.has_root_name())
      fail(field, "'" + name + "' must be relative to the scene file's folder");
    const fs::path normal = relative.lexically_normal();
    if (!normal.empty() && *normal.begin() == "..")
      fail(field, "'" + name + "' leaves the scene file's folder");
    const fs::path base = fs::path(file_).parent_path();
    const fs::path full = base.empty() ? normal : base / normal;
    std::error_code ec;
    if (!fs::is_regular_file(full, ec)) fail(field, "no such file '" + full.string() + "'");
    return full.string();
  }

 private:
  static std::string out_of_range(double v, double lo, double hi) {
    std::ostringstream out;
    out << v << " is outside [" << lo << ", " << hi << "]";
    return out.str();
  }
  std::string file_;
};

PinholeCamera read_camera(const Reader& r, const json& j) {
  const std::string f = "camera";
  r.only_fields(j, f, {"K", "R_world_from_cam", "center", "width", "height"});
  PinholeCamera cam;
  const json& k = r.required(j, f, "K");
  r.only_fields(k, f + ".K", {"fx", "fy", "cx", "cy"});
  cam.fx = r.number(r.required(k, f + ".K", "fx"), f + ".K.fx");
  cam.fy = r.number(r.required(k, f + ".K", "fy"), f + ".K.fy");
  cam.cx = r.number(r.required(k, f + ".K", "cx"), f + ".K.cx");
  cam.cy = r.number(r.required(k, f + ".K", "cy"), f + ".K.cy");
  if (!(cam.fx > 0)) r.fail(f + ".K.fx", "must be positive");
  if (!(cam.fy > 0)) r.fail(f + ".K.fy", "must be positive");
  const json& rot = r.required(j, f, "R_world_from_cam");
  const std::string rf = f + ".R_world_from_cam";
  if (!rot.is_array() || rot.size() != 3) r.fail(rf, "expected 3 rows of 3 numbers");
  for (int row = 0; row < 3; ++row) cam.R_world_from_cam.row(row) = r.vec3(rot[row], Reader::index(rf, row)).transpose();
  const double error = (cam.R_world_from_cam.transpose() * cam.R_world_from_cam - Eigen::Matrix3d::Identity())
                           .cwiseAbs()
                           .maxCoeff();
  if (error > kRotationTolerance || cam.R_world_from_cam.determinant() < 0)
    r.fail(rf, "not a rotation (rows must be orthonormal with determinant +1)");
  cam.center_world = r.vec3(r.required(j, f, "center"), f + ".center");
  cam.width = r.integer(r.required(j, f, "width"), f + ".width", 1, kMaxImageSide);
  cam.height = r.integer(r.required(j, f, "height"), f + ".height", 1, kMaxImageSide);
  return cam;
}

Material read_material(const Reader& r, const json& j, const std::string& f) {
  r.only_fields(j, f, {"type", "albedo", "roughness", "ior", "specular", "emission", "name"});
  Material m;
  const std::string type = r.string(r.required(j, f, "type"), f + ".type");
  try {
    m.type = material_type_from_string(type);
  } catch (const std::invalid_argument& e) {
    r.fail(f + ".type", e.what());
  }
  m.name = j.contains("name") ? r.string(j["name"], f + ".name") : type;
  if (m.type == Material::Type::Dielectric) m.albedo = Vector3f::Ones();  // clear glass (albedo unused)
  if (const json* v = Reader::optional(j, "albedo")) m.albedo = r.rgb(*v, f + ".albedo", 0.0, 1.0);
  if (const json* v = Reader::optional(j, "roughness")) m.roughness = static_cast<float>(r.number(*v, f + ".roughness", 0.0, 1.0));
  if (const json* v = Reader::optional(j, "specular")) m.specular = static_cast<float>(r.number(*v, f + ".specular", 0.0, kMaxCoatSpecular));
  if (const json* v = Reader::optional(j, "ior")) {
    const double ior = r.number(*v, f + ".ior", 1e-3, 100.0);
    if (m.type == Material::Type::Plastic) {
      if (j.contains("specular")) r.fail(f + ".ior", "give either ior or specular for a plastic coat, not both");
      m.specular = static_cast<float>(std::min<double>(std::pow((ior - 1.0) / (ior + 1.0), 2), kMaxCoatSpecular));
    }
    m.ior = static_cast<float>(ior);
  }
  if (const json* v = Reader::optional(j, "emission")) m.emission = r.rgb(*v, f + ".emission", 0.0, 1e9);
  if (m.type == Material::Type::Emissive && !j.contains("emission")) r.fail(f + ".emission", "missing (type emissive)");
  return m;
}

Mesh read_mesh(const Reader& r, const json& j, const std::string& f) {
  r.only_fields(j, f, {"file", "material", "transform", "name"});
  const std::string path = r.file(r.required(j, f, "file"), f + ".file");
  Mesh mesh;
  try {
    mesh = load_mesh_file(path);
  } catch (const std::exception& e) {
    r.fail(f + ".file", e.what());
  }
  if (const json* v = Reader::optional(j, "material")) {
    const Material m = read_material(r, *v, f + ".material");
    mesh.materials.assign(1, m);
    mesh.material_ids.assign(mesh.triangles.size(), 0);
  }
  if (const json* v = Reader::optional(j, "transform")) {
    const std::string tf = f + ".transform";
    if (!v->is_array() || v->size() != 4) r.fail(tf, "expected 4 rows of 4 numbers");
    Eigen::Matrix4d m;
    for (int row = 0; row < 4; ++row) m.row(row) = r.numbers((*v)[row], Reader::index(tf, row), 4).transpose();
    if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kAffineTolerance)
      r.fail(tf, "last row must be [0, 0, 0, 1]");
    const double det = m.topLeftCorner<3, 3>().determinant();
    if (!(std::abs(det) > kMinTransformDeterminant)) r.fail(tf, "the linear part is singular");
    Eigen::Affine3f xf;
    xf.matrix() = m.cast<float>();
    mesh.transform(xf);
    // A mirroring transform turns the winding inside out; keep it outward (dielectrics rely on it).
    if (det < 0)
      for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
  }
  return mesh;
}

// Optional "visible_to_camera" (default true).
bool visible_to_camera(const Reader& r, const json& j, const std::string& f) {
  const json* v = Reader::optional(j, "visible_to_camera");
  return v ? r.boolean(*v, f + ".visible_to_camera") : true;
}

// A light radius: 0 only where `zero_allowed` (a spot's point), else at least
// the smallest radius a sphere light can have.
double light_radius(const Reader& r, const json& j, const std::string& f, bool zero_allowed) {
  const double radius = r.number(r.required(j, f, "radius"), f + ".radius", 0.0, kMaxLightRadius);
  if (radius == 0.0 && !zero_allowed)
    r.fail(f + ".radius", "a sphere of radius 0 emits nothing: give type point (intensity in W/sr)");
  if (radius > 0.0 && radius < kMinSphereLightRadius)
    r.fail(f + ".radius", "must be 0 (a point) or at least " + std::to_string(kMinSphereLightRadius) + " m");
  return radius;
}

bool through_portals(const Reader& r, const json& j, const std::string& f) {
  const json* v = Reader::optional(j, "through_portals");
  return v ? r.boolean(*v, f + ".through_portals") : false;
}

struct Quad {
  Vector3f corner, edge_u, edge_v;
};

// A rectangle given by its centre, facing side and size (area lights, portals).
Quad read_quad(const Reader& r, const json& j, const std::string& f) {
  const Vector3d position = r.vec3(r.required(j, f, "position"), f + ".position");
  const Vector3d n = r.direction(r.required(j, f, "normal"), f + ".normal");
  const Eigen::VectorXd size = r.numbers(r.required(j, f, "size"), f + ".size", 2);
  if (size.minCoeff() < 0) r.fail(f + ".size", "must not be negative");
  // Width along the horizontal tangent Y x normal (+X for a vertical normal),
  // height along normal x tangent, so that edge_u x edge_v faces along the
  // normal; then both turned by rotation_deg about the normal (right-handed:
  // counter-clockwise seen from the lit side).
  Vector3d t = Vector3d::UnitY().cross(n);
  t = t.norm() > kMinDirectionLength ? Vector3d(t.normalized()) : Vector3d::UnitX();
  double turn = 0.0;
  if (const json* v = Reader::optional(j, "rotation_deg"))
    turn = r.number(*v, f + ".rotation_deg", -kMaxRotationDeg, kMaxRotationDeg) * std::numbers::pi / 180.0;
  const Vector3d b0 = n.cross(t);
  const Vector3d u = std::cos(turn) * t + std::sin(turn) * b0;
  const Vector3d v = n.cross(u);
  return {(position - 0.5 * size[0] * u - 0.5 * size[1] * v).cast<float>(), (size[0] * u).cast<float>(),
          (size[1] * v).cast<float>()};
}

void read_area(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  r.only_fields(j, f, {"type", "position", "normal", "size", "rotation_deg", "intensity", "visible_to_camera", "name"});
  const Quad quad = read_quad(r, j, f);
  AreaLight light;
  light.corner = quad.corner;
  light.edge_u = quad.edge_u;
  light.edge_v = quad.edge_v;
  light.radiance = r.rgb(r.required(j, f, "intensity"), f + ".intensity", 0.0, kMaxIntensity);
  light.visible_to_camera = visible_to_camera(r, j, f);
  rig.area_lights.push_back(light);
}

void read_disc(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  r.only_fields(j, f, {"type", "position", "normal", "radius", "intensity", "visible_to_camera", "name"});
  DiscLight light;
  light.centre = r.vec3(r.required(j, f, "position"), f + ".position").cast<float>();
  light.normal = r.direction(r.required(j, f, "normal"), f + ".normal").cast<float>();
  light.radius = static_cast<float>(r.number(r.required(j, f, "radius"), f + ".radius", 0.0, kMaxLightRadius));
  light.radiance = r.rgb(r.required(j, f, "intensity"), f + ".intensity", 0.0, kMaxIntensity);
  light.visible_to_camera = visible_to_camera(r, j, f);
  rig.disc_lights.push_back(light);
}

void read_sphere(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  r.only_fields(j, f, {"type", "position", "radius", "intensity", "visible_to_camera", "name"});
  SphereLight light;
  light.center = r.vec3(r.required(j, f, "position"), f + ".position").cast<float>();
  light.radius = static_cast<float>(light_radius(r, j, f, false));
  light.radiance = r.rgb(r.required(j, f, "intensity"), f + ".intensity", 0.0, kMaxIntensity);
  light.visible_to_camera = visible_to_camera(r, j, f);
  rig.sphere_lights.push_back(light);
}

void read_point(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  // visible_to_camera is taken for symmetry: a point is never seen anyway.
  r.only_fields(j, f, {"type", "position", "intensity", "visible_to_camera", "name"});
  PointLight light;
  light.position = r.vec3(r.required(j, f, "position"), f + ".position").cast<float>();
  light.intensity = r.rgb(r.required(j, f, "intensity"), f + ".intensity", 0.0, kMaxIntensity);
  visible_to_camera(r, j, f);
  rig.point_lights.push_back(light);
}

// A spot: a sphere light of `radius` (intensity = radiance) or, with radius 0,
// a point light (intensity in W/sr), inside a cone of full angle
// cone_angle_deg (Blender's spot_size) with a soft edge `blend` (spot_blend).
void read_spot(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  r.only_fields(j, f, {"type", "position", "direction", "cone_angle_deg", "blend", "radius", "intensity",
                       "visible_to_camera", "name"});
  const Vector3f position = r.vec3(r.required(j, f, "position"), f + ".position").cast<float>();
  SpotCone cone;
  cone.direction = r.direction(r.required(j, f, "direction"), f + ".direction").cast<float>();
  const double angle = r.number(r.required(j, f, "cone_angle_deg"), f + ".cone_angle_deg", 0.0, kMaxSpotConeDeg);
  cone.half_angle = 0.5 * angle * std::numbers::pi / 180.0;
  if (const json* v = Reader::optional(j, "blend")) cone.blend = r.number(*v, f + ".blend", 0.0, 1.0);
  const double radius = light_radius(r, j, f, true);
  const Vector3f intensity = r.rgb(r.required(j, f, "intensity"), f + ".intensity", 0.0, kMaxIntensity);
  const bool visible = visible_to_camera(r, j, f);
  if (radius == 0.0) {
    PointLight light;
    light.position = position;
    light.intensity = intensity;
    light.spot = cone;
    rig.point_lights.push_back(light);
  } else {
    SphereLight light;
    light.center = position;
    light.radius = static_cast<float>(radius);
    light.radiance = intensity;
    light.spot = cone;
    light.visible_to_camera = visible;
    rig.sphere_lights.push_back(light);
  }
}

void read_sun(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  r.only_fields(j, f, {"type", "direction", "intensity", "angle_deg", "visible_to_camera", "through_portals", "name"});
  SunLight sun;
  sun.direction = r.direction(r.required(j, f, "direction"), f + ".direction").cast<float>();
  sun.irradiance = r.rgb(r.required(j, f, "intensity"), f + ".intensity", 0.0, kMaxIntensity);
  double angle = kSunAngularRadiusDeg;
  if (const json* v = Reader::optional(j, "angle_deg")) angle = r.number(*v, f + ".angle_deg", 0.0, kMaxSunAngleDeg);
  sun.angular_radius = angle * std::numbers::pi / 180.0;
  sun.visible_to_camera = visible_to_camera(r, j, f);
  sun.through_portals = through_portals(r, j, f);
  rig.suns.push_back(sun);
}

void read_ibl(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  r.only_fields(j, f, {"type", "file", "intensity", "visible_to_camera", "through_portals", "name"});
  if (rig.environment) r.fail(f, "a scene holds one ibl light");
  const std::string path = r.file(r.required(j, f, "file"), f + ".file");
  const Vector3f scale = j.contains("intensity") ? r.rgb(j["intensity"], f + ".intensity", 0.0, kMaxIntensity)
                                                 : Vector3f::Ones();
  const bool visible = visible_to_camera(r, j, f);
  cv::Mat image;
  try {
    image = capture::load_photo_linear(path);
  } catch (const std::exception& e) {
    r.fail(f + ".file", e.what());
  }
  rig.environment = std::make_shared<EnvironmentLight>(image, scale);
  rig.environment->set_visible_to_camera(visible);
  rig.environment->set_through_portals(through_portals(r, j, f));
}

void read_portal(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  r.only_fields(j, f, {"position", "normal", "size", "rotation_deg", "name"});
  const Quad quad = read_quad(r, j, f);
  const Portal portal{quad.corner, quad.edge_u, quad.edge_v};
  if (!portal.valid()) r.fail(f + ".size", "a portal needs an area (a size of 0 lets nothing through)");
  rig.portals.push_back(portal);
}

void read_light(const Reader& r, const json& j, const std::string& f, LightRig& rig) {
  const std::string type = r.string(r.required(j, f, "type"), f + ".type");
  if (type == "area") read_area(r, j, f, rig);
  else if (type == "disc") read_disc(r, j, f, rig);
  else if (type == "sphere") read_sphere(r, j, f, rig);
  else if (type == "spot") read_spot(r, j, f, rig);
  else if (type == "point") read_point(r, j, f, rig);
  else if (type == "sun") read_sun(r, j, f, rig);
  else if (type == "ibl") read_ibl(r, j, f, rig);
  else r.fail(f + ".type", "unknown light type '" + type + "' (expected area|disc|sphere|spot|point|sun|ibl)");
}

}  // namespace

SceneFile load_scene_file(const std::string& path) {
  const Reader r(path);
  std::ifstream in(path);
  if (!in) throw std::runtime_error("scene file '" + path + "': cannot open");
  json root;
  try {
    root = json::parse(in);
  } catch (const json::exception& e) {
    throw std::runtime_error("scene file '" + path + "': invalid JSON: " + e.what());
  }
  r.only_fields(root, "", {"camera", "meshes", "lights", "portals"});
  SceneFile out;
  out.path = path;
  out.camera = read_camera(r, r.required(root, "", "camera"));
  const json& meshes = r.array(r.required(root, "", "meshes"), "meshes");
  for (size_t i = 0; i < meshes.size(); ++i) out.meshes.push_back(read_mesh(r, meshes[i], Reader::index("meshes", i)));
  const json& lights = r.array(r.required(root, "", "lights"), "lights");
  for (size_t i = 0; i < lights.size(); ++i) read_light(r, lights[i], Reader::index("lights", i), out.lights);
  if (const json* portals = Reader::optional(root, "portals")) {
    const json& list = r.array(*portals, "portals");
    for (size_t i = 0; i < list.size(); ++i) read_portal(r, list[i], Reader::index("portals", i), out.lights);
  }
  return out;
}

std::unique_ptr<Scene> build_scene(const SceneFile& file) {
  auto scene = std::make_unique<Scene>();
  for (const Mesh& mesh : file.meshes) scene->add_mesh(mesh, Layer::Background);
  scene->commit();
  return scene;
}

}  // namespace propcam::render
