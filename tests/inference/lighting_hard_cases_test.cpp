// Hard cases of the lighting stage (issue 5): finite, deterministic lights
// and camera response, or a clear report, whatever the photo.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "propcam/inference/intensity_fit.h"
#include "propcam/inference/lighting.h"
#include "propcam/render/camera.h"

namespace propcam::inference {
namespace {

// A level 64x48 camera 1.5 m up, looking at a wall 4 m away over a floor:
// depth of that box, grey albedo.
struct Stage {
  render::PinholeCamera camera = render::pinhole_with_fov(64, 48, 60.0);
  cv::Mat depth = cv::Mat(48, 64, CV_32F);
  cv::Mat albedo = cv::Mat(48, 64, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  std::vector<SupportPlane> planes;
  Stage() {
    camera.center_world = {0, 1.5, 0};
    camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, 0, 0);
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x) {
        const double ray_y = (y - camera.cy) / camera.fy;  // down
        const double floor = ray_y > 1e-6 ? 1.5 / ray_y : 1e9;
        depth.at<float>(y, x) = static_cast<float>(std::min(4.0, floor));
      }
    SupportPlane floor;
    floor.name = "floor";
    floor.normal = {0, 1, 0};
    planes.push_back(floor);
  }
};

LightingOptions fast() {
  LightingOptions o;
  o.fit_width = 32;
  o.fit_samples_per_pixel = 2;
  o.max_fit_pixels = 256;
  return o;
}

void expect_finite(const LightingEstimate& e) {
  EXPECT_TRUE(std::isfinite(e.gamma) && e.gamma > 0);
  EXPECT_FALSE(e.lights.empty());
  for (const auto& l : e.lights) {
    EXPECT_TRUE(l.intensity.allFinite());
    EXPECT_GE(l.intensity.minCoeff(), 0.0);
    EXPECT_TRUE(l.corner.allFinite() && l.edge_u.allFinite() && l.edge_v.allFinite());
  }
  for (const auto& r : e.reports) EXPECT_TRUE(std::isfinite(r.error)) << r.stage;
}

void expect_same(const LightingEstimate& a, const LightingEstimate& b) {
  ASSERT_EQ(a.lights.size(), b.lights.size());
  for (size_t i = 0; i < a.lights.size(); ++i) EXPECT_EQ(a.lights[i].intensity, b.lights[i].intensity);
  EXPECT_EQ(a.gamma, b.gamma);
}

LightingEstimate run(const cv::Mat& photo, bool indoor = true) {
  const Stage s;
  const LightingEstimate a = estimate_lighting(photo, s.depth, s.albedo, s.camera, s.planes, indoor, fast());
  const LightingEstimate b = estimate_lighting(photo, s.depth, s.albedo, s.camera, s.planes, indoor, fast());
  expect_same(a, b);
  return a;
}

TEST(LightingHardCases, BlackPhoto) { expect_finite(run(cv::Mat::zeros(48, 64, CV_32FC3))); }

TEST(LightingHardCases, FullySaturatedWindow) {
  cv::Mat photo(48, 64, CV_32FC3, cv::Scalar(0.2, 0.2, 0.2));
  photo(cv::Rect(20, 4, 24, 16)).setTo(cv::Scalar(50, 50, 50));  // a blown-out window in the wall
  const LightingEstimate e = run(photo);
  expect_finite(e);
  EXPECT_GT(cv::countNonZero(e.source_mask), 0) << "the window is a visible source";
}

TEST(LightingHardCases, SingleTinyLight) {
  cv::Mat photo(48, 64, CV_32FC3, cv::Scalar(0.1, 0.1, 0.1));
  photo(cv::Rect(31, 5, 2, 2)).setTo(cv::Scalar(20, 20, 20));
  expect_finite(run(photo));
}

TEST(LightingHardCases, LitOnlyFromBehindTheCamera) {
  // Even shading that no visible source explains: out-of-view hypotheses (or
  // the environment) must carry it.
  const LightingEstimate e = run(cv::Mat(48, 64, CV_32FC3, cv::Scalar(0.3, 0.28, 0.25)));
  expect_finite(e);
  double total = 0;
  for (const auto& l : e.lights) total += l.intensity.sum();
  EXPECT_GT(total, 0.0);
}

TEST(LightingHardCases, OutdoorsWithoutASky) { expect_finite(run(cv::Mat(48, 64, CV_32FC3, cv::Scalar(0.4, 0.4, 0.4)), false)); }

// A measured sky over a ground far darker or brighter than any albedo it
// could light: the albedo's scale stops at its bounds, the output stays
// finite and deterministic, and the sky keeps its measured radiance.
TEST(LightingHardCases, AlbedoScaleFromTheSkyAtItsBounds) {
  const Stage s;
  SkyEstimate sky;
  sky.mask = cv::Mat::zeros(48, 64, CV_8U);
  sky.mask.rowRange(0, 8).setTo(255);
  sky.fraction = 8.0 / 48.0;
  sky.mean_colour = {0.6, 0.7, 0.9};
  sky.blue = true;
  for (const double ground : {1e-4, 0.97}) {
    const cv::Mat photo(48, 64, CV_32FC3, cv::Scalar(ground, ground, ground));
    const LightingEstimate a = estimate_lighting(photo, s.depth, s.albedo, s.camera, s.planes, false, fast(), &sky);
    const LightingEstimate b = estimate_lighting(photo, s.depth, s.albedo, s.camera, s.planes, false, fast(), &sky);
    expect_finite(a);
    expect_same(a, b);
    EXPECT_EQ(a.albedo_scale, b.albedo_scale);
    EXPECT_TRUE(std::isfinite(a.albedo_scale));
    EXPECT_GE(a.albedo_scale, 0.1) << ground;
    EXPECT_LE(a.albedo_scale, 1.9) << ground;
    ASSERT_EQ(a.lights.back().type, LightSource::Type::Ibl);
    EXPECT_EQ(a.lights.back().intensity, Eigen::Vector3d::Ones()) << "the sky is a measurement";
  }
}

TEST(LightingHardCases, GammaDrivenToItsBound) {
  // A photo made with a response steeper than the search allows: gamma stops
  // at its bound, finite.
  IntensityFitProblem p;
  p.basis.assign(1, std::vector<float>(100));
  for (int i = 0; i < 100; ++i) p.basis[0][i] = 0.001f * (i + 1);
  for (int i = 0; i < 100; ++i) p.target.push_back(std::pow(p.basis[0][i], 0.08f));
  IntensityFitOptions o;
  o.lambda_gamma_per_pixel = 0.0;
  const IntensityFitResult r = fit_intensities(p, o);
  EXPECT_NEAR(r.gamma, o.min_gamma, 1e-3);
  EXPECT_TRUE(r.weights.allFinite());
}

}  // namespace
}  // namespace propcam::inference

