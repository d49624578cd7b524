#include "propcam/inference/infer.h"
#include "propcam/inference/physical_ranges.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>

#include "load_once.h"
#include "propcam/inference/contact_depth.h"
#include "propcam/inference/scene_class_knn.h"
#include "propcam/inference/scene_classifier.h"


namespace propcam::inference {
namespace {

void check_photo(const cv::Mat& photo, const InferenceOptions& options) {
  if (photo.empty() || photo.type() != CV_32FC3)
    throw std::invalid_argument("infer_scene: the photo must be a non-empty linear RGB image");
  if (photo.cols < kMinPhotoSide || photo.rows < kMinPhotoSide)
    throw std::invalid_argument("infer_scene: the photo is " + std::to_string(photo.cols) + "x" +
                                std::to_string(photo.rows) + "; at least " + std::to_string(kMinPhotoSide) +
                                " pixels per side are needed");
  if (std::max(photo.cols, photo.rows) > kMaxPhotoAspect * std::min(photo.cols, photo.rows))
    throw std::invalid_argument("the photo is " + std::to_string(photo.cols) + "x" + std::to_string(photo.rows) +
                                "; its long side may be at most " + std::to_string(kMaxPhotoAspect) +
                                " times its short side (crop it)");
  require_in_range(options.camera_height_m, kCameraHeightRange, "the camera height");
}

render::PinholeCamera pinhole_from(const CameraEstimate& cam, int width, int height, double camera_height_m) {
  SceneModel s;
  s.width = width;
  s.height = height;
  s.fx = cam.fx;
  s.fy = cam.fy;
  s.cx = cam.cx;
  s.cy = cam.cy;
  s.R_world_from_cam = cam.R_world_from_cam;
  s.camera_height_m = camera_height_m;
  return s.camera();
}

// Databases stay loaded once read (1.5 MB); a missing or broken one is
// reported and the solve goes on without transfer.
std::shared_ptr<const DepthDatabase> cached_depth_database(const std::string& requested, StageReport& report) {
  const std::string path = requested.empty() ? default_depth_database_path() : requested;
  report.stage = "depth_transfer";
  std::string why;
  auto db = load_once<DepthDatabase>(path, why);
  if (!db) {
    report.usable = false;
    report.why = "no depth transfer: " + why;
  }
  return db;
}

// Transferred depth is made at twice the solve grid: finer would only
// resample the database's 64x48 maps.
cv::Size transfer_size(const render::PinholeCamera& camera, int solve_width) {
  const int w = std::clamp(2 * solve_width, 1, camera.width);
  return {w, std::max(1, static_cast<int>(std::lround(static_cast<double>(w) * camera.height / camera.width)))};
}

// The committed scene classifier for the committed references; for other
// references, or with a group left out (benchmarks scoring a scene the
// references hold), one trained on them, kept for the process's life.
std::shared_ptr<const SceneClassifier> scene_classifier_for(const std::string& refs_path, const SceneReferenceSet& refs,
                                                            int left_out, std::string& why) {
  if (refs_path == default_scene_reference_path() && left_out < 0)
    return load_once<SceneClassifier>(default_scene_classifier_path(), why);
  static std::mutex mutex;
  static std::map<std::pair<std::string, int>, std::shared_ptr<const SceneClassifier>> trained;
  std::lock_guard lock(mutex);
  auto& slot = trained[{refs_path, left_out}];
  if (!slot) {
    try {
      slot = std::make_shared<const SceneClassifier>(SceneClassifier::train(refs, left_out));
    } catch (const std::exception& e) {
      why = e.what();
      trained.erase({refs_path, left_out});
      return nullptr;
    }
  }
  return slot;
}

}  // namespace

GeometryEstimate infer_geometry(const cv::Mat& photo, const InferenceOptions& options) {
  check_photo(photo, options);
  auto stage = [&](const char* name) {
    if (options.on_stage) options.on_stage(name);
  };
  GeometryEstimate g;
  stage("lines");
  StageReport lines_report;
  if (options.given_lines) {
    g.lines = *options.given_lines;
    lines_report.stage = "lines";
    lines_report.why = std::to_string(g.lines.size()) + " segments given";
    lines_report.usable = !g.lines.empty();
  } else {
    g.lines = detect_lines(photo, options.lines, lines_report);
  }
  g.reports.push_back(lines_report);

  stage("camera");
  g.camera = estimate_camera(g.lines, photo.cols, photo.rows, options.camera);
  g.reports.push_back(g.camera.report);
  g.pinhole = pinhole_from(g.camera, photo.cols, photo.rows, options.camera_height_m);
  StageReport height_report;
  height_report.stage = "camera_height";
  height_report.why = "prior (board configuration)";
  height_report.details = {{"metres", options.camera_height_m}};
  g.reports.push_back(height_report);

  stage("scene_class");
  StageReport class_report;
  // The sky rule where it sees sky, else k-NN on rendered and real
  // references (inference/README.md, "Scene class"); the rule
  // alone when the references cannot be read.
  std::string refs_why;
  const std::string refs_path = options.scene_references.empty() ? default_scene_reference_path() : options.scene_references;
  if (const auto refs = load_once<SceneReferenceSet>(refs_path, refs_why)) {
    CombinedSceneClassOptions class_options = options.scene_class;
    if (!options.scene_class_left_out.empty()) {
      class_options.knn.exclude_group = refs->find_group(options.scene_class_left_out);
      class_report.details["left_out"] = options.scene_class_left_out;
    }
    std::string classifier_why;
    const auto classifier = scene_classifier_for(refs_path, *refs, class_options.knn.exclude_group, classifier_why);
    g.indoor = classify_indoor_combined(photo, g.pinhole, *refs, class_report, &g.sky, class_options, classifier.get());
    if (!classifier) class_report.details["svm_unavailable"] = classifier_why;
  } else {
    g.indoor = classify_indoor(photo, g.pinhole, class_report, &g.sky, options.scene_class.sky);
    class_report.details["method"] = "sky";
    class_report.details["knn_unavailable"] = refs_why;
  }
  g.reports.push_back(class_report);
  if (!g.indoor) g.sky_mask = g.sky.mask;

  // The orientation map (about a millisecond) serves the box (the floor it
  // sees), the floor-contact target and the E_o prior.
  stage("orientation_map");
  OrientationMap om = estimate_orientation_map(g.lines, g.camera.line_labels, g.pinhole, options.geometry.orientation);
  g.orientation = om.labels;
  g.reports.push_back(om.report);

  stage("geometry");
  g.layout = estimate_layout(g.pinhole, g.lines, g.camera.line_labels, g.indoor, options.layout, g.sky_mask,
                             seen_floor_points(g.orientation, g.pinhole), g.orientation);
  g.reports.push_back(g.layout.report);
  g.depth = g.layout.depth;
  g.normals = g.layout.normals;
  if (options.geometry.solve) {
    DepthProblem problem;
    problem.camera = g.pinhole;
    problem.targets.push_back({g.layout.depth, options.geometry.box_weight, {}});
    problem.sky_mask = g.sky_mask;
    if (options.geometry.solver.use_orientation) problem.orientation_labels = g.orientation;
    if (options.geometry.transfer_weight > 0) {
      stage("depth_transfer");
      StageReport report;
      if (const auto db = cached_depth_database(options.geometry.depth_database, report)) {
        try {
          TransferredDepth t = transfer_depth(photo, g.pinhole, options.camera_height_m, g.indoor, *db,
                                              transfer_size(g.pinhole, options.geometry.solver.width), options.geometry.transfer);
          problem.targets.push_back({t.median, options.geometry.transfer_weight, {}});
          report = t.report;
        } catch (const std::invalid_argument& e) {  // e.g. no example of this scene class
          report.usable = false;
          report.why = std::string("no depth transfer: ") + e.what();
        }
      }
      g.reports.push_back(report);
    }
    if (options.geometry.contact_weight > 0) {
      ContactDepth contact = contact_depth_target(g.orientation, g.pinhole, g.layout.normals);
      problem.targets.push_back({contact.depth, options.geometry.contact_weight, contact.confidence});
    }
    problem.guide_photo = photo;
    // Every data target switched off or silent (no floor seen): the box stands in.
    const bool any_opinion = std::any_of(problem.targets.begin(), problem.targets.end(), [](const DepthTarget& t) {
      return t.weight > 0 && cv::countNonZero(t.depth > 0) > 0;
    });
    if (!any_opinion) problem.targets.push_back({g.layout.depth, 1.0, {}});
    stage("depth");
    DepthSolveOptions solver = options.geometry.solver;
    if (options.geometry.class_weights) solver.weights = g.indoor ? DepthPriorWeights::indoor() : DepthPriorWeights::outdoor();
    DepthSolution depth = solve_depth(problem, solver);
    depth.report.details["box_stood_in"] = !any_opinion;
    g.depth = depth.depth;
    g.normals = depth.normals;
    g.reports.push_back(depth.report);
  }
  // Support surfaces from the final depth; the layout's walls and ceiling
  // stay as unbounded planes (the lighting stage hangs hypotheses on them).
  StageReport support_report;
  g.planes = find_support_planes(g.depth, g.normals, g.pinhole, options.geometry.support, support_report);
  g.reports.push_back(support_report);
  for (const auto& p : g.layout.planes)
    if (p.name != "floor") g.planes.push_back(p);
  return g;
}

namespace {

// NaN becomes 0 and infinities a bright but finite radiance, so no stage sees them.
cv::Mat sanitised(const cv::Mat& photo_linear, const InferenceOptions& options) {
  check_photo(photo_linear, options);
  cv::Mat photo = photo_linear.clone();
  cv::patchNaNs(photo, 0.0);
  return cv::min(cv::max(photo, 0.0), kMaxPhotoRadiance);
}

StageReport imaging_report(const render::PhotoImaging& m) {
  StageReport r;
  r.stage = "imaging";
  r.seconds = m.seconds;
  char blur[64] = "not measured (too few isolated edges)", noise[48] = "not measured (too few flat blocks)";
  if (m.blur_measured)
    std::snprintf(blur, sizeof blur, "sigma %.2f px%s", m.blur_sigma_px,
                  m.blur_read_through_noise ? " (read through the noise)" : "");
  if (m.noise_measured) std::snprintf(noise, sizeof noise, "%.1f levels (median)", m.noise.median_8bit());
  r.why = std::string("edge blur ") + blur + ", noise " + noise;
  const render::Defocus& d = m.defocus;
  if (d.found) {
    char defocus[96];
    std::snprintf(defocus, sizeof defocus, "; defocus: sigma %.2f px at %.1f m to %.2f px at %.1f m",
                  d.sigma_at(1.0 / d.max_dioptres), 1.0 / d.max_dioptres, d.sigma_at(1.0 / d.min_dioptres),
                  1.0 / d.min_dioptres);
    r.why += defocus;
  }
  r.details = {{"blur_sigma_px", m.blur_sigma_px}, {"blur_edges", m.blur_edges}, {"blur_read_through_noise", m.blur_read_through_noise},
               {"defocus_found", d.found}, {"defocus_bands", d.bands.size()},
               {"noise_median_8bit", m.noise.median_8bit()}, {"noise_blocks", m.noise_blocks}};
  return r;
}

}  // namespace

SceneModel complete_scene(const cv::Mat& photo_linear, const GeometryEstimate& g, const InferenceOptions& options) {
  const cv::Mat photo = sanitised(photo_linear, options);
  SceneModel scene;
  scene.width = photo.cols;
  scene.height = photo.rows;
  scene.camera_height_m = options.camera_height_m;
  scene.fx = g.camera.fx;
  scene.fy = g.camera.fy;
  scene.cx = g.camera.cx;
  scene.cy = g.camera.cy;
  scene.R_world_from_cam = g.camera.R_world_from_cam;
  scene.indoor = g.indoor;
  scene.depth = g.depth;
  scene.normals = g.normals;
  scene.planes = g.planes;
  scene.reports = g.reports;
  const render::PinholeCamera& camera = g.pinhole;

  if (options.on_stage) options.on_stage("imaging");
  scene.imaging = render::estimate_photo_imaging(photo, scene.depth);
  scene.reports.push_back(imaging_report(scene.imaging));

  if (options.on_stage) options.on_stage("albedo");
  StageReport albedo_report;
  AlbedoOptions albedo_options = options.albedo;
  if (!scene.indoor && albedo_options.outdoor_method) albedo_options.method = *albedo_options.outdoor_method;
  scene.albedo = estimate_albedo(photo, albedo_options, albedo_report);
  scene.reports.push_back(albedo_report);

  if (options.on_stage) options.on_stage("lighting");
  LightingEstimate lighting = estimate_lighting(photo, scene.depth, scene.albedo, camera, scene.planes, scene.indoor,
                                                options.lighting, scene.indoor ? nullptr : &g.sky,
                                                GeometryCues{g.orientation, g.sky.mask, g.normals});
  scene.hidden_facades = std::move(lighting.hidden_facades);
  scene.enclosure = lighting.enclosure;
  scene.light_source_mask = lighting.source_mask;
  scene.windows = std::move(lighting.windows);
  if (!lighting.albedo.empty()) scene.albedo = lighting.albedo;  // a sun patch's light taken out of it
  if (lighting.albedo_scale != 1.0) {
    scale_albedo(scene.albedo, lighting.albedo_scale);
    for (auto& f : scene.hidden_facades) f.albedo = (f.albedo * static_cast<float>(lighting.albedo_scale)).cwiseMin(1.f);
    scene.enclosure.albedo = (scene.enclosure.albedo * static_cast<float>(lighting.albedo_scale)).cwiseMin(1.f);
  }
  scene.lights = std::move(lighting.lights);
  for (auto& r : lighting.reports) scene.reports.push_back(std::move(r));
  scene.gamma = lighting.gamma;  // fitted with the intensities
  scene.validate();
  return scene;
}

SceneModel infer_scene(const cv::Mat& photo_linear, const InferenceOptions& options) {
  const cv::Mat photo = sanitised(photo_linear, options);
  return complete_scene(photo, infer_geometry(photo, options), options);
}

}  // namespace propcam::inference
