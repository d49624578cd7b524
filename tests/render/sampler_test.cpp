#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "propcam/render/path_tracer.h"
#include "propcam/render/synthetic_room.h"
#include "sampler.h"

namespace propcam::render {
namespace {

using detail::SobolSampler;

// The draws of one sample: the camera's 2D, then 1D, 2D, 2D.
std::vector<float> draws(uint64_t seed, uint64_t pixel, uint32_t index) {
  SobolSampler s(seed, pixel, index);
  std::vector<float> out;
  const Eigen::Vector2f a = s.get2d();
  out.push_back(a.x()), out.push_back(a.y());
  out.push_back(s.get1d());
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector2f b = s.get2d();
    out.push_back(b.x()), out.push_back(b.y());
  }
  return out;
}

TEST(SobolSampler, DrawsArePureFunctionsOfSeedPixelIndexAndDimension) {
  EXPECT_EQ(draws(7, 1234, 5), draws(7, 1234, 5));
  EXPECT_NE(draws(7, 1234, 5), draws(7, 1234, 6));
  EXPECT_NE(draws(7, 1234, 5), draws(7, 1235, 5));
  EXPECT_NE(draws(7, 1234, 5), draws(8, 1234, 5));
  // A copy continues where the original stands (the differential render's two worlds).
  SobolSampler a(1, 2, 3);
  a.get2d();
  SobolSampler b = a;
  EXPECT_EQ(a.get2d(), b.get2d());
  EXPECT_EQ(a.get1d(), b.get1d());
  // Setting the dimension is the same as drawing up to it.
  SobolSampler c(1, 2, 3), d(1, 2, 3);
  c.get2d(), c.get1d();
  d.set_dimension(2);
  EXPECT_EQ(c.get2d(), d.get2d());
}

// The draws equal the textbook composition: the index shuffled by a nested
// uniform scramble, the Sobol point's coordinates scrambled each by its own seed.
TEST(SobolSampler, DrawsAreOwenScrambledSobolPoints) {
  using namespace detail;
  EXPECT_EQ(sobol_dimension1_reversed(0), 0u);
  for (uint32_t i = 0; i < 5000; ++i) {
    ASSERT_EQ(sobol_dimension1_reversed(i * 7919u), reverse_bits(sobol_dimension1(i * 7919u)));
    SobolSampler s(5, 77, i);
    s.set_dimension(static_cast<int>(i % 13));
    const uint32_t key = s.peek_dimension_key();
    const uint32_t shuffled = nested_uniform_scramble(i, key);
    const Eigen::Vector2f expected(
        fraction_to_unit(nested_uniform_scramble(sobol_dimension0(shuffled), hash_combine(key, 1u))),
        fraction_to_unit(nested_uniform_scramble(sobol_dimension1(shuffled), hash_combine(key, 2u))));
    ASSERT_EQ(s.get2d(), expected) << i;
  }
}

TEST(SobolSampler, EveryDrawIsInTheUnitInterval) {
  for (uint32_t index = 0; index < 4096; ++index) {
    SobolSampler s(0xfeed, index * 7919u, index);
    for (int d = 0; d < 16; ++d) {
      const Eigen::Vector2f u = s.get2d();
      const float v = s.get1d();
      ASSERT_GE(u.minCoeff(), 0.f);
      ASSERT_LT(u.maxCoeff(), 1.f);
      ASSERT_GE(v, 0.f);
      ASSERT_LT(v, 1.f);
    }
  }
}

// The first 2^m samples of a pixel, in any 2D draw, put exactly one point in
// every elementary interval of area 2^-m: a (0,m,2)-net, i.e. stratified in
// every aspect of grid at once.
TEST(SobolSampler, PowerOfTwoPrefixesAreZeroMTwoNets) {
  for (const int m : {2, 4, 6, 8}) {
    const uint32_t n = 1u << m;
    for (const int dimension : {0, 1, 5, 17}) {
      std::vector<Eigen::Vector2f> points;
      for (uint32_t i = 0; i < n; ++i) {
        SobolSampler s(42, 99, i);
        s.set_dimension(dimension);
        points.push_back(s.get2d());
      }
      for (int kx = 0; kx <= m; ++kx) {
        const int cells_x = 1 << kx, cells_y = 1 << (m - kx);
        std::set<int> cells;
        for (const auto& p : points)
          cells.insert(static_cast<int>(p.x() * cells_x) * cells_y + static_cast<int>(p.y() * cells_y));
        EXPECT_EQ(cells.size(), n) << "m " << m << " dimension " << dimension << " grid " << cells_x << "x" << cells_y;
      }
    }
  }
}

// Different draws of one sample are not correlated: the mean of the product
// of two dimensions' numbers is 1/4.
TEST(SobolSampler, DifferentDimensionsAreUncorrelated) {
  constexpr int kSamples = 4096;
  double product = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    SobolSampler s(3, 11, static_cast<uint32_t>(i));
    const float a = s.get1d();
    const float b = s.get1d();
    product += static_cast<double>(a) * b;
  }
  EXPECT_NEAR(product / kSamples, 0.25, 0.01);
}

// Passes that continue one pixel's sequence (first_sample) sum to the single
// render of all the samples, up to float rounding of the sums.
TEST(SobolSampler, ContinuingPassesSumToTheSingleRender) {
  SyntheticRoomSpec spec;
  spec.width = 24;
  spec.height = 18;
  const SyntheticRoom room = make_synthetic_room(spec);
  Scene scene;
  scene.add_mesh(room.room, Layer::Background);
  scene.commit();
  RenderSettings settings;
  settings.samples_per_pixel = 8;
  settings.max_bounces = 2;
  const cv::Mat whole = render_image(scene, room.camera, room.lights, settings);
  settings.samples_per_pixel = 4;
  const cv::Mat first = render_image(scene, room.camera, room.lights, settings);
  settings.first_sample = 4;
  const cv::Mat second = render_image(scene, room.camera, room.lights, settings);
  const cv::Mat summed = (first + second) * 0.5;
  EXPECT_LT(cv::norm(summed, whole, cv::NORM_INF), 1e-4 * (1.0 + cv::norm(whole, cv::NORM_INF)));
  // Not the same samples twice: the second pass differs from the first.
  EXPECT_GT(cv::norm(first, second, cv::NORM_INF), 1e-3);
}

}  // namespace
}  // namespace propcam::render
