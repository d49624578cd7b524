// Correctness of the BSDFs in isolation: reciprocity, energy, sample/pdf
// consistency, pdf normalisation and the sampled distribution, Snell and
// total internal reflection, and no NaN anywhere.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "bsdf.h"
#include "sampling.h"

namespace propcam::render {
namespace {

using detail::Bsdf;
using detail::BsdfSample;
using detail::Rng;
using Eigen::Vector3f;

constexpr double kPi = std::numbers::pi;
// f(wo,wi) and f(wi,wo) agree to float round-off (relative).
constexpr float kReciprocityTolerance = 1e-4f;
// The Monte Carlo albedo may exceed 1 by this much (noise of kEnergySamples samples).
constexpr double kEnergyTolerance = 0.02;
constexpr int kEnergySamples = 20000;
// Smooth glass loses nothing: reflected + transmitted energy is 1 within this.
constexpr double kLosslessTolerance = 0.01;
// The pdf sample() reports equals pdf() to float round-off (relative).
constexpr float kPdfMatchTolerance = 1e-5f;
// Integral of pdf over the sphere plus the fraction of failed samples is 1 within this.
constexpr double kPdfIntegralTolerance = 0.02;
// Histogram bins: observed frequency within this many standard deviations
// (plus an absolute slack for the grid integration of the expected value).
constexpr double kHistogramSigmas = 5.0;
constexpr double kHistogramSlack = 2e-3;
constexpr int kHistogramSamples = 200000;
constexpr int kGridZ = 256, kGridPhi = 512;     // integration grid over the sphere (equal-area cells)
constexpr int kBinsZ = 8, kBinsPhi = 16;        // histogram bins (groups of grid cells)

Vector3f direction(double theta_deg, double phi_deg) {
  const double t = theta_deg * kPi / 180.0, p = phi_deg * kPi / 180.0;
  return Vector3f(static_cast<float>(std::sin(t) * std::cos(p)), static_cast<float>(std::sin(t) * std::sin(p)),
                  static_cast<float>(std::cos(t)));
}

// Equal-area parameterisation of the sphere: z uniform in [-1,1], phi uniform.
Vector3f sphere_point(double z, double phi) {
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Vector3f(static_cast<float>(r * std::cos(phi)), static_cast<float>(r * std::sin(phi)), static_cast<float>(z));
}

Vector3f upper_hemisphere(Rng& rng) {
  return sphere_point(rng.uniform(), 2.0 * kPi * rng.uniform());
}

struct BsdfCase {
  std::string name;
  Material material;
  bool entering = true;
  bool broad = true;  // lobes wide enough for grid integration
};

Material make(Material::Type type, float roughness, Vector3f albedo = Vector3f(0.8f, 0.5f, 0.2f)) {
  Material m;
  m.type = type;
  m.roughness = roughness;
  m.albedo = albedo;
  return m;
}

std::vector<BsdfCase> cases() {
  return {
      {"diffuse", make(Material::Type::Diffuse, 1.f), true, true},
      {"plastic_rough", make(Material::Type::Plastic, 0.4f), true, true},
      {"plastic_smooth", make(Material::Type::Plastic, 0.05f), true, false},
      {"metal_rough", make(Material::Type::Metal, 0.35f, {0.95f, 0.64f, 0.54f}), true, true},
      {"metal_mirror", make(Material::Type::Metal, 0.f, {0.95f, 0.64f, 0.54f}), true, false},
      {"glass_rough_entering", make(Material::Type::Dielectric, 0.3f), true, true},
      {"glass_rough_leaving", make(Material::Type::Dielectric, 0.3f), false, true},
      {"glass_smooth_entering", make(Material::Type::Dielectric, 0.f), true, false},
      {"glass_smooth_leaving", make(Material::Type::Dielectric, 0.f), false, false},
  };
}

class BsdfTest : public ::testing::TestWithParam<BsdfCase> {
 protected:
  Bsdf bsdf() const { return Bsdf(GetParam().material, GetParam().material.albedo, GetParam().entering); }
};

const std::vector<double> kViewAngles = {0.0, 20.0, 40.0, 60.0, 75.0, 85.0, 89.0};

TEST_P(BsdfTest, ReflectionIsReciprocal) {
  const Bsdf b = bsdf();
  Rng rng(11, 1);
  for (int i = 0; i < 4000; ++i) {
    const Vector3f wo = upper_hemisphere(rng), wi = upper_hemisphere(rng);
    const Vector3f a = b.eval(wo, wi), c = b.eval(wi, wo);
    ASSERT_TRUE(a.allFinite() && c.allFinite());
    const float scale = std::max({1.f, a.maxCoeff(), c.maxCoeff()});
    ASSERT_LE((a - c).cwiseAbs().maxCoeff(), kReciprocityTolerance * scale)
        << "wo " << wo.transpose() << " wi " << wi.transpose() << " f " << a.transpose() << " vs " << c.transpose();
  }
}

// Directional albedo (energy, i.e. without the 1/eta^2 radiance scaling of
// refraction) by Monte Carlo over the BSDF's own samples.
Eigen::Vector3d albedo(const Bsdf& b, const Vector3f& wo, uint64_t seed) {
  Rng rng(seed, 3);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int i = 0; i < kEnergySamples; ++i) {
    BsdfSample s;
    const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
    if (!b.sample(wo, u0, u1, u2, s)) continue;
    double w = std::abs(s.wi.z()) / s.pdf;
    if (s.transmitted) w *= static_cast<double>(b.eta()) * b.eta();
    sum += s.f.cast<double>() * w;
  }
  return sum / kEnergySamples;
}

TEST_P(BsdfTest, AlbedoNeverExceedsOne) {
  const Bsdf b = bsdf();
  for (double theta : kViewAngles) {
    const Eigen::Vector3d a = albedo(b, direction(theta, 30.0), 5);
    ASSERT_TRUE(a.allFinite());
    EXPECT_LE(a.maxCoeff(), 1.0 + kEnergyTolerance) << "theta " << theta << " albedo " << a.transpose();
    EXPECT_GE(a.minCoeff(), 0.0);
  }
}

TEST_P(BsdfTest, SampledPdfAndValueMatchPdfAndEval) {
  const Bsdf b = bsdf();
  Rng rng(7, 2);
  for (double theta : kViewAngles) {
    const Vector3f wo = direction(theta, 70.0);
    int produced = 0;
    for (int i = 0; i < 4000; ++i) {
      BsdfSample s;
      const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
      if (!b.sample(wo, u0, u1, u2, s)) continue;
      ++produced;
      ASSERT_TRUE(s.f.allFinite() && std::isfinite(s.pdf) && s.pdf > 0.f);
      EXPECT_NEAR(s.wi.norm(), 1.f, 1e-5f);
      EXPECT_EQ(s.transmitted, s.wi.z() < 0.f);
      const float p = b.pdf(wo, s.wi);
      ASSERT_NEAR(s.pdf, p, kPdfMatchTolerance * std::max(1.f, p)) << "theta " << theta;
      ASSERT_LE((s.f - b.eval(wo, s.wi)).cwiseAbs().maxCoeff(), kPdfMatchTolerance * std::max(1.f, s.f.maxCoeff()));
    }
    EXPECT_GT(produced, 0) << "theta " << theta;
  }
}

// The pdf integrates to the probability that sample() produces a direction,
// and sampled directions fall into bins of the sphere as often as the pdf says.
// Only for lobes wide enough for grid integration; the near-delta ones are
// covered by the energy tests (their albedo would be off if the pdf were).
class BsdfDistributionTest : public BsdfTest {};

TEST_P(BsdfDistributionTest, PdfIntegratesToOneAndMatchesTheSampleHistogram) {
  const Bsdf b = bsdf();
  for (double theta : {10.0, 50.0, 80.0}) {
    const Vector3f wo = direction(theta, 0.0);
    std::vector<double> expected(kBinsZ * kBinsPhi, 0.0), observed(kBinsZ * kBinsPhi, 0.0);
    const double cell = 4.0 * kPi / (static_cast<double>(kGridZ) * kGridPhi);  // solid angle per grid cell
    double integral = 0.0;
    for (int iz = 0; iz < kGridZ; ++iz)
      for (int ip = 0; ip < kGridPhi; ++ip) {
        const double z = -1.0 + 2.0 * (iz + 0.5) / kGridZ, phi = 2.0 * kPi * (ip + 0.5) / kGridPhi;
        const double p = b.pdf(wo, sphere_point(z, phi)) * cell;
        integral += p;
        expected[(iz * kBinsZ / kGridZ) * kBinsPhi + ip * kBinsPhi / kGridPhi] += p;
      }
    Rng rng(3, 9);
    int failed = 0;
    for (int i = 0; i < kHistogramSamples; ++i) {
      BsdfSample s;
      const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
      if (!b.sample(wo, u0, u1, u2, s)) {
        ++failed;
        continue;
      }
      double phi = std::atan2(s.wi.y(), s.wi.x());
      if (phi < 0) phi += 2.0 * kPi;
      const int bz = std::clamp(static_cast<int>((s.wi.z() + 1.0) / 2.0 * kBinsZ), 0, kBinsZ - 1);
      const int bp = std::clamp(static_cast<int>(phi / (2.0 * kPi) * kBinsPhi), 0, kBinsPhi - 1);
      observed[bz * kBinsPhi + bp] += 1.0 / kHistogramSamples;
    }
    const double fail_fraction = static_cast<double>(failed) / kHistogramSamples;
    EXPECT_NEAR(integral + fail_fraction, 1.0, kPdfIntegralTolerance)
        << "theta " << theta << ": integral " << integral << ", failed " << fail_fraction;
    for (size_t k = 0; k < expected.size(); ++k) {
      const double sigma = std::sqrt(std::max(expected[k], 1e-9) / kHistogramSamples);
      EXPECT_NEAR(observed[k], expected[k], kHistogramSigmas * sigma + kHistogramSlack)
          << "theta " << theta << " bin z " << k / kBinsPhi << " phi " << k % kBinsPhi;
    }
  }
}

TEST_P(BsdfTest, NoNaNForDegenerateDirections) {
  const Bsdf b = bsdf();
  const std::vector<Vector3f> dirs = {
      {0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}, direction(89.9999, 10), direction(90.0 - 1e-6, 0),
      direction(1e-6, 0), direction(45, 45), Vector3f(0.6f, 0.f, 0.8f), Vector3f(-0.6f, 0.f, -0.8f),
      Vector3f(0.f, 0.f, 0.f)};
  for (const Vector3f& wo : dirs)
    for (const Vector3f& wi : dirs) {
      const Vector3f f = b.eval(wo, wi);
      const float p = b.pdf(wo, wi);
      ASSERT_TRUE(f.allFinite()) << wo.transpose() << " | " << wi.transpose();
      ASSERT_TRUE(std::isfinite(p) && p >= 0.f) << wo.transpose() << " | " << wi.transpose();
    }
  Rng rng(5, 5);
  for (const Vector3f& wo : dirs)
    for (int i = 0; i < 2000; ++i) {
      BsdfSample s;
      const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
      if (!b.sample(wo, u0, u1, u2, s)) continue;
      ASSERT_TRUE(s.wi.allFinite() && s.f.allFinite() && std::isfinite(s.pdf) && s.pdf > 0.f) << wo.transpose();
    }
  // The extreme random numbers (0 and just below 1).
  for (const Vector3f& wo : dirs)
    for (float u : {0.f, 0.5f, 0x1.fffffep-1f})
      for (float v : {0.f, 0.5f, 0x1.fffffep-1f}) {
        BsdfSample s;
        if (b.sample(wo, u, v, u, s)) {
          ASSERT_TRUE(s.f.allFinite() && std::isfinite(s.pdf));
        }
      }
}

std::vector<BsdfCase> broad_cases() {
  std::vector<BsdfCase> out;
  for (const BsdfCase& c : cases())
    if (c.broad) out.push_back(c);
  return out;
}

INSTANTIATE_TEST_SUITE_P(Materials, BsdfTest, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return info.param.name; });
INSTANTIATE_TEST_SUITE_P(Materials, BsdfDistributionTest, ::testing::ValuesIn(broad_cases()),
                         [](const auto& info) { return info.param.name; });

