#include "light_intensities.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "propcam/capture/image_file.h"
#include "propcam/inference/scene_world.h"
#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/intensity_fit.h"
#include "propcam/inference/room_enclosure.h"
#include "propcam/inference/sun_choice.h"
#include "propcam/inference/sun_from_shadows.h"
#include "propcam/inference/support_planes.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"
#include "luminance.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using Clock = LightingClock;

// Pixels this bright (linear) in any channel are clipped: they say nothing of the light.
constexpr double kSaturatedLinear = 0.98;
// A channel whose fitted lights carry less energy than this gets no gain.
constexpr double kMinBasisEnergy = 1e-12;
// The per-channel balance may tint the fitted lights this much, no more.
constexpr double kMinChannelGain = 0.25, kMaxChannelGain = 4.0;

// The albedo's scale the seen sky may imply (LightingOptions::
// albedo_scale_from_sky): a mean albedo of 0.5 (the assumed one) times 0.1
// is coal, times 1.9 is snow. Below kMinMeanAlbedo an albedo image is black
// and says nothing of its mean.
constexpr double kMinAlbedoScale = 0.1, kMaxAlbedoScale = 1.9, kMinMeanAlbedo = 1e-4;

// The photo, depth, albedo and source mask at the fit's (smaller) size.
struct FitImages {
  int w = 0, h = 0;
  render::PinholeCamera camera;
  cv::Mat photo, depth, albedo, mask;
};

FitImages fit_images(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                     const cv::Mat& source_mask, const render::PinholeCamera& camera, const LightingOptions& options) {
  FitImages f;
  f.w = std::min(options.fit_width, camera.width);
  f.h = std::max(1, static_cast<int>(std::lround(static_cast<double>(f.w) * camera.height / camera.width)));
  f.camera = camera.resized(f.w, f.h);
  cv::resize(photo_linear, f.photo, {f.w, f.h}, 0, 0, cv::INTER_AREA);
  cv::resize(depth, f.depth, {f.w, f.h}, 0, 0, cv::INTER_NEAREST);
  cv::resize(albedo, f.albedo, {f.w, f.h}, 0, 0, cv::INTER_AREA);
  cv::resize(source_mask, f.mask, {f.w, f.h}, 0, 0, cv::INTER_NEAREST);
  return f;
}

// Outdoors the buildings that shade the street nearest the camera are
// mostly out of the frame: the seen facades are continued out of it.
std::vector<HiddenFacade> find_facades(const cv::Mat& depth, const cv::Mat& albedo, const render::PinholeCamera& camera,
                                       const LightingOptions& options, const GeometryCues& cues) {
  if (!(!cues.normals.empty() && cues.normals.size() == depth.size())) return {};
  return find_hidden_facades(depth, cues.normals, albedo, camera, options.facades);
}

// Indoors the room is closed around the camera, its lamps inside.
RoomEnclosure close_room(const cv::Mat& depth, const cv::Mat& albedo, const render::PinholeCamera& camera,
                         const std::vector<SupportPlane>& planes, const LightingOptions& options,
                         const std::vector<LightSource>& lights) {
  std::vector<Vector3d> light_positions;
  for (const LightSource& l : lights)
    if (l.type != LightSource::Type::Ibl && !distant_light_direction(l, camera.center_world)) light_positions.push_back(l.position);
  return enclose_room(depth, albedo, camera, room_heights(planes), light_positions, options.enclosure);
}

// The empty scene the basis renders see, at the fit's size: the scene world
// (scene_world.h) the composite renders too, with what lies out of the frame
// found here (facades outdoors, the room's box indoors).
void build_fit_scene(render::Scene& scene, const FitImages& fit, const cv::Mat& depth, const cv::Mat& albedo,
                     const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes, bool indoor,
                     const LightingOptions& options, const GeometryCues& cues, LightingEstimate& out) {
  if (!indoor && options.hidden_facades) out.hidden_facades = find_facades(depth, albedo, camera, options, cues);
  if (indoor && options.enclose_room) out.enclosure = close_room(depth, albedo, camera, planes, options, out.lights);
  SceneWorldOptions world;
  world.depth_mesh.step_pixels = 1;
  world.facades = options.facades;
  world.enclosure = options.enclosure;
  add_scene_world(scene, fit.depth, fit.albedo, fit.camera, out.hidden_facades, out.enclosure, world);
  scene.commit();
}

