#include "propcam/inference/sun_from_shadows.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "propcam/render/path_tracer.h"
#include "luminance.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr double kMinLuminance = 1e-4;       // keeps log L finite on black pixels
constexpr double kMinAlbedoForShading = 0.02;
constexpr double kShadingFloor = 1e-4;       // a pixel neither sky nor sun reaches
constexpr double kShadowRayOffset = 1e-3;    // metres per metre of depth, off the surface
constexpr double kGroundCos = 0.866;         // normals within 30 degrees of up (or down)
constexpr int kFacadeAzimuthBins = 8;
constexpr int kMinGroupPixels = 16;
// The ground's albedo for its bounce light: the estimate's scale is only
// assumed, so it is held to what roads and pavements can be.
constexpr double kDefaultGroundAlbedo = 0.2, kMinGroundAlbedo = 0.05, kMaxGroundAlbedo = 0.6;
// Golden-section steps on log(ratio) after the ladder's best rung.
constexpr int kRatioRefineSteps = 10;

struct Sample {
  Vector3d point, normal;
  double offset = 0;       // shadow ray start along the normal
  double log_photo = 0;
  double sky_shading = 0;  // the sky's environment at unit weight, albedo divided out
  double lower_view = 0;   // share of the lower hemisphere (the ground) the surface faces
  int group = 0;           // shares an albedo offset (SunFromShadowsOptions::groups)
  int group_orientation = 0;
};

// Orientation groups: ground-like, ceiling-like, facades by azimuth, slopes.
int orientation_group(const Vector3d& n) {
  if (n.y() > kGroundCos) return 0;
  if (n.y() < -kGroundCos) return 1;
  if (std::abs(n.y()) > 0.5) return 2;
  const double azimuth = std::atan2(n.x(), n.z()) + std::numbers::pi;  // [0, 2 pi]
  const int bin = std::min(kFacadeAzimuthBins - 1,
                           static_cast<int>(azimuth / (2 * std::numbers::pi) * kFacadeAzimuthBins + 0.5) % kFacadeAzimuthBins);
  return 3 + bin;
}

Vector3d sun_direction(double elevation_deg, double azimuth_deg) {
  const double e = elevation_deg * kDegToRad, a = azimuth_deg * kDegToRad;
  return {std::cos(e) * std::sin(a), std::sin(e), std::cos(e) * std::cos(a)};
}

class Search {
 public:
  Search(const render::Scene& scene, std::vector<Sample> samples, int groups, double ground_albedo,
         const SunFromShadowsOptions& o)
      : scene_(scene), samples_(std::move(samples)), groups_(groups), ground_albedo_(ground_albedo), options_(o),
        sun_(samples_.size()), sum_(groups), count_(groups) {
    for (const Sample& s : samples_) ++count_[s.group];
  }

  // The grouped variance of log photo - log(sky + r * sun) at the best r.
  struct Score {
    double variance = std::numeric_limits<double>::infinity(), ratio = 0;
  };

  Score score(const Vector3d& direction) {
    for (size_t i = 0; i < samples_.size(); ++i) {
      const Sample& s = samples_[i];
      const double cosine = s.normal.dot(direction);
      sun_[i] = cosine > 0 && !scene_.occluded((s.point + s.offset * s.normal).cast<float>(), direction.cast<float>(),
                                               std::numeric_limits<float>::infinity(), false)
                    ? cosine / std::numbers::pi
                    : 0.0;
    }
    // The sunlit ground's bounce, as a uniform lower hemisphere: it lights
    // the shadowed facades of a backlit street more than the sky does.
    double ground_sum = 0;
    int ground_count = 0;
    for (size_t i = 0; i < samples_.size(); ++i)
      if (samples_[i].group_orientation == 0) ground_sum += sun_[i], ++ground_count;
    const double bounce = ground_count > 0 ? ground_albedo_ * ground_sum / ground_count : 0.0;
    for (size_t i = 0; i < samples_.size(); ++i) sun_[i] += bounce * samples_[i].lower_view;
    return best_ratio();
  }

  // The same for light that reaches every pixel alike (no shadow, no
  // orientation): what any added light explains by merely evening out the
  // sky's render noise. A sun must do better than this.
  Score score_ambient() {
    std::fill(sun_.begin(), sun_.end(), 1.0 / std::numbers::pi);
    return best_ratio();
  }

