// Outdoors the seen sky is a radiance measurement, and it fixes the albedo's
// scale that a single photo leaves open (LightingOptions::albedo_scale_from_sky).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "common/compositor.h"
#include "propcam/inference/infer.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/props.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

// A 320x240 generator street and the geometry inferred from it.
struct InferredStreet {
  SyntheticShot shot;
  inference::GeometryEstimate geometry;
};

InferredStreet inferred_street(uint64_t seed, int samples_per_pixel) {
  render::SyntheticStreetSpec spec;
  spec.width = 320;
  spec.height = 240;
  spec.seed = seed;
  render::RenderSettings settings;
  settings.samples_per_pixel = samples_per_pixel;
  InferredStreet s;
  s.shot = shoot_synthetic_street(spec, settings);
  s.geometry = inference::infer_geometry(s.shot.photo_linear, inference::InferenceOptions{});
  return s;
}

struct Fitted {
  double albedo_scale = 0, mean_albedo = 0, brightest_light = 0;
};

Fitted fit_street(const SyntheticShot& shot, const inference::GeometryEstimate& g, double assumed_mean_albedo,
                  bool scale_from_sky) {
  inference::InferenceOptions o;
  o.albedo.mean_albedo = assumed_mean_albedo;
  o.lighting.albedo_scale_from_sky = scale_from_sky;
  const inference::SceneModel est = inference::complete_scene(shot.photo_linear, g, o);
  Fitted f;
  for (const auto& r : est.reports)
    if (r.stage == "light_intensities") f.albedo_scale = r.details.at("albedo_scale").get<double>();
  f.mean_albedo = cv::mean(est.albedo)[1];
  for (const auto& l : est.lights)
    if (l.type != inference::LightSource::Type::Ibl) f.brightest_light = std::max(f.brightest_light, l.intensity.maxCoeff());

  return f;
}

// The albedo's assumed mean is a guess the photo cannot check; with the sky
// setting the scale, halving the guess must not change the fitted albedo or
// the lights (it doubles the scale instead). Without it, the lights follow
// the guess.
TEST(StreetLighting, TheSkyNotTheAssumedMeanSetsTheAlbedoScale) {
  const InferredStreet street = inferred_street(8, 16);  // sky in view, and a sun the fit keeps
  const SyntheticShot& shot = street.shot;
  const inference::GeometryEstimate& g = street.geometry;
  ASSERT_FALSE(g.indoor);
  const Fitted a = fit_street(shot, g, 0.5, true), b = fit_street(shot, g, 0.25, true);
  ASSERT_GT(a.albedo_scale, 0.1);
  ASSERT_LT(b.albedo_scale, 1.9);  // neither at a bound, so the scale is free
  EXPECT_NEAR(b.albedo_scale / a.albedo_scale, 2.0, 0.3);
  EXPECT_NEAR(b.mean_albedo / a.mean_albedo, 1.0, 0.15);
  // The sparsity prior is not scale-free (it weighs the lights before the
  // division by the scale), so the sun moves a little.
  ASSERT_GT(a.brightest_light, 0);
  EXPECT_NEAR(b.brightest_light / a.brightest_light, 1.0, 0.35);
  const Fitted fixed_a = fit_street(shot, g, 0.5, false), fixed_b = fit_street(shot, g, 0.25, false);
  EXPECT_EQ(fixed_a.albedo_scale, 1.0);
  EXPECT_EQ(fixed_b.albedo_scale, 1.0);
  EXPECT_NEAR(fixed_b.mean_albedo / fixed_a.mean_albedo, 0.5, 0.1);
}

// The mean albedo of what the photo shows (its surfaces, not the sky) and
// the irradiance of the brightest distant light (the sun) of a street fitted
// with LightingOptions::min_mean_albedo at `floor`.
struct Floored {
  double albedo_scale = 0, seen_mean_albedo = 0, sun_irradiance = 0;
};