render::RenderSettings basis_render_settings(const LightingOptions& options) {
  render::RenderSettings settings;
  settings.samples_per_pixel = options.fit_samples_per_pixel;
  settings.max_bounces = options.fit_bounces;
  settings.seed = options.seed;
  return settings;
}

// Pixels that inform the fit: not the sources themselves, not sky, not clipped.
std::vector<cv::Point> informative_pixels(const FitImages& fit) {
  std::vector<cv::Point> used;
  for (int y = 0; y < fit.h; ++y)
    for (int x = 0; x < fit.w; ++x) {
      const cv::Vec3f c = fit.photo.at<cv::Vec3f>(y, x);
      if (fit.mask.at<uint8_t>(y, x) == 0 && fit.depth.at<float>(y, x) < render::kSkyDepthM && c[0] < kSaturatedLinear && c[1] < kSaturatedLinear && c[2] < kSaturatedLinear)
        used.push_back({x, y});
    }
  return used;
}

// The lights in the fit, index for index: out.lights[i], colours[i] (unit
// luminance: what the fit may not change) and renders[i]; the environment
// is last.
struct LightBasis {
  std::vector<Vector3d>& colours;
  std::vector<cv::Mat> renders;
  int k = 0;
};

// Channel c in 0..2, or 3 for luminance.
double channel_value(const cv::Mat& image, const cv::Point& p, int c) {
  const cv::Vec3f v = image.at<cv::Vec3f>(p);
  return c < 3 ? v[c] : luminance(v);
}

// The sun found from the shadows (LightingOptions::sun_from_shadows).
struct SearchedSun {
  int index = -1;         // in the basis; -1: none
  double per_sky = 0.0;   // its strength over the sky's, when tied to it
  nlohmann::json report;  // what the search found
};

// Outdoors the sun is searched for after the sky's basis render; a sun
// found (or, untied, the best hypothesis) goes just before the environment
// with its own basis render.
SearchedSun add_searched_sun(const render::Scene& scene, const FitImages& fit, const std::vector<cv::Point>& used,
                             const std::vector<Vector3d>& ranked_sun_directions,
                             const render::RenderSettings& settings, const LightingOptions& options,
                             LightingEstimate& out, LightBasis& basis) {
  SearchedSun searched;
  const auto search_start = Clock::now();
  cv::Mat usable = cv::Mat::zeros(fit.h, fit.w, CV_8U);  // the fit's pixels
  for (const cv::Point& p : used) usable.at<uint8_t>(p) = 255;
  const SunFromShadows found = sun_from_shadows(scene, fit.camera, fit.photo, fit.albedo, basis.renders.back(), usable,
                                                options.sun_search, ranked_sun_directions);
  searched.report = {{"found", found.found}, {"direction", {found.direction.x(), found.direction.y(), found.direction.z()}},
                     {"irradiance_per_sky", found.irradiance_per_sky},
                     {"best_direction", {found.best_direction.x(), found.best_direction.y(), found.best_direction.z()}},
                     {"best_irradiance_per_sky", found.best_irradiance_per_sky},
                     {"variance_ambient", found.variance_ambient}, {"variance_no_sun", found.variance_no_sun},
                     {"variance", found.variance}, {"pixels", found.pixels}, {"groups", found.groups},
                     {"hypotheses", found.hypotheses}, {"ranked_directions", ranked_sun_directions.size()}};
  const bool tied = options.sun_strength_from_shadows;
  if (found.found || (!tied && found.hypotheses > 0 && found.best_irradiance_per_sky > 0)) {
    LightSource sun;
    sun.type = LightSource::Type::Sun;
    sun.direction = found.found ? found.direction : found.best_direction;
    const int at = basis.k - 1;
    out.lights.insert(out.lights.begin() + at, sun);
    basis.colours.insert(basis.colours.begin() + at, Vector3d::Ones());
    std::vector<cv::Mat> sun_basis =
        render::render_background_light_images(scene, fit.camera, make_light_rig({sun}, true), settings);
    basis.renders.insert(basis.renders.begin() + at, sun_basis.front());
    if (tied) {
      searched.index = at;
      searched.per_sky = found.irradiance_per_sky;
    }
    ++basis.k;
  }
  searched.report["seconds"] = seconds_since(search_start);
  return searched;
}

