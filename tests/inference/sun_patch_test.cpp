#include "propcam/inference/sun_patch.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "propcam/inference/lighting.h"
#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/scene.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kPi = std::numbers::pi;

// A room 6 m wide (x in [-3, 3]), 2.8 m high, from z = -6 to z = +2, its
// faces turned inward, with a window in the right wall (x = 3, z in [-4,
// -2.5], y in [0.8, 2.2]). The camera stands at (0, 1.5, 0), looking along
// -Z and 25 degrees down: the right wall, and the window in it, are out of
// the frame. The sun shines in through the window from 35 degrees up, its
// azimuth 20 degrees off the wall's normal, onto the floor ahead.
constexpr double kSunElevation = 35 * kPi / 180, kSunSkew = 20 * kPi / 180;

Vector3d true_sun() {
  return {std::cos(kSunElevation) * std::cos(kSunSkew), std::sin(kSunElevation),
          std::cos(kSunElevation) * std::sin(kSunSkew)};
}

render::Mesh room_with_window() {
  render::Mesh m;
  render::Material wall;
  wall.albedo = {0.55f, 0.5f, 0.45f};
  m.materials = {wall};
  const float x0 = -3, x1 = 3, y0 = 0, y1 = 2.8f, z0 = -6, z1 = 2;
  render::add_quad(m, {x0, y0, z1}, {x1, y0, z1}, {x1, y0, z0}, {x0, y0, z0}, 0, 1.f);  // floor
  render::add_quad(m, {x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1}, 0, 1.f);  // ceiling
  render::add_quad(m, {x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0}, 0, 1.f);  // far wall
  render::add_quad(m, {x1, y0, z1}, {x0, y0, z1}, {x0, y1, z1}, {x1, y1, z1}, 0, 1.f);  // back wall
  render::add_quad(m, {x0, y0, z1}, {x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, 0, 1.f);  // left wall
  // The right wall around its window.
  const float sill = 0.8f, top = 2.2f, wz0 = -4.f, wz1 = -2.5f;
  auto right = [&](float ya, float yb, float za, float zb) {
    render::add_quad(m, {x1, ya, za}, {x1, ya, zb}, {x1, yb, zb}, {x1, yb, za}, 0, 1.f);
  };
  right(y0, sill, z0, z1);
  right(top, y1, z0, z1);
  right(sill, top, z0, wz0);
  right(sill, top, wz1, z1);
  return m;
}

struct SunRoom {
  render::PinholeCamera camera;
  cv::Mat photo, depth, albedo;
};

const SunRoom& sun_room() {
  static const SunRoom room = [] {
    render::Scene scene;
    scene.add_mesh(room_with_window(), render::Layer::Background);
    scene.commit();
    SunRoom r;
    r.camera = render::pinhole_with_fov(160, 120, 60);
    r.camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, -25 * kPi / 180, 0);
    r.camera.center_world = {0, 1.5, 0};
    const render::PrimaryBuffers b = render::render_primary_buffers(scene, r.camera, false);
    r.depth = b.depth.clone();
    r.depth.setTo(render::kSkyDepthM, b.depth <= 0);
    r.albedo = b.albedo;
    render::LightRig rig;
    render::SunLight sun;
    sun.direction = true_sun().cast<float>();
    sun.irradiance = Vector3f::Constant(6.f);
    rig.suns.push_back(sun);
    render::AreaLight panel;  // a dim ceiling panel: the room's own light
    panel.corner = {-0.5f, 2.79f, -3.5f};
    panel.edge_u = {1.f, 0.f, 0.f};
    panel.edge_v = {0.f, 0.f, 1.f};
    if (panel.normal().y() > 0) std::swap(panel.edge_u, panel.edge_v);
    panel.radiance = Vector3f::Constant(1.5f);
    rig.area_lights.push_back(panel);
    render::RenderSettings settings;
    settings.samples_per_pixel = 32;
    settings.max_bounces = 2;
    r.photo = render::render_background_image(scene, r.camera, rig, settings);
    return r;
  }();
  return room;
}

RoomHeights floor_and_ceiling() {
  RoomHeights h;
  h.floor_y = 0.0;
  h.ceiling_y = 2.8;
  return h;
}

double azimuth_error_deg(const Vector3d& a, const Vector3d& b) {
  const double da = std::atan2(a.z(), a.x()), db = std::atan2(b.z(), b.x());
  return std::abs(std::remainder(da - db, 2 * kPi)) * 180 / kPi;
}

