#include "propcam/render/synthetic_room.h"

#include "propcam/render/mesh_shapes.h"

#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <random>

namespace propcam::render {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

cv::Mat tile_texture(const cv::Vec3f& base, std::mt19937& rng) {
  // 512 px = one 1.2 m tile period: 2x2 tiles with grout lines in both
  // directions (lines along both horizontal axes) and slightly varied tones.
  cv::Mat tex(512, 512, CV_32FC3);
  std::uniform_real_distribution<float> tone(0.85f, 1.1f);
  const float tones[4] = {tone(rng), tone(rng), tone(rng), tone(rng)};
  for (int y = 0; y < tex.rows; ++y)
    for (int x = 0; x < tex.cols; ++x) {
      const bool grout = (x % 256) < 5 || (y % 256) < 5;
      const float grain = 0.95f + 0.05f * std::sin(x * 0.11f + 2.f * std::sin(y * 0.07f));
      const float k = grout ? 0.3f : tones[(y / 256) * 2 + x / 256] * grain;
      tex.at<cv::Vec3f>(y, x) = base * k;
    }
  return tex;
}

cv::Mat wall_texture(const cv::Vec3f& base, const cv::Vec3f& trim) {
  // Striped wallpaper above panelling, a skirting board and a picture rail:
  // long vertical and horizontal edges, as real rooms have. One tile = 1 m
  // horizontally; the texture is mapped with v = height over 3 m.
  cv::Mat tex(512, 128, CV_32FC3);
  for (int y = 0; y < tex.rows; ++y) {
    const float h = 3.f * (1.f - (y + 0.5f) / tex.rows);  // metres above floor
    for (int x = 0; x < tex.cols; ++x) {
      cv::Vec3f c = base;
      const bool stripe = (x % 64) < 4;                      // every 0.5 m
      if (h < 0.9f) c = base * 0.8f;                         // panelling
      if (stripe) c = base * (h < 0.9f ? 0.45f : 0.7f);
      if (h < 0.12f || (h > 0.88f && h < 0.93f) || (h > 2.05f && h < 2.12f)) c = trim;
      tex.at<cv::Vec3f>(y, x) = c;
    }
  }
  return tex;
}

Material textured(const std::string& name, const cv::Mat& texture) {
  Material m;
  m.name = name;
  m.albedo = Eigen::Vector3f::Ones();
  m.texture = std::make_shared<const cv::Mat>(texture);
  return m;
}

Material plain(const std::string& name, const Eigen::Vector3f& albedo) {
  Material m;
  m.name = name;
  m.albedo = albedo;
  return m;
}

}  // namespace

