// The light arriving at a point, reduced to its first moments: what the
// lighting benches compare between an inferred scene and the truth (the
// dominant light's direction and the irradiance on a level surface).
//
// Moments of the incident luminance L(w) (Rec. 709 Y of linear RGB) over the
// sphere of directions w:
//   vector        = integral L(w) w dw   (its direction: the dominant light)
//   irradiance_up = integral L(w) max(0, w.y) dw   (on an upward-facing surface)
//   total         = integral L(w) dw
// For a uniform disc of radiance L, angular radius a, seen along axis n:
// vector = L pi sin^2(a) n, total = L 2 pi (1 - cos a).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>

#include "propcam/render/lights.h"
#include "propcam/render/scene.h"

namespace propcam::firmware {

struct LightMoments {
  Eigen::Vector3d vector = Eigen::Vector3d::Zero();  // world frame (Y up)
  double irradiance_up = 0;
  double total = 0;
};

// The scene's light at `point`, in three parts, each past the scene's
// occluders (props left out):
//  - what surfaces send toward the point (one or two bounces): a cube map of
//    six 90-degree faces of face_px x face_px rendered from the point by
//    render_background_image, each sample a 2-bounce path minus the same
//    camera ray at 0 bounces (so a light seen directly cancels exactly),
//    summed with each pixel's exact solid angle;
//  - the environment (and emissive surfaces) seen directly: the same faces
//    rendered at 0 bounces with the environment alone;
//  - area and sphere lights seen directly, by light sampling with shadow
//    rays (a 24x24 jittered grid per light: small bright bulbs a pixel grid
//    would catch with a few samples), and suns analytically, each where the
//    ray toward it is free (a 0.27-degree disc is missed by pixel sampling)
//    and, for a sun through the rig's portals, crosses one.
// Lights are scaled down for the renders (and the sums up again) so that no
// seen light reaches the path tracer's per-sample clamp. Prop lamps
// (prop_only) are left out. Deterministic for a seed. Cost: 6 (2 spp + 1)
// renders of face_px^2 pixels at 1 spp, two of them at 0 bounces.
// Throws std::invalid_argument for face_px < 2, spp < 1 or a non-finite point.
LightMoments probe_light_moments(const render::Scene& scene, const render::LightRig& lights,
                                 const Eigen::Vector3f& point, int face_px, int spp, uint64_t seed);

// The moments of an equirectangular panorama (CV_32FC3 linear RGB in the
// EnvironmentLight convention, render/lights.h: the centre column looks along
// -Z, columns increase toward +X, row 0 is +Y), each texel weighted by its
// exact solid angle (2 pi / cols) (cos theta0 - cos theta1). Negative and
// non-finite texels count as 0. Throws std::invalid_argument for an empty or
// non-CV_32FC3 image.
LightMoments latlong_light_moments(const cv::Mat& latlong);

// The same moments seen in another frame (vector only; irradiance_up and
// total stay as measured in the world, whose up is Y).
inline LightMoments rotated(const LightMoments& m, const Eigen::Matrix3d& frame_from_world) {
  LightMoments out = m;
  out.vector = frame_from_world * m.vector;
  return out;
}

}  // namespace propcam::firmware
