#include "bench/bench_lighting.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "common/bench_common.h"
#include "common/compositor.h"
#include "common/progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/infer.h"
#include "propcam/inference/lighting.h"
#include "propcam/inference/support_planes.h"
#include "worlds/synthetic_truth.h"
#include "worlds/world_metrics.h"

namespace propcam::firmware {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;
using nlohmann::json;

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
// Monte Carlo samples per light for the light vector at the prop's base.
constexpr int kLightVectorSamples = 2048;
// The prop's region: pixels where the true insertion differs from the photo
// by more than this share of the photo's mean luminance (summed over RGB),
// cleaned of render-noise specks, then grown by a few pixels.
constexpr double kRegionThresholdOfMean = 0.15;
constexpr int kRegionGrowPx = 2;
constexpr double kNoiseBlurSigmaPx = 1.5;
// Yaw of the prop (degrees): a cube turned off the room's axes shows two faces.
constexpr double kPropYawDeg = 30.0;

double luminance(const Vector3f& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }

// What the lights deliver at a point: the first moment of incident radiance
// over the sphere (its direction is the dominant light direction) and the
// irradiance on an upward-facing surface (luminance). Unoccluded: the lights
// alone, as a light probe would see them with the room taken away.
struct LightAtPoint {
  Vector3d vector = Vector3d::Zero();
  double irradiance_up = 0.0;
};

LightAtPoint light_at(const render::LightRig& rig, const Vector3f& p) {
  LightAtPoint out;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const auto add = [&](const Vector3f& direction, const Vector3f& radiance, double pdf, double weight) {
    if (!(pdf > 0) || !direction.allFinite()) return;
    const double l = luminance(radiance) * weight / pdf;
    if (!std::isfinite(l)) return;
    out.vector += l * direction.cast<double>();
    out.irradiance_up += l * std::max(0.0f, direction.y());
  };
  const double w = 1.0 / kLightVectorSamples;
  for (const auto& a : rig.area_lights)
    for (int i = 0; i < kLightVectorSamples; ++i) {
      const render::LightSample s = a.sample(p, u(rng), u(rng));
      add(s.direction, s.radiance, s.pdf, w);
    }
  for (const auto& b : rig.sphere_lights)
    for (int i = 0; i < kLightVectorSamples; ++i) {
      const render::LightSample s = b.sample(p, u(rng), u(rng));
      add(s.direction, s.radiance, s.pdf, w);
    }
  for (const auto& d : rig.disc_lights)
    for (int i = 0; i < kLightVectorSamples; ++i) {
      const render::LightSample s = d.sample(p, u(rng), u(rng));
      add(s.direction, s.radiance, s.pdf, w);
    }
  for (const auto& point : rig.point_lights) {
    const render::LightSample s = point.sample(p);  // a delta: one sample is exact
    add(s.direction, s.radiance, s.pdf, 1.0);
  }
  for (const auto& sun : rig.suns) {
    if (!sun.emits()) continue;
    const Vector3f d = sun.direction.normalized();
    if (rig.arrives_from_outside(p, d, sun.through_portals)) add(d, sun.irradiance, 1.0, 1.0);
  }
  if (rig.environment && rig.environment->valid())
    for (int i = 0; i < kLightVectorSamples; ++i) {
      float pdf = 0.f;
      const Vector3f d = rig.environment->sample(u(rng), u(rng), pdf);
      if (rig.arrives_from_outside(p, d, rig.environment->through_portals()))
        add(d, rig.environment->radiance(d), pdf, w);
    }
  return out;
}

double angle_deg(const Vector3d& a, const Vector3d& b) {
  if (!(a.norm() > 0) || !(b.norm() > 0)) return 180.0;
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * kRadToDeg;
}

double mean_luminance(const cv::Mat& rgb, const cv::Mat& mask) {
  const cv::Scalar m = cv::mean(rgb, mask);
  return 0.2126 * m[0] + 0.7152 * m[1] + 0.0722 * m[2];
}

struct Shot {
  std::string name;
  SyntheticShot shot;
  inference::GeometryEstimate geometry;
  render::PropPlacement placement;
  cv::Mat reference;  // the prop truly in the scene
  cv::Mat region;     // CV_8U: where it changes the photo
  LightAtPoint truth_light;
  Vector3f probe;     // the prop's base, a little above the floor
};

struct Config {
  std::string sweep, label;
  double value = 0;
  std::function<void(inference::InferenceOptions&)> apply;
};

struct Errors {
  double direction_deg = 0, irradiance_rel = 0, rerender = 0, composite_rel = 0, seconds = 0, gamma = 0;
  // Streets: the brightest far light against the true sun, in the camera's
  // frame (the estimate's world may be turned against the truth's).
  double sun_deg = std::nan(""), sun_elevation_deg = std::nan(""), true_sun_elevation_deg = std::nan("");
  double world_turn_deg = 0;  // how far the estimate's world axes are turned from the truth's
  int lights = 0;
};

// The composite as `propcam composite` makes it: light added in the scene's
// response, back to the photo's encoding.
cv::Mat composite_like_the_cli(const cv::Mat& photo, const inference::SceneModel& scene, const render::Mesh& prop,
                               const render::PropPlacement& placement, int spp) {
  render::RenderSettings settings;
  settings.samples_per_pixel = spp;
  const cv::Mat scene_photo = capture::srgb_linear_to_response_linear(photo, scene.gamma);
  const CompositeResult r = composite_prop(scene_photo, scene, prop, placement, settings);
  return capture::response_linear_to_srgb_linear(r.composite_linear, scene.gamma);
}

// Both images are blurred first: at bench sample counts the per-pixel Monte
// Carlo noise of reference and composite would otherwise swamp the lighting's
// error (shading and shadow are smooth at this scale).
double composite_error(const Shot& s, const cv::Mat& composite) {
  if (cv::countNonZero(s.region) == 0) return std::nan("");
  cv::Mat a, b;
  cv::GaussianBlur(composite, a, {0, 0}, kNoiseBlurSigmaPx);
  cv::GaussianBlur(s.reference, b, {0, 0}, kNoiseBlurSigmaPx);
  return rmse_in_mask(a, b, s.region) / std::max(1e-9, mean_luminance(b, s.region));
}

// The light, its irradiance and the composite of an estimated scene.
//
// The estimate's world and the truth's share only the camera: the inferred
// world axes are the scene's vanishing directions, whose order and sign
// depend on the view (looking across a street, the estimate's Z is the
// truth's X). So the probe is the point at the same place relative to the
// camera, and light vectors are compared in the camera's frame.
void score_scene(const Shot& s, const inference::SceneModel& est, const render::Mesh& prop, int spp, Errors& e) {
  const render::PinholeCamera& true_camera = s.shot.room.camera;
  const render::PinholeCamera est_camera = est.camera();
  const Eigen::Matrix3d est_from_true = est_camera.R_world_from_cam * true_camera.R_world_from_cam.transpose();
  const Vector3f probe = (est_camera.center_world + est_from_true * (s.probe.cast<double>() - true_camera.center_world)).cast<float>();
  const LightAtPoint l = light_at(est.light_rig(), probe);
  e.direction_deg = angle_deg(est_camera.R_world_from_cam.transpose() * l.vector,
                              true_camera.R_world_from_cam.transpose() * s.truth_light.vector);
  e.world_turn_deg = std::acos(std::clamp((est_from_true.trace() - 1.0) / 2.0, -1.0, 1.0)) * kRadToDeg;
  e.irradiance_rel = s.truth_light.irradiance_up > 0 ? std::abs(l.irradiance_up / s.truth_light.irradiance_up - 1.0)
                                                     : std::nan("");
  e.composite_rel = composite_error(s, composite_like_the_cli(s.shot.photo_linear, est, prop, s.placement, spp));
  e.gamma = est.gamma;
  e.lights = static_cast<int>(est.lights.size());
  if (s.shot.room.lights.suns.empty()) return;
  const Vector3d true_sun = s.shot.room.lights.suns.front().direction.cast<double>().normalized();
  const Vector3d& centre = est_camera.center_world;
  double brightest = 0;
  Vector3d sun = Vector3d::Zero();
  for (const auto& l : est.lights) {
    const std::optional<Vector3d> d = inference::distant_light_direction(l, centre);
    const std::optional<Vector3d> irradiance = inference::distant_light_irradiance(l, centre);
    if (!d || !irradiance) continue;
    const double power = luminance(irradiance->cast<float>());
    if (power > brightest) brightest = power, sun = *d;
  }
  e.true_sun_elevation_deg = std::asin(std::clamp(true_sun.y(), -1.0, 1.0)) * kRadToDeg;
  if (brightest <= 0) return;
  e.sun_deg = angle_deg(est_camera.R_world_from_cam.transpose() * sun, true_camera.R_world_from_cam.transpose() * true_sun);
  e.sun_elevation_deg = std::asin(std::clamp(sun.y(), -1.0, 1.0)) * kRadToDeg;
}

Errors evaluate(const Shot& s, const inference::InferenceOptions& o, const render::Mesh& prop, int spp) {
  const inference::SceneModel est = inference::complete_scene(s.shot.photo_linear, s.geometry, o);
  Errors e;
  for (const auto& r : est.reports) {
    if (r.stage == "albedo" || r.stage == "light_sources" || r.stage == "ibl_ranking" || r.stage == "environment" ||
        r.stage == "light_intensities")
      e.seconds += r.seconds;
    if (r.stage == "light_intensities") e.rerender = r.error;
  }
  score_scene(s, est, prop, spp, e);
  return e;
}

// The oracle: the geometry replaced by the truth's (camera, depth, normals;
// support planes found again on them), the rest inferred as usual. What the
// lighting stages reach when the geometry is right; no device has it.
inference::GeometryEstimate true_geometry(const Shot& s) {
  inference::GeometryEstimate g = s.geometry;
  const inference::SceneModel& truth = s.shot.truth;
  g.pinhole = truth.camera();
  g.camera.fx = truth.fx, g.camera.fy = truth.fy, g.camera.cx = truth.cx, g.camera.cy = truth.cy;
  g.camera.R_world_from_cam = truth.R_world_from_cam;
  g.depth = truth.depth.clone();
  g.normals = truth.normals.clone();
  inference::StageReport report;
  g.planes = inference::find_support_planes(g.depth, g.normals, g.pinhole, inference::InferenceOptions{}.geometry.support,
                                            report);
  return g;
}

// The Khan-style baseline on the same geometry and albedo: the photo wrapped
// onto a sphere is the only light, at its measured radiance.
Errors evaluate_baseline(const Shot& s, const render::Mesh& prop, int spp) {
  const inference::SceneModel est = khan_baseline(
      inference::complete_scene(s.shot.photo_linear, s.geometry, inference::InferenceOptions{}), s.shot.photo_linear);
  Errors e;
  e.rerender = std::nan("");
  score_scene(s, est, prop, spp, e);
  return e;
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

json summary(const std::vector<Errors>& errors) {
  const auto col = [&](double Errors::*m) {
    std::vector<double> v;
    for (const auto& e : errors) v.push_back(e.*m);
    return v;
  };
  double seconds = 0;
  for (const auto& e : errors) seconds += e.seconds;
  return {{"direction_deg_median", median(col(&Errors::direction_deg))},
          {"irradiance_rel_median", median(col(&Errors::irradiance_rel))},
          {"rerender_rel_rms_median", median(col(&Errors::rerender))},
          {"composite_rel_rmse_median", median(col(&Errors::composite_rel))},
          {"gamma_median", median(col(&Errors::gamma))},
          {"seconds_mean", errors.empty() ? 0.0 : seconds / errors.size()}};
}

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

std::vector<Config> configs(const std::vector<std::string>& sweeps) {
  const auto wanted = [&](const std::string& s) {
    return sweeps.empty() || std::find(sweeps.begin(), sweeps.end(), s) != sweeps.end();
  };
  std::vector<Config> out;
  out.push_back({"default", "default", 0, [](inference::InferenceOptions&) {}});
  if (wanted("basis_spp"))
    for (int spp : {2, 4, 16})
      out.push_back({"basis_spp", std::to_string(spp) + " spp", static_cast<double>(spp),
                     [spp](inference::InferenceOptions& o) { o.lighting.fit_samples_per_pixel = spp; }});
  if (wanted("basis_width"))
    for (int w : {80, 320})
      out.push_back({"basis_width", std::to_string(w) + " px", static_cast<double>(w),
                     [w](inference::InferenceOptions& o) { o.lighting.fit_width = w; }});
  if (wanted("fit_pixels"))
    for (int n : {256, 4096})
      out.push_back({"fit_pixels", std::to_string(n) + " pixels", static_cast<double>(n),
                     [n](inference::InferenceOptions& o) { o.lighting.max_fit_pixels = n; }});
  if (wanted("superpixels"))
    for (int px : {8, 20})
      out.push_back({"superpixels", std::to_string(px) + " px superpixels", static_cast<double>(px),
                     [px](inference::InferenceOptions& o) { o.lighting.classifier.superpixel_px = px; }});
  if (wanted("tint"))
    for (double t : {1.0, 1.25, 1.5})
      out.push_back({"tint", "tint <= " + std::to_string(t).substr(0, 4), t,
                     [t](inference::InferenceOptions& o) { o.lighting.max_light_tint = t; }});
  if (wanted("ibl")) {
    // Ranked panoramas whose lights join the candidates (default: 1 indoors, 3 outdoors).
    for (int k : {0, 1, 3})
      out.push_back({"ibl", k == 0 ? "no IBL ranking" : std::to_string(k) + " ranked IBLs", static_cast<double>(k),
                     [k](inference::InferenceOptions& o) { o.lighting.ibl_candidates = k; }});
    out.push_back({"ibl", "paper's: 1 indoors, 3 outdoors", 13, [](inference::InferenceOptions& o) {
                     o.lighting.ibl_candidates_indoor = 1;
                     o.lighting.ibl_candidates_outdoor = 3;
                   }});
    out.push_back({"ibl", "ranked IBLs, no hypotheses", -1,
                   [](inference::InferenceOptions& o) { o.lighting.keep_hypotheses = false; }});
  }
  if (wanted("sky"))
    out.push_back({"sky", "sky held at 1, albedo mean 0.5", 0,
                   [](inference::InferenceOptions& o) { o.lighting.albedo_scale_from_sky = false; }});
  if (wanted("sun")) {
    out.push_back({"sun", "sun searched from cast shadows", 2,
                   [](inference::InferenceOptions& o) { o.lighting.sun_from_shadows = true; }});
    out.push_back({"sun", "searched direction, strength by the fit", 3, [](inference::InferenceOptions& o) {
                     o.lighting.sun_from_shadows = true;
                     o.lighting.sun_strength_from_shadows = false;
                   }});
    out.push_back({"sun", "searched on the photo, strength by the fit", 4, [](inference::InferenceOptions& o) {
                     o.lighting.sun_from_shadows = true;
                     o.lighting.sun_strength_from_shadows = false;
                     o.lighting.sun_search.shading_only = false;
                   }});
    out.push_back({"sun", "24 hypotheses, elevations 15/35/60", 5, [](inference::InferenceOptions& o) {
                     o.lighting.sun_elevations_deg = {15.0, 35.0, 60.0};
                   }});
    out.push_back({"sun", "16 sun hypotheses, by fit error", 0,
                   [](inference::InferenceOptions& o) { o.lighting.sun_from_shading = false; }});
  }
  if (wanted("nosun"))
    out.push_back({"nosun", "outdoors no sun: sky and ranked non-sun lights only", 0, [](inference::InferenceOptions& o) {
                     o.lighting.sun_azimuths = 0;
                     o.lighting.ibl_candidates_outdoor = 0;
                   }});
  if (wanted("sun_strength"))
    for (double m : {0.05, 0.10, 0.20})
      out.push_back({"sun_strength", "seen mean albedo >= " + std::to_string(m).substr(0, 4), m,
                     [m](inference::InferenceOptions& o) { o.lighting.min_mean_albedo = m; }});
  if (wanted("facades"))
    out.push_back({"facades", "hidden facades (seen facades continued out of the frame)", 1,
                   [](inference::InferenceOptions& o) { o.lighting.hidden_facades = true; }});
  if (wanted("albedo")) {
    out.push_back({"albedo", "Color Retinex everywhere", 0, [](inference::InferenceOptions& o) {
                     o.albedo.method = inference::AlbedoOptions::Method::Retinex;
                     o.albedo.outdoor_method.reset();
                   }});
    for (double f : {0.01, 0.02, 0.08})
      out.push_back({"albedo", "blurred shading everywhere, sigma " + std::to_string(f).substr(0, 4) + " of diagonal", f,
                     [f](inference::InferenceOptions& o) {
                       o.albedo.method = inference::AlbedoOptions::Method::BlurredShading;
                       o.albedo.outdoor_method.reset();
                       o.albedo.blur_sigma_fraction = f;
                     }});
  }
  if (wanted("response")) {
    out.push_back({"response", "gamma held at 1/2.2", 0,
                   [](inference::InferenceOptions& o) { o.lighting.fit.fit_gamma = false; }});
    out.push_back({"response", "paper's lambda_gamma only", 1,
                   [](inference::InferenceOptions& o) { o.lighting.fit.lambda_gamma_per_pixel = 0.0; }});
  }
  return out;
}

}  // namespace

json run_lighting_bench(const LightingBenchOptions& o) {
  if (o.rooms + o.streets <= 0) throw std::invalid_argument("bench lighting: no scenes (--rooms and --streets are 0)");
  if (o.spp < 1) throw std::invalid_argument("bench lighting: --spp must be positive");
  Progress progress(o.quiet);
  const render::Mesh prop = load_prop(o.prop);
  const double height = o.prop_height_m > 0 ? o.prop_height_m : natural_height(o.prop, prop);
  render::RenderSettings settings;
  settings.samples_per_pixel = o.spp;

  std::vector<Shot> shots;
  const auto add_scenes = [&](const std::string& kind, int count, auto spec, auto shoot) {
    spec.width = o.width;
    spec.height = o.height;
    for (int seed = 1; seed <= count; ++seed) {
      progress.stage("bench lighting: " + kind + " " + std::to_string(seed));
      spec.seed = static_cast<uint64_t>(seed);
      Shot s;
      s.name = kind + " " + std::to_string(seed);
      s.shot = shoot(spec, settings);
      s.geometry = inference::infer_geometry(s.shot.photo_linear, inference::InferenceOptions{});
      const Eigen::Vector2d at = free_floor_pixel(s.shot.room);
      s.placement = render::PropPlacement{at.x(), at.y(), height, kPropYawDeg};
      s.reference = render_full_insertion(s.shot.room, prop, s.placement, settings);
      const double threshold = kRegionThresholdOfMean * 3.0 * std::max(1e-6, mean_luminance(s.shot.photo_linear, {}));
      cv::Mat region = changed_pixels(s.reference, s.shot.photo_linear, threshold);
      cv::morphologyEx(region, region, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
      cv::dilate(region, s.region, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * kRegionGrowPx + 1, 2 * kRegionGrowPx + 1}));
      s.probe = s.shot.room.free_floor_point + Vector3f(0.f, 0.05f, 0.f);
      s.truth_light = light_at(s.shot.room.lights, s.probe);  // the rig that rendered the photo
      shots.push_back(std::move(s));
    }
  };
  add_scenes("room", o.rooms, render::SyntheticRoomSpec{}, shoot_synthetic_room);
  add_scenes("street", o.streets, render::SyntheticStreetSpec{}, shoot_synthetic_street);

