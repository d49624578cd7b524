#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "propcam/inference/intensity_fit.h"

namespace propcam::inference {
namespace {

// Smooth, distinct synthetic "basis renders" over n pixels: light k falls off
// from its own position along a 1D strip.
std::vector<std::vector<float>> strip_basis(int sources, int n, double brightness) {
  std::vector<std::vector<float>> basis(sources, std::vector<float>(n));
  for (int k = 0; k < sources; ++k) {
    const double centre = (k + 0.5) / sources;
    for (int i = 0; i < n; ++i) {
      const double x = static_cast<double>(i) / (n - 1);
      basis[k][i] = static_cast<float>(brightness / (0.05 + (x - centre) * (x - centre)));
    }
  }
  return basis;
}

// The photo those lights make through a camera response x^gamma.
std::vector<float> encode(const std::vector<std::vector<float>>& basis, const std::vector<double>& w, double gamma) {
  std::vector<float> t(basis[0].size());
  for (size_t i = 0; i < t.size(); ++i) {
    double s = 0;
    for (size_t k = 0; k < basis.size(); ++k) s += w[k] * basis[k][i];
    t[i] = static_cast<float>(std::pow(s, gamma));
  }
  return t;
}

TEST(IntensityFit, RecoversWeightsAndAnSrgbLikeResponse) {
  IntensityFitProblem p;
  p.basis = strip_basis(4, 400, 0.002);  // peaks below 1: nothing clips
  const std::vector<double> truth = {2.0, 0.0, 5.0, 1.0};
  p.target = encode(p.basis, truth, 1.0 / 2.2);
  IntensityFitOptions paper;  // the paper's weights: the data decide the response
  paper.lambda_gamma_per_pixel = 0.0;
  const IntensityFitResult r = fit_intensities(p, paper);
  ASSERT_EQ(r.weights.size(), 4);
  EXPECT_NEAR(r.gamma, 1.0 / 2.2, 0.01);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(r.weights[k], truth[k], 0.02 * 5.0) << k;
  EXPECT_EQ(r.weights[1], 0.0) << "the unused light is pruned";
  EXPECT_LT(r.data_error, 0.01);
}

TEST(IntensityFit, FitsAResponseOtherThanThePrior) {
  // A camera with a flatter curve (gamma 1/1.6): the data pull gamma away
  // from 1/2.2 against the prior.
  IntensityFitProblem p;
  p.basis = strip_basis(3, 600, 0.004);
  const std::vector<double> truth = {1.0, 3.0, 2.0};
  p.target = encode(p.basis, truth, 1.0 / 1.6);
  IntensityFitOptions paper;
  paper.lambda_gamma_per_pixel = 0.0;
  const IntensityFitResult r = fit_intensities(p, paper);
  EXPECT_NEAR(r.gamma, 1.0 / 1.6, 0.02);
  // The default prior per pixel holds the response nearer the prior.
  const IntensityFitResult d = fit_intensities(p);
  EXPECT_LT(std::abs(d.gamma - 1.0 / 2.2), std::abs(r.gamma - 1.0 / 2.2));
  IntensityFitOptions held;
  held.fit_gamma = false;
  const IntensityFitResult h = fit_intensities(p, held);
  EXPECT_DOUBLE_EQ(h.gamma, 1.0 / 2.2);
  EXPECT_GT(h.data_error, r.data_error);
}

TEST(IntensityFit, SparsityPrunesARedundantLightAndNoiseDisfavoursTheNoisyTwin) {
  // Two identical basis renders: any split fits. The noise prior makes the
  // noisy one lose; the sparsity prior turns it off.
  IntensityFitProblem p;
  auto one = strip_basis(1, 300, 0.01)[0];
  p.basis = {one, one};
  p.target = encode({one}, {3.0}, 1.0 / 2.2);
  p.noise = {0.0, 5.0};
  const IntensityFitResult r = fit_intensities(p);
  EXPECT_EQ(r.weights[1], 0.0);
  EXPECT_NEAR(r.weights[0], 3.0, 0.15);
}

TEST(IntensityFit, HeldWeightsStayAndDeadLightsStayOff) {
  IntensityFitProblem p;
  p.basis = strip_basis(3, 200, 0.01);
  std::fill(p.basis[2].begin(), p.basis[2].end(), 0.0f);  // lights nothing
  p.target = encode(p.basis, {1.0, 2.0, 0.0}, 1.0 / 2.2);
  p.lower = {1.0, 0.0, 0.0};
  p.upper = {1.0, 1e9, 1e9};
  const IntensityFitResult r = fit_intensities(p);
  EXPECT_DOUBLE_EQ(r.weights[0], 1.0);
  EXPECT_NEAR(r.weights[1], 2.0, 0.1);
  EXPECT_EQ(r.weights[2], 0.0);
}

TEST(IntensityFit, BasisNoiseRanksANoisyRenderAboveASmoothOne) {
  cv::Mat smooth(64, 64, CV_32FC3), noisy(64, 64, CV_32FC3);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      const float v = 0.5f + 0.004f * x;
      smooth.at<cv::Vec3f>(y, x) = {v, v, v};
      const float n = v * 2.f * u(rng);
      noisy.at<cv::Vec3f>(y, x) = {n, n, n};
    }
  EXPECT_LT(basis_noise(smooth, {}), 0.02);
  EXPECT_GT(basis_noise(noisy, {}), 10 * basis_noise(smooth, {}));
  EXPECT_EQ(basis_noise(cv::Mat::zeros(8, 8, CV_32FC3), {}), 0.0);
}

}  // namespace
}  // namespace propcam::inference