SyntheticRoom make_synthetic_room(const SyntheticRoomSpec& spec) {
  std::mt19937 rng(static_cast<uint32_t>(spec.seed * 2654435761u + 17u));
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  auto between = [&](float lo, float hi) { return lo + (hi - lo) * unit(rng); };

  SyntheticRoom out;
  const float width = between(4.f, 6.f), depth = between(4.5f, 7.f), height = between(2.5f, 3.0f);
  const float back = between(0.6f, 1.2f);  // wall behind the camera
  const float x0 = -width / 2, x1 = width / 2, z0 = -depth, z1 = back;
  out.room_min = {x0, 0.f, z0};
  out.room_max = {x1, height, z1};

  Mesh& m = out.room;
  const cv::Vec3f floor_colour(between(0.35f, 0.6f), between(0.22f, 0.4f), between(0.12f, 0.25f));
  const cv::Vec3f wall_colour(between(0.55f, 0.8f), between(0.55f, 0.8f), between(0.5f, 0.75f));
  const cv::Vec3f trim_colour(0.85f, 0.85f, 0.82f);
  m.materials.push_back(textured("floor", tile_texture(floor_colour, rng)));
  m.materials.push_back(textured("wall", wall_texture(wall_colour, trim_colour * 0.6f)));
  m.materials.push_back(plain("ceiling", {0.8f, 0.8f, 0.8f}));
  m.materials.push_back(plain("cabinet", {between(0.2f, 0.6f), between(0.2f, 0.5f), between(0.2f, 0.4f)}));
  Material panel = plain("light_panel", {0.f, 0.f, 0.f});
  panel.type = Material::Type::Emissive;
  const float power = between(6.f, 10.f);
  const Eigen::Vector3f radiance = Eigen::Vector3f(1.f, between(0.9f, 1.f), between(0.75f, 0.95f)) * power;
  panel.emission = radiance;
  m.materials.push_back(panel);
  enum { kFloor, kWall, kCeiling, kCabinet, kPanel };

  using V = Eigen::Vector3f;
  const float wall_tile = 1.f, wall_v = 3.f;
  add_quad(m, V(x0, 0, z1), V(x1, 0, z1), V(x1, 0, z0), V(x0, 0, z0), kFloor, 1.2f);
  // Walls: uvs with v measured down from 3 m so the trim lands at fixed heights.
  auto wall = [&](V a, V b) {  // a -> b along the floor, normal facing into the room
    const int base = static_cast<int>(m.positions.size());
    const float len = (b - a).norm() / wall_tile;
    m.positions.insert(m.positions.end(), {a, b, b + V(0, height, 0), a + V(0, height, 0)});
    const float top = 1.f - height / wall_v;
    m.uvs.insert(m.uvs.end(), {{0.f, 1.f}, {len, 1.f}, {len, top}, {0.f, top}});
    m.triangles.emplace_back(base, base + 1, base + 2);
    m.triangles.emplace_back(base, base + 2, base + 3);
    m.material_ids.insert(m.material_ids.end(), {kWall, kWall});
  };
  wall(V(x0, 0, z0), V(x1, 0, z0));  // front
  wall(V(x1, 0, z0), V(x1, 0, z1));  // right
  wall(V(x1, 0, z1), V(x0, 0, z1));  // back
  wall(V(x0, 0, z1), V(x0, 0, z0));  // left
  add_quad(m, V(x0, height, z0), V(x1, height, z0), V(x1, height, z1), V(x0, height, z1), kCeiling, 1.f);

  // Furniture against the front and a side wall.
  const float cab_w = between(0.8f, 1.6f), cab_h = between(0.6f, 1.0f);
  const float cab_x = between(x0 + 0.3f, x1 - 0.3f - cab_w);
  add_box(m, V(cab_x, 0, z0), V(cab_x + cab_w, cab_h, z0 + 0.45f), kCabinet);
  const float shelf_z = between(z0 + 0.8f, z0 + depth * 0.5f);
  add_box(m, V(x0, 0, shelf_z), V(x0 + 0.4f, between(1.2f, 1.9f), shelf_z + 0.9f), kCabinet);

  // One or two ceiling panels, with area lights just below them.
  const int panels = 1 + static_cast<int>(unit(rng) * 2.f) % 2;
  for (int i = 0; i < panels; ++i) {
    const float cx = between(x0 * 0.5f, x1 * 0.5f);
    const float cz = panels == 1 ? between(z0 * 0.6f, z0 * 0.3f) : z0 * (0.25f + 0.45f * i);
    const float hx = between(0.3f, 0.6f), hz = between(0.3f, 0.6f);
    const float y = height - 1e-3f;
    add_quad(m, V(cx - hx, y, cz - hz), V(cx + hx, y, cz - hz), V(cx + hx, y, cz + hz), V(cx - hx, y, cz + hz), kPanel,
             1.f);
    AreaLight light;
    light.corner = V(cx - hx, height - 4e-3f, cz - hz);
    light.edge_u = V(2 * hx, 0, 0);  // edge_u x edge_v points down, into the room
    light.edge_v = V(0, 0, 2 * hz);
    light.radiance = radiance;
    out.lights.area_lights.push_back(light);
  }
  m.compute_vertex_normals();
  m.normals.clear();  // flat shading: boxes and walls are planar

  // Camera: inside the room near the back wall, looking toward the front
  // wall with some yaw and a downward pitch, as people hold cameras.
  PinholeCamera& cam = out.camera;
  cam = pinhole_with_fov(spec.width, spec.height, spec.horizontal_fov_deg > 0 ? spec.horizontal_fov_deg : between(50.f, 75.f));
  const double yaw = between(-25.f, 25.f) * kDegToRad;
  const double pitch = -between(8.f, 22.f) * kDegToRad;
  cam.R_world_from_cam = rotation_from_yaw_pitch_roll(yaw, pitch, 0.0);
  const Eigen::Vector3d forward = cam.R_world_from_cam.col(2);
  cam.center_world = {between(x0 * 0.3f, x1 * 0.3f), spec.camera_height_m, z1 - 0.3};

  // A floor point about 2.5 m ahead of the camera, kept off the furniture.
  Eigen::Vector3d ahead = cam.center_world + Eigen::Vector3d(forward.x(), 0, forward.z()).normalized() * 2.5;
  ahead.x() = std::clamp(ahead.x(), x0 + 0.8, x1 - 0.8);
  ahead.z() = std::clamp(ahead.z(), z0 + 1.2, z1 - 1.0);
  out.free_floor_point = Eigen::Vector3f(static_cast<float>(ahead.x()), 0.f, static_cast<float>(ahead.z()));
  return out;
}

}  // namespace propcam::render