  json rows = json::array();
  const auto add_row = [&](const std::string& sweep, const std::string& label, double value,
                           const std::function<Errors(const Shot&)>& run) {
    std::vector<Errors> all, rooms, streets;
    json scenes = json::array();
    for (const Shot& s : shots) {
      progress.stage("bench lighting: " + label + ", " + s.name);
      const Errors e = run(s);
      all.push_back(e);
      (s.shot.truth.indoor ? rooms : streets).push_back(e);
      scenes.push_back({{"scene", s.name}, {"direction_deg", number_or_null(e.direction_deg)},
                        {"irradiance_rel", number_or_null(e.irradiance_rel)}, {"rerender_rel_rms", number_or_null(e.rerender)},
                        {"composite_rel_rmse", number_or_null(e.composite_rel)}, {"gamma", e.gamma},
                        {"lights", e.lights}, {"seconds", e.seconds}, {"world_turn_deg", e.world_turn_deg}, {"region_pixels", cv::countNonZero(s.region)}});
      if (std::isfinite(e.true_sun_elevation_deg))
        scenes.back().update({{"sun_deg", number_or_null(e.sun_deg)}, {"sun_elevation_deg", number_or_null(e.sun_elevation_deg)},
                              {"true_sun_elevation_deg", e.true_sun_elevation_deg}});
    }
    json row = {{"sweep", sweep}, {"label", label}, {"value", value}, {"all", summary(all)}, {"scenes", scenes}};
    if (!rooms.empty()) row["rooms"] = summary(rooms);
    if (!streets.empty()) row["streets"] = summary(streets);
    rows.push_back(row);
  };
  add_row("baseline", "Khan-style environment", 0, [&](const Shot& s) { return evaluate_baseline(s, prop, o.spp); });
  for (const Config& c : configs(o.sweeps))
    add_row(c.sweep, c.label, c.value, [&](const Shot& s) {
      inference::InferenceOptions opts;
      c.apply(opts);
      return evaluate(s, opts, prop, o.spp);
    });
  // Only when named: it is a diagnosis, not a knob.
  if (std::find(o.sweeps.begin(), o.sweeps.end(), "oracle") != o.sweeps.end()) {
    // A calibrated lens (the board's calibration, `--focal PX --fixed-focal`):
    // the true focal length, everything else inferred. Unlike the rows below,
    // a device can have this.
    add_row("oracle", "calibrated lens", 0, [&](const Shot& s) {
      inference::InferenceOptions opts;
      opts.camera.prior_focal_px = s.shot.truth.fx;
      opts.camera.fixed_focal = true;
      Shot calibrated = s;
      calibrated.geometry = inference::infer_geometry(s.shot.photo_linear, opts);
      return evaluate(calibrated, opts, prop, o.spp);
    });
    for (const bool search : {false, true})
      add_row("oracle", search ? "true geometry, sun searched" : "true camera and depth", search, [&](const Shot& s) {
        Shot with_truth = s;
        with_truth.geometry = true_geometry(s);
        inference::InferenceOptions opts;
        opts.lighting.sun_from_shadows = search;
        return evaluate(with_truth, opts, prop, o.spp);
      });
  }
  return {{"size", {o.width, o.height}}, {"spp", o.spp}, {"prop", o.prop}, {"prop_height_m", height}, {"rows", rows}};
}

