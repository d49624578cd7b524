// inference: the camera with no or only parallel lines, black / saturated /
// tiny / non-finite photos through the whole of infer_scene, an ill-posed
// depth solve, the intensity fit with collinear or zero basis renders, IBL
// panoramas with NaN / Inf / negative texels, corrupt scene folders.
#include <filesystem>
#include <fstream>
#include <limits>

#include <nlohmann/json.hpp>

#include "catalogue.h"
#include "propcam/inference/camera.h"
#include "propcam/inference/depth_solve.h"
#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/ibl_library.h"
#include "propcam/inference/infer.h"
#include "propcam/inference/intensity_fit.h"
#include "propcam/inference/sun_choice.h"
#include "propcam/inference/scene_classifier.h"
#include "propcam/inference/scene_model.h"

namespace propcam::inference {
namespace {

namespace fs = std::filesystem;
using hard_cases::check;
using hard_cases::Digest;
using hard_cases::Expect;
using hard_cases::HardCase;

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

void add_matrix(Digest& d, const Eigen::MatrixXd& m) {
  for (Eigen::Index i = 0; i < m.size(); ++i) d.number(m.data()[i]);
}

void add_camera(Digest& d, const CameraEstimate& c) {
  d.number(c.fx);
  d.number(c.fy);
  d.number(c.cx);
  d.number(c.cy);
  add_matrix(d, c.R_world_from_cam);
  d.integer(static_cast<int>(c.which));
  d.integer(c.focal_from_vanishing_points);
  for (int label : c.line_labels) d.integer(label);
}

// Everything a scene model holds but the seconds its stages took.
void add_scene(Digest& d, const SceneModel& s) {
  s.validate();  // throws on a non-finite number or a size mismatch
  d.integer(s.width);
  d.integer(s.height);
  for (double v : {s.fx, s.fy, s.cx, s.cy, s.camera_height_m, s.gamma}) d.number(v);
  add_matrix(d, s.R_world_from_cam);
  d.integer(s.indoor);
  d.mat(s.depth);
  d.mat(s.albedo);
  d.mat(s.normals);
  for (const LightSource& l : s.lights) {
    d.integer(static_cast<int>(l.type));
    add_matrix(d, l.position);
    add_matrix(d, l.intensity);
    add_matrix(d, l.corner);
    d.mat(l.environment);
  }
  for (const SupportPlane& p : s.planes) {
    d.text(p.name);
    add_matrix(d, p.normal);
    d.number(p.offset);
  }
  for (const HiddenFacade& f : s.hidden_facades) {
    add_matrix(d, f.normal);
    for (double v : {f.offset, f.bottom_m, f.top_m, f.along_min, f.along_max}) d.number(v);
  }
  for (const StageReport& r : s.reports) {
    d.text(r.stage);
    d.integer(r.usable);
  }
}

// The wall-clock guards of the camera refinement, the depth solve and the
// intensity fit raised far above what these small inputs need: on a loaded
// machine a guard could stop a solve early and the two runs would differ;
// with them out of the way the iteration bounds alone decide.
constexpr double kNoClock = 120.0;
InferenceOptions unclocked() {
  InferenceOptions o;
  o.camera.max_refine_seconds = kNoClock;
  o.geometry.solver.max_seconds = kNoClock;
  o.lighting.fit.max_seconds = kNoClock;
  return o;
}
CameraOptions unclocked_camera() {
  CameraOptions o;
  o.max_refine_seconds = kNoClock;
  return o;
}
IntensityFitOptions unclocked_fit() {
  IntensityFitOptions o;
  o.max_seconds = kNoClock;
  return o;
}

cv::Mat room(int w, int h) {
  cv::Mat img(h, w, CV_32FC3, cv::Scalar(0.3f, 0.3f, 0.28f));
  img.rowRange(h / 2, h).setTo(cv::Scalar(0.2f, 0.12f, 0.06f));
  for (int x = w / 8; x + 2 <= w; x += std::max(4, w / 4))
    img.colRange(x, x + 2).rowRange(0, h / 2).setTo(cv::Scalar(0.05f, 0.05f, 0.05f));
  return img;
}

std::vector<LineSegment> parallel_lines(int n) {
  std::vector<LineSegment> lines;
  for (int i = 0; i < n; ++i) lines.push_back({{10.0 + 14 * i, 20.0}, {40.0 + 14 * i, 200.0}});
  return lines;
}

IntensityFitProblem ramps(int lights) {
  IntensityFitProblem p;
  p.basis.assign(lights, std::vector<float>(64));
  for (int i = 0; i < 64; ++i)
    for (int k = 0; k < lights; ++k) p.basis[k][i] = 0.01f * (k % 2 ? 64 - i : i + 1);
  p.target.assign(64, 0.5f);
  return p;
}

void add_fit(Digest& d, const IntensityFitResult& r) {
  add_matrix(d, r.weights);
  d.number(r.gamma);
  d.number(r.data_error);
  d.integer(r.pruned);
}

// A valid 4x3 scene model saved to `dir`.
void save_small_scene(const fs::path& dir) {
  SceneModel s;
  s.width = 4;
  s.height = 3;
  s.fx = s.fy = 4;
  s.cx = 1.5;
  s.cy = 1;
  s.depth = cv::Mat(3, 4, CV_32F, cv::Scalar(2.f));
  s.albedo = cv::Mat(3, 4, CV_32FC3, cv::Scalar::all(0.5));
  s.normals = cv::Mat(3, 4, CV_32FC3, cv::Scalar(0, 1, 0));
  save_scene(s, dir.string());
}

// Sets every member named `key` in the JSON tree.
bool set_everywhere(nlohmann::json& j, const std::string& key, const nlohmann::json& value) {
  bool found = false;
  if (j.is_object()) {
    for (auto& [k, v] : j.items()) {
      if (k == key) {
        v = value;
        found = true;
      } else {
        found |= set_everywhere(v, key, value);
      }
    }
  } else if (j.is_array()) {
    for (auto& v : j) found |= set_everywhere(v, key, value);
  }
  return found;
}

}  // namespace
}  // namespace propcam::inference

