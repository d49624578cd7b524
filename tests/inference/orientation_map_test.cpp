#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <numbers>
#include <random>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "propcam/capture/image_file.h"
#include "propcam/inference/camera.h"
#include "propcam/inference/orientation_map.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"
#include "room_truth.h"

namespace propcam::inference {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

render::PinholeCamera make_camera(int w, int h, double f, double yaw_deg, double pitch_deg, Eigen::Vector3d centre) {
  render::PinholeCamera cam = render::pinhole_with_fov(w, h, 90.0);
  cam.fx = cam.fy = f;
  cam.R_world_from_cam = render::rotation_from_yaw_pitch_roll(yaw_deg * kDegToRad, pitch_deg * kDegToRad, 0.0);
  cam.center_world = centre;
  return cam;
}

// A corridor: x in [-2, 2], y (up) in [0, 3], z from the camera to the back wall at -10.
constexpr double kHalfWidth = 2.0, kCeiling = 3.0, kBack = -10.0;

struct Labelled {
  std::vector<LineSegment> lines;
  std::vector<int> labels;
};

// Adds the 3D segment p-q (along world axis `axis`) when both ends are in front of the camera.
void add_line(const render::PinholeCamera& cam, Eigen::Vector3d p, Eigen::Vector3d q, int axis, Labelled& out) {
  Eigen::Vector2d a, b;
  if (!cam.project(p, a) || !cam.project(q, b)) return;
  out.lines.push_back({a, b});
  out.labels.push_back(axis);
}

// The edges of the corridor's box and a few surface markings: floor tiles,
// ceiling seams, wall panels and a door frame on the back wall.
Labelled corridor_lines(const render::PinholeCamera& cam) {
  Labelled l;
  const double near = -1.0;
  using V = Eigen::Vector3d;
  for (double x : {-kHalfWidth, kHalfWidth})
    for (double y : {0.0, kCeiling}) add_line(cam, V(x, y, near), V(x, y, kBack), 2, l);  // long corners
  for (double x : {-1.0, 0.0, 1.0}) add_line(cam, V(x, 0, -2), V(x, 0, kBack), 2, l);  // floor tiles along
  for (double x : {-1.0, 1.0}) add_line(cam, V(x, kCeiling, -2), V(x, kCeiling, kBack), 2, l);  // ceiling seams
  for (double z = -3; z > kBack; z -= 1.0) add_line(cam, V(-kHalfWidth, 0, z), V(kHalfWidth, 0, z), 0, l);  // tiles across
  for (double z : {-4.0, -7.0}) add_line(cam, V(-kHalfWidth, kCeiling, z), V(kHalfWidth, kCeiling, z), 0, l);
  for (double y : {0.0, kCeiling}) add_line(cam, V(-kHalfWidth, y, kBack), V(kHalfWidth, y, kBack), 0, l);  // back edges
  for (double x : {-kHalfWidth, kHalfWidth}) add_line(cam, V(x, 0, kBack), V(x, kCeiling, kBack), 1, l);  // back corners
  for (double z : {-3.0, -5.0, -7.0})
    for (double x : {-kHalfWidth, kHalfWidth}) add_line(cam, V(x, 0, z), V(x, kCeiling, z), 1, l);  // wall panels
  for (double x : {-0.5, 0.5}) add_line(cam, V(x, 0, kBack), V(x, 2.0, kBack), 1, l);  // door frame
  add_line(cam, V(-0.5, 2.0, kBack), V(0.5, 2.0, kBack), 0, l);                      // door lintel
  return l;
}

// The true orientation of the corridor surface seen through a pixel.
SurfaceOrientation corridor_truth(const render::PinholeCamera& cam, double u, double v) {
  const Eigen::Vector3d o = cam.center_world, d = cam.ray_direction(u, v);
  double best = std::numeric_limits<double>::infinity();
  SurfaceOrientation label = SurfaceOrientation::kUnknown;
  auto try_plane = [&](int axis, double value, SurfaceOrientation orientation) {
    if (std::abs(d[axis]) < 1e-12) return;
    const double t = (value - o[axis]) / d[axis];
    if (t > 0 && t < best) {
      best = t;
      label = orientation;
    }
  };
  try_plane(0, d.x() < 0 ? -kHalfWidth : kHalfWidth, SurfaceOrientation::kNormalX);
  try_plane(1, d.y() < 0 ? 0.0 : kCeiling, SurfaceOrientation::kNormalY);
  if (d.z() < 0) try_plane(2, kBack, SurfaceOrientation::kNormalZ);
  return label;
}

struct Score {
  double coverage = 0, accuracy = 0;
  std::array<double, 4> region_coverage{};  // per true orientation, fraction of its pixels labelled right
};

Score score_corridor(const OrientationMap& map, const render::PinholeCamera& cam);

void print(const char* what, const Score& s) {
  std::cout << what << ": coverage " << s.coverage << ", accuracy " << s.accuracy << ", X/Y/Z regions covered "
            << s.region_coverage[1] << " / " << s.region_coverage[2] << " / " << s.region_coverage[3] << "\n";
}

Score score_corridor(const OrientationMap& map, const render::PinholeCamera& cam) {
  const render::PinholeCamera out = cam.resized(map.labels.cols, map.labels.rows);
  Score s;
  std::array<int, 4> region{}, region_right{};
  int labelled = 0, right = 0;
  for (int y = 0; y < map.labels.rows; ++y)
    for (int x = 0; x < map.labels.cols; ++x) {
      const int truth = static_cast<int>(corridor_truth(out, x, y));
      const int got = map.labels.at<uint8_t>(y, x);
      ++region[truth];
      if (got == 0) continue;
      ++labelled;
      right += got == truth;
      region_right[truth] += got == truth;
    }
  s.coverage = static_cast<double>(labelled) / map.labels.total();
  s.accuracy = labelled ? static_cast<double>(right) / labelled : 0;
  for (int k = 1; k < 4; ++k) s.region_coverage[k] = region[k] ? static_cast<double>(region_right[k]) / region[k] : 0;
  return s;
}

TEST(OrientationMap, CorridorSurfacesGetTheirNormals) {
  // Frontal view: VP_Z in the frame, VP_X and VP_Y at infinity.
  const render::PinholeCamera cam = make_camera(640, 480, 500, 0, 0, {0, 1.5, 0});
  const Labelled l = corridor_lines(cam);
  const OrientationMap map = estimate_orientation_map(l.lines, l.labels, cam);
  ASSERT_EQ(map.labels.type(), CV_8U);
  EXPECT_EQ(map.labels.cols, 160);
  EXPECT_EQ(map.labels.rows, 120);
  const Score s = score_corridor(map, cam);
  print("frontal corridor", s);
  EXPECT_GT(s.accuracy, 0.98) << "coverage " << s.coverage;  // measured 0.999 at 0.96 coverage
  EXPECT_GT(s.coverage, 0.85);
  EXPECT_GT(s.region_coverage[2], 0.9) << "floor and ceiling";
  EXPECT_GT(s.region_coverage[1], 0.85) << "side walls";
  EXPECT_GT(s.region_coverage[3], 0.75) << "back wall";
  EXPECT_EQ(map.report.stage, "orientation_map");
  EXPECT_TRUE(map.report.usable);
  EXPECT_NEAR(map.report.details["coverage"].get<double>(), s.coverage, 1e-12);
}

TEST(OrientationMap, TurnedAndTiltedCorridor) {
  // All three vanishing points finite.
  const render::PinholeCamera cam = make_camera(640, 480, 450, 20, -12, {0.6, 1.4, 0});
  const Labelled l = corridor_lines(cam);
  const OrientationMap map = estimate_orientation_map(l.lines, l.labels, cam);
  const Score s = score_corridor(map, cam);
  print("turned corridor", s);
  EXPECT_GT(s.accuracy, 0.98) << "coverage " << s.coverage;  // measured 0.998 at 0.94 coverage
  EXPECT_GT(s.coverage, 0.85);
  EXPECT_GT(s.region_coverage[2], 0.9) << "floor and ceiling";
  EXPECT_GT(s.region_coverage[1], 0.8) << "side walls";
  EXPECT_GT(s.region_coverage[3], 0.75) << "back wall";
}

TEST(OrientationMap, FloorAloneIsLevel) {
  // A tiled floor seen from above at 45 degrees: everything labelled is kNormalY.
  const render::PinholeCamera cam = make_camera(320, 240, 260, 10, -45, {0, 1.5, 0});
  Labelled l;
  for (double x = -3; x <= 3; x += 0.5) add_line(cam, {x, 0, -0.5}, {x, 0, -5}, 2, l);
  for (double z = -0.5; z >= -5; z -= 0.5) add_line(cam, {-3, 0, z}, {3, 0, z}, 0, l);
  const OrientationMap map = estimate_orientation_map(l.lines, l.labels, cam);
  EXPECT_GT(map.report.details["fraction_y"].get<double>(), 0.3);
  EXPECT_EQ(map.report.details["fraction_x"].get<double>(), 0.0);
  EXPECT_EQ(map.report.details["fraction_z"].get<double>(), 0.0);
}

// Projected axis-aligned segments scattered through a 6 x 3 x 8 m room, with
// pixel noise and a share of clutter (label -1): what the camera stage hands over.
Labelled scattered_lines(const render::PinholeCamera& cam, int count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(-3, 3), y(0, 3), z(-9, -1), len(0.3, 1.5), unit(0, 1);
  std::normal_distribution<double> noise(0, 0.5);
  Labelled l;
  while (static_cast<int>(l.lines.size()) < count) {
    const Eigen::Vector3d p(x(rng), y(rng), z(rng));
    const int axis = static_cast<int>(unit(rng) * 3) % 3;
    Eigen::Vector3d q = p;
    q[axis] += len(rng);
    Eigen::Vector2d a, b;
    if (!cam.project(p, a) || !cam.project(q, b)) continue;
    auto inside = [&](const Eigen::Vector2d& v) {
      return v.x() >= 0 && v.y() >= 0 && v.x() < cam.width && v.y() < cam.height;
    };
    if (!inside(a) || !inside(b) || (a - b).norm() < 16) continue;
    l.lines.push_back({a + Eigen::Vector2d(noise(rng), noise(rng)), b + Eigen::Vector2d(noise(rng), noise(rng))});
    l.labels.push_back(unit(rng) < 0.1 ? -1 : axis);
  }
  return l;
}

// A measurement, not a test (timing goals live in benchmarks): run it with
// --gtest_also_run_disabled_tests --gtest_filter='*TimingAt640x480*'.
TEST(OrientationMap, DISABLED_TimingAt640x480With400Lines) {
  const render::PinholeCamera cam = make_camera(640, 480, 520, 25, -10, {0, 1.5, 0});
  const Labelled l = scattered_lines(cam, 400, 3);
  std::vector<double> ms;
  for (int run = 0; run < 15; ++run) {
    const auto t0 = std::chrono::steady_clock::now();
    const OrientationMap map = estimate_orientation_map(l.lines, l.labels, cam);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    ASSERT_EQ(map.labels.cols, 160);
  }
  std::sort(ms.begin(), ms.end());
  std::cout << "640x480, 400 lines: median " << ms[ms.size() / 2] << " ms, min " << ms.front() << " ms\n";
}

TEST(OrientationMap, OutputSizeFollowsTheAspectRatio) {
  const render::PinholeCamera cam = make_camera(640, 360, 500, 0, 0, {0, 1.5, 0});
  OrientationMapOptions o;
  o.width = 101;
  const OrientationMap map = estimate_orientation_map({}, {}, cam, o);
  EXPECT_EQ(map.labels.cols, 101);
  EXPECT_EQ(map.labels.rows, 57);  // round(101 * 360 / 640) = round(56.8)
}

TEST(OrientationMap, ColourMap) {
  cv::Mat labels(1, 5, CV_8U);
  for (int n = 0; n < 5; ++n) labels.at<uint8_t>(0, n) = static_cast<uint8_t>(n);
  const cv::Mat c = orientation_map_to_color(labels);
  ASSERT_EQ(c.type(), CV_8UC3);
  EXPECT_EQ(c.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(c.at<cv::Vec3b>(0, 1), cv::Vec3b(255, 0, 0));
  EXPECT_EQ(c.at<cv::Vec3b>(0, 2), cv::Vec3b(0, 255, 0));
  EXPECT_EQ(c.at<cv::Vec3b>(0, 3), cv::Vec3b(0, 0, 255));
  EXPECT_EQ(c.at<cv::Vec3b>(0, 4), cv::Vec3b(0, 0, 0));
  EXPECT_THROW(orientation_map_to_color(cv::Mat(2, 2, CV_32F)), std::invalid_argument);
}

// ---- Synthetic rooms through the real pipeline (detect_lines -> estimate_camera -> map).

struct RoomScore {
  double coverage = 0, accuracy = 0, seconds = 0;
  int lines = 0;
  std::string camera_case;
};

// The true label of each output pixel: the true world normal, taken to the
// estimated camera's Manhattan frame (through camera coordinates), and its
// dominant axis. Pixels without a surface (depth 0) are not counted.
RoomScore score_room(const OrientationMap& map, const cv::Mat& true_normals, const cv::Mat& true_depth,
                     const Eigen::Matrix3d& R_true, const Eigen::Matrix3d& R_est) {
  const Eigen::Matrix3d est_from_true = R_est * R_true.transpose();
  const double sx = static_cast<double>(true_normals.cols) / map.labels.cols;
  const double sy = static_cast<double>(true_normals.rows) / map.labels.rows;
  int seen = 0, labelled = 0, right = 0;
  for (int y = 0; y < map.labels.rows; ++y)
    for (int x = 0; x < map.labels.cols; ++x) {
      const int tx = std::clamp(static_cast<int>((x + 0.5) * sx), 0, true_normals.cols - 1);
      const int ty = std::clamp(static_cast<int>((y + 0.5) * sy), 0, true_normals.rows - 1);
      if (!(true_depth.at<float>(ty, tx) > 0)) continue;
      ++seen;
      const int got = map.labels.at<uint8_t>(y, x);
      if (got == 0) continue;
      const cv::Vec3f n = true_normals.at<cv::Vec3f>(ty, tx);
      const Eigen::Vector3d ne = est_from_true * Eigen::Vector3d(n[0], n[1], n[2]);
      int axis = 0;
      ne.cwiseAbs().maxCoeff(&axis);
      ++labelled;
      right += got == axis + 1;
    }
  RoomScore s;
  s.coverage = seen ? static_cast<double>(labelled) / seen : 0;
  s.accuracy = labelled ? static_cast<double>(right) / labelled : 0;
  return s;
}

RoomScore run_pipeline(const cv::Mat& photo, const cv::Mat& true_normals, const cv::Mat& true_depth,
                       const Eigen::Matrix3d& R_true, const OrientationMapOptions& o, cv::Mat* labels = nullptr) {
  StageReport lines_report;
  const std::vector<LineSegment> lines = detect_lines(photo, {}, lines_report);
  const CameraEstimate est = estimate_camera(lines, photo.cols, photo.rows);
  render::PinholeCamera cam;
  cam.width = photo.cols;
  cam.height = photo.rows;
  cam.fx = est.fx;
  cam.fy = est.fy;
  cam.cx = est.cx;
  cam.cy = est.cy;
  cam.R_world_from_cam = est.R_world_from_cam;
  const OrientationMap map = estimate_orientation_map(lines, est.line_labels, cam, o);
  RoomScore s = score_room(map, true_normals, true_depth, R_true, est.R_world_from_cam);
  s.seconds = map.report.seconds;
  s.lines = static_cast<int>(lines.size());
  s.camera_case = to_string(est.which);
  if (labels) *labels = map.labels;
  return s;
}

TEST(OrientationMap, SyntheticRoomsThroughThePipeline) {
  // Reduced resolution and samples keep this quick; docs/orientation_map.md's table is
  // the full-resolution run (DISABLED_SyntheticRoomTable below). Seed 2 is
  // the hardest of 1-8 there. Measured here: seed 2 coverage 0.47, accuracy
  // 0.875; seed 4: 0.63, 0.876 (lower than at 640x480 with 64 spp, where
  // detect_lines sees cleaner edges).
  for (uint64_t seed : {2u, 4u}) {
    const RoomTruth t = room_truth(seed, 480, 360);
    render::Scene scene;
    scene.add_mesh(t.room.room, render::Layer::Background);
    scene.commit();
    render::RenderSettings settings;
    settings.samples_per_pixel = 16;
    const cv::Mat photo = render::render_image(scene, t.room.camera, t.room.lights, settings);
    OrientationMapOptions o;
    o.width = 160;
    const RoomScore s = run_pipeline(photo, t.normals, t.depth, t.room.camera.R_world_from_cam, o);
    std::cout << "seed " << seed << ": coverage " << s.coverage << ", accuracy " << s.accuracy << "\n";
    EXPECT_GT(s.accuracy, 0.80) << "seed " << seed << " coverage " << s.coverage;
    EXPECT_GT(s.coverage, 0.30) << "seed " << seed;
  }
}

// docs/orientation_map.md's table: photos written by `propcam synth --seed N -o DIR/seedN`
// (N = 1..8), then
//   PROPCAM_OM_SYNTH=DIR build/release/tests/inference_tests
//     --gtest_also_run_disabled_tests --gtest_filter='*SyntheticRoomTable*'
// prints the per-seed table for the default options and one summary row per
// knob variant. Optional PROPCAM_OM_PNG=DIR2 writes the colour maps there.
struct RoomInput {
  int seed;
  cv::Mat photo;
  SceneModel truth;
  std::vector<LineSegment> lines;
  CameraEstimate camera;
};

TEST(OrientationMap, DISABLED_SyntheticRoomTable) {
  const char* dir = std::getenv("PROPCAM_OM_SYNTH");
  if (!dir) GTEST_SKIP() << "set PROPCAM_OM_SYNTH";
  const char* png_dir = std::getenv("PROPCAM_OM_PNG");
  std::vector<RoomInput> rooms;
  for (int seed = 1; seed <= 8; ++seed) {
    const std::filesystem::path folder = std::filesystem::path(dir) / ("seed" + std::to_string(seed));
    if (!std::filesystem::exists(folder / "photo.exr")) continue;
    RoomInput r{seed, capture::load_photo_linear((folder / "photo.exr").string()),
                load_scene((folder / "truth").string()), {}, {}};
    StageReport lines_report;
    r.lines = detect_lines(r.photo, {}, lines_report);
    r.camera = estimate_camera(r.lines, r.photo.cols, r.photo.rows);
    rooms.push_back(std::move(r));
  }
  ASSERT_FALSE(rooms.empty());
  auto run = [&](const RoomInput& r, const OrientationMapOptions& o, cv::Mat* labels) {
    render::PinholeCamera cam;
    cam.width = r.photo.cols;
    cam.height = r.photo.rows;
    cam.fx = r.camera.fx;
    cam.fy = r.camera.fy;
    cam.cx = r.camera.cx;
    cam.cy = r.camera.cy;
    cam.R_world_from_cam = r.camera.R_world_from_cam;
    const OrientationMap map = estimate_orientation_map(r.lines, r.camera.line_labels, cam, o);
    RoomScore s = score_room(map, r.truth.normals, r.truth.depth, r.truth.R_world_from_cam, cam.R_world_from_cam);
    s.seconds = map.report.seconds;
    if (labels) *labels = map.labels;
    return s;
  };
  std::cout << "| seed | camera case | lines | coverage | accuracy | ms |\n|---|---|---|---|---|---|\n";
  double sum_cov = 0, sum_acc = 0;
  for (const RoomInput& r : rooms) {
    cv::Mat labels;
    const RoomScore s = run(r, {}, &labels);
    if (png_dir) {
      std::filesystem::create_directories(png_dir);
      cv::Mat big, blend;
      cv::resize(orientation_map_to_color(labels), big, r.photo.size(), 0, 0, cv::INTER_NEAREST);
      cv::addWeighted(capture::linear_to_srgb8(r.photo), 0.5, big, 0.5, 0, blend);
      capture::write_image((std::filesystem::path(png_dir) / ("seed" + std::to_string(r.seed) + ".png")).string(), blend);
    }
    std::cout << std::fixed << std::setprecision(3) << "| " << r.seed << " | " << to_string(r.camera.which) << " | "
              << r.lines.size() << " | " << s.coverage << " | " << s.accuracy << " | " << std::setprecision(1)
              << 1000 * s.seconds << " |\n";
    sum_cov += s.coverage;
    sum_acc += s.accuracy;
  }
  std::cout << std::setprecision(3) << "| mean | | | " << sum_cov / rooms.size() << " | " << sum_acc / rooms.size()
            << " | |\n\n";

  std::vector<std::pair<std::string, OrientationMapOptions>> variants;
  auto add = [&](std::string name, auto edit) {
    OrientationMapOptions o;
    edit(o);
    variants.emplace_back(std::move(name), o);
  };
  add("default", [](OrientationMapOptions&) {});
  add("block_by_lines_ahead = false", [](OrientationMapOptions& o) { o.block_by_lines_ahead = false; });
  for (double f : {0.25, 0.35, 0.7, 1.0})
    add("max_sweep_fraction = " + std::to_string(f).substr(0, 4), [f](OrientationMapOptions& o) { o.max_sweep_fraction = f; });
  for (double a : {5.0, 10.0, 15.0, 25.0, 30.0})
    add("min_sweep_angle_deg = " + std::to_string(a).substr(0, 4), [a](OrientationMapOptions& o) { o.min_sweep_angle_deg = a; });
  for (double m : {0.0, 0.003, 0.012})
    add("block_margin_fraction = " + std::to_string(m).substr(0, 5), [m](OrientationMapOptions& o) { o.block_margin_fraction = m; });
  for (double e : {0.0, 0.1})
    add("end_inset_fraction = " + std::to_string(e).substr(0, 4), [e](OrientationMapOptions& o) { o.end_inset_fraction = e; });
  for (double l : {0.0, 0.04})
    add("min_sweep_length_fraction = " + std::to_string(l).substr(0, 4), [l](OrientationMapOptions& o) { o.min_sweep_length_fraction = l; });
  for (int w : {80, 320})
    add("width = " + std::to_string(w), [w](OrientationMapOptions& o) { o.width = w; });
  std::cout << "| variant | mean coverage | mean accuracy | worst accuracy |\n|---|---|---|---|\n";
  for (const auto& [name, o] : variants) {
    double cov = 0, acc = 0, worst = 1;
    for (const RoomInput& r : rooms) {
      const RoomScore s = run(r, o, nullptr);
      cov += s.coverage;
      acc += s.accuracy;
      worst = std::min(worst, s.accuracy);
    }
    std::cout << "| " << name << " | " << cov / rooms.size() << " | " << acc / rooms.size() << " | " << worst << " |\n";
  }
}

}  // namespace
}  // namespace propcam::inference
