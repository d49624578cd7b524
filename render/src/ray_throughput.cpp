#include "propcam/render/ray_throughput.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>

#include "sampling.h"

namespace propcam::render {
namespace {

using Clock = std::chrono::steady_clock;
constexpr float kInfinity = std::numeric_limits<float>::infinity();
// The path tracer's self-intersection offset (path_tracer.cpp): a fraction of
// the point's distance from the world origin plus an absolute floor.
constexpr float kRayOffsetRelative = 1e-4f;
constexpr float kRayOffsetAbsolute = 1e-4f;
// Rays handed to a thread at a time: large enough that the shared counter is
// no bottleneck, small enough that the threads finish together.
constexpr size_t kChunkRays = 4096;

int resolve_threads(int threads) {
  const int hw = static_cast<int>(std::thread::hardware_concurrency());
  return threads > 0 ? threads : std::max(1, hw);
}

// Runs `trace_one(i)` (true on a hit) on `threads` threads until the whole
// batch has been traced once and `min_seconds` have passed. The threads stay
// up for the whole loop and take chunks of rays from one counter that runs
// cyclically through the batch.
template <typename TraceOne>
RayThroughput timed_loop(size_t batch_size, int threads, double min_seconds, TraceOne&& trace_one) {
  RayThroughput out;
  out.threads = resolve_threads(threads);
  if (batch_size == 0) return out;
  const size_t chunks_per_batch = (batch_size + kChunkRays - 1) / kChunkRays;
  std::atomic<size_t> next_chunk{0};
  std::atomic<uint64_t> hits{0}, rays{0};
  const auto start = Clock::now();
  auto worker = [&] {
    uint64_t local_hits = 0, local_rays = 0;
    for (size_t chunk; (chunk = next_chunk.fetch_add(1)) < chunks_per_batch ||
                       std::chrono::duration<double>(Clock::now() - start).count() < min_seconds;) {
      const size_t begin = (chunk % chunks_per_batch) * kChunkRays;
      const size_t end = std::min(batch_size, begin + kChunkRays);
      for (size_t i = begin; i < end; ++i) local_hits += trace_one(i) ? 1 : 0;
      local_rays += end - begin;
    }
    hits += local_hits;
    rays += local_rays;
  };
  {
    std::vector<std::jthread> pool;
    for (int i = 1; i < out.threads; ++i) pool.emplace_back(worker);
    worker();
  }
  out.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  out.rays = rays;
  out.hits = hits;
  out.repeats = static_cast<double>(out.rays) / static_cast<double>(batch_size);
  return out;
}

void embree_error(void* user, RTCError code, const char* message) {
  auto* last_error = static_cast<std::string*>(user);
  if (last_error->empty())
    *last_error = "embree error " + std::to_string(static_cast<int>(code)) + ": " + (message ? message : "");
}

}  // namespace

RayBatch camera_and_bounce_rays(const Scene& scene, const PinholeCamera& camera, bool with_props,
                                int samples_per_pixel, uint64_t seed, const cv::Mat& pixels, int tile_size) {
  if (samples_per_pixel <= 0) throw std::invalid_argument("camera_and_bounce_rays: samples_per_pixel must be positive");
  if (!pixels.empty() && (pixels.type() != CV_8U || pixels.cols != camera.width || pixels.rows != camera.height))
    throw std::invalid_argument("camera_and_bounce_rays: the pixel mask must be CV_8U at the camera's size");
  const int tile = std::max(1, tile_size);
  RayBatch batch;
  const Eigen::Vector3f origin = camera.center_world.cast<float>();
  for (int ty = 0; ty < camera.height; ty += tile)
    for (int tx = 0; tx < camera.width; tx += tile)
      for (int y = ty; y < std::min(camera.height, ty + tile); ++y)
        for (int x = tx; x < std::min(camera.width, tx + tile); ++x) {
          if (!pixels.empty() && !pixels.at<uint8_t>(y, x)) continue;
          detail::Rng rng(seed, static_cast<uint64_t>(y) * static_cast<uint64_t>(camera.width) + static_cast<uint64_t>(x));
          for (int s = 0; s < samples_per_pixel; ++s) {
            const double u = x + rng.uniform() - 0.5, v = y + rng.uniform() - 0.5;
            const Eigen::Vector3f dir = camera.ray_direction(u, v).cast<float>();
            batch.origins.push_back(origin);
            batch.directions.push_back(dir);
            RayHit hit;
            if (!scene.intersect(origin, dir, kInfinity, with_props, hit)) continue;
            const SurfacePoint sp = scene.surface(hit, origin, dir);
            const detail::Frame frame(sp.geometric_normal);
            const float u1 = rng.uniform(), u2 = rng.uniform();
            batch.origins.push_back(sp.position + sp.geometric_normal * (kRayOffsetAbsolute +
                                                                         kRayOffsetRelative * sp.position.cwiseAbs().maxCoeff()));
            batch.directions.push_back(frame.to_world(detail::cosine_hemisphere(u1, u2)).normalized());
          }
        }
  return batch;
}

struct EmbreeRayLoop::State {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::string last_error;
  ~State() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  void check(const char* where) const {
    if (!last_error.empty()) throw std::runtime_error(std::string(where) + ": " + last_error);
  }
};

EmbreeRayLoop::EmbreeRayLoop(const std::vector<const Mesh*>& meshes) : state_(std::make_unique<State>()) {
  // As Scene: our own threads trace, the device gets no thread pool.
  state_->device = rtcNewDevice("threads=1");
  if (!state_->device) throw std::runtime_error("cannot create Embree device");
  rtcSetDeviceErrorFunction(state_->device, embree_error, &state_->last_error);
  state_->scene = rtcNewScene(state_->device);
  rtcSetSceneBuildQuality(state_->scene, RTC_BUILD_QUALITY_HIGH);
  for (const Mesh* mesh : meshes) {
    if (!mesh || mesh->empty()) continue;
    RTCGeometry geometry = rtcNewGeometry(state_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh->positions.size()));
    for (size_t i = 0; i < mesh->positions.size(); ++i)
      for (int k = 0; k < 3; ++k) vertices[3 * i + k] = mesh->positions[i][k];
    auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh->triangles.size()));
    for (size_t i = 0; i < mesh->triangles.size(); ++i)
      for (int k = 0; k < 3; ++k) indices[3 * i + k] = static_cast<unsigned>(mesh->triangles[i][k]);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(state_->scene, geometry);
    rtcReleaseGeometry(geometry);
  }
  rtcCommitScene(state_->scene);
  state_->check("EmbreeRayLoop");
}

EmbreeRayLoop::~EmbreeRayLoop() = default;

RayThroughput EmbreeRayLoop::trace(const RayBatch& batch, int threads, double min_seconds) const {
  const RTCScene scene = state_->scene;
  return timed_loop(batch.size(), threads, min_seconds, [&](size_t i) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    const Eigen::Vector3f& o = batch.origins[i];
    const Eigen::Vector3f& d = batch.directions[i];
    rh.ray.org_x = o.x(); rh.ray.org_y = o.y(); rh.ray.org_z = o.z();
    rh.ray.dir_x = d.x(); rh.ray.dir_y = d.y(); rh.ray.dir_z = d.z();
    rh.ray.tnear = 0.f;
    rh.ray.tfar = kInfinity;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.flags = 0;
    rh.ray.time = 0.f;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &context, &rh);
    return rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
  });
}

RayThroughput trace_with_scene(const Scene& scene, bool with_props, const RayBatch& batch, int threads,
                               double min_seconds) {
  return timed_loop(batch.size(), threads, min_seconds, [&](size_t i) {
    RayHit hit;
    return scene.intersect(batch.origins[i], batch.directions[i], kInfinity, with_props, hit);
  });
}

}  // namespace propcam::render
