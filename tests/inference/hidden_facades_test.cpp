#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "propcam/inference/hidden_facades.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

struct Seen {
  render::PinholeCamera camera;
  cv::Mat depth, normals, albedo;
};

// What a camera 1.6 m up, looking along -Z, sees of `mesh`: depth (the sky
// at render::kSkyDepthM, as inference leaves it), world normals, albedo.
Seen look_at(const render::Mesh& mesh, double yaw = 0.0) {
  render::Scene scene;
  scene.add_mesh(mesh, render::Layer::Background);
  scene.commit();
  Seen s;
  s.camera = render::pinhole_with_fov(160, 120, 60);
  s.camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(yaw, 0, 0);
  s.camera.center_world = {0, 1.6, 0};
  const render::PrimaryBuffers b = render::render_primary_buffers(scene, s.camera, false);
  s.depth = b.depth.clone();
  s.depth.setTo(render::kSkyDepthM, b.depth <= 0);
  s.normals = b.normal;
  s.albedo = b.albedo;
  return s;
}

render::Mesh ground() {
  render::Mesh m;
  render::Material g, wall;
  g.albedo = {0.2f, 0.2f, 0.2f};
  wall.albedo = {0.6f, 0.5f, 0.4f};
  m.materials = {g, wall};
  render::add_quad(m, {-60, 0, 30}, {60, 0, 30}, {60, 0, -120}, {-60, 0, -120}, 0, 1.f);
  return m;
}

// A street along Z: facades at x = -8 and x = +8, 10 m high, from behind the
// camera to far ahead.
render::Mesh street() {
  render::Mesh m = ground();
  render::add_box(m, {-14, 0, -100}, {-8, 10, 20}, 1);
  render::add_box(m, {8, 0, -100}, {14, 10, 20}, 1);
  return m;
}

bool sunlit(const render::Mesh& mesh, const Vector3d& point, const Vector3d& sun) {
  render::Scene scene;
  scene.add_mesh(mesh, render::Layer::Background);
  scene.commit();
  return !scene.occluded(point.cast<float>(), sun.cast<float>(), std::numeric_limits<float>::infinity(), false);
}

TEST(HiddenFacades, AStreetsTwoFacadesAreFoundAtTheirPlanesAndHeight) {
  const Seen s = look_at(street());
  const auto facades = find_hidden_facades(s.depth, s.normals, s.albedo, s.camera);
  ASSERT_EQ(facades.size(), 2u);
  for (const HiddenFacade& f : facades) {
    EXPECT_NEAR(std::abs(f.normal.x()), 1.0, 1e-9);
    // Facing the camera (x = 0): the facade at x = -8 faces +X.
    EXPECT_GT(f.normal.dot(s.camera.center_world) + f.offset, 0);
    EXPECT_NEAR(f.offset, 8.0, 0.3);
    EXPECT_NEAR(f.bottom_m, 0.0, 0.3);
    EXPECT_NEAR(f.top_m, 10.0, 0.5);
    EXPECT_NEAR(f.albedo.x(), 0.6f, 0.05f);
    EXPECT_LE(f.along_min, f.seen_min);
    EXPECT_GE(f.along_max, f.seen_max);
    EXPECT_NO_THROW(f.validate());
  }
}

// The point of it: the street near the camera, whose facades are out of the
// frame, is shaded by them from a low side sun; the depth map's mesh alone
// lets the sun through.
TEST(HiddenFacades, TheFacadesBesideTheCameraShadeTheNearStreet) {
  const Seen s = look_at(street());
  const render::Mesh seen = render::mesh_from_depth(s.depth, s.albedo, s.camera);
  const auto facades = find_hidden_facades(s.depth, s.normals, s.albedo, s.camera);
  const render::Mesh hidden = hidden_facade_mesh(facades, s.depth, s.camera);
  ASSERT_FALSE(hidden.empty());
  // No cell is in the frame: what the camera sees is the depth map's alone.
  for (const Vector3f& p : hidden.positions) {
    Eigen::Vector2d px;
    const bool in_frame = s.camera.project(p.cast<double>(), px) && px.x() > 0.5 && px.x() < s.camera.width - 0.5 &&
                          px.y() > 0.5 && px.y() < s.camera.height - 0.5;
    EXPECT_FALSE(in_frame) << p.transpose();
  }
  const Vector3d sun = Vector3d(-std::cos(0.35), std::sin(0.35), 0.0).normalized();  // 20 degrees, from -X
  const Vector3d near_street(0, 0.01, -6);  // in the frame; its facades at z = -6 are not
  Eigen::Vector2d px;
  ASSERT_TRUE(s.camera.project(near_street, px));
  ASSERT_LT(px.y(), s.camera.height);
  EXPECT_FALSE(sunlit(street(), near_street, sun));  // the truth
  EXPECT_TRUE(sunlit(seen, near_street, sun));        // the depth map alone
  render::Mesh both = seen;
  both.append(hidden);
  EXPECT_FALSE(sunlit(both, near_street, sun));
  // A sun from straight ahead still reaches it.
  EXPECT_TRUE(sunlit(both, near_street, Vector3d(0, 0.5, -1).normalized()));
}

// A block beside an open square: its side wall is not continued across the
// ground the camera sees in front of it.
TEST(HiddenFacades, ASideWallIsNotContinuedAcrossTheSeenGround) {
  render::Mesh m = ground();
  render::add_box(m, {2, 0, -40}, {12, 8, -12}, 1);
  const Seen s = look_at(m);
  const auto facades = find_hidden_facades(s.depth, s.normals, s.albedo, s.camera);
  bool side_wall = false;
  for (const auto& f : facades) side_wall = side_wall || (f.normal.x() < -0.99 && std::abs(f.offset - 2.0) < 0.3);
  ASSERT_TRUE(side_wall) << "the block's side wall (x = 2, facing -X) is a facade";
  // The wall ends 12 m ahead; a cell past its seen end is a metre's doubt,
  // a continuation toward the camera (to z = +40) would be the error.
  const render::Mesh hidden = hidden_facade_mesh(facades, s.depth, s.camera);
  for (const Vector3f& p : hidden.positions) EXPECT_LT(p.z(), -9.5f) << p.transpose();
}

TEST(HiddenFacades, IsDeterministic) {
  const Seen s = look_at(street());
  const auto a = hidden_facade_mesh(find_hidden_facades(s.depth, s.normals, s.albedo, s.camera), s.depth, s.camera);
  const auto b = hidden_facade_mesh(find_hidden_facades(s.depth, s.normals, s.albedo, s.camera), s.depth, s.camera);
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (size_t i = 0; i < a.positions.size(); ++i) EXPECT_EQ(a.positions[i], b.positions[i]);
}

}  // namespace
}  // namespace propcam::inference
