#include "propcam/inference/lit_wall_lamp.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "box_room.h"
#include "propcam/inference/lighting.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kPi = std::numbers::pi;

// The box room (box_room.h) closed, seen 8 degrees down. A bare bulb
// stands at `kLamp`, right of the frame and level with the camera's plane:
// the photo does not show it, only the pool it throws on the far and right
// walls. A dim ceiling panel ahead is the room's own light.
const Vector3d kLamp(2.3, 1.3, -1.6);
constexpr double kPlaceToleranceM = 0.8;

// The layout's planes of that room: normals facing the camera, n.x + offset = 0.
std::vector<SupportPlane> room_planes() {
  auto plane = [](const char* name, Vector3d normal, double offset) {
    SupportPlane p;
    p.name = name;
    p.normal = normal;
    p.offset = offset;
    return p;
  };
  return {plane("floor", {0, 1, 0}, 0.0), plane("ceiling", {0, -1, 0}, 2.8), plane("wall_front", {0, 0, 1}, 6.0),
          plane("wall_left", {1, 0, 0}, 3.0), plane("wall_right", {-1, 0, 0}, 3.0)};
}

const box_room::View& lamp_room() {
  static const box_room::View room = [] {
    render::Mesh closed = box_room::without_right_wall({0.6f, 0.55f, 0.5f});
    box_room::add_right_wall(closed, box_room::kFloorY, box_room::kCeilingY, box_room::kFarZ, box_room::kBackZ);
    render::LightRig rig;
    render::SphereLight bulb;
    bulb.center = kLamp.cast<float>();
    bulb.radius = 0.05f;
    bulb.radiance = Vector3f::Constant(1500.f);
    rig.sphere_lights.push_back(bulb);
    rig.area_lights.push_back(box_room::dim_ceiling_panel(0.5f));
    return box_room::render_view(closed, 8, rig);
  }();
  return room;
}

// The bulb is out of the frame (the test would be void otherwise).
TEST(LitWallLamp, TheRoomsLampIsOutOfTheFrame) {
  const box_room::View& r = lamp_room();
  const Vector3d c = r.camera.world_to_camera(kLamp);
  const double u = r.camera.fx * c.x() / c.z() + r.camera.cx;
  EXPECT_TRUE(c.z() <= 0 || u >= r.photo.cols);
}

// The walls' pool of light points at the bulb. The pool is mostly on one
// wall, so distance trades against spread, and the light bounced off the
// walls out of view widens it: the place is found within 0.8 m, the
// direction a prop ahead would be lit from within 10 degrees.
TEST(LitWallLamp, FindsTheLampOutOfViewFromThePoolOnTheWalls) {
  const box_room::View& r = lamp_room();
  const LitWallLamp lamp = find_lit_wall_lamp(r.photo, r.depth, r.albedo, r.camera, room_planes());
  ASSERT_TRUE(lamp.found) << lamp.why << " " << lamp.details.dump();
  EXPECT_LT((lamp.position - kLamp).norm(), kPlaceToleranceM) << lamp.details.dump();
  const Vector3d prop(0, 0, -3);
  const double angle_deg =
      std::acos(std::clamp((lamp.position - prop).normalized().dot((kLamp - prop).normalized()), -1.0, 1.0)) * 180 / kPi;
  EXPECT_LT(angle_deg, 10.0);
  EXPECT_GT(lamp.explained, 0.8);
  EXPECT_GT(lamp.lamp_share, 0.5);
}

// Without the albedo the walls are taken as evenly painted; this room's
// are, so the lamp is the same.
TEST(LitWallLamp, EvenlyPaintedWallsNeedNoAlbedo) {
  const box_room::View& r = lamp_room();
  const LitWallLamp with = find_lit_wall_lamp(r.photo, r.depth, r.albedo, r.camera, room_planes());
  const LitWallLamp without = find_lit_wall_lamp(r.photo, r.depth, cv::Mat(), r.camera, room_planes());
  ASSERT_TRUE(without.found) << without.why;
  EXPECT_LT((without.position - with.position).norm(), 0.15);
}

// Through the lighting stage: the bulb joins the candidates and the fit
// gives it light; off (the default) or outdoors, it is not there.
TEST(LitWallLamp, TheLightingFitsTheLampItFound) {
  const box_room::View& r = lamp_room();
  LightingOptions o;
  o.lamp_from_lit_walls = true;
  o.fit_width = 80, o.fit_samples_per_pixel = 4, o.max_fit_pixels = 512;
  const auto points_near_the_lamp = [](const LightingEstimate& e) {
    int n = 0;
    for (const LightSource& l : e.lights)
      if (l.type == LightSource::Type::Point && (l.position - kLamp).norm() < kPlaceToleranceM && l.intensity.maxCoeff() > 0) ++n;
    return n;
  };
  const LightingEstimate on = estimate_lighting(r.photo, r.depth, r.albedo, r.camera, room_planes(), true, o);
  EXPECT_EQ(points_near_the_lamp(on), 1);
  o.lamp_from_lit_walls = false;
  EXPECT_EQ(points_near_the_lamp(estimate_lighting(r.photo, r.depth, r.albedo, r.camera, room_planes(), true, o)), 0);
  o.lamp_from_lit_walls = true;
  EXPECT_EQ(points_near_the_lamp(estimate_lighting(r.photo, r.depth, r.albedo, r.camera, room_planes(), false, o)), 0);
}

}  // namespace
}  // namespace propcam::inference