  Score best_ratio() {
    Score best;
    best.variance = variance(0.0);
    // A geometric ladder of ratios, then golden-section refinement around its best rung.
    const double step = std::log(options_.max_ratio / options_.min_ratio) / std::max(1, options_.ratio_steps - 1);
    int best_rung = -1;
    for (int j = 0; j < options_.ratio_steps; ++j) {
      const double r = options_.min_ratio * std::exp(step * j);
      const double v = variance(r);
      if (v < best.variance) best = {v, r}, best_rung = j;
    }
    if (best_rung < 0) return best;
    double lo = std::log(best.ratio) - step, hi = std::log(best.ratio) + step;
    constexpr double kGolden = 0.6180339887498949;
    double a = hi - kGolden * (hi - lo), b = lo + kGolden * (hi - lo);
    double va = variance(std::exp(a)), vb = variance(std::exp(b));
    for (int i = 0; i < kRatioRefineSteps; ++i) {
      if (va < vb) hi = b, b = a, vb = va, a = hi - kGolden * (hi - lo), va = variance(std::exp(a));
      else lo = a, a = b, va = vb, b = lo + kGolden * (hi - lo), vb = variance(std::exp(b));
    }
    const double r = std::exp(va < vb ? a : b), v = std::min(va, vb);
    if (v < best.variance) best = {v, r};
    return best;
  }

  double variance(double ratio) {
    std::fill(sum_.begin(), sum_.end(), 0.0);
    double sum_sq = 0;
    for (size_t i = 0; i < samples_.size(); ++i) {
      const Sample& s = samples_[i];
      const double e = s.log_photo - std::log(s.sky_shading + ratio * sun_[i] + kShadingFloor);
      sum_[s.group] += e;
      sum_sq += e * e;
    }
    double explained = 0;
    for (int g = 0; g < groups_; ++g)
      if (count_[g] > 0) explained += sum_[g] * sum_[g] / count_[g];
    return std::max(0.0, sum_sq - explained) / std::max<size_t>(1, samples_.size());
  }

 private:
  const render::Scene& scene_;
  std::vector<Sample> samples_;
  int groups_;
  double ground_albedo_;
  SunFromShadowsOptions options_;
  std::vector<double> sun_, sum_;
  std::vector<int> count_;
};

}  // namespace

