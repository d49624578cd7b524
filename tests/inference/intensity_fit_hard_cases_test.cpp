// Hard cases of the intensity and camera-response fit: finite, deterministic
// output or a clear error.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "propcam/inference/intensity_fit.h"

namespace propcam::inference {
namespace {

// Two ramps across 100 pixels, one rising, one falling.
IntensityFitProblem ramps(float target) {
  IntensityFitProblem p;
  p.basis.assign(2, std::vector<float>(100));
  for (int i = 0; i < 100; ++i) {
    p.basis[0][i] = 0.01f * (i + 1);
    p.basis[1][i] = 0.01f * (100 - i);
  }
  p.target.assign(100, target);
  return p;
}

void expect_finite(const IntensityFitResult& r) {
  EXPECT_TRUE(std::isfinite(r.gamma) && r.gamma > 0);
  EXPECT_TRUE(r.weights.allFinite());
  EXPECT_TRUE((r.weights.array() >= 0).all());
  EXPECT_TRUE(std::isfinite(r.data_error));
}

TEST(IntensityFitHardCases, BlackPhoto) { expect_finite(fit_intensities(ramps(0.0f))); }

TEST(IntensityFitHardCases, SaturatedPhotoWithNonFiniteBasisValues) {
  IntensityFitProblem p = ramps(1.0f);
  p.basis[0][7] = std::numeric_limits<float>::quiet_NaN();
  p.basis[1][9] = std::numeric_limits<float>::infinity();
  p.target[3] = std::numeric_limits<float>::quiet_NaN();
  const IntensityFitResult a = fit_intensities(p);
  expect_finite(a);
  const IntensityFitResult b = fit_intensities(p);  // deterministic
  EXPECT_EQ(a.weights, b.weights);
  EXPECT_EQ(a.gamma, b.gamma);
}

TEST(IntensityFitHardCases, AllBasisRendersBlack) {
  IntensityFitProblem p = ramps(0.5f);
  for (auto& b : p.basis) std::fill(b.begin(), b.end(), 0.0f);
  const IntensityFitResult r = fit_intensities(p);
  expect_finite(r);
  EXPECT_EQ(r.weights.sum(), 0.0);
}

TEST(IntensityFitHardCases, IdenticalBasisRendersCollinearColumns) {
  // Three copies of one light: any split fits; the answer must still be
  // finite, deterministic and carry the whole light.
  IntensityFitProblem p = ramps(0.5f);
  p.basis = {p.basis[0], p.basis[0], p.basis[0]};
  for (int i = 0; i < 100; ++i) p.target[i] = std::pow(0.8f * p.basis[0][i], 1.0f / 2.2f);  // nothing clips
  const IntensityFitResult a = fit_intensities(p);
  const IntensityFitResult b = fit_intensities(p);
  expect_finite(a);
  EXPECT_EQ(a.weights, b.weights);
  EXPECT_NEAR(a.weights.sum(), 0.8, 0.04);
}

TEST(IntensityFitHardCases, NoSourcesOrNoPixelsSayWhy) {
  IntensityFitProblem none;
  const IntensityFitResult r = fit_intensities(none);
  EXPECT_EQ(r.weights.size(), 0);
  EXPECT_EQ(r.termination, "no light sources");
  IntensityFitProblem no_pixels;
  no_pixels.basis.assign(2, {});
  EXPECT_EQ(fit_intensities(no_pixels).termination, "no pixels to fit");
}

TEST(IntensityFitHardCases, InconsistentSizesAreRejected) {
  IntensityFitProblem p = ramps(0.5f);
  p.basis[1].pop_back();
  EXPECT_THROW(fit_intensities(p), std::invalid_argument);
  IntensityFitProblem q = ramps(0.5f);
  q.noise = {1.0};
  EXPECT_THROW(fit_intensities(q), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::inference
