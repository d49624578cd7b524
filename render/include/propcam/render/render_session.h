// Progressive differential rendering in tiles: passes of growing samples,
// a composite snapshot and a per-tile error estimate after each pass, cancel
// and resume at any time, deterministic for a seed. Tiles the prop cannot
// affect (see prop_reach.h) are never traced and keep the photo.
#pragma once

#include <atomic>
#include <mutex>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/render/denoise.h"

#include "propcam/render/path_tracer.h"
#include "propcam/render/prop_reach.h"
#include "propcam/render/relight.h"

namespace propcam::render {

struct SessionSettings {
  RenderSettings render;            // seed, bounces, threads, tile size (samples_per_pixel is ignored)
  int max_samples_per_pixel = 256;  // a tile stops here
  // A tile stops when the standard error of its change image, relative to
  // its brightness, falls below this (0: never; run to max samples).
  double target_relative_error = 0.0;
  // No tile converges before this many samples: with few samples, a tile
  // whose paths all missed the prop's faint penumbra shows zero variance.
  int min_samples_to_converge = 8;
  bool cull_tiles = true;           // skip tiles the prop cannot affect
  ReachOptions reach;
  // composite() filters the prop's change (denoise.h) in the tiles where the
  // two half buffers say the filter lowers the error.
  bool denoise = false;
  DenoiseOptions denoise_options;
};

// What the last denoised() did.
struct DenoiseReport {
  int tiles_judged = 0;    // traced tiles with pixels the prop changed
  int tiles_filtered = 0;  // of those, where the filter lowered the error
  double seconds = 0.0;    // guides (once), both filters and the test
};

struct TileStatus {
  cv::Rect rect;
  bool affected = true;         // false: culled, never traced
  int samples = 0;              // per pixel so far
  double relative_error = 0.0;  // standard error of the change / tile brightness
  double seconds = 0.0;         // time spent on this tile (all passes, summed over threads)
  bool done = false;            // converged, at the sample limit, or culled
};

struct PassReport {
  int pass = 0;
  int max_samples = 0;          // samples per pixel of the most sampled tile
  int tiles_traced = 0;         // in this pass
  int tiles_culled = 0;
  int tiles_done = 0;
  double max_relative_error = 0.0;  // over affected tiles
  double pass_seconds = 0.0;
  double total_seconds = 0.0;
  bool cancelled = false;       // stopped early; the unfinished tiles of this pass were dropped
};

class RenderSession {
 public:
  // `scene` holds the background and the prop; `prop_bounds` is the prop's
  // world bounding box (for culling). The references must outlive the session.
  RenderSession(const Scene& scene, const PinholeCamera& camera, const LightRig& lights, const cv::Mat& photo_linear,
                const Eigen::AlignedBox3f& prop_bounds, const SessionSettings& settings);

  // One pass: every unfinished tile doubles its samples up to 16 (the first
  // pass gives one), then adds half of them (24, 36, 54, ...). `cancel` is polled between tiles; a cancelled pass keeps the tiles
  // it finished, and the next call resumes where it stopped.
  PassReport run_pass(const std::atomic<bool>* cancel = nullptr);
  bool finished() const;
  // The next pass's seconds, from the last pass's time per pixel-sample and
  // the pixel-samples the next one adds (0 before the first pass).
  double predicted_next_pass_seconds() const;

  cv::Mat composite() const;            // CV_32FC3 linear, the photo's size (denoised if settings.denoise)
  DifferentialRender differential() const;
  // The change filtered where it helps (tiles with under 2 or over
  // denoise_options.max_samples samples stay raw);
  // `report` (optional) says where and at what cost.
  DifferentialRender denoised(DenoiseReport* report = nullptr) const;
  // The change split by light (needs settings.render.light_layers); empty otherwise.
  LightLayers light_layers() const;
  cv::Mat tile_error_map() const;       // CV_32F, each pixel its tile's relative error (0 where culled)
  cv::Mat touched() const;              // CV_8U, 255 where some sample of the pixel the prop changed
  const std::vector<TileStatus>& tiles() const { return tiles_; }
  const PropReach& reach() const { return reach_; }
  RenderStats stats() const;            // rays and samples so far
  int passes() const { return passes_; }

 private:
  void render_tile(int index, int first_sample, int count);
  int samples_to_add(const TileStatus& t) const;  // by the next pass
  // Calls f(x, y, pixel) for every pixel with samples, tile by tile.
  template <typename F>
  void for_each_traced_pixel(const F& f) const {
    for (size_t t = 0; t < tiles_.size(); ++t) {
      const cv::Rect& r = tiles_[t].rect;
      const std::vector<DifferentialPixel>& pixels = tile_pixels_[t];
      for (size_t i = 0; i < pixels.size(); ++i)
        if (pixels[i].samples > 0) f(r.x + static_cast<int>(i) % r.width, r.y + static_cast<int>(i) / r.width, pixels[i]);
    }
  }

  const Scene& scene_;
  const PinholeCamera& camera_;
  const LightRig& lights_;
  cv::Mat photo_;
  SessionSettings settings_;
  PropReach reach_;
  std::vector<TileStatus> tiles_;
  std::vector<std::vector<DifferentialPixel>> tile_pixels_;  // per tile, row by row; empty until traced
  // The denoiser's guides, traced once on first use (over affected tiles).
  mutable std::mutex guides_mutex_;
  mutable DenoiseGuides guides_;
  int passes_ = 0;
  double total_seconds_ = 0.0;
  double last_pass_seconds_ = 0.0;
  long long last_pass_pixel_samples_ = 0;
};

}  // namespace propcam::render
