// Light sources: one-sided area quads (sources seen in the photo, ceiling
// panels) and discs, spheres (bulbs, optionally spots), points (optionally
// spots), suns (distant discs) and an environment map (light from outside
// the frame).
//
// Units: linear RGB, relative to the photo's exposure. Area, disc and sphere
// lights and the environment give radiance (W/sr/m^2); a point light gives
// intensity (W/sr); a sun gives the irradiance (W/m^2) it delivers to a
// surface facing it, whatever its angular size.
//
// Lights are not geometry: they cast no shadows and rays pass through them.
// The path tracer samples each one toward every shading point (next-event
// estimation) and also counts it when a BSDF-sampled ray meets it, weighting
// the two with the power heuristic; the camera sees them directly unless
// `visible_to_camera` is false. A point light is a delta light: sampled only,
// never met. A light with no area, no radius or no power emits nothing and
// is skipped.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

namespace propcam::render {

// A direction from a receiving point toward a light, and what arrives along it.
struct LightSample {
  Eigen::Vector3f direction = Eigen::Vector3f::Zero();  // unit, toward the light
  float distance = 0.f;  // to the sampled point on the light; infinity for the sun and the environment
  Eigen::Vector3f radiance = Eigen::Vector3f::Zero();  // arriving along -direction
  float pdf = 0.f;  // solid-angle density of `direction`; 0: no sample (nothing arrives)
  // A delta light (a point): `radiance` is the irradiance I/d^2 arriving on a
  // surface facing it and `pdf` is 1, so radiance * cos / pdf stays the
  // arriving irradiance; MIS treats its density as infinite (weight 1).
  bool delta = false;
};

// Below this area (m^2) a quad's normal and its pdf dist^2 / (cos * area) are
// numerically meaningless; such a light emits nothing.
constexpr float kMinAreaLightArea = 1e-10f;
// Below this radius (m) a sphere light emits nothing (its pdf 1 / solid angle
// overflows): a light without size is a PointLight.
constexpr float kMinSphereLightRadius = 1e-6f;
// Below this radius (m) a disc light emits nothing (its area is under kMinAreaLightArea).
constexpr float kMinDiscLightRadius = 1e-5f;
// The Sun's angular radius seen from the Earth, in degrees.
constexpr double kSunAngularRadiusDeg = 0.265;
// Sun cones are clamped to [kMinSunAngularRadius, kMaxSunAngularRadius]
// radians: below the minimum a float direction cannot tell inside from outside
// (and the radiance E / (pi sin^2) heads for overflow); 0 means "as small as possible".
constexpr double kMinSunAngularRadius = 1e-4;
constexpr double kMaxSunAngularRadius = 0.5;

// Parallelogram corner + s*edge_u + t*edge_v, s,t in [0,1]; emits radiance on
// the side of edge_u x edge_v. A rectangle is sampled uniformly by the solid
// angle it subtends (Urena et al. 2013); a parallelogram with skewed edges, or
// a rectangle too small or seen too edge-on for that, uniformly by area.
struct AreaLight {
  Eigen::Vector3f corner = Eigen::Vector3f::Zero();
  Eigen::Vector3f edge_u = Eigen::Vector3f::UnitX();
  Eigen::Vector3f edge_v = Eigen::Vector3f::UnitZ();
  Eigen::Vector3f radiance = Eigen::Vector3f::Ones();
  // False: camera rays do not see it (it still lights the scene and shows in
  // reflections), as Cycles' camera ray visibility.
  bool visible_to_camera = true;

  Eigen::Vector3f normal() const { return edge_u.cross(edge_v).normalized(); }
  float area() const { return edge_u.cross(edge_v).norm(); }
  Eigen::Vector3f centre() const { return corner + 0.5f * (edge_u + edge_v); }

  bool emits() const;
  LightSample sample(const Eigen::Vector3f& from, float u1, float u2) const;
  // The ray origin + t*direction (unit) meets the emitting side at t > 0;
  // `pdf` is then the density sample(origin, ...) has for `direction`.
  bool intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float& t, float& pdf) const;
};

// One-sided disc of uniform radiance, emitting on the side of `normal`;
// sampled uniformly by area (pdf d^2 / (cos A), the same from intersect()).
struct DiscLight {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  Eigen::Vector3f normal = -Eigen::Vector3f::UnitY();  // emitting side (normalised on use)
  float radius = 0.1f;
  Eigen::Vector3f radiance = Eigen::Vector3f::Ones();
  bool visible_to_camera = true;