std::string format_lighting_bench(const json& r) {
  std::ostringstream out;
  char line[400];
  std::snprintf(line, sizeof line,
                "Lighting on generator scenes (%dx%d, %d spp, prop %s %.2f m): medians over scenes, time = mean per "
                "scene of albedo + sources + basis renders + fit\n",
                r["size"][0].get<int>(), r["size"][1].get<int>(), r["spp"].get<int>(),
                r["prop"].get<std::string>().c_str(), r["prop_height_m"].get<double>());
  out << line;
  const auto num = [](const json& j) { return j.is_number() ? j.get<double>() : std::nan(""); };
  for (const char* group : {"all", "rooms", "streets"}) {
    if (!r["rows"][0].contains(group)) continue;
    out << "\n" << group << ":\n";
    std::snprintf(line, sizeof line, "%-11s %-26s %9s %9s %9s %10s %7s %8s\n", "sweep", "knob", "direction", "irradiance",
                  "rerender", "composite", "gamma", "seconds");
    out << line;
    for (const auto& row : r["rows"]) {
      const json& a = row[group];
      std::snprintf(line, sizeof line, "%-11s %-26s %8.1f° %9.3f %9.3f %10.3f %7.3f %8.3f\n",
                    row["sweep"].get<std::string>().c_str(), row["label"].get<std::string>().c_str(),
                    num(a["direction_deg_median"]), num(a["irradiance_rel_median"]), num(a["rerender_rel_rms_median"]),
                    num(a["composite_rel_rmse_median"]), num(a["gamma_median"]), num(a["seconds_mean"]));
      out << line;
    }
  }
  out << "\ndirection: angle between the estimated and true light vectors (first moment of incident radiance) at "
         "the prop's base; irradiance: |E_est/E_true - 1| on an upward surface there; rerender: relative RMS of the "
         "empty scene re-rendered with the fitted lights against the photo; composite: RMSE in the prop's region "
         "against a render with the prop truly inserted, over that region's mean luminance\n";
  return out.str();
}

