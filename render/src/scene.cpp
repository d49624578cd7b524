#include "propcam/render/scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "emissive_lights.h"

namespace propcam::render {
namespace {

// One error callback for the device instead of checking every call; it only
// records (throwing through Embree's C frames is undefined), callers check.
void embree_error(void* user, RTCError code, const char* message) {
  auto* last_error = static_cast<std::string*>(user);
  if (last_error->empty())
    *last_error = "embree error " + std::to_string(static_cast<int>(code)) + ": " + (message ? message : "");
}

Eigen::Vector3f sample_texture(const cv::Mat& texture, const Eigen::Vector2f& uv) {
  // Bilinear lookup with wrap-around (uv in texture space, v down).
  const float fx = uv.x() * texture.cols - 0.5f;
  const float fy = uv.y() * texture.rows - 0.5f;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const float ax = fx - x0, ay = fy - y0;
  auto texel = [&](int x, int y) {
    x = ((x % texture.cols) + texture.cols) % texture.cols;
    y = ((y % texture.rows) + texture.rows) % texture.rows;
    const cv::Vec3f c = texture.at<cv::Vec3f>(y, x);
    return Eigen::Vector3f(c[0], c[1], c[2]);
  };
  return (1 - ay) * ((1 - ax) * texel(x0, y0) + ax * texel(x0 + 1, y0)) +
         ay * ((1 - ax) * texel(x0, y0 + 1) + ax * texel(x0 + 1, y0 + 1));
}

// The viewer must see the shading side of a surface: where an interpolated
// normal leans away from the incoming ray (the silhouettes of smooth-shaded
// meshes), it is turned toward the ray until the cosine is this much. Unlike
// pbrt, which lets the lobe flip to the far side (so such pixels go dark),
// this keeps the BSDF's wo above its normal, as Cycles' ensure_valid_reflection does.
constexpr float kMinViewCosine = 0.02f;
// Below this length the interpolated normal has no direction; the geometric one is used.
constexpr float kMinNormalLength = 1e-6f;

// `shading` turned toward `wo` (both unit, on the side of `geometric`) until
// their cosine is at least kMinViewCosine: the smallest rotation that does it.
Eigen::Vector3f facing_shading_normal(const Eigen::Vector3f& shading, const Eigen::Vector3f& geometric,
                                      const Eigen::Vector3f& wo) {
  const float cosine = shading.dot(wo);
  if (cosine >= kMinViewCosine) return shading;
  const Eigen::Vector3f across = shading - cosine * wo;  // the part of the normal perpendicular to wo
  const float across_length = across.norm();
  if (!(across_length > kMinNormalLength)) return geometric;
  const Eigen::Vector3f turned =
      kMinViewCosine * wo + std::sqrt(1.f - kMinViewCosine * kMinViewCosine) * (across / across_length);
  return turned.dot(geometric) > 0.f && turned.allFinite() ? turned.normalized() : geometric;
}

}  // namespace

// Instance ids in the world with props: the background is instance 0, prop
// k is instance k + 1.
constexpr unsigned kBackgroundInstance = 0;
struct Scene::EmbreeState {
  RTCDevice device = nullptr;
  RTCScene background = nullptr;  // background meshes only, attached by mesh index
  RTCScene full = nullptr;        // instances: the background, and each prop
  std::vector<RTCScene> prop_scenes;       // one per prop, its mesh in prop space
  std::vector<RTCGeometry> prop_instances;  // retained, to move props
  std::vector<int> instance_mesh;           // instance id - 1 -> mesh index
  std::string last_error;
  void check(const char* where) {
    if (!last_error.empty()) throw std::runtime_error(std::string(where) + ": " + last_error);
  }
  ~EmbreeState() {
    for (RTCGeometry g : prop_instances) rtcReleaseGeometry(g);
    for (RTCScene s : prop_scenes) rtcReleaseScene(s);
    if (background) rtcReleaseScene(background);
    if (full) rtcReleaseScene(full);
    if (device) rtcReleaseDevice(device);
  }
};

namespace {

RTCGeometry make_triangle_geometry(RTCDevice device, const Mesh& mesh) {
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.positions.size()));
  for (size_t i = 0; i < mesh.positions.size(); ++i)
    for (int k = 0; k < 3; ++k) vertices[3 * i + k] = mesh.positions[i][k];
  auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh.triangles.size()));
  for (size_t i = 0; i < mesh.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) indices[3 * i + k] = static_cast<unsigned>(mesh.triangles[i][k]);
  rtcCommitGeometry(geometry);
  return geometry;
}

void set_instance_transform(RTCGeometry instance, const Eigen::Affine3f& xf) {
  // Embree's 3x4 column-major layout is exactly Eigen's affine matrix minus the last row.
  const Eigen::Matrix<float, 3, 4> m = xf.matrix().topRows<3>();
  rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, m.data());
  rtcCommitGeometry(instance);
}

}  // namespace

