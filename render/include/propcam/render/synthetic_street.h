// A generator of synthetic Manhattan streets with exact ground truth (camera,
// pose, depth, albedo, sun and sky), rendered by our own path tracer: the
// outdoor counterpart of synthetic_room.h for tests, `propcam bench geometry`
// and the depth-transfer database.
#pragma once

#include <cstdint>

#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/mesh.h"

namespace propcam::render {

struct SyntheticStreetSpec {
  int width = 640;
  int height = 480;
  uint64_t seed = 1;              // varies street width, buildings, camera yaw/pitch/roll, sun
  double horizontal_fov_deg = 0;  // 0: drawn from the seed in [50, 75]
  double camera_height_m = 1.5;
};

struct SyntheticStreet {
  PinholeCamera camera;  // exact intrinsics and pose (world Y up, ground at y = 0, buildings along the axes)
  Mesh scene;            // road, sidewalks, kerbs, facades with windows and cornices, parked cars
  LightRig lights;       // one sun and a sky environment (the sky has no geometry)
  Eigen::Vector3f scene_min, scene_max;
  Eigen::Vector3f free_ground_point;  // a free spot on the ground in front of the camera
};

SyntheticStreet make_synthetic_street(const SyntheticStreetSpec& spec);

}  // namespace propcam::render
