#include <gtest/gtest.h>

#include "propcam/render/path_tracer.h"
#include "propcam/render/props.h"
#include "propcam/render/synthetic_room.h"

namespace propcam::render {
namespace {

// Moving an instanced prop must render what a scene built with the prop
// already in place renders, without rebuilding the background.
TEST(SceneInstancing, AMovedPropRendersLikeOneBuiltInPlace) {
  SyntheticRoomSpec spec;
  spec.width = 64;
  spec.height = 48;
  const SyntheticRoom room = make_synthetic_room(spec);
  const Mesh prop = make_prop("sphere_plinth");
  const Eigen::Affine3f there = Eigen::Translation3f(room.free_floor_point) * Eigen::Scaling(0.5f);

  Scene moved;
  moved.add_mesh(room.room, Layer::Background);
  const int index = moved.add_prop(prop, Eigen::Affine3f(Eigen::Translation3f(100, 0, 0)));
  moved.commit();
  moved.set_prop_transform(index, there);

  Scene built;
  built.add_mesh(room.room, Layer::Background);
  Mesh placed = prop;
  placed.transform(there);
  built.add_mesh(placed, Layer::Prop);
  built.commit();

  EXPECT_TRUE(moved.world_bounds(index).isApprox(placed.bounds(), 1e-5f));
  RenderSettings s;
  s.samples_per_pixel = 4;
  const DifferentialRender a = render_differential(moved, room.camera, room.lights, s);
  const DifferentialRender b = render_differential(built, room.camera, room.lights, s);
  EXPECT_GT(cv::countNonZero(a.coverage > 0), 20) << "the prop is in view";
  // Instancing transforms rays rather than vertices: equal up to float rounding.
  EXPECT_LT(cv::norm(a.coverage, b.coverage, cv::NORM_L1) / a.coverage.total(), 1e-3);
  cv::Mat diff;
  cv::absdiff(a.change, b.change, diff);
  EXPECT_LT(cv::mean(diff)[0], 2e-3);
}

TEST(SceneInstancing, BadPropOperationsAreClearErrors) {
  Scene scene;
  const int background = scene.add_mesh(make_prop("cube"), Layer::Background);
  const int prop = scene.add_prop(make_prop("cube"), Eigen::Affine3f::Identity());
  scene.commit();
  EXPECT_THROW(scene.set_prop_transform(background, Eigen::Affine3f::Identity()), std::invalid_argument);
  EXPECT_THROW(scene.set_prop_transform(7, Eigen::Affine3f::Identity()), std::invalid_argument);
  Eigen::Affine3f bad = Eigen::Affine3f::Identity();
  bad(0, 3) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(scene.set_prop_transform(prop, bad), std::invalid_argument);
  EXPECT_THROW(scene.add_prop(make_prop("cube"), Eigen::Affine3f::Identity()), std::logic_error) << "after commit";
}

}  // namespace
}  // namespace propcam::render