Scene::Scene()
    : embree_(std::make_unique<EmbreeState>()), emissive_lights_(std::make_unique<detail::EmissiveLights>()) {
  embree_->device = rtcNewDevice("threads=1");  // our own threads trace; no TBB pool
  if (!embree_->device) throw std::runtime_error("cannot create Embree device");
  rtcSetDeviceErrorFunction(embree_->device, embree_error, &embree_->last_error);
  embree_->background = rtcNewScene(embree_->device);
  embree_->full = rtcNewScene(embree_->device);
  rtcSetSceneBuildQuality(embree_->background, RTC_BUILD_QUALITY_HIGH);
  // The top level holds a handful of instances and is rebuilt when a prop moves.
  rtcSetSceneFlags(embree_->full, RTC_SCENE_FLAG_DYNAMIC);
  RTCGeometry background_instance = rtcNewGeometry(embree_->device, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(background_instance, embree_->background);
  set_instance_transform(background_instance, Eigen::Affine3f::Identity());
  rtcAttachGeometryByID(embree_->full, background_instance, kBackgroundInstance);
  rtcReleaseGeometry(background_instance);
}

Scene::~Scene() = default;

int Scene::add_mesh(Mesh mesh, Layer layer) {
  if (layer == Layer::Prop) return add_prop(std::move(mesh), Eigen::Affine3f::Identity());
  if (committed_) throw std::logic_error("Scene::add_mesh after commit");
  mesh.validate();
  if (mesh.empty()) throw std::invalid_argument("Scene::add_mesh: mesh has no triangles");
  const auto id = static_cast<unsigned>(meshes_.size());
  RTCGeometry geometry = make_triangle_geometry(embree_->device, mesh);
  rtcAttachGeometryByID(embree_->background, geometry, id);
  rtcReleaseGeometry(geometry);
  meshes_.push_back({std::move(mesh), layer});
  update_bounds();
  embree_->check("Scene::add_mesh");
  return static_cast<int>(id);
}

int Scene::add_prop(Mesh mesh, const Eigen::Affine3f& world_from_prop) {
  if (committed_) throw std::logic_error("Scene::add_prop after commit");
  mesh.validate();
  if (mesh.empty()) throw std::invalid_argument("Scene::add_prop: mesh has no triangles");
  if (!world_from_prop.matrix().allFinite()) throw std::invalid_argument("Scene::add_prop: non-finite transform");
  const auto id = static_cast<int>(meshes_.size());
  RTCGeometry geometry = make_triangle_geometry(embree_->device, mesh);
  RTCScene prop_scene = rtcNewScene(embree_->device);
  rtcSetSceneBuildQuality(prop_scene, RTC_BUILD_QUALITY_HIGH);
  rtcAttachGeometryByID(prop_scene, geometry, 0);
  rtcReleaseGeometry(geometry);
  embree_->prop_scenes.push_back(prop_scene);
  RTCGeometry instance = rtcNewGeometry(embree_->device, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(instance, prop_scene);
  set_instance_transform(instance, world_from_prop);
  const auto instance_id = static_cast<unsigned>(embree_->prop_instances.size() + 1);
  rtcAttachGeometryByID(embree_->full, instance, instance_id);
  embree_->prop_instances.push_back(instance);  // keeps the reference
  embree_->instance_mesh.push_back(id);
  Entry entry{std::move(mesh), Layer::Prop};
  entry.instance_id = instance_id;
  meshes_.push_back(std::move(entry));
  ++prop_count_;
  meshes_.back().world_from_local = world_from_prop;
  meshes_.back().normal_matrix = world_from_prop.linear().inverse().transpose();
  update_bounds();
  embree_->check("Scene::add_prop");
  return id;
}

void Scene::set_prop_transform(int mesh_index, const Eigen::Affine3f& world_from_prop) {
  if (mesh_index < 0 || mesh_index >= static_cast<int>(meshes_.size()) || meshes_[mesh_index].layer != Layer::Prop)
    throw std::invalid_argument("Scene::set_prop_transform: not a prop");
  if (!world_from_prop.matrix().allFinite()) throw std::invalid_argument("Scene::set_prop_transform: non-finite transform");
  Entry& entry = meshes_[mesh_index];
  set_instance_transform(embree_->prop_instances[entry.instance_id - 1], world_from_prop);
  entry.world_from_local = world_from_prop;
  entry.normal_matrix = world_from_prop.linear().inverse().transpose();
  update_bounds();
  if (committed_) rtcCommitScene(embree_->full);  // the top level only
  embree_->check("Scene::set_prop_transform");
  const auto& materials = entry.mesh.materials;
  if (committed_ && std::any_of(materials.begin(), materials.end(),
                                [](const Material& m) { return m.type == Material::Type::Emissive; }))
    emissive_lights_ = std::make_unique<detail::EmissiveLights>(*this);
}

Eigen::AlignedBox3f Scene::world_bounds(int index) const {
  const Entry& e = meshes_[index];
  const Eigen::AlignedBox3f local = e.mesh.bounds();
  Eigen::AlignedBox3f out;
  for (int c = 0; c < 8; ++c) out.extend(e.world_from_local * local.corner(static_cast<Eigen::AlignedBox3f::CornerType>(c)));
  return out;
}

void Scene::update_bounds() {
  bounds_.setEmpty();
  for (size_t i = 0; i < meshes_.size(); ++i) bounds_.extend(world_bounds(static_cast<int>(i)));
}

void Scene::commit() {
  for (RTCScene s : embree_->prop_scenes) rtcCommitScene(s);
  rtcCommitScene(embree_->background);
  rtcCommitScene(embree_->full);
  embree_->check("Scene::commit");
  committed_ = true;
  emissive_lights_ = std::make_unique<detail::EmissiveLights>(*this);
}

bool Scene::intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
                      bool with_props, RayHit& hit) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  rh.ray.org_x = origin.x(); rh.ray.org_y = origin.y(); rh.ray.org_z = origin.z();
  rh.ray.dir_x = direction.x(); rh.ray.dir_y = direction.y(); rh.ray.dir_z = direction.z();
  rh.ray.tnear = 0.f;
  rh.ray.tfar = t_max;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.ray.time = 0.f;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(with_props ? embree_->full : embree_->background, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  hit.t = rh.ray.tfar;
  // Through the background instance (or in the background scene) the
  // geometry id is the mesh index; through a prop's instance, look it up.
  const unsigned instance = rh.hit.instID[0];
  hit.mesh = with_props && instance != kBackgroundInstance && instance != RTC_INVALID_GEOMETRY_ID
                 ? embree_->instance_mesh[instance - 1]
                 : static_cast<int>(rh.hit.geomID);
  hit.triangle = static_cast<int>(rh.hit.primID);
  hit.u = rh.hit.u;
  hit.v = rh.hit.v;
  return true;
}

bool Scene::occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_max,
                     bool with_props) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray;
  ray.org_x = origin.x(); ray.org_y = origin.y(); ray.org_z = origin.z();
  ray.dir_x = direction.x(); ray.dir_y = direction.y(); ray.dir_z = direction.z();
  ray.tnear = 0.f;
  ray.tfar = t_max;
  ray.mask = 0xFFFFFFFFu;
  ray.flags = 0;
  ray.time = 0.f;
  rtcOccluded1(with_props ? embree_->full : embree_->background, &context, &ray);
  return ray.tfar < 0.f;  // Embree sets tfar to -inf on occlusion
}

