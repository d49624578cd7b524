// CPU path tracer on Embree: next-event estimation to every light (area,
// disc, sphere and spot, point, sun, environment), MIS (power heuristic)
// between light and BSDF sampling for all of them (a point light is a delta:
// light sampling only), Russian roulette, and the one-pass differential
// render (I_obj and I_noobj from shared random numbers). Lights and materials:
// lights.h, mesh.h, render/README.md.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>
#include <opencv2/core.hpp>

#include "propcam/render/camera.h"
#include "propcam/render/lights.h"
#include "propcam/render/scene.h"

namespace propcam::render {

// A sample's luminance above which its radiance is scaled down, so a rare
// caustic path cannot leave a white fleck (bias traded for variance, as
// production renderers do).
constexpr float kDefaultMaxSampleLuminance = 64.f;

struct RenderSettings {
  int samples_per_pixel = 16;
  // Path vertices after the camera hit that may scatter: 1 is direct light
  // only, so Blender Cycles' max_bounces B is max_bounces B + 1 (the CLI's
  // --bounces counts as Cycles does). The paper allows 16.
  int max_bounces = 4;
  uint64_t seed = 0x5eed;   // the same seed gives the same image
  // render_image and render_background_*: the pixels' samples are numbers
  // [first_sample, first_sample + samples_per_pixel) of one low-discrepancy
  // sequence per pixel, so passes that continue it sum to the single render.
  int first_sample = 0;
  // Per-sample luminance clamp; 0 (or less) turns it off.
  float max_sample_luminance = kDefaultMaxSampleLuminance;
  int threads = 0;          // 0: all hardware threads
  int tile_size = 32;
  // Keep the prop's change split by light (rig order, then emissive surfaces)
  // so light intensities can be changed after rendering (relight.h).
  bool light_layers = false;
  // Transport the renderer may skip (see transport_plan.h): light that
  // reaches the photo's surfaces via a specular prop (caustics), or via any
  // prop (its bounce light). Shadows are traced either way.
  bool caustics = true;
  bool prop_interreflection = true;
  // Called from worker threads with the finished fraction in [0,1].
  std::function<void(double)> progress;
};

struct RenderStats {
  double seconds = 0.0;
  uint64_t camera_samples = 0;
  uint64_t rays = 0;                 // closest-hit and shadow rays
  uint64_t paths_without_prop = 0;   // second paths traced for I_noobj
  uint64_t paths_prop_untouched = 0; // samples whose I_noobj path was skipped (identical to I_obj)
};

// Ground-truth buffers from one centred camera ray per pixel.
struct PrimaryBuffers {
  cv::Mat depth;   // CV_32F, metres along camera z; 0 where nothing was hit
  cv::Mat albedo;  // CV_32FC3 linear
  cv::Mat normal;  // CV_32FC3 world-space unit normal
  cv::Mat prop_coverage;  // CV_8U, 255 where a prop is seen
};

// Renders the scene (with its props) as the camera sees it. Linear RGB CV_32FC3.
cv::Mat render_image(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                     const RenderSettings& settings, RenderStats* stats = nullptr);

// The same without the props (the empty scene).
cv::Mat render_background_image(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                const RenderSettings& settings, RenderStats* stats = nullptr);

// The empty scene split by light: element i is what rig light i alone
// renders (LightRig::only order), from one set of paths shared by all lights
// (next-event estimation toward each at every vertex), so k lights cost far
// less than k renders. Each light's estimate is the one a render of it alone
// makes, up to noise, except that the luminance clamp of a sample
// (max_sample_luminance) applies to the lights' sum. Emissive surfaces outside
// the rig are dropped.
std::vector<cv::Mat> render_background_light_images(const Scene& scene, const PinholeCamera& camera,
                                                    const LightRig& lights, const RenderSettings& settings,
                                                    RenderStats* stats = nullptr);

// The share of each pixel of `region` (clipped to the image) whose
// rays_per_side² stratified camera rays first hit a prop: CV_32F, the
// region's size. A composite rendered at a smaller size gets its prop's
// silhouette at this camera's resolution from it.
cv::Mat render_prop_coverage(const Scene& scene, const PinholeCamera& camera, const cv::Rect& region,
                             int rays_per_side, int threads = 0);

// `only_where` (CV_8U, optional): pixels left at zero where it is zero.
PrimaryBuffers render_primary_buffers(const Scene& scene, const PinholeCamera& camera, bool with_props,
                                      const cv::Mat& only_where = cv::Mat());

// The prop's effect on the photo, from one set of shared samples.
struct DifferentialRender {
  cv::Mat coverage;  // CV_32F, M: fraction of camera samples that see a prop
  cv::Mat change;    // CV_32FC3, mean over samples of (prop seen ? I_obj : I_obj - I_noobj)
  RenderStats stats;
};

DifferentialRender render_differential(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                       const RenderSettings& settings);

// One pixel's differential samples [first_sample, first_sample + count), the
// unit of progressive rendering. Sample s draws from its own random stream
// (seed, pixel, s), so any split into passes gives bit-identical sums.
struct DifferentialPixel {
  Eigen::Vector3f change_sum = Eigen::Vector3f::Zero();  // sum of per-sample changes
  Eigen::Vector3f change_sum_odd = Eigen::Vector3f::Zero();  // the same over odd sample numbers (denoise.h's halves)
  std::vector<Eigen::Vector3f> change_sum_per_light;     // with light layers: the same, split by light
  double change_luminance_sq_sum = 0.0;                  // for the standard error
  int prop_samples = 0;                                  // samples whose camera ray saw a prop
  int samples = 0;
  uint64_t rays = 0, second_paths = 0, untouched = 0;
};

// Adds samples [first_sample, first_sample + count) to every pixel of `rect`;
// `pixels` holds rect's pixels row by row (rect.area() of them). One call per
// tile: the integrator (and each light's derived sampling data) is set up once.
void accumulate_differential_pixels(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                    const RenderSettings& settings, const cv::Rect& rect, int first_sample, int count,
                                    std::vector<DifferentialPixel>& pixels);

// Debevec's additive differential compositing, per sample:
// I_final = M*I_obj + (1-M)*(I_b + I_obj - I_noobj), clamped at 0.
cv::Mat composite_differential(const cv::Mat& photo_linear, const DifferentialRender& render);

}  // namespace propcam::render