TEST(Bsdf, SmoothGlassReflectsPlusTransmitsEverything) {
  for (bool entering : {true, false}) {
    const Bsdf b(make(Material::Type::Dielectric, 0.f), Vector3f::Ones(), entering);
    for (double theta : {0.0, 20.0, 40.0, 60.0, 75.0, 85.0}) {
      const Eigen::Vector3d a = albedo(b, direction(theta, 0.0), 17);
      EXPECT_NEAR(a.x(), 1.0, kLosslessTolerance) << (entering ? "entering" : "leaving") << " theta " << theta;
    }
  }
}

TEST(Bsdf, WhitePlasticUnderASmoothCoatLosesAlmostNothing) {
  const Bsdf b(make(Material::Type::Plastic, 0.f, Vector3f::Ones()), Vector3f::Ones());
  for (double theta : {0.0, 30.0, 60.0, 75.0}) {
    const Eigen::Vector3d a = albedo(b, direction(theta, 0.0), 19);
    EXPECT_NEAR(a.x(), 1.0, 2 * kLosslessTolerance) << "theta " << theta;
  }
}

TEST(Bsdf, FresnelOfGlass) {
  EXPECT_NEAR(detail::fresnel_dielectric(1.f, 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(detail::fresnel_dielectric(1.f, 1.f / 1.5f), 0.04f, 1e-6f);
  EXPECT_FLOAT_EQ(detail::fresnel_dielectric(0.f, 1.5f), 1.f);
  // Beyond the critical angle (41.8 deg) from inside: total internal reflection.
  EXPECT_FLOAT_EQ(detail::fresnel_dielectric(std::cos(45.f * static_cast<float>(kPi) / 180.f), 1.f / 1.5f), 1.f);
  // Brewster's angle: the parallel polarisation vanishes, R = r_perp^2 / 2.
  const float brewster = std::atan(1.5f);
  EXPECT_NEAR(detail::fresnel_dielectric(std::cos(brewster), 1.5f), 0.0739f, 1e-3f);
}

TEST(Bsdf, SmoothGlassRefractsBySnellsLaw) {
  const float eta = 1.5f;
  const Bsdf b(make(Material::Type::Dielectric, 0.f), Vector3f::Ones(), true);
  const Vector3f wo = direction(45.0, 0.0);
  Rng rng(1, 1);
  int transmitted = 0, on_snell = 0;
  for (int i = 0; i < 1000; ++i) {
    BsdfSample s;
    const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
    if (!b.sample(wo, u0, u1, u2, s) || !s.transmitted) continue;
    ++transmitted;
    const float sin_t = std::sqrt(s.wi.x() * s.wi.x() + s.wi.y() * s.wi.y());
    if (std::abs(sin_t - std::sin(45.f * static_cast<float>(kPi) / 180.f) / eta) < 2e-3f) ++on_snell;
    EXPECT_LT(s.wi.x(), 0.f);  // continues to the other side of the normal
  }
  EXPECT_GT(transmitted, 900);  // Fresnel reflects ~5% at 45 degrees
  // GGX has long tails even at the smallest alpha: nearly all, not all, on Snell's direction.
  EXPECT_GT(on_snell, 0.97 * transmitted);
}

TEST(Bsdf, TotalInternalReflectionNeverTransmits) {
  const Bsdf b(make(Material::Type::Dielectric, 0.f), Vector3f::Ones(), false);  // inside glass
  const Vector3f wo = direction(60.0, 0.0);  // beyond the critical angle
  Rng rng(2, 2);
  for (int i = 0; i < 1000; ++i) {
    BsdfSample s;
    const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
    if (!b.sample(wo, u0, u1, u2, s)) continue;
    EXPECT_FALSE(s.transmitted);
  }
  EXPECT_FLOAT_EQ(b.pdf(wo, direction(150.0, 180.0)), 0.f);
}

TEST(Bsdf, DegenerateMaterialParametersStayFinite) {
  std::vector<Material> materials;
  for (auto type : {Material::Type::Plastic, Material::Type::Metal, Material::Type::Dielectric}) {
    for (float roughness : {0.f, -1.f, 1e-9f, NAN, 5.f}) {
      Material m = make(type, roughness);
      materials.push_back(m);
    }
    for (float ior : {1.f, 0.f, -2.f, NAN, 1e6f}) {
      Material m = make(type, 0.2f);
      m.ior = ior;
      m.specular = ior;
      materials.push_back(m);
    }
  }
  Rng rng(9, 9);
  for (const Material& m : materials)
    for (bool entering : {true, false}) {
      const Bsdf b(m, Vector3f(NAN, 2.f, -1.f), entering);
      for (int i = 0; i < 500; ++i) {
        const Vector3f wo = upper_hemisphere(rng);
        BsdfSample s;
        const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
        if (b.sample(wo, u0, u1, u2, s)) {
          ASSERT_TRUE(s.f.allFinite() && std::isfinite(s.pdf));
        }
        const Vector3f wi = sphere_point(2.0 * rng.uniform() - 1.0, 2.0 * kPi * rng.uniform());
        ASSERT_TRUE(b.eval(wo, wi).allFinite());
        ASSERT_TRUE(std::isfinite(b.pdf(wo, wi)));
      }
    }
}

TEST(Bsdf, MaterialNamesIncludeTheNewTypesAndKeepGlossy) {
  EXPECT_EQ(material_type_from_string("glossy"), Material::Type::Glossy);
  EXPECT_EQ(material_type_from_string("plastic"), Material::Type::Plastic);
  EXPECT_EQ(material_type_from_string("glass"), Material::Type::Dielectric);
  EXPECT_EQ(material_type_from_string("dielectric"), Material::Type::Dielectric);
  EXPECT_EQ(material_type_from_string("metal"), Material::Type::Metal);
  EXPECT_THROW(material_type_from_string("velvet"), std::invalid_argument);
  EXPECT_STREQ(to_string(Material::Type::Dielectric), "dielectric");
  Material m;
  m.specular = 0.04f;
  EXPECT_NEAR(m.coat_ior(), 1.5f, 1e-5f);
}

}  // namespace
}  // namespace propcam::render
