#include "propcam/inference/infer.h"

#include <stdexcept>

#include "propcam/inference/sky.h"

namespace propcam::inference {

SceneModel infer_scene(const cv::Mat& photo_linear, const InferenceOptions& options) {
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3)
    throw std::invalid_argument("infer_scene: the photo must be a non-empty linear RGB image");
  if (photo_linear.cols < kMinPhotoSide || photo_linear.rows < kMinPhotoSide)
    throw std::invalid_argument("infer_scene: the photo is " + std::to_string(photo_linear.cols) + "x" +
                                std::to_string(photo_linear.rows) + "; at least " + std::to_string(kMinPhotoSide) +
                                " pixels per side are needed");
  if (!(options.camera_height_m > 0)) throw std::invalid_argument("infer_scene: camera height must be positive");
  auto stage = [&](const char* name) {
    if (options.on_stage) options.on_stage(name);
  };
  // NaN becomes 0 and infinities a bright but finite radiance, so no stage sees them.
  cv::Mat photo = photo_linear.clone();
  cv::patchNaNs(photo, 0.0);
  photo = cv::min(cv::max(photo, 0.0), kMaxPhotoRadiance);

  SceneModel scene;
  scene.width = photo.cols;
  scene.height = photo.rows;
  scene.camera_height_m = options.camera_height_m;

  stage("lines");
  StageReport lines_report;
  std::vector<LineSegment> lines;
  if (options.given_lines) {
    lines = *options.given_lines;
    lines_report.stage = "lines";
    lines_report.why = std::to_string(lines.size()) + " segments given";
    lines_report.usable = !lines.empty();
  } else {
    lines = detect_lines(photo, options.lines, lines_report);
  }
  scene.reports.push_back(lines_report);

  stage("camera");
  const CameraEstimate cam = estimate_camera(lines, photo.cols, photo.rows, options.camera);
  scene.fx = cam.fx;
  scene.fy = cam.fy;
  scene.cx = cam.cx;
  scene.cy = cam.cy;
  scene.R_world_from_cam = cam.R_world_from_cam;
  scene.reports.push_back(cam.report);
  StageReport height_report;
  height_report.stage = "camera_height";
  height_report.why = "prior (board configuration)";
  height_report.details = {{"metres", options.camera_height_m}};
  scene.reports.push_back(height_report);

  stage("scene_class");
  StageReport class_report;
  SkyEstimate sky;
  scene.indoor = classify_indoor(photo, scene.camera(), class_report, &sky);
  scene.reports.push_back(class_report);

  stage("geometry");
  const render::PinholeCamera camera = scene.camera();
  Layout layout = estimate_layout(camera, lines, cam.line_labels, scene.indoor, options.layout,
                                  scene.indoor ? cv::Mat() : sky.mask);
  scene.depth = layout.depth;
  scene.normals = layout.normals;
  scene.planes = layout.planes;
  scene.reports.push_back(layout.report);

  stage("albedo");
  StageReport albedo_report;
  scene.albedo = estimate_albedo(photo, options.albedo, albedo_report);
  scene.reports.push_back(albedo_report);

  stage("lighting");
  LightingEstimate lighting = estimate_lighting(photo, scene.depth, scene.albedo, camera, scene.planes, scene.indoor,
                                                options.lighting, scene.indoor ? nullptr : &sky);
  scene.lights = std::move(lighting.lights);
  for (auto& r : lighting.reports) scene.reports.push_back(std::move(r));
  scene.gamma = 2.2;  // photos are linearised with the sRGB curve; fitting it is a later issue
  scene.validate();
  return scene;
}

}  // namespace propcam::inference