namespace propcam::inference {
namespace {

const StageReport* report(const LightingEstimate& e, const std::string& stage) {
  for (const auto& r : e.reports)
    if (r.stage == stage) return &r;
  return nullptr;
}

// The committed ranker adds its panorama's lights; a missing or corrupt one
// is reported and the hypotheses alone stay (each run twice).
TEST(LightingHardCases, MissingOrCorruptIblRankerFallsBackToTheHypotheses) {
  cv::Mat photo(48, 64, CV_32FC3, cv::Scalar(0.3, 0.25, 0.2));
  const LightingEstimate with = run(photo);
  const StageReport* ranked = report(with, "ibl_ranking");
  ASSERT_NE(ranked, nullptr);
  EXPECT_TRUE(ranked->usable) << ranked->why;
  EXPECT_GE(ranked->details["ranked_candidates"].get<int>(), 1);
  const std::string corrupt = ::testing::TempDir() + "/corrupt_ranker.yml";
  std::ofstream(corrupt) << "%YAML:1.0\nformat: propcam-ibl-ranker\nversion: 1\nweights: [1, 2, 3]\n";
  for (const std::string& path : {std::string("/nonexistent/ranker.yml.gz"), corrupt}) {
    LightingOptions o = fast();
    o.ibl_ranker = path;
    const Stage s;
    const LightingEstimate a = estimate_lighting(photo, s.depth, s.albedo, s.camera, s.planes, true, o);
    const LightingEstimate b = estimate_lighting(photo, s.depth, s.albedo, s.camera, s.planes, true, o);
    expect_same(a, b);
    expect_finite(a);
    const StageReport* r = report(a, "ibl_ranking");
    ASSERT_NE(r, nullptr);
    EXPECT_FALSE(r->usable);
    EXPECT_NE(r->why.find(path), std::string::npos) << r->why;
    EXPECT_EQ(r->details["ranked_candidates"].get<int>(), 0);
    EXPECT_GT(r->details["hypotheses"].get<int>(), 0);
  }
}

}  // namespace
}  // namespace propcam::inference