void plot_lighting_bench(const json& r, const std::string& dir) {
  std::ostringstream dat;
  std::string last;
  double baseline = std::nan("");
  for (const auto& row : r["rows"]) {
    const std::string sweep = row["sweep"];
    const json& a = row["all"];
    if (sweep == "baseline") {
      baseline = a["composite_rel_rmse_median"].is_number() ? a["composite_rel_rmse_median"].get<double>() : std::nan("");
      continue;
    }
    if (sweep != last) dat << (last.empty() ? "" : "\n\n") << "\"" << sweep << "\" seconds composite direction label\n";
    last = sweep;
    std::string label = row["label"];
    std::replace(label.begin(), label.end(), ' ', '_');
    const auto num = [](const json& j) { return j.is_number() ? j.get<double>() : std::nan(""); };
    dat << row["value"].get<double>() << " " << num(a["seconds_mean"]) << " " << num(a["composite_rel_rmse_median"]) << " "
        << num(a["direction_deg_median"]) << " \"" << label << "\"\n";
  }
  std::ostringstream gp;
  gp << "$data << EOD\n" << dat.str() << "\nEOD\n"
     << "set terminal png size 1100,480 noenhanced\nset grid\nset key top right\nset output '"
     << (std::filesystem::path(dir) / "lighting.png").string() << "'\n"
     << "set multiplot layout 1,2 title 'Lighting on generator scenes: error against seconds per scene (labels: the knob)'\n"
        "set xlabel 'seconds per scene (albedo + lights + fit)'\nset ylabel 'composite error in the prop region (median)'\n";
  if (std::isfinite(baseline)) gp << "baseline = " << baseline << "\n";
  gp << "plot for [i=0:*] $data index i using 2:3 with linespoints pt 7 title columnhead(1), "
        "$data using 2:3:5 with labels offset 0,1 font ',7' notitle"
     << (std::isfinite(baseline) ? ", baseline with lines dt 2 lw 2 title 'Khan-style environment'" : "") << "\n"
     << "set ylabel 'light direction error (median, deg)'\n"
        "plot for [i=0:*] $data index i using 2:4 with linespoints pt 7 title columnhead(1), "
        "$data using 2:4:5 with labels offset 0,1 font ',7' notitle\n"
        "unset multiplot\n";
  run_gnuplot(dir, "lighting.gp", gp.str());
}

