// A box room our renderer draws for the lighting tests (sun patch, lit-wall
// lamp): 6 m wide (x in [-3, 3]), 2.8 m high, from z = -6 to z = +2, its
// faces turned inward, seen from (0, 1.5, 0) along -Z.
#pragma once

#include <numbers>
#include <opencv2/core.hpp>

#include "propcam/render/depth_mesh.h"
#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"

namespace propcam::inference::box_room {

constexpr float kX0 = -3, kX1 = 3, kFloorY = 0, kCeilingY = 2.8f, kFarZ = -6, kBackZ = 2;

// Floor, ceiling, far, back and left walls; the right wall (x = kX1) is the
// caller's, which may open it.
inline render::Mesh without_right_wall(const Eigen::Vector3f& albedo) {
  render::Mesh m;
  render::Material wall;
  wall.albedo = albedo;
  m.materials = {wall};
  const float x0 = kX0, x1 = kX1, y0 = kFloorY, y1 = kCeilingY, z0 = kFarZ, z1 = kBackZ;
  render::add_quad(m, {x0, y0, z1}, {x1, y0, z1}, {x1, y0, z0}, {x0, y0, z0}, 0, 1.f);  // floor
  render::add_quad(m, {x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1}, 0, 1.f);  // ceiling
  render::add_quad(m, {x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0}, 0, 1.f);  // far wall
  render::add_quad(m, {x1, y0, z1}, {x0, y0, z1}, {x0, y1, z1}, {x1, y1, z1}, 0, 1.f);  // back wall
  render::add_quad(m, {x0, y0, z1}, {x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, 0, 1.f);  // left wall
  return m;
}

// A piece of the right wall: y in [ya, yb], z in [za, zb].
inline void add_right_wall(render::Mesh& m, float ya, float yb, float za, float zb) {
  render::add_quad(m, {kX1, ya, za}, {kX1, ya, zb}, {kX1, yb, zb}, {kX1, yb, za}, 0, 1.f);
}

struct View {
  render::PinholeCamera camera;
  cv::Mat photo, depth, albedo;
};

// The room seen 160 x 120 with a 60-degree field, pitched down by
// `pitch_deg`, lit by `rig` (32 spp, 2 bounces).
inline View render_view(const render::Mesh& room, double pitch_deg, const render::LightRig& rig) {
  render::Scene scene;
  scene.add_mesh(room, render::Layer::Background);
  scene.commit();
  View v;
  v.camera = render::pinhole_with_fov(160, 120, 60);
  v.camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, -pitch_deg * std::numbers::pi / 180, 0);
  v.camera.center_world = {0, 1.5, 0};
  const render::PrimaryBuffers b = render::render_primary_buffers(scene, v.camera, false);
  v.depth = b.depth.clone();
  v.depth.setTo(render::kSkyDepthM, b.depth <= 0);
  v.albedo = b.albedo;
  render::RenderSettings settings;
  settings.samples_per_pixel = 32;
  settings.max_bounces = 2;
  v.photo = render::render_background_image(scene, v.camera, rig, settings);
  return v;
}

// A dim ceiling panel of 1 m^2 ahead of the camera: a room's own light.
inline render::AreaLight dim_ceiling_panel(float radiance) {
  render::AreaLight panel;
  panel.corner = {-0.5f, kCeilingY - 0.01f, -3.5f};
  panel.edge_u = {1.f, 0.f, 0.f};
  panel.edge_v = {0.f, 0.f, 1.f};
  if (panel.normal().y() > 0) std::swap(panel.edge_u, panel.edge_v);
  panel.radiance = Eigen::Vector3f::Constant(radiance);
  return panel;
}

}  // namespace propcam::inference::box_room
