// Pinhole camera in the OpenCV convention (x right, y down, z forward; pixel
// (0,0) is the centre of the top-left pixel) placed in a gravity-aligned world
// (Y up, metres).
#pragma once

#include <cmath>
#include <numbers>

#include <Eigen/Dense>

namespace propcam::render {

struct PinholeCamera {
  int width = 0;
  int height = 0;
  double fx = 1.0, fy = 1.0, cx = 0.0, cy = 0.0;
  Eigen::Matrix3d R_world_from_cam = Eigen::Matrix3d::Identity();
  Eigen::Vector3d center_world = Eigen::Vector3d::Zero();

  // Unit direction in world coordinates through continuous pixel position (u, v).
  Eigen::Vector3d ray_direction(double u, double v) const {
    return (R_world_from_cam * Eigen::Vector3d((u - cx) / fx, (v - cy) / fy, 1.0)).normalized();
  }
  Eigen::Vector3d world_to_camera(const Eigen::Vector3d& p) const {
    return R_world_from_cam.transpose() * (p - center_world);
  }
  // The same camera with a resized image (pixel centres stay on the same rays).
  PinholeCamera resized(int new_width, int new_height) const {
    PinholeCamera out = *this;
    const double sx = static_cast<double>(new_width) / width, sy = static_cast<double>(new_height) / height;
    out.width = new_width;
    out.height = new_height;
    out.fx = fx * sx;
    out.fy = fy * sy;
    out.cx = (cx + 0.5) * sx - 0.5;
    out.cy = (cy + 0.5) * sy - 0.5;
    return out;
  }
  // Projects a world point; returns false if it lies behind the camera.
  bool project(const Eigen::Vector3d& p_world, Eigen::Vector2d& pixel) const {
    const Eigen::Vector3d pc = world_to_camera(p_world);
    if (pc.z() <= 1e-9) return false;
    pixel = {fx * pc.x() / pc.z() + cx, fy * pc.y() / pc.z() + cy};
    return true;
  }
};

// A camera with horizontal field of view `hfov_deg`, the principal point at
// the image centre, at the world origin looking along -Z.
inline PinholeCamera pinhole_with_fov(int width, int height, double hfov_deg) {
  PinholeCamera cam;
  cam.width = width;
  cam.height = height;
  cam.fx = cam.fy = width / 2.0 / std::tan(hfov_deg * std::numbers::pi / 360.0);
  cam.cx = (width - 1) / 2.0;
  cam.cy = (height - 1) / 2.0;
  return cam;
}

// World-from-camera rotation (camera x right, y down, z forward; world Y up)
// of a camera turned by yaw about Y (0: looking along -Z, positive: towards
// -X), pitched up by `pitch` and rolled by `roll` about its optical axis (radians).
inline Eigen::Matrix3d rotation_from_yaw_pitch_roll(double yaw, double pitch, double roll) {
  const Eigen::Vector3d forward(-std::sin(yaw) * std::cos(pitch), std::sin(pitch), -std::cos(yaw) * std::cos(pitch));
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d R;
  R.col(0) = std::cos(roll) * right + std::sin(roll) * down;
  R.col(1) = -std::sin(roll) * right + std::cos(roll) * down;
  R.col(2) = forward;
  return R;
}

}  // namespace propcam::render
