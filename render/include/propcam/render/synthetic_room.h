// A generator of synthetic Manhattan rooms with exact ground truth (camera,
// pose, depth, albedo, lights), rendered by our own path tracer. Tests and
// `propcam bench` use it where the paper used annotated datasets.
#pragma once

#include <cstdint>

#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/mesh.h"

namespace propcam::render {

struct SyntheticRoomSpec {
  int width = 640;
  int height = 480;
  uint64_t seed = 1;           // varies room size, colours, camera yaw/pitch, lights
  double horizontal_fov_deg = 0;  // 0: drawn from the seed in [50, 75]
  double camera_height_m = 1.5;
};

struct SyntheticRoom {
  PinholeCamera camera;       // exact intrinsics and pose
  Mesh room;                  // floor, walls, ceiling, furniture, light panels (emissive)
  LightRig lights;            // the area lights matching the emissive panels
  Eigen::Vector3f room_min, room_max;
  // A free spot on the floor in front of the camera, for test insertions.
  Eigen::Vector3f free_floor_point;
};

SyntheticRoom make_synthetic_room(const SyntheticRoomSpec& spec);

}  // namespace propcam::render
