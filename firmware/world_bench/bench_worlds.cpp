#include "world_bench/bench_worlds.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "common/bench_common.h"
#include "common/compositor.h"
#include "common/progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/infer.h"
#include "propcam/inference/lighting.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/vignetting.h"
#include "tools/scene_reference_builder.h"
#include "worlds/world_metrics.h"

namespace propcam::firmware {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

// The prop's true influence: where the true insertion differs from the
// photo by more than this (display values summed over RGB; an 8-bit step is
// 0.004 per channel), specks removed, the prop's own pixels added, grown.
constexpr double kRegionChange = 0.03;
constexpr int kRegionGrowPx = 2;
// A composite pixel counts as changed by more than the same amount; changes
// this far outside the true influence count against it.
constexpr int kOutsideMarginPx = 6;
// Depth at or beyond this is sky (render::kSkyDepthM, with room to spare).
constexpr double kSkyFromM = 0.5 * render::kSkyDepthM;
// LMSE windows: this share of the longer image side.
constexpr double kLmseWindowShare = 0.1;
// The light probe at the prop's base: cube faces of this many pixels.
constexpr int kProbeFacePx = 24, kProbeSpp = 16;
constexpr uint64_t kProbeSeed = 17;
// A Blender scene's truth counts as clean at or below this render noise
// (8-bit levels; composite errors are 10-30 levels).
constexpr double kCleanTruthNoise8bit = 5.0;

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }
double num(const json& j) { return j.is_number() ? j.get<double>() : std::nan(""); }

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

cv::Mat to_display(const cv::Mat& srgb_linear) {
  cv::Mat display;
  capture::linear_to_srgb8(srgb_linear).convertTo(display, CV_32FC3, 1.0 / 255.0);
  return display;
}

cv::Mat changed(const cv::Mat& a, const cv::Mat& b) { return changed_pixels(a, b, kRegionChange); }

cv::Mat disc(int radius) { return cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * radius + 1, 2 * radius + 1}); }