// The patch is found, and its sun comes from the right wall's side at the
// true azimuth (the outline's sheared sides), above the horizon.
TEST(SunPatch, FindsTheSunThroughAWindowOutOfView) {
  const SunRoom& r = sun_room();
  const SunPatch p = find_sun_patch(r.photo, r.depth, r.camera, floor_and_ceiling());
  ASSERT_TRUE(p.found) << p.why << " " << p.details.dump();
  EXPECT_GT(p.brightness_ratio, 2.0);
  EXPECT_LT(azimuth_error_deg(p.sun_direction, true_sun()), 8.0) << p.details.dump();
  const double elevation_deg = std::asin(p.sun_direction.y()) * 180 / kPi;
  EXPECT_GT(elevation_deg, 15.0);
  EXPECT_LT(elevation_deg, 65.0);
  EXPECT_NEAR(p.sun_direction.norm(), 1.0, 1e-9);
}

// The window lets the sun reach the patch and whatever stands in it, and
// no floor outside it.
TEST(SunPatch, ItsWindowPassesTheSunOntoThePatchOnly) {
  const SunRoom& r = sun_room();
  const SunPatch p = find_sun_patch(r.photo, r.depth, r.camera, floor_and_ceiling());
  ASSERT_TRUE(p.found) << p.why;
  render::LightRig rig;
  rig.portals.push_back({p.window.corner.cast<float>(), p.window.edge_u.cast<float>(), p.window.edge_v.cast<float>()});
  const Vector3f d = p.sun_direction.cast<float>();
  const Vector3d centre = p.corner + 0.5 * (p.along_wall + p.along_sun);
  EXPECT_TRUE(rig.arrives_from_outside(centre.cast<float>(), d, true));
  // Half a metre up, the point in the patch's light column still gets it.
  const Vector3d raised = centre + p.sun_direction * (0.5 / p.sun_direction.y());
  EXPECT_TRUE(rig.arrives_from_outside(raised.cast<float>(), d, true));
  // A floor point a metre beside the patch does not.
  const Vector3d beside = centre + 1.0 * (p.along_wall.normalized() * (0.5 * p.along_wall.norm() + 1.0));
  EXPECT_FALSE(rig.arrives_from_outside(beside.cast<float>(), d, true));
  // The window lies above the patch, under the ceiling.
  EXPECT_GT(p.window.corner.y(), 1.5);
  EXPECT_LT(p.window.corner.y(), 2.8);
}

// An albedo that took the patch's light in is made continuous with the
// floor around it.
TEST(SunPatch, TakesThePatchsLightOutOfTheAlbedo) {
  const SunRoom& r = sun_room();
  const SunPatch p = find_sun_patch(r.photo, r.depth, r.camera, floor_and_ceiling());
  ASSERT_TRUE(p.found) << p.why;
  cv::Mat lit = r.photo.clone();  // the photo itself as the albedo: all light taken in
  const double factor = take_sun_patch_out_of_albedo(lit, p);
  EXPECT_GT(factor, 2.0);
  const double inside = cv::mean(lit, p.mask)[1], around = cv::mean(lit, p.ring)[1];
  EXPECT_NEAR(inside / around, 1.0, 0.05);
  // Outside the patch nothing changed.
  cv::Mat outside;
  cv::bitwise_not(p.mask, outside);
  EXPECT_EQ(cv::norm(lit, r.photo, cv::NORM_INF, outside), 0.0);
  // The true albedo has no light in it: it stays.
  cv::Mat albedo = r.albedo.clone();
  EXPECT_EQ(take_sun_patch_out_of_albedo(albedo, p), 1.0);
}

// Through the lighting stage: the sun through the patch's window is a
// fitted light of the room, and the scene gets the window.
TEST(SunPatch, TheLightingFitsTheSunThroughTheWindow) {
  const SunRoom& r = sun_room();
  SupportPlane floor, ceiling;
  floor.name = "floor";
  floor.normal = {0, 1, 0};
  ceiling.name = "ceiling";
  ceiling.normal = {0, -1, 0};
  ceiling.offset = 2.8;
  LightingOptions o;
  o.sun_from_patch = true;
  o.fit_width = 80, o.fit_samples_per_pixel = 4, o.max_fit_pixels = 512;
  const LightingEstimate e = estimate_lighting(r.photo, r.depth, r.albedo, r.camera, {floor, ceiling}, true, o);
  ASSERT_EQ(e.windows.size(), 1u);
  int suns = 0;
  for (const LightSource& l : e.lights)
    if (l.type == LightSource::Type::Sun && l.through_windows) {
      ++suns;
      EXPECT_GT(l.intensity.maxCoeff(), 0.0);
      EXPECT_LT(azimuth_error_deg(l.direction, true_sun()), 8.0);
    }
  EXPECT_EQ(suns, 1);
  // Off (the default), or outdoors, nothing of it.
  o.sun_from_patch = false;
  EXPECT_TRUE(estimate_lighting(r.photo, r.depth, r.albedo, r.camera, {floor, ceiling}, true, o).windows.empty());
  o.sun_from_patch = true;
  const LightingEstimate outdoors = estimate_lighting(r.photo, r.depth, r.albedo, r.camera, {floor}, false, o);
  EXPECT_TRUE(outdoors.windows.empty());
}

}  // namespace
}  // namespace propcam::inference