SunFromShadows sun_from_shadows(const render::Scene& scene, const render::PinholeCamera& camera, const cv::Mat& photo,
                                const cv::Mat& albedo, const cv::Mat& sky_basis, const cv::Mat& usable,
                                const SunFromShadowsOptions& options, const std::vector<Eigen::Vector3d>& more_directions) {
  SunFromShadows out;
  if (photo.empty() || photo.size() != albedo.size() || photo.size() != sky_basis.size() || photo.size() != usable.size() ||
      photo.cols != camera.width || photo.rows != camera.height || options.azimuths < 1 || options.elevations_deg.empty() ||
      !(options.min_ratio > 0) || !(options.max_ratio > options.min_ratio) || options.ratio_steps < 2)
    return out;
  const render::PrimaryBuffers primary = render::render_primary_buffers(scene, camera, false);
  std::vector<cv::Point> candidates;
  for (int y = 0; y < photo.rows; ++y)
    for (int x = 0; x < photo.cols; ++x)
      if (usable.at<uint8_t>(y, x) && primary.depth.at<float>(y, x) > 0) candidates.push_back({x, y});
  const size_t max_pixels = static_cast<size_t>(std::max(1, options.max_pixels));
  const size_t stride = std::max<size_t>(1, (candidates.size() + max_pixels - 1) / max_pixels);
  constexpr int kGroups = 3 + kFacadeAzimuthBins;
  std::vector<Sample> samples;
  std::vector<int> group_count(kGroups, 0);
  double ground_albedo_sum = 0;
  int ground_pixels = 0;
  for (size_t i = 0; i < candidates.size(); i += stride) {
    const cv::Point p = candidates[i];
    const double depth = primary.depth.at<float>(p);
    const cv::Vec3f nv = primary.normal.at<cv::Vec3f>(p);
    Sample s;
    // On the primary ray the depth came from (pixel centres at integers, as
    // render_primary_buffers casts them): off it, a point on a grazing ground
    // sinks below the surface and is always in shadow.
    s.point = camera.center_world +
              camera.R_world_from_cam * Vector3d((p.x - camera.cx) / camera.fx, (p.y - camera.cy) / camera.fy, 1.0) * depth;
    s.normal = Vector3d(nv[0], nv[1], nv[2]);
    if (!s.point.allFinite() || !(s.normal.norm() > 0.5)) continue;
    s.normal.normalize();
    if (s.normal.dot(camera.center_world - s.point) < 0) s.normal = -s.normal;  // the side the camera sees
    s.offset = kShadowRayOffset * std::max(1.0, depth);
    const double a = std::max(kMinAlbedoForShading, luminance(albedo.at<cv::Vec3f>(p)));
    s.log_photo = std::log(std::max(kMinLuminance, luminance(photo.at<cv::Vec3f>(p)) / (options.shading_only ? a : 1.0)));
    s.sky_shading = luminance(sky_basis.at<cv::Vec3f>(p)) / std::max(kMinAlbedoForShading, luminance(albedo.at<cv::Vec3f>(p)));
    if (!std::isfinite(s.log_photo) || !std::isfinite(s.sky_shading)) continue;
    s.lower_view = 0.5 * (1.0 - s.normal.y());
    s.group_orientation = orientation_group(s.normal);
    if (s.group_orientation == 0) ground_albedo_sum += luminance(albedo.at<cv::Vec3f>(p)), ++ground_pixels;
    s.group = options.groups == SunFromShadowsOptions::Groups::One              ? 0
              : options.groups == SunFromShadowsOptions::Groups::GroundAndWalls ? (orientation_group(s.normal) == 0 ? 0 : 1)
                                                                                : orientation_group(s.normal);
    ++group_count[s.group];
    samples.push_back(s);
  }
  // Groups too small to have a mean of their own are dropped.
  std::erase_if(samples, [&](const Sample& s) { return group_count[s.group] < kMinGroupPixels; });
  out.pixels = static_cast<int>(samples.size());
  for (int c : group_count) out.groups += c >= kMinGroupPixels;
  if (samples.empty()) return out;

  const double ground_albedo =
      std::clamp(ground_pixels > 0 ? ground_albedo_sum / ground_pixels : kDefaultGroundAlbedo, kMinGroundAlbedo, kMaxGroundAlbedo);
  Search search(scene, std::move(samples), kGroups, ground_albedo, options);
  out.variance_no_sun = search.variance(0.0);
  out.variance_ambient = search.score_ambient().variance;
  double best_variance = std::numeric_limits<double>::infinity(), best_ratio = 0, best_elevation = 0, best_azimuth = 0;
  const auto consider = [&](double elevation, double azimuth) {
    if (elevation <= 0 || elevation >= 90) return;
    const Search::Score s = search.score(sun_direction(elevation, azimuth));
    ++out.hypotheses;
    if (s.variance < best_variance)
      best_variance = s.variance, best_ratio = s.ratio, best_elevation = elevation, best_azimuth = azimuth;
  };
  for (double elevation : options.elevations_deg)
    for (int a = 0; a < options.azimuths; ++a) consider(elevation, 360.0 * a / options.azimuths);
  for (const Vector3d& d : more_directions)
    if (d.allFinite() && d.norm() > 0) {
      const Vector3d u = d.normalized();
      consider(std::asin(std::clamp(u.y(), -1.0, 1.0)) / kDegToRad, std::atan2(u.x(), u.z()) / kDegToRad);
    }
  double azimuth_step = 360.0 / options.azimuths;
  double elevation_step = options.elevations_deg.size() > 1
                              ? std::abs(options.elevations_deg[1] - options.elevations_deg[0])
                              : 10.0;
  for (int round = 0; round < options.refine_rounds; ++round) {
    azimuth_step /= 2, elevation_step /= 2;
    const double e0 = best_elevation, a0 = best_azimuth;
    for (int de = -1; de <= 1; ++de)
      for (int da = -1; da <= 1; ++da)
        if (de != 0 || da != 0) consider(e0 + de * elevation_step, a0 + da * azimuth_step);
  }
  out.variance = best_variance;
  out.found = std::isfinite(best_variance) && best_ratio > 0 &&
              best_variance < (1.0 - options.min_variance_explained) * out.variance_ambient;
  if (std::isfinite(best_variance)) {
    out.best_direction = sun_direction(best_elevation, best_azimuth);
    out.best_irradiance_per_sky = best_ratio;
  }
  if (out.found) {
    out.direction = out.best_direction;
    out.irradiance_per_sky = best_ratio;
  }
  return out;
}

}  // namespace propcam::inference
