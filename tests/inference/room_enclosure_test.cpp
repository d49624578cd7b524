#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "propcam/inference/lighting.h"
#include "propcam/inference/room_enclosure.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

// A room 6 m wide (x in [-3, 3]), 2.8 m high, from z = -5 to z = +2, its
// faces turned inward; the camera stands at (0, 1.5, 0) looking along -Z,
// so the ceiling above it, the wall behind it and the side walls beside it
// are out of the frame.
render::Mesh room() {
  render::Mesh m;
  render::Material wall;
  wall.albedo = {0.6f, 0.5f, 0.4f};
  m.materials = {wall};
  const float x0 = -3, x1 = 3, y0 = 0, y1 = 2.8f, z0 = -5, z1 = 2;
  render::add_quad(m, {x0, y0, z1}, {x1, y0, z1}, {x1, y0, z0}, {x0, y0, z0}, 0, 1.f);  // floor, up
  render::add_quad(m, {x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1}, 0, 1.f);  // ceiling, down
  render::add_quad(m, {x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0}, 0, 1.f);  // far wall, +Z
  render::add_quad(m, {x1, y0, z1}, {x0, y0, z1}, {x0, y1, z1}, {x1, y1, z1}, 0, 1.f);  // back wall, -Z
  render::add_quad(m, {x0, y0, z1}, {x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, 0, 1.f);  // left, +X
  render::add_quad(m, {x1, y0, z0}, {x1, y0, z1}, {x1, y1, z1}, {x1, y1, z0}, 0, 1.f);  // right, -X
  return m;
}

struct Seen {
  render::PinholeCamera camera;
  cv::Mat depth, albedo;
};

Seen look_at(const render::Mesh& mesh) {
  render::Scene scene;
  scene.add_mesh(mesh, render::Layer::Background);
  scene.commit();
  Seen s;
  s.camera = render::pinhole_with_fov(160, 120, 60);
  s.camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, 0, 0);  // along -Z
  s.camera.center_world = {0, 1.5, 0};
  const render::PrimaryBuffers b = render::render_primary_buffers(scene, s.camera, false);
  s.depth = b.depth.clone();
  s.depth.setTo(render::kSkyDepthM, b.depth <= 0);
  s.albedo = b.albedo;
  return s;
}

// Share of the upper hemisphere's directions from `point` that leave the
// mesh for the sky: what an environment light would light it through.
double open_sky_share(const render::Mesh& mesh, const Vector3d& point) {
  render::Scene scene;
  scene.add_mesh(mesh, render::Layer::Background);
  scene.commit();
  int open = 0, all = 0;
  for (int i = 0; i < 24; ++i)
    for (int j = 1; j < 12; ++j) {
      const double az = 2 * std::numbers::pi * i / 24, el = 0.5 * std::numbers::pi * j / 12;
      const Vector3f dir(static_cast<float>(std::cos(el) * std::cos(az)), static_cast<float>(std::sin(el)),
                         static_cast<float>(std::cos(el) * std::sin(az)));
      open += !scene.occluded(point.cast<float>(), dir, std::numeric_limits<float>::infinity(), false);
      ++all;
    }
  return static_cast<double>(open) / all;
}

TEST(RoomEnclosure, HoldsTheSeenRoomTheCameraAndTheLights) {
  const Seen s = look_at(room());
  const Vector3d lamp(2.0, 2.7, 1.8);  // behind the camera, out of the frame
  RoomHeights heights;
  heights.floor_y = 0.0;
  heights.ceiling_y = 2.8;
  RoomEnclosureOptions o;
  const RoomEnclosure box = enclose_room(s.depth, s.albedo, s.camera, heights, {lamp}, o);
  ASSERT_FALSE(box.empty());
  EXPECT_NO_THROW(box.validate());
  // The far wall the camera sees, the floor and ceiling the layout gives, with the margin.
  EXPECT_NEAR(box.min.z(), -5.0 - o.margin_m, 0.05);
  EXPECT_NEAR(box.min.y(), 0.0 - o.margin_m, 1e-3);
  EXPECT_NEAR(box.max.y(), 2.8 + o.margin_m, 1e-3);
  // Behind the camera: as far as the lamp, which it must hold.
  EXPECT_NEAR(box.max.z(), lamp.z() + o.margin_m, 1e-9);
  EXPECT_TRUE((box.min.array() < lamp.array()).all() && (box.max.array() > lamp.array()).all());
  // Sideways as far as the frame sees (the far wall's ends, 2.9 m out).
  EXPECT_NEAR(box.min.x(), -2.9 - o.margin_m, 0.25);
  EXPECT_NEAR(box.max.x(), 2.9 + o.margin_m, 0.25);
  EXPECT_NEAR(box.albedo.x(), 0.6f, 1e-3f);
  EXPECT_NEAR(box.albedo.z(), 0.4f, 1e-3f);
}

