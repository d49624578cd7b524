// The work behind the appliance's screens, free of threads and UI: analyse
// a still, list the props, find the spots a prop can stand on, render the
// composite progressively, predict render times from this device's measured
// throughput, and relight / refocus the result without re-rendering.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "appliance/appliance_state.h"
#include "common/compositor.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/mesh.h"
#include "propcam/render/render_session.h"

namespace propcam::firmware {

// Thrown from inside a job when its cancel flag is seen.
struct JobCancelled : std::runtime_error {
  JobCancelled() : std::runtime_error("cancelled") {}
};

// ---------------------------------------------------------------- analysis

struct Analysis {
  cv::Mat photo_linear;  // CV_32FC3 linear sRGB at the working size (job_budget.h)
  cv::Mat scene_photo;   // the same in the camera response's linear space (what light adds in)
  cv::Mat photo_rgb8;    // for the screen, at the working size
  // The still as the camera delivered it, when larger than the working size:
  // the composite is exported at its size.
  cv::Mat full_photo_linear;
  inference::SceneModel scene;
  // The lens's calibrated fall-off (the board's), given to the prop by the
  // camera match; unknown: none.
  render::Vignetting vignetting;
};

// Infers the scene of a still, reduced to `working_pixels` when larger.
// `on_stage` is called before each stage with its name; it may throw
// JobCancelled to stop between stages. A known `vignetting` (the board's
// calibration) is divided out of the photo the scene is inferred from.
Analysis analyse_still(const cv::Mat& photo_linear, const cv::Mat& photo_rgb8, double camera_height_m,
                       long working_pixels, const std::function<void(const std::string&)>& on_stage,
                       const render::Vignetting& vignetting = {});

// ---------------------------------------------------------------- props

struct PropEntry {
  std::string name;         // shown on screen
  std::string material;     // "glossy", "metal", ...
  std::string source;       // a preset name or a mesh file (load_prop's argument)
  bool from_usb = false;
  double natural_height_m = 0.0;
  cv::Mat thumbnail;        // CV_8UC3 RGB; empty when none could be made
};

// Mesh files a stick may carry in its props/ folder.
inline constexpr int kMaxUsbProps = 64;
// The presets (thumbnails rendered once and cached in `thumbnail_cache`,
// when not empty) followed by the OBJ files in `usb_root`/props (sorted; at
// most kMaxUsbProps; unreadable ones are left out with a log line).
std::vector<PropEntry> list_props(const std::filesystem::path& thumbnail_cache, const std::filesystem::path& usb_root,
                                  int thumbnail_size);

// ---------------------------------------------------------------- placement

struct Spot {
  cv::Point2d pixel;      // where the prop's base is seen
  std::string surface;    // the support plane's name ("floor", "support_1") or "surface"
  double distance_m = 0;  // camera to base
};

// Up to `max_spots` pixels on support surfaces spread over the image (a grid,
// each cell's most upward-facing point near its centre), ordered left to right
// and near to far; the one nearest the lower middle of the image first.
// Empty when the scene has no horizontal surface facing up.
std::vector<Spot> find_spots(const inference::SceneModel& scene, int max_spots);

// The prop's base outline at `spot` (a rectangle of the prop's footprint on
// the support plane, projected), in image pixels; empty when it cannot be
// projected.
std::vector<cv::Point2d> footprint_outline(const inference::SceneModel& scene, const Spot& spot,
                                           const render::Mesh& prop, double height_m);

// A quick look at the prop where it would stand, for the placement screen:
// the prop seen by one ray per pixel, shaded by its albedo under a light
// from above and behind the camera, drawn over the photo. The world (depth
// mesh, acceleration structure) is built once per prop; moving the prop to
// another spot only re-places the instance.
class PlacementPreview {
 public:
  // Throws std::invalid_argument as build_composite_world does.
  PlacementPreview(std::shared_ptr<const Analysis> analysis, const PropEntry& prop, const Spot& first_spot);
  // CV_8UC3 RGB at the photo's size; the photo alone when the spot has no support.
  cv::Mat render(const Spot& spot);
  const std::string& prop_source() const { return prop_source_; }
  const Analysis* analysis() const { return analysis_.get(); }