// Bounds on each light's weight. The environment is last; a seen sky is
// measured: weight 1, or, when it sets the albedo's scale, the scale (see
// LightingOptions).
struct WeightBounds {
  std::vector<double> lower, upper;
};

WeightBounds weight_bounds(int k, bool sky_calibrated, bool scale_from_sky, const std::vector<cv::Point>& used,
                           const cv::Mat& fit_albedo, const LightingOptions& options) {
  WeightBounds b{std::vector<double>(k, 0.0), std::vector<double>(k, std::numeric_limits<double>::infinity())};
  if (scale_from_sky) {
    // The scale that brings the seen surfaces' mean albedo to the floor.
    double albedo_sum = 0;
    for (const cv::Point& p : used) albedo_sum += luminance(fit_albedo.at<cv::Vec3f>(p));
    const double mean_albedo = used.empty() ? 0.0 : albedo_sum / static_cast<double>(used.size());
    const double floor_scale = mean_albedo > kMinMeanAlbedo ? options.min_mean_albedo / mean_albedo : kMinAlbedoScale;
    b.lower[k - 1] = std::clamp(floor_scale, kMinAlbedoScale, kMaxAlbedoScale);
    b.upper[k - 1] = kMaxAlbedoScale;
  } else if (sky_calibrated) {
    b.lower[k - 1] = b.upper[k - 1] = 1.0;
  }
  return b;
}

// At most max_fit_pixels of the used pixels, evenly spread.
std::vector<cv::Point> spread_pixels(const std::vector<cv::Point>& used, int max_fit_pixels) {
  std::vector<cv::Point> fit_pixels;
  const size_t max_pixels = static_cast<size_t>(std::max(1, max_fit_pixels));
  const size_t stride = std::max<size_t>(1, (used.size() + max_pixels - 1) / max_pixels);
  for (size_t i = 0; i < used.size(); i += stride) fit_pixels.push_back(used[i]);
  return fit_pixels;
}

// Which lights, how bright, and the camera response: the paper's fit
// (intensity_fit.h) on luminance, the photo as the camera encoded it
// (fitting each channel on its own lets a light turn a colour no lamp has,
// e.g. a blue-only sun). A searched sun is weighed with the sky, at the
// ratio its shadows set: the sky's column becomes sky + ratio * sun, and the
// sun's own is off (in `bounds` too).
IntensityFitProblem luminance_fit_problem(const LightBasis& basis, const cv::Mat& fit_photo,
                                          const std::vector<cv::Point>& fit_pixels, const SearchedSun& sun,
                                          WeightBounds& bounds) {
  const int k = basis.k;
  IntensityFitProblem problem;
  problem.lower = bounds.lower;
  problem.upper = bounds.upper;
  problem.basis.assign(k, std::vector<float>(fit_pixels.size()));
  for (int i = 0; i < k; ++i) {
    for (size_t n = 0; n < fit_pixels.size(); ++n)
      problem.basis[i][n] = static_cast<float>(channel_value(basis.renders[i], fit_pixels[n], 3));
    problem.noise.push_back(basis_noise(basis.renders[i], {}));
  }
  if (sun.index >= 0) {
    for (size_t n = 0; n < fit_pixels.size(); ++n)
      problem.basis[k - 1][n] += static_cast<float>(sun.per_sky * problem.basis[sun.index][n]);
    problem.lower[sun.index] = problem.upper[sun.index] = bounds.upper[sun.index] = 0.0;
  }
  for (const auto& p : fit_pixels)
    problem.target.push_back(capture::linear_to_srgb(static_cast<float>(channel_value(fit_photo, p, 3))));
  return problem;
}

// The sun hypotheses are basis[suns_begin, suns_end).
struct SunRange {
  int begin = 0, end = 0;
};

