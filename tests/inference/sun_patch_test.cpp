#include "propcam/inference/sun_patch.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "box_room.h"
#include "propcam/inference/lighting.h"

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
  render::Mesh m = box_room::without_right_wall({0.55f, 0.5f, 0.45f});
  // The right wall around its window.
  const float sill = 0.8f, top = 2.2f, wz0 = -4.f, wz1 = -2.5f;
  box_room::add_right_wall(m, box_room::kFloorY, sill, box_room::kFarZ, box_room::kBackZ);
  box_room::add_right_wall(m, top, box_room::kCeilingY, box_room::kFarZ, box_room::kBackZ);
  box_room::add_right_wall(m, sill, top, box_room::kFarZ, wz0);
  box_room::add_right_wall(m, sill, top, wz1, box_room::kBackZ);
  return m;
}

const box_room::View& sun_room() {
  static const box_room::View room = [] {
    render::LightRig rig;
    render::SunLight sun;
    sun.direction = true_sun().cast<float>();
    sun.irradiance = Vector3f::Constant(6.f);
    rig.suns.push_back(sun);
    rig.area_lights.push_back(box_room::dim_ceiling_panel(1.5f));  // the room's own light
    return box_room::render_view(room_with_window(), 25, rig);
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
  const box_room::View& r = sun_room();
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
  const box_room::View& r = sun_room();
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
  const box_room::View& r = sun_room();
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
  const box_room::View& r = sun_room();
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
