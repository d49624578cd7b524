#include <gtest/gtest.h>

#include "propcam/render/depth_mesh.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"
#include "propcam/render/synthetic_street.h"

namespace propcam::render {
namespace {

struct Seen {
  SyntheticStreet street;
  PrimaryBuffers buffers;
};

Seen see(uint64_t seed, int w = 160, int h = 120) {
  SyntheticStreetSpec spec;
  spec.width = w;
  spec.height = h;
  spec.seed = seed;
  Seen s{make_synthetic_street(spec), {}};
  Scene scene;
  scene.add_mesh(s.street.scene, Layer::Background);
  scene.commit();
  s.buffers = render_primary_buffers(scene, s.street.camera, false);
  return s;
}

double sky_fraction(const cv::Mat& depth) { return 1.0 - static_cast<double>(cv::countNonZero(depth > 0)) / depth.total(); }

TEST(SyntheticStreet, DeterministicVariedAndWithSkyAboveTheHorizon) {
  const Seen a = see(3), b = see(3);
  EXPECT_EQ(a.street.scene.triangles.size(), b.street.scene.triangles.size());
  EXPECT_EQ(cv::norm(a.buffers.depth, b.buffers.depth, cv::NORM_INF), 0.0);
  std::vector<double> skies, means;
  int with_sky = 0;
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    const Seen s = see(seed);
    const double f = sky_fraction(s.buffers.depth);
    skies.push_back(f);
    means.push_back(cv::mean(s.buffers.depth, s.buffers.depth > 0)[0]);
    with_sky += f > 0.01;
    // Nothing hit below the horizon: the ground reaches it.
    const int bottom = s.street.camera.height - 1;
    EXPECT_GT(s.buffers.depth.at<float>(bottom, s.street.camera.width / 2), 0.f) << seed;
    EXPECT_NEAR(s.street.camera.center_world.y(), 1.5, 1e-9);
  }
  EXPECT_GE(with_sky, 4);
  EXPECT_GT(*std::max_element(skies.begin(), skies.end()) - *std::min_element(skies.begin(), skies.end()), 0.05);
  EXPECT_GT(*std::max_element(means.begin(), means.end()) / *std::min_element(means.begin(), means.end()), 1.3);
}

TEST(SyntheticStreet, FreeGroundPointIsSeenOnTheGround) {
  for (uint64_t seed : {1, 2, 5, 37}) {
    const Seen s = see(seed, 320, 240);
    Eigen::Vector2d px;
    ASSERT_TRUE(s.street.camera.project(s.street.free_ground_point.cast<double>(), px)) << seed;
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    ASSERT_TRUE(x >= 0 && y >= 0 && x < 320 && y < 240) << seed;
    const double expected = s.street.camera.world_to_camera(s.street.free_ground_point.cast<double>()).z();
    EXPECT_NEAR(s.buffers.depth.at<float>(y, x), expected, 0.02 * expected) << seed;
    EXPECT_GT(s.buffers.normal.at<cv::Vec3f>(y, x)[1], 0.99f) << seed;
  }
}

TEST(SyntheticStreet, FreeGroundPointIsNeverOnOrBehindAKerbOrCar) {
  // Seed 37 once put it on a kerb (the pixel saw the kerb's top, 0.12 m up);
  // others behind a kerb or out of the frame. Checked over many seeds.
  int bad = 0;
  for (uint64_t seed = 1; seed <= 120; ++seed) {
    const Seen s = see(seed, 160, 120);
    Eigen::Vector2d px;
    const bool ahead = s.street.camera.project(s.street.free_ground_point.cast<double>(), px);
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    if (!ahead || x < 0 || y < 0 || x >= 160 || y >= 120) {
      ADD_FAILURE() << "seed " << seed << " out of frame";
      ++bad;
      continue;
    }
    const double expected = s.street.camera.world_to_camera(s.street.free_ground_point.cast<double>()).z();
    const bool ok = std::abs(s.buffers.depth.at<float>(y, x) - expected) < 0.02 * expected &&
                    s.buffers.normal.at<cv::Vec3f>(y, x)[1] > 0.99f;
    if (!ok) ADD_FAILURE() << "seed " << seed << ": depth " << s.buffers.depth.at<float>(y, x) << " expected " << expected;
    bad += !ok;
  }
  EXPECT_EQ(bad, 0);
}

TEST(SyntheticStreet, TheSunCastsShadowsTheSkyDoesNot) {
  // Rendered with and without the sun: the sun adds light somewhere and not
  // everywhere on the ground (shadows of buildings, kerbs and cars).
  SyntheticStreetSpec spec;
  spec.width = 96;
  spec.height = 72;
  spec.seed = 2;
  const SyntheticStreet st = make_synthetic_street(spec);
  ASSERT_EQ(st.lights.suns.size(), 1u);
  ASSERT_TRUE(st.lights.environment);
  Scene scene;
  scene.add_mesh(st.scene, Layer::Background);
  scene.commit();
  RenderSettings s;
  s.samples_per_pixel = 8;
  LightRig sky_only = st.lights;
  sky_only.suns.clear();
  const cv::Mat both = render_image(scene, st.camera, st.lights, s), sky = render_image(scene, st.camera, sky_only, s);
  const PrimaryBuffers b = render_primary_buffers(scene, st.camera, false);
  int lit = 0, shadowed = 0;
  for (int y = 0; y < 72; ++y)
    for (int x = 0; x < 96; ++x) {
      if (!(b.depth.at<float>(y, x) > 0) || b.normal.at<cv::Vec3f>(y, x)[1] < 0.99f) continue;
      const float gain = both.at<cv::Vec3f>(y, x)[1] / std::max(1e-6f, sky.at<cv::Vec3f>(y, x)[1]);
      (gain > 2.f ? lit : shadowed) += 1;
    }
  EXPECT_GT(lit, 50);
  EXPECT_GT(shadowed, 5);
}

}  // namespace
}  // namespace propcam::render