namespace propcam::hard_cases {

void add_inference_cases(std::vector<HardCase>& cases) {
  using namespace propcam::inference;
  const std::string m = "inference";
  cases.push_back({"CameraFromNoLines", m, "estimate_camera on no line segments, 640x480",
                   "the prior camera (level, prior focal length), finite", Expect::Result, {}, [](Digest& d) {
                     const CameraEstimate c = estimate_camera({}, 640, 480, unclocked_camera());
                     check(!c.focal_from_vanishing_points, "no lines cannot fix the focal length");
                     add_camera(d, c);
                   }});
  cases.push_back({"CameraFromParallelLines", m, "estimate_camera on 30 segments that are all parallel",
                   "a finite camera from one direction (focal length the prior)", Expect::Result, {}, [](Digest& d) {
                     const CameraEstimate c = estimate_camera(parallel_lines(30), 640, 480, unclocked_camera());
                     check(!c.focal_from_vanishing_points, "one direction cannot fix the focal length");
                     add_camera(d, c);
                   }});
  cases.push_back({"CameraFromNonFiniteSegments", m,
                   "estimate_camera on parallel lines plus segments with NaN / Inf endpoints and zero length",
                   "a finite camera (the broken segments ignored)", Expect::Result, {}, [](Digest& d) {
                     auto lines = parallel_lines(10);
                     const double nan = std::numeric_limits<double>::quiet_NaN(),
                                  inf = std::numeric_limits<double>::infinity();
                     lines.push_back({{nan, 1}, {2, 3}});
                     lines.push_back({{0, 0}, {inf, -inf}});
                     lines.push_back({{5, 5}, {5, 5}});
                     add_camera(d, estimate_camera(lines, 640, 480, unclocked_camera()));
                   }});
  cases.push_back({"CameraOfZeroWidth", m, "estimate_camera for a 0x480 image", "error naming the size",
                   Expect::Error, {"size"}, [](Digest&) { estimate_camera(parallel_lines(3), 0, 480); }});
  cases.push_back({"InferBlackFrame", m, "infer_scene on a black 32x24 photo",
                   "a finite, valid scene model (fallbacks reported)", Expect::Result, {}, [](Digest& d) {
                     add_scene(d, infer_scene(cv::Mat(24, 32, CV_32FC3, cv::Scalar::all(0)), unclocked()));
                   }});
  cases.push_back({"InferSaturatedFrame", m, "infer_scene on a 32x24 photo at 1e6 with +Inf pixels",
                   "a finite, valid scene model (radiance clipped)", Expect::Result, {}, [](Digest& d) {
                     cv::Mat img(24, 32, CV_32FC3, cv::Scalar::all(1e6));
                     img.at<cv::Vec3f>(3, 3) = {kInf, kInf, kInf};
                     add_scene(d, infer_scene(img, unclocked()));
                   }});
  cases.push_back({"InferSmallestFrame", m, "infer_scene on a 16x16 room (kMinPhotoSide)",
                   "a finite, valid scene model", Expect::Result, {}, [](Digest& d) {
                     add_scene(d, infer_scene(room(kMinPhotoSide, kMinPhotoSide), unclocked()));
                   }});
  cases.push_back({"InferNonFinitePixels", m, "infer_scene on a 32x24 room with NaN, -Inf and negative pixels",
                   "a finite, valid scene model (pixels neutralised)", Expect::Result, {}, [](Digest& d) {
                     cv::Mat img = room(32, 24);
                     img.at<cv::Vec3f>(2, 2) = {kNan, kNan, kNan};
                     img.at<cv::Vec3f>(20, 5) = {-kInf, 1.f, -5.f};
                     img.row(10).setTo(cv::Scalar::all(-1));
                     add_scene(d, infer_scene(img, unclocked()));
                   }});
  cases.push_back({"InferOneByOneFrame", m, "infer_scene on a 1x1 photo", "error saying the photo is too small",
                   Expect::Error, {"1x1", "at least 16"}, [](Digest&) {
                     infer_scene(cv::Mat(1, 1, CV_32FC3, cv::Scalar::all(0.5)));
                   }});
  cases.push_back({"DepthSolveWithNoOpinion", m, "solve_depth whose only target is -1 everywhere",
                   "error saying no target has depth", Expect::Error, {"target"}, [](Digest&) {
                     DepthProblem p;
                     p.camera.width = 32;
                     p.camera.height = 24;
                     p.camera.fx = p.camera.fy = 30;
                     p.camera.cx = 16;
                     p.camera.cy = 12;
                     p.targets.push_back({cv::Mat(24, 32, CV_32F, cv::Scalar(-1.f)), 1.0, {}});
                     solve_depth(p);
                   }});
  cases.push_back({"DepthSolveIllConditioned", m,
                   "solve_depth, 24x16: targets 0.01 m and 1e5 m at weights 1e8 and 1e-8, NaN holes, a camera looking straight down",
                   "finite, positive depth and unit normals", Expect::Result, {}, [](Digest& d) {
                     DepthProblem p;
                     p.camera.width = 24;
                     p.camera.height = 16;
                     p.camera.fx = p.camera.fy = 20;
                     p.camera.cx = 11.5;
                     p.camera.cy = 7.5;
                     p.camera.center_world = {0, 1.5, 0};
                     p.camera.R_world_from_cam << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // z (forward) is world -y
                     cv::Mat near(16, 24, CV_32F, cv::Scalar(0.01f)), far(16, 24, CV_32F, cv::Scalar(1e5f));
                     near(cv::Rect(0, 0, 8, 8)).setTo(kNan);
                     far.col(3).setTo(kInf);
                     p.targets.push_back({near, 1e8, {}});
                     p.targets.push_back({far, 1e-8, {}});
                     DepthSolveOptions o;
                     o.max_seconds = kNoClock;
                     const DepthSolution s = solve_depth(p, o);
                     double lo = 0;
                     cv::minMaxLoc(s.depth, &lo);
                     check(lo > 0, "depth is positive");
                     d.mat(s.depth);
                     d.mat(s.normals);
                   }});
  cases.push_back({"IntensityFitCollinearBasis", m, "fit_intensities with three identical basis renders",
                   "finite, non-negative weights and response", Expect::Result, {}, [](Digest& d) {
                     IntensityFitProblem p = ramps(1);
                     p.basis = {p.basis[0], p.basis[0], p.basis[0]};
                     const IntensityFitResult r = fit_intensities(p, unclocked_fit());
                     check((r.weights.array() >= 0).all(), "weights are non-negative");
                     add_fit(d, r);
                   }});
  cases.push_back({"IntensityFitZeroBasis", m, "fit_intensities whose basis renders are all zero",
                   "finite weights, all zero", Expect::Result, {}, [](Digest& d) {
                     IntensityFitProblem p = ramps(2);
                     for (auto& b : p.basis) std::fill(b.begin(), b.end(), 0.f);
                     const IntensityFitResult r = fit_intensities(p, unclocked_fit());
                     check(r.weights.sum() == 0.0, "no light can explain the photo");
                     add_fit(d, r);
                   }});
  cases.push_back({"SunChoiceBlackSkyAndNonFiniteTexels", m,
                   "choose_sun with a black sky render, then NaN/Inf photo and candidate texels",
                   "a candidate in range, finite shares and correlations", Expect::Result, {}, [](Digest& d) {
                     const auto filled = [](float v) { return cv::Mat(12, 16, CV_32FC3, cv::Scalar::all(v)); };
                     std::vector<cv::Point> pixels;
                     for (int y = 0; y < 12; ++y)
                       for (int x = 0; x < 16; ++x) pixels.push_back({x, y});
                     cv::Mat photo = filled(0.3f), sun = filled(0.5f);
                     photo.at<cv::Vec3f>(0, 0) = cv::Vec3f::all(kNan);
                     photo.at<cv::Vec3f>(1, 1) = cv::Vec3f::all(kInf);
                     sun.at<cv::Vec3f>(2, 2) = cv::Vec3f::all(kNan);
                     for (const cv::Mat& sky : {filled(0.f), filled(0.1f)}) {
                       const SunChoice c = choose_sun({sun, filled(0.2f)}, sky, filled(0.5f), photo, pixels);
                       check(c.chosen >= 0 && c.chosen < 2, "a candidate is chosen");
                       for (size_t i = 0; i < 2; ++i)
                         check(std::isfinite(c.sunlit_share[i]) && std::isfinite(c.agreement[i]), "finite scores");
                       d.integer(c.chosen);
                       d.integer(c.must_be_sunlit);
                       for (size_t i = 0; i < 2; ++i) d.number(c.sunlit_share[i]), d.number(c.agreement[i]);
                     }
                   }});
  cases.push_back({"IntensityFitMismatchedSizes", m, "fit_intensities with a 64-pixel basis and a 63-pixel target",
                   "error saying a basis render has the wrong pixel count", Expect::Error, {"pixel count"}, [](Digest&) {
                     IntensityFitProblem p = ramps(2);
                     p.target.pop_back();
                     fit_intensities(p);
                   }});
  cases.push_back({"IblNonFiniteAndNegativeTexels", m,
                   "a 64x32 panorama with NaN, +Inf and negative texels and one bright patch: sanitize_latlong, find_light_regions",
                   "finite, non-negative texels and finite light regions", Expect::Result, {}, [](Digest& d) {
                     cv::Mat pano(32, 64, CV_32FC3, cv::Scalar::all(0.2));
                     pano(cv::Rect(10, 4, 4, 3)).setTo(cv::Scalar::all(50));
                     pano.at<cv::Vec3f>(1, 1) = {kNan, kNan, kNan};
                     pano.at<cv::Vec3f>(5, 40) = {kInf, kInf, kInf};
                     pano.row(20).setTo(cv::Scalar::all(-3));
                     const cv::Mat clean = sanitize_latlong(pano);
                     double lo = 0;
                     cv::minMaxLoc(clean.reshape(1), &lo);
                     check(lo >= 0, "texels are non-negative");
                     d.mat(clean);
                     for (const IblLightRegion& r : find_light_regions(clean, SceneKind::Indoor)) {
                       add_matrix(d, r.direction);
                       d.number(r.solid_angle_sr);
                       d.number(r.power_share);
                     }
                   }});
  cases.push_back({"SceneJsonTruncated", m, "a scene folder whose scene.json is cut mid-object",
                   "error naming scene.json", Expect::Error, {"scene.json"}, [](Digest&) {
                     hard_cases::ScratchDir dir("SceneJsonTruncated");
                     save_small_scene(dir / "scene");
                     hard_cases::write_text_file(dir / "scene" / "scene.json", "{\"width\": 4, \"height\"");
                     load_scene((dir / "scene").string());
                   }});
  cases.push_back({"SceneClassifierTruncated", m, "a scene classifier model cut to its first 200 bytes",
                   "error naming the model file", Expect::Error, {"cut_classifier.yml"}, [](Digest&) {
                     hard_cases::ScratchDir dir("SceneClassifierTruncated");
                     std::ifstream in(default_scene_classifier_path(), std::ios::binary);
                     std::string head(200, '\0');
                     in.read(head.data(), static_cast<std::streamsize>(head.size()));
                     // The compressed head under a plain-text name: broken as YAML and as gzip.
                     hard_cases::write_text_file(dir / "cut_classifier.yml", head.substr(0, static_cast<size_t>(in.gcount())));
                     SceneClassifier::load((dir / "cut_classifier.yml").string());
                   }});
  cases.push_back({"SceneJsonNegativeFocal", m, "a saved scene whose focal lengths were edited to -4",
                   "error naming the focal length", Expect::Error, {"focal length"}, [](Digest&) {
                     hard_cases::ScratchDir dir("SceneJsonNegativeFocal");
                     save_small_scene(dir / "scene");
                     const fs::path file = dir / "scene" / "scene.json";
                     nlohmann::json j;
                     std::ifstream(file) >> j;
                     check(set_everywhere(j, "fx", -4.0), "setup: scene.json has fx");
                     hard_cases::write_text_file(file, j.dump());
                     load_scene((dir / "scene").string());
                   }});
  cases.push_back({"HiddenFacadesOfBrokenMaps", m,
                   "find_hidden_facades and hidden_facade_mesh on a 64x48 view of a wall whose depth and normals are "
                   "NaN, Inf, 0 or negative in stripes",
                   "finite facades and a finite mesh with no cell in the frame", Expect::Result, {}, [](Digest& d) {
                     render::PinholeCamera c = render::pinhole_with_fov(64, 48, 60);
                     c.center_world = {0, 1.6, 0};
                     cv::Mat depth(48, 64, CV_32F, cv::Scalar(10.f)), normals(48, 64, CV_32FC3, cv::Scalar(0.f, 0.f, 1.f));
                     const float bad[] = {kNan, kInf, 0.f, -3.f};
                     for (int x = 0; x < 64; x += 5) {
                       depth.col(x).setTo(bad[x % 4]);
                       normals.col(x + 1 < 64 ? x + 1 : x).setTo(cv::Scalar(bad[x % 4], 0.f, bad[(x + 1) % 4]));
                     }
                     const auto facades = find_hidden_facades(depth, normals, cv::Mat(), c);
                     const render::Mesh mesh = hidden_facade_mesh(facades, depth, c);
                     mesh.validate();
                     for (const auto& f : facades) {
                       f.validate();
                       add_matrix(d, f.normal);
                       for (double v : {f.offset, f.bottom_m, f.top_m, f.along_min, f.along_max}) d.number(v);
                     }
                     for (const auto& p : mesh.positions) {
                       Eigen::Vector2d px;
                       check(!(c.project(p.cast<double>(), px) && px.x() > 0.5 && px.x() < 63.5 && px.y() > 0.5 && px.y() < 47.5),
                             "a hidden cell is in the frame");
                       add_matrix(d, p.cast<double>());
                     }
                   }});
  cases.push_back({"HiddenFacadeBeyondBounds", m,
                   "hidden_facade_mesh for a facade 10^9 m long (a corrupt scene.json's)",
                   "error naming the extent, before any cell is built", Expect::Error, {"extent"}, [](Digest&) {
                     const render::PinholeCamera c = render::pinhole_with_fov(64, 48, 60);
                     HiddenFacade f;
                     f.normal = Eigen::Vector3d::UnitX();
                     f.top_m = 10;
                     f.along_min = f.seen_min = -1e9;
                     f.along_max = f.seen_max = 1e9;
                     hidden_facade_mesh({f}, cv::Mat(48, 64, CV_32F, cv::Scalar(10.f)), c);
                   }});
}

}  // namespace propcam::hard_cases