void add_bench_lighting_options(CLI::App& cmd, LightingBenchArgs& a) {
  cmd.add_option("--rooms", a.options.rooms, "Synthetic rooms (seeds 1..N)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--streets", a.options.streets, "Synthetic streets (seeds 1..N)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--size", a.size, "Photo size WxH");
  cmd.add_option("--spp", a.options.spp, "Samples per pixel of photos, references and composites")->check(CLI::PositiveNumber);
  cmd.add_option("--prop", a.options.prop, "Prop inserted for the composite error");
  cmd.add_option("--height", a.options.prop_height_m, "Prop height in metres (0: its natural height)");
  cmd.add_option("--sweeps", a.sweeps, "Comma-separated subset of basis_spp,basis_width,fit_pixels,superpixels,tint,ibl,sky,sun,facades,nosun,sun_strength,albedo,response (default: all), or oracle (the true camera and depth; only when named)");
  cmd.add_option("--plot", a.options.plot_dir, "Write lighting.png (gnuplot) to this folder");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_lighting_command(LightingBenchArgs a) {
  parse_bench_size(a.size, 16, a.options.width, a.options.height);
  a.options.sweeps = parse_sweeps(a.sweeps, {"default", "basis_spp", "basis_width", "fit_pixels", "superpixels", "tint", "ibl", "sky", "sun", "facades", "nosun", "sun_strength", "albedo", "response", "oracle"});
  a.options.quiet = a.json_out;
  return report_bench_result(run_lighting_bench(a.options),
                             a.json_out, a.options.plot_dir, plot_lighting_bench, format_lighting_bench);
}

}  // namespace propcam::firmware