 private:
  std::shared_ptr<const Analysis> analysis_;
  std::string prop_source_;
  double height_m_ = 0;
  render::Mesh prop_;
  CompositeWorld world_;
};

// ---------------------------------------------------------------- quality tiers

struct TierSpec {
  appliance::Tier tier = appliance::Tier::Good;
  int max_samples_per_pixel = 64;
  double target_relative_error = 0.1;  // a tile stops here
};
TierSpec tier_spec(appliance::Tier tier);

// Render throughput of this device (pixel-samples per second of the
// differential path tracer), measured by every render and kept in a file so
// predictions improve with use. Starts from a conservative default.
class ThroughputModel {
 public:
  static constexpr double kDefaultPixelSamplesPerSecond = 2.0e5;
  explicit ThroughputModel(std::filesystem::path file = {});
  double pixel_samples_per_second() const { return rate_; }
  bool measured() const { return measured_; }
  // Seconds for `pixels` traced at up to spp samples (a tile stopping early is not predicted).
  double predict_seconds(double pixels, int samples_per_pixel) const;
  // Folds in one render's measurement and saves the file (atomically).
  void record(double pixel_samples, double seconds);

 private:
  std::filesystem::path file_;
  double rate_ = kDefaultPixelSamplesPerSecond;
  bool measured_ = false;
};

// ---------------------------------------------------------------- rendering

// What the screen shows of a render in flight; immutable once published.
struct RenderSnapshot {
  cv::Mat composite;                 // CV_32FC3, response-linear (before relighting)
  cv::Mat display;                   // the same in linear sRGB, for the screen (made on the worker)
  std::vector<render::TileStatus> tiles;
  double converged_fraction = 0.0;   // done affected tiles / affected tiles
  double elapsed_seconds = 0.0;
  double seconds_to_good = -1.0;     // predicted; < 0 unknown
  double seconds_to_done = -1.0;
  int samples_per_pixel = 0;
  int skipped_tiles = 0;
  std::vector<std::string> skipped_effects;
  bool finished = false;
  bool stopped_by_time_budget = false;  // finished because the next pass would end after the budget
  // Filled when the render ends (converged or stopped): for relighting and depth of field.
  render::LightLayers layers;
  cv::Mat depth;
  SharpCoverage full_size_coverage;  // the prop at the still's size, when it was worked reduced
  double prop_distance_m = 2.0;
  cv::Point2d base_pixel;  // where the prop stands (the spot, or a level pixel beside it)
};

// One progressive render of a placed prop. It ends when its tiles converge
// or reach the tier's samples, or when the next pass would end after
// `time_budget_seconds` of rendering (0: no budget).
class CompositeRender {
 public:
  CompositeRender(std::shared_ptr<const Analysis> analysis, const PropEntry& prop, const Spot& spot, TierSpec tier,
                  int threads, double time_budget_seconds = 0.0);
  // Runs one pass; false when there is nothing left to do.
  bool run_pass(const std::atomic<bool>* cancel);
  bool finished() const;
  bool out_of_time() const;
  // A snapshot of the current state; with `final_layers` also the light layers and depth.
  std::shared_ptr<const RenderSnapshot> snapshot(bool final_layers) const;
  double pixel_samples() const;  // traced so far
  double seconds() const { return seconds_; }

 private:
  std::shared_ptr<const Analysis> analysis_;
  render::Mesh prop_;
  CompositeWorld world_;
  render::TransportPlan plan_;
  TierSpec tier_;
  double time_budget_seconds_ = 0.0;
  std::unique_ptr<render::RenderSession> session_;
  std::vector<render::PassReport> passes_;
  double seconds_ = 0.0;
};

// ---------------------------------------------------------------- adjusting

// Relight and depth of field from the adjusting screen's slider steps.
struct Adjustment {
  double scene_ev = 0.0;       // the photo's own light, in stops
  double prop_ev = 0.0;        // the light the prop receives and casts (its change), in stops
  double focus_m = 0.0;        // 0: on the prop
  double aperture_m = 0.0;     // 0: pinhole (no blur)
};
inline constexpr double kEvPerStep = 0.25;
inline constexpr double kFocusStopsPerStep = 0.25;  // focus distance doubles every 4 steps
inline constexpr double kApertureMetresPerStep = 0.004;
Adjustment adjustment_from_steps(const std::array<int, appliance::kRelightParamCount>& steps, double prop_distance_m);
// "+0.50 EV", "2.4 m", "8 mm" (pinhole: "pinhole").
std::string describe_step(appliance::RelightParam param, int step, double prop_distance_m);

// The composite as the user sees it: relit, refocused, in linear sRGB.
cv::Mat adjusted_composite(const Analysis& analysis, const RenderSnapshot& render, const Adjustment& adjustment);
// adjusted_composite at the still's own size when it was worked reduced (its
// change carried up onto the full still, working_size.h), else the same.
cv::Mat exported_composite(const Analysis& analysis, const RenderSnapshot& render, const Adjustment& adjustment);

}  // namespace propcam::firmware