  double area() const;
  bool emits() const;
  LightSample sample(const Eigen::Vector3f& from, float u1, float u2) const;
  bool intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float& t, float& pdf) const;
};

// The cone of a spot light, as Blender Cycles 3.4 shapes it: along a unit
// direction w leaving the light at angle theta from the axis the light is
// scaled by cos(theta) * smoothstep((cos theta - cos h) / ((1 - cos h) blend))
// for theta < h (the half-angle; the smoothstep only where its argument is
// below 1), and 0 outside. Blender's spot_size is the full angle 2h and
// spot_blend is `blend`. The cos(theta) factor is Cycles 3.4's too.
struct SpotCone {
  Eigen::Vector3f direction = -Eigen::Vector3f::UnitY();  // the way the light shines (normalised on use)
  double half_angle = std::numbers::pi / 8;  // radians, [0, pi/2]: 0 emits nothing, pi/2 is a hemisphere
  double blend = 0.15;                        // [0, 1]: 0 a hard edge, 1 soft from the axis out

  // The scale along w (from the light outward; need not be unit); 0 for a
  // degenerate cone or direction.
  double attenuation(const Eigen::Vector3d& w) const;
  // The same for the cosine of the angle from the axis.
  double attenuation_at_cos(double cos_theta) const;
  bool valid() const;  // a finite axis, finite angle and blend
};

// A sphere of uniform radiance emitting outward. From outside it is sampled
// uniformly within the cone of directions it subtends; points inside receive
// nothing from it. With a `spot` cone, a point p receives the radiance scaled
// by the cone's attenuation along centre -> p (the same for every ray from p,
// so sample() and intersect() agree).
struct SphereLight {
  Eigen::Vector3f center = Eigen::Vector3f::Zero();
  float radius = 0.1f;
  Eigen::Vector3f radiance = Eigen::Vector3f::Ones();
  std::optional<SpotCone> spot;
  bool visible_to_camera = true;
  // A prop's own lamp (props.h prop_lights): it shines only in the world with
  // props, so differential rendering adds its light to the photo.
  bool prop_only = false;

  bool emits() const;
  // The radiance reaching `point` from the sphere (its spot cone applied).
  Eigen::Vector3f radiance_toward(const Eigen::Vector3f& point) const;
  LightSample sample(const Eigen::Vector3f& from, float u1, float u2) const;
  bool intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float& t, float& pdf) const;
};

// A point of `intensity` I (W/sr): a surface at distance d, at angle theta
// to it, receives I cos(theta) / d^2 (times the spot cone's attenuation).
// A delta light: light sampling only (LightSample::delta); no ray meets it
// and the camera never sees it. Points nearer than 1e-6 m receive nothing.
struct PointLight {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  Eigen::Vector3f intensity = Eigen::Vector3f::Ones();
  std::optional<SpotCone> spot;

  bool emits() const;
  // The two numbers are unused (the signature of the other lights).
  LightSample sample(const Eigen::Vector3f& from, float u1 = 0.f, float u2 = 0.f) const;
};

// A distant disc of uniform radiance: all directions within `angular_radius`
// of `direction`. `irradiance` is what a surface facing it receives, so its
// radiance is irradiance / (pi sin^2(angular_radius)) and a surface at angle
// theta receives irradiance * cos(theta) (while the disc is above its horizon).
struct SunLight {
  Eigen::Vector3f direction = Eigen::Vector3f::UnitY();  // toward the sun (normalised on use)
  double angular_radius = kSunAngularRadiusDeg * std::numbers::pi / 180.0;  // radians
  Eigen::Vector3f irradiance = Eigen::Vector3f::Ones();  // W/m^2 normal to `direction`
  bool visible_to_camera = true;
  // Light from outside a room: it arrives only along rays that cross one of
  // the rig's portals (its windows).
  bool through_portals = false;

  bool emits() const;
  Eigen::Vector3f radiance() const;
  LightSample sample(float u1, float u2) const;
  // Density of sample() for a direction: uniform in the cone, 0 outside.
  float pdf(const Eigen::Vector3f& direction) const;
};

// Equirectangular environment in world coordinates (Y up). The centre column
// looks along -Z and columns increase toward +X (phi = atan2(x, -z), u =
// (phi + pi) / 2pi): the column a quarter across looks along -X, three
// quarters across along +X, and the seam (column 0 and the last) is +Z;
// row 0 is +Y.
// Importance sampled in proportion to luminance times sin(theta).
class EnvironmentLight {
 public:
  EnvironmentLight() = default;
  // `latlong` is CV_32FC3 linear RGB; negative and non-finite texels are clamped to 0.
  explicit EnvironmentLight(const cv::Mat& latlong, Eigen::Vector3f scale = Eigen::Vector3f::Ones());