Floored fit_with_albedo_floor(const InferredStreet& street, double floor) {
  inference::InferenceOptions o;
  o.lighting.min_mean_albedo = floor;
  const inference::SceneModel est = inference::complete_scene(street.shot.photo_linear, street.geometry, o);
  Floored f;
  for (const auto& r : est.reports)
    if (r.stage == "light_intensities") f.albedo_scale = r.details.at("albedo_scale").get<double>();
  double sum = 0;
  int n = 0;
  for (int y = 0; y < est.albedo.rows; ++y)
    for (int x = 0; x < est.albedo.cols; ++x) {
      if (!(est.depth.at<float>(y, x) < render::kSkyDepthM)) continue;
      const cv::Vec3f a = est.albedo.at<cv::Vec3f>(y, x);
      sum += 0.2126 * a[0] + 0.7152 * a[1] + 0.0722 * a[2];
      ++n;
    }
  f.seen_mean_albedo = n > 0 ? sum / n : 0.0;
  const Eigen::Vector3d centre = est.camera().center_world;
  for (const auto& l : est.lights)
    if (const auto irradiance = inference::distant_light_irradiance(l, centre))
      f.sun_irradiance = std::max(f.sun_irradiance, irradiance->mean());
  return f;
}

// Street 17's fit, left alone, darkens the albedo to a tenth of the assumed
// mean and makes up for it with a sun several times the true one. With a
// floor on the seen surfaces' mean albedo the scale stops there, and the sun
// comes out dimmer.
TEST(StreetLighting, AFloorOnTheSeenMeanAlbedoHoldsAndDimsTheSun) {
  const InferredStreet street = inferred_street(17, 16);
  ASSERT_FALSE(street.geometry.indoor);
  const Floored low = fit_with_albedo_floor(street, 0.02), high = fit_with_albedo_floor(street, 0.2);
  EXPECT_LT(low.seen_mean_albedo, 0.15) << "the case this guards: the fit darkens the albedo";
  EXPECT_GE(high.seen_mean_albedo, 0.2 * 0.9);  // the floor is set on the fit's pixels, at its size
  EXPECT_GT(high.albedo_scale, low.albedo_scale);
  ASSERT_GT(low.sun_irradiance, 0);
  EXPECT_LT(high.sun_irradiance, low.sun_irradiance);
  // A floor no scale can reach stops at the scale's bound, finite.
  const Floored absurd = fit_with_albedo_floor(street, 100.0);
  EXPECT_TRUE(std::isfinite(absurd.albedo_scale));
  EXPECT_LE(absurd.albedo_scale, 1.9 + 1e-9);
  EXPECT_TRUE(std::isfinite(absurd.sun_irradiance));
}

}  // namespace
}  // namespace propcam::firmware