// Outdoors there is one sun, and the ground alone cannot tell its
// azimuth: the fit weighs only the sun the photo calls for (sun_choice.h:
// the one that lights what the measured sky alone cannot make so bright,
// and whose shading agrees best with the photo). The others' upper bounds
// become 0.
nlohmann::json keep_chosen_sun(const LightBasis& basis, SunRange suns, const FitImages& fit,
                               const std::vector<cv::Point>& used, const LightingOptions& options,
                               std::vector<double>& upper) {
  const std::vector<cv::Mat> candidates(basis.renders.begin() + suns.begin, basis.renders.begin() + suns.end);
  const SunChoice choice = choose_sun(candidates, basis.renders[basis.k - 1], fit.albedo, fit.photo, used, options.sun_choice);
  for (int i = suns.begin; i < suns.end; ++i)
    if (i != suns.begin + choice.chosen) upper[i] = 0.0;
  return {{"must_be_sunlit_pixels", choice.must_be_sunlit},
          {"sunlit_share", choice.sunlit_share},
          {"agreement", choice.agreement},
          {"chosen", choice.chosen}};
}

IntensityFitResult fit_with_upper_bounds(IntensityFitProblem& problem, const std::vector<double>& upper,
                                         const IntensityFitOptions& o) {
  problem.upper = upper;
  return fit_intensities(problem, o);
}

// Outdoors there is one sun: of the sun hypotheses the fit used, keep the
// one that alone (with the other lights) explains the photo best.
IntensityFitResult best_one_sun_fit(IntensityFitProblem& problem, const std::vector<double>& upper,
                                    const IntensityFitOptions& fit_options, const IntensityFitResult& chosen,
                                    SunRange suns) {
  // The response is settled: each one-sun refit keeps it.
  IntensityFitOptions one_sun = fit_options;
  one_sun.fit_gamma = false;
  one_sun.gamma0 = chosen.gamma;
  IntensityFitResult best;
  double best_error = std::numeric_limits<double>::infinity();
  int iterations = chosen.iterations;
  for (int sun = suns.begin; sun < suns.end; ++sun) {
    if (!(chosen.weights[sun] > 0)) continue;
    std::vector<double> bound = upper;
    for (int i = suns.begin; i < suns.end; ++i)
      if (i != sun) bound[i] = 0.0;
    IntensityFitResult one = fit_with_upper_bounds(problem, bound, one_sun);
    iterations += one.iterations;
    if (one.data_error < best_error) {
      best_error = one.data_error;
      best = std::move(one);
    }
  }
  best.iterations = iterations;
  return best;
}

// The fit of the lights' weights and the camera response; a searched sun
// gets its share of the sky's weight back.
IntensityFitResult fit_light_weights(IntensityFitProblem& problem, const std::vector<double>& upper, int k,
                                     const SearchedSun& sun, SunRange suns, bool indoor,
                                     const LightingOptions& options) {
  IntensityFitOptions fit_options = options.fit;
  fit_options.max_seconds = std::max(0.05, options.fit.max_seconds);
  IntensityFitResult chosen = fit_with_upper_bounds(problem, upper, fit_options);
  if (sun.index >= 0) chosen.weights[sun.index] = sun.per_sky * chosen.weights[k - 1];
  int suns_used = 0;
  for (int i = suns.begin; i < suns.end; ++i) suns_used += chosen.weights[i] > 0;
  if (!indoor && suns_used > 1) chosen = best_one_sun_fit(problem, upper, fit_options, chosen, suns);
  return chosen;
}

// The photo, linear under the fitted response: what the gains and the
// error below compare against (and what the compositor relights). Per used pixel.
std::vector<Vector3d> photo_under_response(const cv::Mat& fit_photo, const std::vector<cv::Point>& used,
                                           double response) {
  std::vector<Vector3d> photo_response(used.size());
  for (size_t n = 0; n < used.size(); ++n)
    for (int c = 0; c < 3; ++c)
      photo_response[n][c] =
          std::pow(static_cast<double>(capture::linear_to_srgb(static_cast<float>(channel_value(fit_photo, used[n], c)))), response);
  return photo_response;
}

