// Preset thumbnails rendered by the project's own path tracer (props.h).
#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/props.h"
#include "propcam/render/scene.h"

namespace propcam::render {
namespace {

constexpr double kThumbnailFovDeg = 30.0;
// Key light radiance and sky radiance: the ground in the key lands near 0.4
// (mid-grey after sRGB encoding), whatever the prop's size.
constexpr float kKeyRadiance = 6.f;
constexpr float kSkyRadiance = 0.2f;

}  // namespace

cv::Mat render_prop_thumbnail(const std::string& name, int size, int samples_per_pixel) {
  if (size < 1 || samples_per_pixel < 1) throw std::invalid_argument("thumbnail size and samples must be >= 1");
  return render_mesh_thumbnail(make_prop(name), size, samples_per_pixel);
}

cv::Mat render_mesh_thumbnail(const Mesh& prop, int size, int samples_per_pixel) {
  if (size < 1 || samples_per_pixel < 1) throw std::invalid_argument("thumbnail size and samples must be >= 1");
  if (prop.positions.empty()) throw std::invalid_argument("thumbnail: the mesh is empty");
  const Eigen::AlignedBox3f box = prop.bounds();
  const Eigen::Vector3f target = box.center();
  const float radius = std::max(0.5f * box.sizes().norm(), 1e-3f);

  Scene scene;
  Mesh ground;
  Material grey;
  grey.name = "thumbnail_ground";
  grey.albedo = Eigen::Vector3f::Constant(0.5f);
  ground.materials.push_back(grey);
  const float g = 40.f * radius;  // far enough that its edge is only seen at the horizon
  using V = Eigen::Vector3f;
  // The ground touches the mesh's lowest point (presets stand on y = 0; a
  // mesh from a stick may not).
  const float floor_y = box.min().y();
  add_quad(ground, V(-g, floor_y, g), V(g, floor_y, g), V(g, floor_y, -g), V(-g, floor_y, -g), 0, 1.f);
  scene.add_mesh(ground, Layer::Background);
  scene.add_prop(prop, Eigen::Affine3f::Identity());
  scene.commit();

  // From the front right (the mug's handle shows) and 20 degrees above.
  const double pi = 3.14159265358979323846;
  const double yaw = 25.0 * pi / 180.0, pitch = 20.0 * pi / 180.0;
  const Eigen::Vector3d to_eye(std::sin(yaw) * std::cos(pitch), std::sin(pitch), std::cos(yaw) * std::cos(pitch));
  const double half_fov = 0.5 * kThumbnailFovDeg * pi / 180.0;
  const double distance = 1.05 * radius / std::sin(half_fov);  // the bounding sphere fits the frame
  PinholeCamera camera;
  camera.width = camera.height = size;
  camera.fx = camera.fy = 0.5 * size / std::tan(half_fov);
  camera.cx = camera.cy = 0.5 * size - 0.5;
  camera.center_world = target.cast<double>() + distance * to_eye;
  const Eigen::Vector3d forward = -to_eye;
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d down = forward.cross(right);  // camera y points down the image
  camera.R_world_from_cam.col(0) = right;
  camera.R_world_from_cam.col(1) = down;
  camera.R_world_from_cam.col(2) = forward;

  // Key: a square soft box up and to the left of the camera, facing the prop.
  LightRig rig;
  const V to_key = V(-0.5f, 1.f, 0.6f).normalized();
  const V key_centre = target + 4.f * radius * to_key;
  V u = V::UnitY().cross(to_key).normalized(), v = to_key.cross(u);
  if (u.cross(v).dot(to_key) > 0.f) std::swap(u, v);  // emit toward the prop
  AreaLight key;
  const float side = 2.f * radius;
  key.edge_u = side * u;
  key.edge_v = side * v;
  key.corner = key_centre - 0.5f * (key.edge_u + key.edge_v);
  key.radiance = V::Constant(kKeyRadiance);
  rig.area_lights.push_back(key);
  rig.environment = std::make_shared<EnvironmentLight>(cv::Mat(8, 16, CV_32FC3, cv::Scalar::all(kSkyRadiance)));
  for (const SphereLight& lamp : prop_lights(prop, Eigen::Affine3f::Identity())) rig.sphere_lights.push_back(lamp);

  RenderSettings settings;
  settings.samples_per_pixel = samples_per_pixel;
  settings.max_bounces = 8;  // light through a glass's two walls and back
  return render_image(scene, camera, rig, settings);
}

}  // namespace propcam::render