cv::Mat true_region(const WorldScene& w) {
  cv::Mat region = changed(w.insertion_display, w.photo_display);
  cv::morphologyEx(region, region, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
  if (!w.prop_mask.empty()) region |= w.prop_mask;
  cv::dilate(region, region, disc(kRegionGrowPx));
  return region;
}

// The composite `propcam composite` writes, display-encoded; `placed` gets
// where the prop stood. Throws as composite_prop does.
cv::Mat composite_display(const WorldScene& w, const inference::SceneModel& scene, const render::Mesh& prop, int spp,
                          const std::optional<render::CameraMatchOptions>& camera, render::PlacedProp* placed = nullptr,
                          render::CameraMatchReport* matched = nullptr) {
  render::RenderSettings settings;
  settings.samples_per_pixel = spp;
  CompositeOptions options;
  options.match_camera = camera.has_value();
  if (camera) options.camera_match = *camera;
  const cv::Mat scene_photo = capture::srgb_linear_to_response_linear(w.photo_linear, scene.gamma);
  const CompositeResult r = composite_prop(scene_photo, scene, prop, w.placement, settings, options);
  if (placed) *placed = r.placed;
  if (matched) *matched = r.camera_match;
  return to_display(capture::response_linear_to_srgb_linear(r.composite_linear, scene.gamma));
}

json image_scores(const cv::Mat& image, const WorldScene& w, const cv::Mat& region) {
  const double rmse = cv::countNonZero(region) ? rmse_in_mask(image, w.insertion_display, region) : std::nan("");
  return {{"rmse", number_or_null(rmse)},
          {"ssim", number_or_null(ssim_in_mask(image, w.insertion_display, region))}};
}

// The camera's look on the prop: the noise of its inside (8-bit levels, the
// mean over channels of the region's noise) and the blur of its silhouette
// (px, from as few as kLookMinEdges edge pixels: props are small); null
// where too little of either to measure.
constexpr int kLookMinEdges = 10;
json prop_look(const cv::Mat& display, const cv::Mat& prop_mask) {
  cv::Mat inside, grown, srgb8;
  cv::erode(prop_mask, inside, cv::Mat(), {-1, -1}, 2);
  cv::dilate(prop_mask, grown, cv::Mat(), {-1, -1}, 2);
  const cv::Mat band = grown & ~inside;
  int pixels = 0, edges = 0;
  const std::array<float, 3> noise = render::region_noise_sigma(display, inside, &pixels);
  display.convertTo(srgb8, CV_8UC3, 255.0);
  const double blur = render::estimate_edge_blur(capture::srgb8_to_linear(srgb8), band, &edges, kLookMinEdges);
  const double noise_8bit = 255.0 * (noise[0] + noise[1] + noise[2]) / 3.0;
  return {{"noise_8bit", pixels >= render::kMinRegionNoisePixels ? json(noise_8bit) : json(nullptr)}, {"blur_px", edges ? json(blur) : json(nullptr)}};
}

json stage_seconds(const std::vector<inference::StageReport>& reports) {
  json s = json::object();
  for (const auto& r : reports) s[r.stage] = s.value(r.stage, 0.0) + r.seconds;
  return s;
}

// The light at the prop's base in the camera's frame, for each side.
Eigen::Vector3d in_camera(const render::PinholeCamera& camera, const Eigen::Vector3d& world_vector) {
  return camera.R_world_from_cam.transpose() * world_vector;
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::vector<double> column(const json& rows, const std::function<json(const json&)>& get) {
  std::vector<double> v;
  for (const json& r : rows) v.push_back(num(get(r)));
  return v;
}

json at_path(const json& j, std::initializer_list<const char*> keys) {
  const json* p = &j;
  for (const char* k : keys) {
    if (!p->is_object() || !p->contains(k)) return nullptr;
    p = &(*p)[k];
  }
  return *p;
}

// A summary's mean seconds per scene: inference, composite and probes (the
// other keys are inference's stages, already in "inference").
double seconds_per_scene(const json& summary) {
  double total = 0;
  if (summary.contains("seconds_mean"))
    for (const auto& [key, v] : summary["seconds_mean"].items())
      if (key == "inference" || key == "composite" || key == "light_probe" || key == "probe_renders") total += num(v);
  return total;
}

struct Row {
  std::string sweep, label;
  std::function<void(inference::InferenceOptions&)> apply;  // null: the default inference
  int spp = 0;                                              // 0: the bench's
  // The photo's camera effects the composite matches (null: none).
  std::optional<render::CameraMatchOptions> camera = render::CameraMatchOptions{};
  bool truth = false;  // the world's truth stands in for the inference (own and Blender worlds)
  bool panorama = true;  // also measured on the panorama world
  // Every photo and insertion put through this lens's fall-off, and whether
  // the composite knows it (the scene inferred with it divided out, the
  // prop's layer darkened by it) or not.
  std::optional<render::Vignetting> lens;
  bool lens_calibrated = false;
};

// The vignette sweep's lens: corners at exp(-0.5) = 0.61 of the centre, an
// uncorrected wide lens.
const render::Vignetting kBenchLens{-0.5, 0.0};

// A world scene's camera files through `lens`: photo and insertion decoded,
// darkened, and re-encoded to 8 bits as the camera's file would be.
WorldScene through_lens(const WorldScene& w, const render::Vignetting& lens) {
  WorldScene out = w;
  const auto vignetted_display = [&](const cv::Mat& display, cv::Mat* linear) {
    cv::Mat srgb8, encoded;
    display.convertTo(srgb8, CV_8UC3, 255.0);
    srgb8 = capture::linear_to_srgb8(render::vignette_image(capture::srgb8_to_linear(srgb8), lens));
    if (linear) *linear = capture::srgb8_to_linear(srgb8);
    srgb8.convertTo(encoded, CV_32FC3, 1.0 / 255.0);
    return encoded;
  };
  out.photo_display = vignetted_display(w.photo_display, &out.photo_linear);
  out.insertion_display = vignetted_display(w.insertion_display, nullptr);
  return out;
}

bool wants_sweep(const std::vector<std::string>& sweeps, const std::string& s) {
  return std::find(sweeps.begin(), sweeps.end(), s) != sweeps.end();
}

// `panoramas_only_classifier`: the light classifier trained without the
// Blender world's photos (the "lights" sweep).
std::vector<Row> rows_for(const std::vector<std::string>& sweeps, const std::string& panoramas_only_classifier) {
  const auto wanted = [&](const std::string& s) { return wants_sweep(sweeps, s); };
  std::vector<Row> out{{"default", "default", nullptr, 0}};
  if (wanted("spp"))
    for (int spp : {16, 256}) out.push_back({"spp", std::to_string(spp) + " spp composite", nullptr, spp});
  if (wanted("albedo"))
    for (const auto method : {inference::AlbedoOptions::Method::Retinex, inference::AlbedoOptions::Method::BlurredShading})
      out.push_back({"albedo",
                     method == inference::AlbedoOptions::Method::Retinex ? "Color Retinex everywhere" : "blurred shading everywhere",
                     [method](inference::InferenceOptions& o) {
                       o.albedo.method = method;
                       o.albedo.outdoor_method.reset();
                     }});
  if (wanted("grey_world"))
    out.push_back({"grey_world", "albedo's mean made grey (the cast left to the lights)",
                   [](inference::InferenceOptions& o) { o.albedo.grey_world = true; }});
  if (wanted("fit"))
    for (int spp : {2, 16})
      out.push_back({"fit", std::to_string(spp) + " spp basis renders", [spp](inference::InferenceOptions& o) {
                       o.lighting.fit_samples_per_pixel = spp;
                     }});
  // The panorama world's views are scored with leave-one-out classifiers
  // of its own, so this row is measured on the other worlds only.
  if (wanted("lights"))
    out.push_back({"lights", "light classifier from panoramas only",
                   [panoramas_only_classifier](inference::InferenceOptions& o) {
                     o.lighting.light_classifier = panoramas_only_classifier;
                   },
                   0, render::CameraMatchOptions{}, false, false});
  if (wanted("outdoor_sources"))
    for (const auto& entry : {std::pair{"0.7", 0.7}, {"0.9", 0.9}}) {
      const double share = entry.second;  // a copy: lambdas may not capture structured bindings before clang 16
      out.push_back({"outdoor_sources", std::string("outdoor sources at a vote share of ") + entry.first,
                     [share](inference::InferenceOptions& o) { o.lighting.outdoor_source_threshold = share; }});
    }
  if (wanted("enclosure"))
    out.push_back({"enclosure", "room closed (enclosure)", [](inference::InferenceOptions& o) {
                     o.lighting.enclose_room = true;
                   }});
  if (wanted("sun_patch"))
    out.push_back({"sun_patch", "sun from a patch on the floor", [](inference::InferenceOptions& o) {
                     o.lighting.sun_from_patch = true;
                   }});
  if (wanted("lit_walls"))
    out.push_back({"lit_walls", "lamp from the walls' shading", [](inference::InferenceOptions& o) {
                     o.lighting.lamp_from_lit_walls = true;
                   }});
  if (wanted("geometry"))
    out.push_back({"geometry", "box layout only (no depth solve)", [](inference::InferenceOptions& o) {
                     o.geometry.solve = false;
                   }});
  // A diagnosis, not a knob: the truth as a scene model holds it (true
  // camera, depth, albedo, lights and emitters; nothing out of the frame)
  // through our compositor and renderer. Where it falls short of the photo,
  // the scene model cannot carry the scene's light, whatever the inference.
  if (wanted("oracle")) out.push_back({"oracle", "the truth as a scene model (oracle)", nullptr, 0, render::CameraMatchOptions{}, true});
  if (wanted("colour"))
    out.push_back({"colour", "light tint free of the photo's cast", [](inference::InferenceOptions& o) {
                     o.lighting.tint_within_photo_cast = false;
                   }});
  // A lens's fall-off on every photo (and its truth), unknown to the
  // composite or calibrated.
  if (wanted("vignette")) {
    render::CameraMatchOptions calibrated;
    calibrated.vignetting = kBenchLens;
    calibrated.vignetting_source = "the bench's lens";
    out.push_back({"vignette", "lens fall-off (corners 0.61), not known", nullptr, 0, render::CameraMatchOptions{},
                   false, false, kBenchLens, false});
    out.push_back({"vignette", "lens fall-off (corners 0.61), calibrated", nullptr, 0, calibrated, false, false,
                   kBenchLens, true});
    // The same inference as the calibrated row: what darkening the prop's layer itself gains.
    out.push_back({"vignette", "lens fall-off (corners 0.61), calibrated, prop not darkened", nullptr, 0,
                   render::CameraMatchOptions{}, false, false, kBenchLens, true});
  }
  // The camera match's effects one at a time and none, on the default inference.
  if (wanted("camera")) {
    render::CameraMatchOptions blur_only, noise_only;
    blur_only.noise = false;
    noise_only.blur = false;
    out.push_back({"camera", "camera match off", nullptr, 0, std::nullopt, false, false});
    out.push_back({"camera", "camera match: blur only", nullptr, 0, blur_only, false, false});
    out.push_back({"camera", "camera match: noise only", nullptr, 0, noise_only, false, false});
  }
  return out;
}

// The committed models learnt from the Blender world's tune photos: the
// scene-class references hold them (build-scene-refs --blender-world) and
// the light classifier trained on them (train-light-classifier
// --blender-world). A tune scene is scored without its own photo: its group
// left out of the references, the light classifier of its fold.
struct LeftOut {
  std::vector<std::string> light_classifier_of_fold;  // empty: no tune scene scored
  int folds = 1;
};

// The committed light classifier's training spec, with this bench's Blender world.
LightTrainingSpec committed_light_spec(const WorldsBenchOptions& o) {
  LightTrainingSpec spec = committed_light_training_spec(
      o.panorama.pmndrs_dir.empty() ? default_pmndrs_dir() : o.panorama.pmndrs_dir, o.blender_dir);
  spec.quiet = o.quiet;
  return spec;
}

LeftOut left_out_models(const WorldsBenchOptions& o, const std::vector<WorldScene>& scenes) {
  LeftOut out;
  const bool any_tune = std::any_of(scenes.begin(), scenes.end(),
                                    [](const WorldScene& w) { return w.world == "blender" && w.split == "tune"; });
  if (!any_tune) return out;
  const LightTrainingSpec spec = committed_light_spec(o);
  out.folds = spec.blender_folds;
  out.light_classifier_of_fold = blender_fold_light_classifiers(spec, o.panorama.cache_dir);
  return out;
}

inference::InferenceOptions options_for(const WorldScene& w, const inference::InferenceOptions& given,
                                        const LeftOut& left_out) {
  inference::InferenceOptions options = given;
  if (w.world != "blender") return options;
  options.scene_class_left_out = blender_scene_group(w.name);
  if (w.split == "tune" && options.lighting.light_classifier.empty() && !left_out.light_classifier_of_fold.empty())
    options.lighting.light_classifier =
        left_out.light_classifier_of_fold.at(blender_light_fold(w.name, left_out.folds));
  return options;
}

}  // namespace

json score_world_scene(const WorldScene& w, const inference::InferenceOptions& options, int spp) {
  const auto start = Clock::now();
  const inference::SceneModel est = inference::infer_scene(w.photo_linear, options);
  return score_world_estimate(w, est, seconds_since(start), spp);
}

json score_world_estimate(const WorldScene& w, const inference::SceneModel& est, double inference_seconds, int spp,
                          const std::optional<render::CameraMatchOptions>& camera_match) {
  json row = {{"world", w.world}, {"scene", w.name}, {"split", w.split}, {"kind", w.kind},
              {"indoor_true", w.truth.indoor}, {"indoor", est.indoor}, {"indoor_right", est.indoor == w.truth.indoor},
              {"truth_noise_8bit", number_or_null(w.render_noise_8bit)}};
  row["scene_class"] = scene_class_cues(est.reports);
  for (const auto& r : est.reports)
    if (r.stage == "sun_patch" || r.stage == "lit_wall_lamp")
      row[r.stage] = {{"found", r.usable}, {"why", r.why}, {"details", r.details}};
  json seconds = stage_seconds(est.reports);
  seconds["inference"] = inference_seconds;

  const render::PinholeCamera camera = est.camera();
  const CameraErrors ce = camera_errors(camera, w.true_camera);
  row["camera"] = {{"focal_rel", ce.focal_rel}, {"up_deg", ce.up_deg}, {"pitch_deg", ce.pitch_deg},
                   {"roll_deg", ce.roll_deg}, {"height_rel", number_or_null(ce.height_rel)}};

  // Depth and albedo where the truth sees a surface.
  if (!w.truth.depth.empty()) {
    const cv::Mat surface = (w.truth.depth > 0) & (w.truth.depth < kSkyFromM);
    const cv::Mat called_sky = surface & (est.depth >= kSkyFromM);
    const int n = cv::countNonZero(surface);
    row["depth"] = {{"abs_rel", number_or_null(depth_abs_rel_median_scaled(est.depth, w.truth.depth, surface, kSkyFromM))},
                    {"sky_on_surface", n ? static_cast<double>(cv::countNonZero(called_sky)) / n : 0.0}};
    if (!w.truth.albedo.empty()) {
      const int window = std::max(4, static_cast<int>(std::lround(kLmseWindowShare * std::max(w.truth.width, w.truth.height))));
      row["albedo_lmse"] = number_or_null(albedo_lmse(est.albedo, w.truth.albedo, surface, window));
    }
  }
  if (!w.emitters.empty()) {
    const EmitterCounts c = count_emitters(w.emitters, est.light_source_mask);
    row["emitters"] = {{"truth", c.truth}, {"found", c.found}, {"detected", c.detected}, {"right", c.right}};
  }

  if (!w.insertion_display.empty()) {
    const render::Mesh prop = load_prop(w.prop);
    const cv::Mat region = true_region(w);
    row["region_pixels"] = cv::countNonZero(region);
    row["photo"] = image_scores(w.photo_display, w, region);
    auto t = Clock::now();
    render::PlacedProp placed;
    cv::Mat composite;
    try {
      render::CameraMatchReport matched;
      composite = composite_display(w, est, prop, spp, camera_match, &placed, &matched);
      row["placed"] = true;
      json steps = json::object();
      for (const auto& step : matched.steps) steps[step.effect] = step.applied;
      row["camera_match"] = {{"applied", steps}, {"blur_sigma_px", matched.blur_sigma_px},
                             {"noise_added_8bit", matched.noise_added_8bit}, {"prop_noise_8bit", matched.prop_noise_8bit}};
      seconds["camera_match"] = matched.seconds;
    } catch (const std::invalid_argument& e) {
      // The appliance refuses the spot: the user keeps the photo.
      composite = w.photo_display.clone();
      row["placed"] = false;
      row["placement_error"] = e.what();
    }
    seconds["composite"] = seconds_since(t);
    row["composite"] = image_scores(composite, w, region);
    if (row["placed"].get<bool>() && !w.prop_mask.empty())
      row["prop_look"] = {{"composite", prop_look(composite, w.prop_mask)}, {"truth", prop_look(w.insertion_display, w.prop_mask)}};
    cv::Mat outside;
    cv::dilate(region, outside, disc(kOutsideMarginPx));
    outside = ~outside;
    row["changed_outside_share"] = static_cast<double>(cv::countNonZero(changed(composite, w.photo_display) & outside)) /
                                   static_cast<double>(composite.total());

    // The Khan-style baseline: the same scene, lit only by the photo wrapped onto a sphere.
    const inference::SceneModel khan = khan_baseline(est, w.photo_linear);
    try {
      row["khan"] = image_scores(composite_display(w, khan, prop, spp, camera_match), w, region);
    } catch (const std::invalid_argument&) {
      row["khan"] = row["photo"];
    }

    // The light the prop receives, each side's in its own camera frame.
    if (w.true_light && row["placed"].get<bool>()) {
      t = Clock::now();
      const CompositeWorld world = build_composite_world(est, prop, w.placement);
      const Eigen::Vector3f base = world.placed.base_world + Eigen::Vector3f::UnitY() * static_cast<float>(kProbeLiftM);
      const LightMoments m = probe_light_moments(*world.scene, world.lights, base, kProbeFacePx, kProbeSpp, kProbeSeed);
      const Eigen::Vector3d est_vector = in_camera(camera, m.vector), true_vector = in_camera(w.true_camera, w.true_light->vector);
      row["direction_deg"] = angle_between_deg(est_vector, true_vector);
      // Each side's light vector in its camera frame (x right, y down, z ahead), for the study of what went wrong.
      row["light_vector"] = {{"estimate", {est_vector.x(), est_vector.y(), est_vector.z()}},
                             {"truth", {true_vector.x(), true_vector.y(), true_vector.z()}}};
      seconds["light_probe"] = seconds_since(t);
    }
  }
  row["seconds"] = seconds;
  return row;
}

namespace {

json summarise_rows(const json& rows) {
  json s = {{"scenes", rows.size()}};
  if (rows.empty()) return s;
  int right = 0;
  EmitterCounts e;
  bool any_emitters = false;
  int beats_photo = 0, composites = 0, placed = 0;
  for (const json& r : rows) {
    right += r.value("indoor_right", false);
    if (r.contains("emitters")) {
      any_emitters = true;
      e.truth += r["emitters"]["truth"].get<int>();
      e.found += r["emitters"]["found"].get<int>();
      e.detected += r["emitters"]["detected"].get<int>();
      e.right += r["emitters"]["right"].get<int>();
    }
    if (r.contains("composite") && r["region_pixels"].get<int>() > 0) {
      ++composites;
      placed += r.value("placed", false);
      beats_photo += num(r["composite"]["rmse"]) < num(r["photo"]["rmse"]);
    }
  }
  s["indoor_accuracy"] = static_cast<double>(right) / rows.size();
  if (any_emitters)
    s["emitters"] = {{"truth", e.truth}, {"found", e.found}, {"detected", e.detected}, {"right", e.right},
                     {"recall", number_or_null(e.truth ? static_cast<double>(e.found) / e.truth : std::nan(""))},
                     {"precision", number_or_null(e.detected ? static_cast<double>(e.right) / e.detected : std::nan(""))}};
  const auto med = [&](std::initializer_list<const char*> keys) {
    return number_or_null(median(column(rows, [&](const json& r) { return at_path(r, keys); })));
  };
  const auto med_where = [&](std::initializer_list<const char*> keys, bool indoor) {
    json subset = json::array();
    for (const json& r : rows)
      if (r.value("indoor_true", true) == indoor) subset.push_back(r);
    return number_or_null(median(column(subset, [&](const json& r) { return at_path(r, keys); })));
  };
  s["focal_rel_median"] = med({"camera", "focal_rel"});
  s["up_deg_median"] = med({"camera", "up_deg"});
  s["depth_abs_rel_median"] = med({"depth", "abs_rel"});
  s["sky_on_surface_median"] = med({"depth", "sky_on_surface"});
  s["albedo_lmse_median"] = med({"albedo_lmse"});
  s["direction_deg_median"] = med({"direction_deg"});
  s["direction_deg_median_indoor"] = med_where({"direction_deg"}, true);
  s["direction_deg_median_outdoor"] = med_where({"direction_deg"}, false);
  if (composites) {
    for (const char* which : {"composite", "photo", "khan"})
      s[which] = {{"rmse_median", med({which, "rmse"})}, {"ssim_median", med({which, "ssim"})}};
    s["composite_beats_photo_share"] = static_cast<double>(beats_photo) / composites;
    s["placed_share"] = static_cast<double>(placed) / composites;
    s["changed_outside_share_median"] = med({"changed_outside_share"});
    // How far the prop's noise and edge blur are from the truth's, per scene.
    const auto look_gap = [&](const char* what) {
      return number_or_null(median(column(rows, [&](const json& r) {
        return json(std::abs(num(at_path(r, {"prop_look", "composite", what})) - num(at_path(r, {"prop_look", "truth", what}))));
      })));
    };
    s["prop_look"] = {{"noise_8bit_median", {{"composite", med({"prop_look", "composite", "noise_8bit"})},
                                             {"truth", med({"prop_look", "truth", "noise_8bit"})}}},
                      {"blur_px_median", {{"composite", med({"prop_look", "composite", "blur_px"})},
                                          {"truth", med({"prop_look", "truth", "blur_px"})}}},
                      {"noise_gap_8bit_median", look_gap("noise_8bit")},
                      {"blur_gap_px_median", look_gap("blur_px")}};
  }
  // Mean seconds per stage over the scenes.
  std::map<std::string, double> total;
  for (const json& r : rows)
    for (const auto& [stage, value] : r["seconds"].items()) total[stage] += value.get<double>();
  json mean = json::object();
  for (const auto& [stage, value] : total) mean[stage] = value / rows.size();
  s["seconds_mean"] = mean;
  return s;
}

}  // namespace

json summarise_world(const json& rows) {
  json s = summarise_rows(rows);
  // Beside all scenes, those whose truth is clean: render noise well below
  // the composite errors measured (docs/blender_world.md, "Noise").
  json clean = json::array();
  bool noise_known = false;
  for (const json& r : rows) {
    const double noise = num(r.value("truth_noise_8bit", json(nullptr)));
    noise_known |= std::isfinite(noise);
    if (!std::isfinite(noise) || noise <= kCleanTruthNoise8bit) clean.push_back(r);
  }
  if (noise_known) {
    s["clean_truth"] = summarise_rows(clean);
    s["clean_truth"]["max_noise_8bit"] = kCleanTruthNoise8bit;
  }
  return s;
}

json run_worlds_bench(const WorldsBenchOptions& o) {
  Progress progress(o.quiet);
  const auto wants = [&](const char* w) { return std::find(o.worlds.begin(), o.worlds.end(), w) != o.worlds.end(); };
  std::vector<WorldScene> scenes;
  if (wants("own")) {
    progress.stage("bench worlds: rendering our own world");
    for (auto& s : make_own_world(o.own)) scenes.push_back(std::move(s));
  }
  if (wants("blender")) {
    progress.stage("bench worlds: reading the Blender world in " + o.blender_dir);
    std::vector<WorldScene> blender = load_blender_world(o.blender_dir, o.split == "all" ? "" : o.split);
    if (blender.empty()) throw std::runtime_error("the Blender world in '" + o.blender_dir + "' has no rendered scene of split '" + o.split + "'");
    if (o.max_scenes > 0 && static_cast<int>(blender.size()) > o.max_scenes) blender.resize(o.max_scenes);
    for (auto& s : blender) scenes.push_back(std::move(s));
  }
  const LeftOut left_out = left_out_models(o, scenes);
  std::string panoramas_only_classifier;
  if (wants_sweep(o.sweeps, "lights")) {
    progress.stage("bench worlds: the light classifier from panoramas only");
    LightTrainingSpec spec = committed_light_spec(o);
    spec.blender_world.clear();
    panoramas_only_classifier = cached_light_classifier(spec, o.panorama.cache_dir, "panoramas_only");
  }
  json result_rows = json::array();
  // The default inference of each scene, kept for the rows that change only the composite.
  std::vector<std::pair<inference::SceneModel, double>> default_estimates(scenes.size());
  // The vignette sweep's inferences, through the lens: known or not.
  std::vector<std::pair<inference::SceneModel, double>> unknown_lens_estimates(scenes.size()),
      calibrated_lens_estimates(scenes.size());
  for (const Row& row : rows_for(o.sweeps, panoramas_only_classifier)) {
    json worlds = json::object();
    std::map<std::string, json> per_world;
    for (size_t i = 0; i < scenes.size(); ++i) {
      const WorldScene& s = scenes[i];
      progress.stage("bench worlds: " + row.label + ", " + s.world + " " + s.name);
      const int spp = row.spp > 0 ? row.spp : o.spp;
      if (row.lens) {
        const WorldScene through = through_lens(s, *row.lens);
        auto& [estimate, seconds] = (row.lens_calibrated ? calibrated_lens_estimates : unknown_lens_estimates)[i];
        if (estimate.width == 0) {
          const auto start = Clock::now();
          const inference::InferenceOptions defaults;
          const render::Vignetting known = row.lens_calibrated ? *row.lens : render::Vignetting{};
          estimate = inference::infer_scene(render::devignette(through.photo_linear, known),
                                            options_for(s, defaults, left_out));
          seconds = seconds_since(start);
        }
        per_world[s.world].push_back(score_world_estimate(through, estimate, seconds, spp, row.camera));
        continue;
      }
      if (row.truth) {
        inference::SceneModel truth = s.truth;
        truth.light_source_mask = s.emitters;
        truth.imaging = render::estimate_photo_imaging(s.photo_linear);  // the photo's, as the inference has it
        per_world[s.world].push_back(score_world_estimate(s, truth, 0.0, spp, row.camera));
        continue;
      }
      if (row.apply) {
        inference::InferenceOptions options;
        row.apply(options);
        per_world[s.world].push_back(score_world_scene(s, options_for(s, options, left_out), spp));  // camera matched
        continue;
      }
      auto& [estimate, seconds] = default_estimates[i];
      if (estimate.width == 0) {
        const auto start = Clock::now();
        const inference::InferenceOptions defaults;
        estimate = inference::infer_scene(s.photo_linear, options_for(s, defaults, left_out));
        seconds = seconds_since(start);
      }
      per_world[s.world].push_back(score_world_estimate(s, estimate, seconds, spp, row.camera));
    }
    for (auto& [world, rows] : per_world) worlds[world] = {{"summary", summarise_world(rows)}, {"scenes", rows}};
    if (wants("panorama") && row.panorama && !row.truth && (row.apply || row.sweep == "default")) {
      progress.stage("bench worlds: " + row.label + ", panorama views");
      PanoramaWorldOptions p = o.panorama;
      p.quiet = o.quiet;
      worlds["panorama"] = run_panorama_world(p, row.apply);
    }
    result_rows.push_back({{"sweep", row.sweep}, {"label", row.label}, {"worlds", worlds}});
  }
  return {{"split", o.split}, {"spp", o.spp}, {"blender_dir", o.blender_dir}, {"rows", result_rows}};
}

std::string format_worlds_bench(const json& r) {
  std::ostringstream out;
  char line[512];
  out << "Worlds (Blender split: " << r["split"].get<std::string>() << "; composite " << r["spp"].get<int>()
      << " spp): medians over scenes\n";
  for (const json& row : r["rows"]) {
    out << "\n== " << row["label"].get<std::string>() << " ==\n";
    std::snprintf(line, sizeof line, "%-9s %6s %7s %7s %8s %7s %7s %7s %8s %8s %8s %8s %8s %7s %7s\n", "world", "scenes",
                  "in/out", "lights", "", "focal", "depth", "albedo", "dir in", "dir out", "comp", "photo", "khan", "beats",
                  "s/scene");
    out << line;
    std::snprintf(line, sizeof line, "%-9s %6s %7s %7s %8s %7s %7s %7s %8s %8s %8s %8s %8s %7s %7s\n", "", "", "right",
                  "recall", "precis.", "rel", "absrel", "LMSE", "deg", "deg", "RMSE", "RMSE", "RMSE", "photo", "");
    out << line;
    for (const auto& [world, w] : row["worlds"].items()) {
      const json& s = w["summary"];
      const double total = seconds_per_scene(s);
      std::snprintf(line, sizeof line,
                    "%-9s %6d %7.2f %7.2f %8.2f %7.3f %7.3f %7.3f %8.1f %8.1f %8.4f %8.4f %8.4f %7.2f %7.1f\n",
                    world.c_str(), s.value("scenes", 0), num(at_path(s, {"indoor_accuracy"})),
                    num(at_path(s, {"emitters", "recall"})), num(at_path(s, {"emitters", "precision"})),
                    num(at_path(s, {"focal_rel_median"})), num(at_path(s, {"depth_abs_rel_median"})),
                    num(at_path(s, {"albedo_lmse_median"})), num(at_path(s, {"direction_deg_median_indoor"})),
                    num(at_path(s, {"direction_deg_median_outdoor"})), num(at_path(s, {"composite", "rmse_median"})),
                    num(at_path(s, {"photo", "rmse_median"})), num(at_path(s, {"khan", "rmse_median"})),
                    num(at_path(s, {"composite_beats_photo_share"})), total);
      out << line;
      if (s.contains("composite")) {
        std::snprintf(line, sizeof line, "%-9s SSIM over the prop's region: composite %.3f, photo %.3f, Khan %.3f; placed %.0f%%; changed outside %.4f\n",
                      "", num(at_path(s, {"composite", "ssim_median"})), num(at_path(s, {"photo", "ssim_median"})),
                      num(at_path(s, {"khan", "ssim_median"})), 100 * num(at_path(s, {"placed_share"})),
                      num(at_path(s, {"changed_outside_share_median"})));
        out << line;
        std::snprintf(line, sizeof line,
                      "%-9s the prop's look: noise %.1f levels (truth %.1f; gap %.1f), silhouette blur %.2f px (truth %.2f; gap %.2f)\n",
                      "", num(at_path(s, {"prop_look", "noise_8bit_median", "composite"})),
                      num(at_path(s, {"prop_look", "noise_8bit_median", "truth"})),
                      num(at_path(s, {"prop_look", "noise_gap_8bit_median"})),
                      num(at_path(s, {"prop_look", "blur_px_median", "composite"})),
                      num(at_path(s, {"prop_look", "blur_px_median", "truth"})),
                      num(at_path(s, {"prop_look", "blur_gap_px_median"})));
        out << line;
      }
      if (s.contains("clean_truth") && s["clean_truth"].contains("composite")) {
        const json& c = s["clean_truth"];
        std::snprintf(line, sizeof line,
                      "%-9s truth noise <= %.0f levels (%d scenes): composite %.4f, photo %.4f, Khan %.4f RMSE; SSIM %.3f / %.3f / %.3f; beats photo %.2f; dir in %.1f, out %.1f\n",
                      "", num(c["max_noise_8bit"]), c.value("scenes", 0), num(at_path(c, {"composite", "rmse_median"})),
                      num(at_path(c, {"photo", "rmse_median"})), num(at_path(c, {"khan", "rmse_median"})),
                      num(at_path(c, {"composite", "ssim_median"})), num(at_path(c, {"photo", "ssim_median"})),
                      num(at_path(c, {"khan", "ssim_median"})), num(at_path(c, {"composite_beats_photo_share"})),
                      num(at_path(c, {"direction_deg_median_indoor"})), num(at_path(c, {"direction_deg_median_outdoor"})));
        out << line;
      }
      if (s.contains("probe")) {
        out << "          probe spheres, RMSE / scale-invariant RMSE:";
        for (const auto& [sphere, p] : s["probe"].items()) {
          std::snprintf(line, sizeof line, " %s %.3f / %.3f;", sphere.c_str(), num(p["rmse_median"]), num(p["si_rmse_median"]));
          out << line;
        }
        out << " placed " << s.value("placed", 0) << "\n          Khan-style baseline, scale-invariant RMSE (ours below it):";
        for (const auto& [sphere, p] : s["probe"].items()) {
          std::snprintf(line, sizeof line, " %s %.3f (%.0f%%);", sphere.c_str(), num(p["khan_si_rmse_median"]),
                        100 * num(p["si_beats_khan_share"]));
          out << line;
        }
        out << "\n";
      }
    }
  }
  out << "\nin/out: indoor/outdoor right; lights: visible emitters >= 0.1% of the frame (recall, precision); focal: "
         "|f/f_true - 1|; depth: abs-rel after median scaling; albedo: LMSE; dir: dominant light at the prop's base, "
         "camera frame; comp/photo/khan RMSE: display values over the prop's true region against the true "
         "insertion (the composite, the untouched photo, the Khan-style environment); beats photo: share of scenes "
         "whose composite is closer than the photo; the prop's look: medians of the noise of its inside and the "
         "edge blur of its silhouette, and of their gaps to the truth's, per scene; s/scene: inference + composite + probe\n";
  return out.str();
}

void plot_worlds_bench(const json& r, const std::string& dir) {
  std::ostringstream dat;
  for (const json& row : r["rows"]) {
    std::string label = row["label"];
    std::replace(label.begin(), label.end(), ' ', '_');
    for (const auto& [world, w] : row["worlds"].items()) {
      const json& s = w["summary"];
      const double total = seconds_per_scene(s);
      dat << world << " " << total << " " << num(at_path(s, {"composite", "rmse_median"})) << " "
          << num(at_path(s, {"direction_deg_median"})) << " \"" << label << "\"\n";
    }
  }
  std::ostringstream gp;
  gp << "$data << EOD\n" << dat.str() << "EOD\n"
     << "set terminal png size 1100,480 noenhanced\nset grid\nset key top right\nset output '"
     << (std::filesystem::path(dir) / "worlds.png").string() << "'\n"
     << "set multiplot layout 1,2 title 'bench worlds: error against seconds per scene (one point per row and world)'\n"
        "set xlabel 'seconds per scene (inference + composite)'\nset ylabel 'composite RMSE in the prop region (median)'\n"
        "plot $data using 2:3:1 with labels point pt 7 offset 0,1 notitle\n"
        "set ylabel 'dominant light direction error (median, deg)'\n"
        "plot $data using 2:4:1 with labels point pt 7 offset 0,1 notitle\n"
        "unset multiplot\n";
  run_gnuplot(dir, "worlds.gp", gp.str());
}

void add_bench_worlds_options(CLI::App& cmd, WorldsBenchArgs& a) {
  cmd.add_option("--worlds", a.worlds, "Comma-separated subset of own,blender,panorama");
  cmd.add_option("--dir", a.options.blender_dir, "The Blender world (scripts/make_blender_world.sh --out DIR)");
  cmd.add_option("--split", a.options.split, "Blender world split: tune | held | all")
      ->check(CLI::IsMember({"tune", "held", "all"}));
  cmd.add_option("--spp", a.options.spp, "Composite samples per pixel")->check(CLI::Range(1, 4096));
  cmd.add_option("--max-scenes", a.options.max_scenes, "Blender world: at most this many scenes (0: all)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--rooms", a.options.own.rooms, "Own world: synthetic rooms (seeds 1..N)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--streets", a.options.own.streets, "Own world: synthetic streets (seeds 1..N)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--own-size", a.own_size, "Own world: photo size WxH");
  cmd.add_option("--own-spp", a.options.own.spp, "Own world: samples per pixel of photos and insertions")->check(CLI::Range(1, 4096));
  cmd.add_option("--panoramas", a.options.panorama.panoramas, "Panorama world: names or EXR files (default: all 26)")->delimiter(',');
  cmd.add_option("--views", a.options.panorama.views_per_panorama, "Panorama world: views per panorama")->check(CLI::PositiveNumber);
  cmd.add_option("--sweeps", a.sweeps, "Extra rows: comma-separated subset of spp,albedo,grey_world,fit,lights,outdoor_sources,enclosure,sun_patch (the sun of a patch on the floor),lit_walls (a lamp out of view from the walls' shading),geometry,oracle (the true scene),camera (the camera match's effects),colour (the light tint unbounded by the photo's cast),vignette (a lens's fall-off on every photo, unknown and calibrated)");
  cmd.add_option("--plot", a.options.plot_dir, "Write worlds.png (gnuplot) to this folder");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_worlds_command(WorldsBenchArgs a) {
  a.options.worlds = parse_sweeps(a.worlds, {"own", "blender", "panorama"});
  if (a.options.worlds.empty()) throw std::invalid_argument("--worlds names no world");
  a.options.sweeps = parse_sweeps(a.sweeps, {"spp", "albedo", "grey_world", "fit", "lights", "outdoor_sources", "enclosure", "sun_patch", "lit_walls", "geometry", "oracle", "camera", "colour", "vignette"});
  parse_bench_size(a.own_size, 16, a.options.own.width, a.options.own.height);
  a.options.quiet = a.json_out;
  return report_bench_result(run_worlds_bench(a.options),
                             a.json_out, a.options.plot_dir, plot_worlds_bench, format_worlds_bench);
}

}  // namespace propcam::firmware
