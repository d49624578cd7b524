// Line sets of Manhattan scenes projected through known cameras, for the
// camera and geometry tests.
#pragma once

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "propcam/inference/camera.h"
#include "propcam/render/camera.h"

namespace propcam::inference::testing {

inline constexpr double kLineSceneRadToDeg = 180.0 / std::numbers::pi;

// A 640x480 camera 1.5 m above the floor, turned by yaw and pitch (degrees).
inline render::PinholeCamera make_camera(double f, double yaw_deg, double pitch_deg) {
  render::PinholeCamera cam = render::pinhole_with_fov(640, 480, 90.0);
  cam.fx = cam.fy = f;
  cam.R_world_from_cam = render::rotation_from_yaw_pitch_roll(yaw_deg / kLineSceneRadToDeg, pitch_deg / kLineSceneRadToDeg, 0.0);
  cam.center_world = {0, 1.5, 0};
  return cam;
}

// Random axis-aligned 3D segments inside a 6x3x8 m room, projected with
// pixel noise: one attempt adds a segment along `axis` when both ends land in
// the 640x480 frame at least 20 px apart.
struct SegmentSampler {
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> x{-3, 3}, y{0, 3}, z{-8, -1.5}, len{0.5, 1.5};
  std::normal_distribution<double> noise;
  SegmentSampler(uint64_t seed, double noise_px) : rng(seed), noise(0, noise_px) {}

  void attempt(const render::PinholeCamera& cam, int axis, std::vector<LineSegment>& lines) {
    const Eigen::Vector3d p(x(rng), y(rng), z(rng));
    Eigen::Vector3d q = p;
    q[axis] += len(rng);
    Eigen::Vector2d a, b;
    if (!cam.project(p, a) || !cam.project(q, b)) return;
    auto inside = [&](const Eigen::Vector2d& v) { return v.x() >= 0 && v.y() >= 0 && v.x() < 640 && v.y() < 480; };
    if (!inside(a) || !inside(b) || (a - b).norm() < 20) return;
    lines.push_back({a + Eigen::Vector2d(noise(rng), noise(rng)), b + Eigen::Vector2d(noise(rng), noise(rng))});
  }
};

// `per_axis` segments along each of the three axes.
inline std::vector<LineSegment> manhattan_lines(const render::PinholeCamera& cam, int per_axis, double noise_px,
                                                uint64_t seed) {
  SegmentSampler sampler(seed, noise_px);
  std::vector<LineSegment> lines;
  for (int axis = 0; axis < 3; ++axis)
    for (int i = 0; i < per_axis * 20 && static_cast<int>(lines.size()) < per_axis * (axis + 1); ++i)
      sampler.attempt(cam, axis, lines);
  return lines;
}

// `count` projected segments along one world axis only.
inline std::vector<LineSegment> axis_lines(const render::PinholeCamera& cam, int axis, int count, double noise_px,
                                           uint64_t seed) {
  SegmentSampler sampler(seed, noise_px);
  std::vector<LineSegment> lines;
  for (int i = 0; i < count * 100 && static_cast<int>(lines.size()) < count; ++i) sampler.attempt(cam, axis, lines);
  return lines;
}

// The camera turned about its optical axis by `roll_deg` (image rotated clockwise).
inline render::PinholeCamera rolled(render::PinholeCamera cam, double roll_deg) {
  const Eigen::Vector3d forward = cam.R_world_from_cam.col(2);
  const double yaw = std::atan2(-forward.x(), -forward.z()), pitch = std::asin(std::clamp(forward.y(), -1.0, 1.0));
  cam.R_world_from_cam = render::rotation_from_yaw_pitch_roll(yaw, pitch, roll_deg / kLineSceneRadToDeg);
  return cam;
}

}  // namespace propcam::inference::testing