namespace propcam::firmware {
namespace {

// Street 5 inferred with the sun searched from cast shadows (off by
// default); `tied`: LightingOptions::sun_strength_from_shadows. `search`
// gets the search's report.
inference::SceneModel street_with_the_sun_searched(bool tied, nlohmann::json& search) {
  const InferredStreet street = inferred_street(5, 16);
  const SyntheticShot& shot = street.shot;
  const inference::GeometryEstimate& g = street.geometry;
  EXPECT_FALSE(g.indoor);
  inference::InferenceOptions o;
  o.lighting.sun_from_shadows = true;
  o.lighting.sun_strength_from_shadows = tied;
  inference::SceneModel est = inference::complete_scene(shot.photo_linear, g, o);
  for (const auto& r : est.reports)
    if (r.stage == "light_intensities") search = r.details.at("sun_from_shadows");
  return est;
}

// With the sun searched from cast shadows, a street's fit
// keeps at most one sun, of the searched kind, weighed with the sky, and the
// search says what it tried.
TEST(StreetLighting, TheSunSearchedFromShadowsIsOneSunWeighedWithTheSky) {
  nlohmann::json search;
  const inference::SceneModel est = street_with_the_sun_searched(true, search);
  EXPECT_NO_THROW(est.validate());
  ASSERT_TRUE(search.is_object());
  EXPECT_GT(search.at("hypotheses").get<int>(), 100);
  int suns = 0, far_quads = 0;
  for (const auto& l : est.lights) {
    if (l.type == inference::LightSource::Type::Sun) {
      ++suns;
      EXPECT_NEAR(l.direction.norm(), 1.0, 1e-9);
      EXPECT_GT(l.intensity.minCoeff(), 0.0);
    }
    if (l.type == inference::LightSource::Type::Area && inference::distant_light_direction(l, est.camera().center_world))
      ++far_quads;
  }
  EXPECT_EQ(suns, search.at("found").get<bool>() ? 1 : 0);
  EXPECT_EQ(far_quads, 0);  // no hypotheses beside the searched sun
}

// With the search's strength left to the fit
// (LightingOptions::sun_strength_from_shadows = false), the best searched
// direction is the street's one sun candidate, found or not, and what the
// search reports as its best direction is that sun's.
TEST(StreetLighting, TheSearchedDirectionWithTheFitsStrengthIsTheOneSunCandidate) {
  nlohmann::json search;
  const inference::SceneModel est = street_with_the_sun_searched(false, search);
  EXPECT_NO_THROW(est.validate());
  ASSERT_TRUE(search.is_object());
  ASSERT_GT(search.at("best_irradiance_per_sky").get<double>(), 0.0);
  const Eigen::Vector3d best(search["best_direction"][0].get<double>(), search["best_direction"][1].get<double>(),
                             search["best_direction"][2].get<double>());
  EXPECT_NEAR(best.norm(), 1.0, 1e-9);
  EXPECT_GT(best.y(), 0.0) << "the sun is above the horizon";
  int suns = 0;
  for (const auto& l : est.lights)
    if (l.type == inference::LightSource::Type::Sun) {
      ++suns;
      EXPECT_LT((l.direction - best).norm(), 1e-9);
      EXPECT_TRUE(l.intensity.allFinite());
      EXPECT_GE(l.intensity.minCoeff(), 0.0);  // the fit may weigh it to nothing
    }
  EXPECT_LE(suns, 1);
}

}  // namespace
}  // namespace propcam::firmware

namespace propcam::firmware {
namespace {

// With LightingOptions::hidden_facades on (off by default), a street's seen
// facades are continued out of the frame: the lighting reports them, the
// scene model keeps them and the compositor's world holds them beside the
// depth mesh and the prop.
TEST(StreetLighting, HiddenFacadesReachTheSceneModelAndTheComposite) {
  const InferredStreet street = inferred_street(5, 8);  // looking along the street, a facade on each side
  const SyntheticShot& shot = street.shot;
  const inference::GeometryEstimate& g = street.geometry;
  ASSERT_FALSE(g.indoor);
  inference::InferenceOptions o;
  o.lighting.hidden_facades = true;
  inference::SceneModel est = inference::complete_scene(shot.photo_linear, g, o);
  ASSERT_FALSE(est.hidden_facades.empty());
  for (const auto& r : est.reports) {
    if (r.stage == "light_intensities") {
      EXPECT_EQ(r.details.at("hidden_facades").get<size_t>(), est.hidden_facades.size());
    }
  }
  for (const auto& f : est.hidden_facades) {
    EXPECT_NO_THROW(f.validate());
    EXPECT_GE(f.top_m - f.bottom_m, 2.0);
  }
  const Eigen::Vector2d at = free_floor_pixel(shot.room);
  const render::Mesh cube = render::make_prop("cube");
  EXPECT_EQ(build_composite_world(est, cube, {at.x(), at.y(), 0.4, 0.0}).scene->mesh_count(), 3);
  est.hidden_facades.clear();
  EXPECT_EQ(build_composite_world(est, cube, {at.x(), at.y(), 0.4, 0.0}).scene->mesh_count(), 2);
  // Off (the default), none.
  EXPECT_TRUE(inference::complete_scene(shot.photo_linear, g, inference::InferenceOptions{}).hidden_facades.empty());
}

}  // namespace
}  // namespace propcam::firmware