// The fitted weights as the colour step sees them: which lights are on,
// and the measured sky's weight (index `fixed`, or -1).
struct FittedLights {
  const Eigen::VectorXd& weights;
  std::vector<bool> active;
  int fixed = -1;
  double sky_weight = 0.0;
};

// Colour: each light keeps its own colour (a seen source the colour it has
// in the photo, unseen ones white) and one gain per channel balances the
// fitted lights against the photo, like a white balance; a measured sky
// keeps its fitted weight (1, or the albedo's scale).
Vector3d balance_gains(const LightBasis& basis, const FittedLights& lights, const std::vector<cv::Point>& used,
                       const std::vector<Vector3d>& photo_response) {
  Vector3d gains = Vector3d::Ones();
  for (int c = 0; c < 3; ++c) {
    double oo = 0, oy = 0;
    for (size_t n = 0; n < used.size(); ++n) {
      const cv::Point& p = used[n];
      double others = 0;
      for (int i = 0; i < basis.k; ++i)
        if (i != lights.fixed && lights.active[i])
          others += lights.weights[i] * basis.colours[i][c] * channel_value(basis.renders[i], p, c);
      const double target = photo_response[n][c] -
                            (lights.fixed >= 0 ? lights.sky_weight * channel_value(basis.renders[lights.fixed], p, c) : 0.0);
      oo += others * others;
      oy += others * target;
    }
    gains[c] = oo > kMinBasisEnergy ? std::clamp(oy / oo, kMinChannelGain, kMaxChannelGain) : 1.0;
  }
  return gains;
}

// The balance may tint the lights only so far: the estimated albedo already
// carries the room's colour cast (interreflections), so a strong tint
// double-counts it (a warm room fitted blue lights, and a grey prop came
// out blue).
void limit_tint(double max_light_tint, Vector3d& gains) {
  const double level = luminance(gains);
  const double max_tint = std::max(1.0, max_light_tint);
  if (level > 0)
    for (int c = 0; c < 3; ++c) gains[c] = level * std::clamp(gains[c] / level, 1.0 / max_tint, max_tint);
}

// Nor against the photo's own cast: a camera's white balance leaves the
// light it saw neutral or with the cast the photo shows, never the
// opposite one (a warm hotel room fitted pale-blue lights, and a white
// plinth came out blue). Each channel's tint lies between neutral and the
// cast of the fit's pixels.
void tint_within_photo_cast(const std::vector<Vector3d>& photo_response, Vector3d& gains) {
  Vector3d photo_sum = Vector3d::Zero();
  for (const auto& v : photo_response) photo_sum += v;
  const double level = luminance(gains), photo_level = luminance(photo_sum);
  if (level > 0 && photo_level > 0)
    for (int c = 0; c < 3; ++c) {
      const double cast = photo_sum[c] / photo_level;
      gains[c] = level * std::clamp(gains[c] / level, std::min(1.0, cast), std::max(1.0, cast));
    }
}

Vector3d channel_gains(const LightBasis& basis, const FittedLights& lights, const std::vector<cv::Point>& used,
                       const std::vector<Vector3d>& photo_response, bool searched_sun, const LightingOptions& options) {
  Vector3d gains = balance_gains(basis, lights, used, photo_response);
  // A searched sun's strength is the shadows' (weighed with the sky): the
  // balance may tint it, not rescale it.
  if (searched_sun) {
    const double level = luminance(gains);
    if (level > 0) gains /= level;
  }
  limit_tint(options.max_light_tint, gains);
  if (options.tint_within_photo_cast) tint_within_photo_cast(photo_response, gains);
  return gains;
}

// Each light's RGB weight, and how well they re-render the used pixels.
struct ColourWeights {
  std::vector<Vector3d> weights;
  double residual = 0, signal = 0;
};

