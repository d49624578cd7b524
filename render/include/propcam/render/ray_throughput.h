// Closest-hit throughput with nothing else around it (no shading, sampling or
// bookkeeping): the ceiling for the path tracer's rays per second on the same
// geometry. `propcam bench render` compares the two.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/mesh.h"
#include "propcam/render/scene.h"

namespace propcam::render {

struct RayBatch {
  std::vector<Eigen::Vector3f> origins;
  std::vector<Eigen::Vector3f> directions;  // unit
  size_t size() const { return origins.size(); }
};

// Rays like the first two segments of the renderer's paths, in its order
// (tiles of `tile_size`, pixel by pixel, sample by sample): a camera ray
// through a random point of the pixel and, where it hits, a ray from the hit
// point (offset off the surface like the path tracer's) in a cosine-distributed
// direction about the geometric normal facing the camera ray. Only pixels
// where `pixels` (CV_8U at camera size) is non-zero; all when it is empty.
// The first hits are found in the world with or without the props.
RayBatch camera_and_bounce_rays(const Scene& scene, const PinholeCamera& camera, bool with_props,
                                int samples_per_pixel, uint64_t seed, const cv::Mat& pixels = {},
                                int tile_size = 32);

struct RayThroughput {
  uint64_t rays = 0;     // closest-hit queries traced (the batch, repeated)
  uint64_t hits = 0;
  double repeats = 0;    // times the batch was traced (the last time may be partial)
  int threads = 0;
  double seconds = 0.0;  // wall time of the timed loop
  double rays_per_s() const { return seconds > 0 ? static_cast<double>(rays) / seconds : 0.0; }
};

// A bare Embree scene over `meshes`, built as Scene builds its worlds (an
// Embree device with one thread, high build quality, triangle geometry), so
// the BVH is the one the renderer traverses.
class EmbreeRayLoop {
 public:
  explicit EmbreeRayLoop(const std::vector<const Mesh*>& meshes);
  ~EmbreeRayLoop();
  EmbreeRayLoop(const EmbreeRayLoop&) = delete;
  EmbreeRayLoop& operator=(const EmbreeRayLoop&) = delete;

  // rtcIntersect1 on every ray of the batch (t in [0, inf)), split in chunks
  // over `threads` threads (0: all hardware threads), the whole batch
  // repeated until at least `min_seconds` have passed.
  RayThroughput trace(const RayBatch& batch, int threads, double min_seconds) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// The same loop through Scene::intersect (what the path tracer calls).
RayThroughput trace_with_scene(const Scene& scene, bool with_props, const RayBatch& batch, int threads,
                               double min_seconds);

}  // namespace propcam::render