SurfacePoint Scene::surface(const RayHit& hit, const Eigen::Vector3f& origin,
                            const Eigen::Vector3f& direction) const {
  const Entry& entry = meshes_[hit.mesh];
  const Mesh& mesh = entry.mesh;
  const Eigen::Vector3i tri = mesh.triangles[hit.triangle];
  const Eigen::Vector3f& p0 = mesh.positions[tri[0]];
  const Eigen::Vector3f& p1 = mesh.positions[tri[1]];
  const Eigen::Vector3f& p2 = mesh.positions[tri[2]];
  const float w = 1.f - hit.u - hit.v;

  SurfacePoint sp;
  sp.layer = entry.layer;
  sp.position = origin + hit.t * direction;
  // Prop meshes live in prop space: normals go to the world by the normal matrix.
  const bool instanced = entry.layer == Layer::Prop;
  Eigen::Vector3f ng = (p1 - p0).cross(p2 - p0);
  if (instanced) ng = entry.normal_matrix * ng;
  const float ng_len = ng.norm();
  ng = ng_len > 0.f ? Eigen::Vector3f(ng / ng_len) : Eigen::Vector3f(-direction);
  sp.front_face = ng.dot(direction) <= 0.f;
  if (!sp.front_face) ng = -ng;  // two-sided: face the viewer
  sp.geometric_normal = ng;
  Eigen::Vector3f ns = ng;
  if (!mesh.normals.empty()) {
    Eigen::Vector3f interpolated =
        w * mesh.normals[tri[0]] + hit.u * mesh.normals[tri[1]] + hit.v * mesh.normals[tri[2]];
    if (instanced) interpolated = entry.normal_matrix * interpolated;
    const float len = interpolated.norm();
    if (len > kMinNormalLength) {
      interpolated /= len;
      if (interpolated.dot(ng) < 0.f) interpolated = -interpolated;
      ns = facing_shading_normal(interpolated, ng, -direction);
    }
  }
  sp.shading_normal = ns;
  const Material& material = mesh.materials[mesh.material_ids[hit.triangle]];
  sp.material = &material;
  sp.albedo = material.albedo;
  if (material.texture && !material.texture->empty() && !mesh.uvs.empty()) {
    const Eigen::Vector2f uv = w * mesh.uvs[tri[0]] + hit.u * mesh.uvs[tri[1]] + hit.v * mesh.uvs[tri[2]];
    sp.albedo = sp.albedo.cwiseProduct(sample_texture(*material.texture, uv));
  }
  return sp;
}

}  // namespace propcam::render