ColourWeights colour_weights(const LightBasis& basis, const FittedLights& lights, const Vector3d& gains,
                             const std::vector<cv::Point>& used, const std::vector<Vector3d>& photo_response) {
  const int k = basis.k;
  ColourWeights out{std::vector<Vector3d>(k, Vector3d::Zero())};
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < k; ++i)
      out.weights[i][c] = i == lights.fixed ? lights.sky_weight
                                            : (lights.active[i] ? lights.weights[i] * basis.colours[i][c] * gains[c] : 0.0);
    for (size_t n = 0; n < used.size(); ++n) {
      double predicted = 0;
      for (int i = 0; i < k; ++i) predicted += out.weights[i][c] * channel_value(basis.renders[i], used[n], c);
      const double observed = photo_response[n][c];
      out.residual += (observed - predicted) * (observed - predicted);
      out.signal += observed * observed;
    }
  }
  return out;
}

// Sets the lights' intensities and prunes those the fit switched off (the
// point of the sparsity prior: they cost render time and add nothing); the
// environment is always kept. Returns whether any light is on.
bool set_intensities_and_prune(const std::vector<Vector3d>& weights, LightingEstimate& out) {
  bool any_light = false;
  for (size_t i = 0; i < weights.size(); ++i) {
    out.lights[i].intensity = weights[i];
    any_light = any_light || weights[i].maxCoeff() > 0;
  }
  std::vector<LightSource> kept;
  for (auto& l : out.lights)
    if (l.type == LightSource::Type::Ibl || l.intensity.maxCoeff() > 0) kept.push_back(std::move(l));
  out.lights = std::move(kept);
  if (!any_light && !out.lights.empty()) {
    // A black photo or a fit that switched everything off: keep a dim
    // environment so the prop is still visible rather than pure black.
    out.lights.back().intensity = Eigen::Vector3d::Constant(1.0);
  }
  return any_light;
}

// The light fit's figures for its stage report.
struct FitDiagnostics {
  int basis_renders = 0, samples_per_pixel = 0;
  cv::Size resolution;
  size_t pixels = 0, fit_pixels = 0, visible_sources = 0, hypotheses = 0;
  double basis_seconds = 0.0;
  Clock::time_point start, fit_start;
  nlohmann::json sun_choice, sun_from_shadows;
};

StageReport intensity_report(const FitDiagnostics& d, const IntensityFitResult& chosen, const ColourWeights& colour,
                             bool any_light, const LightingEstimate& out) {
  const double response = 1.0 / chosen.gamma;
  StageReport r;
  r.stage = "light_intensities";
  r.usable = d.pixels != 0 && any_light;
  r.why = d.pixels == 0 ? "no unclipped pixels to fit" : (any_light ? "fitted to basis renders" : "no light explains the photo");
  r.iterations = chosen.iterations;
  r.seconds = seconds_since(d.start);
  r.error = colour.signal > 0 ? std::sqrt(colour.residual / colour.signal) : 0.0;  // relative RMS of the re-render
  r.details = {{"basis_renders", d.basis_renders}, {"resolution", {d.resolution.width, d.resolution.height}},
               {"samples_per_pixel", d.samples_per_pixel},
               {"converged", chosen.converged}, {"termination", chosen.termination}, {"pixels", d.pixels},
               {"fit_pixels", d.fit_pixels}, {"gamma_solves", chosen.solves},
               {"camera_response_gamma", chosen.gamma}, {"response_exponent", response},
               {"albedo_scale", out.albedo_scale},
               {"fit_error_encoded", chosen.data_error},
               {"basis_render_seconds", d.basis_seconds}, {"fit_seconds", seconds_since(d.fit_start)},
               {"sun_choice", d.sun_choice}, {"sun_from_shadows", d.sun_from_shadows},
               {"hidden_facades", out.hidden_facades.size()}, {"enclosed", !out.enclosure.empty()},
               {"visible_sources", d.visible_sources}, {"hypotheses", d.hypotheses}, {"kept", out.lights.size()}};
  return r;
}

// The fit's result as the colour step sees it: which lights are on, and
// the measured sky (the last light, when it was seen) at its fitted weight.
FittedLights fitted_lights(const IntensityFitResult& chosen, int k, bool sky_calibrated, const WeightBounds& bounds) {
  FittedLights lights{chosen.weights, std::vector<bool>(k)};
  for (int i = 0; i < k; ++i) lights.active[i] = chosen.weights[i] > 0;
  lights.fixed = sky_calibrated ? k - 1 : -1;
  lights.sky_weight =
      lights.fixed < 0 ? 0.0 : std::clamp(chosen.weights[lights.fixed], bounds.lower[lights.fixed], bounds.upper[lights.fixed]);
  return lights;
}