  bool valid() const { return !image_.empty(); }
  const cv::Mat& image() const { return image_; }
  Eigen::Vector3f scale() const { return scale_; }
  void set_scale(const Eigen::Vector3f& scale) { scale_ = scale; }
  // False: camera rays that escape see black; it still lights the scene.
  bool visible_to_camera() const { return visible_to_camera_; }
  void set_visible_to_camera(bool visible) { visible_to_camera_ = visible; }
  // Light from outside a room: it arrives only along rays that cross one of
  // the rig's portals (its windows).
  bool through_portals() const { return through_portals_; }
  void set_through_portals(bool through) { through_portals_ = through; }

  // 0 for a non-finite direction.
  Eigen::Vector3f radiance(const Eigen::Vector3f& direction) const;
  // Samples a direction from two uniform numbers; returns its solid-angle pdf.
  Eigen::Vector3f sample(float u1, float u2, float& pdf) const;
  float pdf(const Eigen::Vector3f& direction) const;

  static Eigen::Vector2f direction_to_uv(const Eigen::Vector3f& d);  // [0,1)^2
  static Eigen::Vector3f uv_to_direction(float u, float v);

 private:
  cv::Mat image_;
  Eigen::Vector3f scale_ = Eigen::Vector3f::Ones();
  std::vector<float> marginal_cdf_;     // over rows, size rows+1
  std::vector<float> conditional_cdf_;  // per row over columns, rows*(cols+1)
  std::vector<float> row_weight_;
  float total_weight_ = 0.f;
  bool visible_to_camera_ = true;
  bool through_portals_ = false;
};

// A window in walls the scene does not hold: the parallelogram corner +
// s*edge_u + t*edge_v, s,t in [0,1], crossed from either side. A room's
// walls out of view are not geometry, so a sun or sky marked
// `through_portals` would otherwise reach everything in it from every
// direction; with portals it reaches a point only through its windows, as
// in the room. The lights are still sampled over their whole extent: a
// small window is found by few of the sky's samples (noisier, not biased).
struct Portal {
  Eigen::Vector3f corner = Eigen::Vector3f::Zero();
  Eigen::Vector3f edge_u = Eigen::Vector3f::UnitX();
  Eigen::Vector3f edge_v = Eigen::Vector3f::UnitY();

  // Finite corners and an area of at least kMinAreaLightArea.
  bool valid() const;
  // The ray origin + t*direction crosses the parallelogram at some t > 0.
  bool crossed_by(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction) const;
};

// Every light of a scene. Lights are indexed in this order: area lights,
// sphere lights (spots among them), suns, disc lights, point lights (spots
// among them), then the environment (if any); count(), only(), the path
// tracer's per-light layers (relight.h, render_background_light_images) and
// its per-bounce sampler dimensions follow it. Discs and points come after
// the suns so that a rig without them keeps the indices it always had.
struct LightRig {
  std::vector<AreaLight> area_lights;
  std::vector<SphereLight> sphere_lights;
  std::vector<SunLight> suns;
  std::vector<DiscLight> disc_lights;
  std::vector<PointLight> point_lights;
  std::shared_ptr<EnvironmentLight> environment;  // may be null
  // The windows that suns and an environment marked `through_portals` shine
  // through; such a light with no portal reaches nothing.
  std::vector<Portal> portals;

  // Index of the first light of each kind.
  int first_sphere() const { return static_cast<int>(area_lights.size()); }
  int first_sun() const { return first_sphere() + static_cast<int>(sphere_lights.size()); }
  int first_disc() const { return first_sun() + static_cast<int>(suns.size()); }
  int first_point() const { return first_disc() + static_cast<int>(disc_lights.size()); }
  int environment_index() const { return first_point() + static_cast<int>(point_lights.size()); }
  int count() const { return environment_index() + (environment ? 1 : 0); }
  // A rig holding only light `index` (and the portals); throws std::out_of_range.
  LightRig only(int index) const;
  // Whether light from outside reaches `origin` along `direction` (toward
  // the light): always when `through_portals` is false, else when the ray
  // crosses a portal.
  bool arrives_from_outside(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                            bool through_portals) const;
};

}  // namespace propcam::render
