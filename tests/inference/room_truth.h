// Exact depth and normals of a synthetic room (no path tracing: primary rays only).
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"
#include "propcam/render/synthetic_room.h"

namespace propcam::inference {

struct RoomTruth {
  render::SyntheticRoom room;
  cv::Mat depth, normals;
};

inline RoomTruth room_truth(uint64_t seed, int width, int height) {
  render::SyntheticRoomSpec spec;
  spec.width = width;
  spec.height = height;
  spec.seed = seed;
  RoomTruth t{render::make_synthetic_room(spec), {}, {}};
  render::Scene scene;
  scene.add_mesh(t.room.room, render::Layer::Background);
  scene.commit();
  const render::PrimaryBuffers b = render::render_primary_buffers(scene, t.room.camera, false);
  t.depth = b.depth;
  t.normals = b.normal;
  return t;
}

}  // namespace propcam::inference