// Weighs the basis renders against the photo (luminance, then colour) and
// sets the lights' intensities, the camera response and the albedo's scale.
void weigh_lights(const LightBasis& basis, const FitImages& fit, const std::vector<cv::Point>& used,
                  const SearchedSun& sun, bool indoor, bool sky_calibrated, const LightingOptions& options,
                  FitDiagnostics& d, LightingEstimate& out) {
  const int k = basis.k;
  const bool scale_from_sky = sky_calibrated && options.albedo_scale_from_sky;
  WeightBounds bounds = weight_bounds(k, sky_calibrated, scale_from_sky, used, fit.albedo, options);
  const std::vector<cv::Point> fit_pixels = spread_pixels(used, options.max_fit_pixels);
  IntensityFitProblem problem = luminance_fit_problem(basis, fit.photo, fit_pixels, sun, bounds);
  const SunRange suns{static_cast<int>(d.visible_sources), k - 1};
  if (!indoor && options.sun_from_shading && suns.end - suns.begin > 1)
    d.sun_choice = keep_chosen_sun(basis, suns, fit, used, options, bounds.upper);
  const IntensityFitResult chosen = fit_light_weights(problem, bounds.upper, k, sun, suns, indoor, options);
  const double response = 1.0 / chosen.gamma;
  const std::vector<Vector3d> photo_response = photo_under_response(fit.photo, used, response);
  const FittedLights lights = fitted_lights(chosen, k, sky_calibrated, bounds);
  const Vector3d gains = channel_gains(basis, lights, used, photo_response, sun.index >= 0, options);
  ColourWeights colour = colour_weights(basis, lights, gains, used, photo_response);
  // The sky's weight is the albedo's scale: lights in the scaled albedo's
  // units render the same image with the sky at its measured radiance.
  if (scale_from_sky) {
    out.albedo_scale = lights.sky_weight;
    for (auto& w : colour.weights) w /= lights.sky_weight;
  }
  d.hypotheses = out.lights.size();
  const bool any_light = set_intensities_and_prune(colour.weights, out);
  d.fit_pixels = fit_pixels.size();
  out.reports.push_back(intensity_report(d, chosen, colour, any_light, out));
  out.gamma = response;
}

// Basis renders of the empty scene, one light at a time, then the paper's
// fit of intensities and camera response.
}  // namespace

void fit_light_intensities(const LightFitInputs& in, std::vector<Vector3d>& colours, LightingEstimate& out) {
  const LightingOptions& options = in.options;
  FitDiagnostics d;
  d.start = Clock::now();
  const FitImages fit = fit_images(in.photo_linear, in.depth, in.albedo, out.source_mask, in.camera, options);
  render::Scene scene;
  build_fit_scene(scene, fit, in.depth, in.albedo, in.camera, in.planes, in.indoor, options, in.cues, out);
  // Area lights first, the environment last: the same order as out.lights,
  // so basis render i belongs to out.lights[i].
  const render::LightRig rig = make_light_rig(out.lights, true, out.windows);
  const render::RenderSettings settings = basis_render_settings(options);
  // One set of paths for all lights (render_background_light_images): about
  // half the time of a render per light.
  LightBasis basis{colours, render::render_background_light_images(scene, fit.camera, rig, settings), rig.count()};
  const std::vector<cv::Point> used = informative_pixels(fit);
  SearchedSun sun;
  if (in.search_sun) sun = add_searched_sun(scene, fit, used, in.ranked_sun_directions, settings, options, out, basis);
  d.basis_seconds = seconds_since(d.start);
  d.fit_start = Clock::now();
  d.basis_renders = basis.k;
  d.samples_per_pixel = settings.samples_per_pixel;
  d.resolution = {fit.w, fit.h};
  d.pixels = used.size();
  d.visible_sources = in.visible_sources;
  d.sun_from_shadows = sun.report;
  weigh_lights(basis, fit, used, sun, in.indoor, in.sky_calibrated, options, d, out);
}

}  // namespace propcam::inference