// What the camera sees stays the depth map's: with the enclosure added no
// pixel sees anything nearer than the depth map's mesh alone shows it.
TEST(RoomEnclosure, TheCameraSeesTheDepthMapAlone) {
  const Seen s = look_at(room());
  const RoomEnclosure box = enclose_room(s.depth, s.albedo, s.camera, {}, {});
  const render::Mesh seen = render::mesh_from_depth(s.depth, s.albedo, s.camera);
  const auto depth_of = [&](const render::Mesh& mesh) {
    render::Scene scene;
    scene.add_mesh(mesh, render::Layer::Background);
    scene.commit();
    return render::render_primary_buffers(scene, s.camera, false).depth.clone();
  };
  render::Mesh both = seen;
  both.append(room_enclosure_mesh(box, s.depth, s.camera));
  const cv::Mat alone = depth_of(seen), closed = depth_of(both);
  int nearer = 0, seen_pixels = 0;
  for (int y = 0; y < alone.rows; ++y)
    for (int x = 0; x < alone.cols; ++x) {
      const float a = alone.at<float>(y, x), c = closed.at<float>(y, x);
      if (!(a > 0)) continue;  // the mesh's half-pixel rim: the enclosure may show there
      ++seen_pixels;
      nearer += c < (1.f - 1e-4f) * a;
    }
  EXPECT_GT(seen_pixels, alone.rows * alone.cols * 9 / 10);
  EXPECT_EQ(nearer, 0);
}

// The point of it: a spot on the floor ahead of the camera sees the sky
// through the room's open back and top when the depth map is all there is,
// and none of it when the room is closed.
TEST(RoomEnclosure, ClosesTheRoomAnEnvironmentWouldLightThroughItsOpenBack) {
  const Seen s = look_at(room());
  const render::Mesh seen = render::mesh_from_depth(s.depth, s.albedo, s.camera);
  const Vector3d spot(0.3, 0.02, -4.0);  // on the seen floor
  EXPECT_GT(open_sky_share(seen, spot), 0.3);
  render::Mesh closed = seen;
  closed.append(room_enclosure_mesh(enclose_room(s.depth, s.albedo, s.camera, {}, {}), s.depth, s.camera));
  EXPECT_LT(open_sky_share(closed, spot), 0.01);
}

// Through the lighting stage: a room lit from outside the frame is closed
// around the camera and every light the fit kept; a street is not.
TEST(RoomEnclosure, TheLightingClosesARoomAroundItsLights) {
  const Seen s = look_at(room());
  SupportPlane floor;
  floor.name = "floor";
  floor.normal = {0, 1, 0};
  LightingOptions o;
  o.enclose_room = true;
  o.fit_width = 32, o.fit_samples_per_pixel = 2, o.max_fit_pixels = 256;
  const cv::Mat photo(s.depth.size(), CV_32FC3, cv::Scalar(0.3, 0.28, 0.25));
  const LightingEstimate indoors = estimate_lighting(photo, s.depth, s.albedo, s.camera, {floor}, true, o);
  ASSERT_FALSE(indoors.enclosure.empty());
  EXPECT_TRUE((indoors.enclosure.min.array() < s.camera.center_world.array()).all());
  EXPECT_TRUE((indoors.enclosure.max.array() > s.camera.center_world.array()).all());
  for (const LightSource& l : indoors.lights) {
    if (l.type == LightSource::Type::Ibl || distant_light_direction(l, s.camera.center_world)) continue;
    EXPECT_TRUE((indoors.enclosure.min.array() < l.position.array()).all() &&
                (indoors.enclosure.max.array() > l.position.array()).all())
        << l.position.transpose();
  }
  EXPECT_TRUE(estimate_lighting(photo, s.depth, s.albedo, s.camera, {floor}, false, o).enclosure.empty());
}

TEST(RoomEnclosure, IsDeterministic) {
  const Seen s = look_at(room());
  const RoomEnclosure a = enclose_room(s.depth, s.albedo, s.camera, {}, {}), b = enclose_room(s.depth, s.albedo, s.camera, {}, {});
  EXPECT_EQ(a.min, b.min);
  EXPECT_EQ(a.max, b.max);
  const render::Mesh ma = room_enclosure_mesh(a, s.depth, s.camera), mb = room_enclosure_mesh(b, s.depth, s.camera);
  ASSERT_EQ(ma.positions.size(), mb.positions.size());
  for (size_t i = 0; i < ma.positions.size(); ++i) EXPECT_EQ(ma.positions[i], mb.positions[i]);
}

}  // namespace
}  // namespace propcam::inference
