#include "propcam/inference/lighting.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "propcam/inference/light_classifier.h"
#include "propcam/inference/support_planes.h"
#include "load_once.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/scene.h"
#include "light_intensities.h"
#include "luminance.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using Clock = LightingClock;

// Source quads are pulled this far toward the camera off the surface they were seen on.
constexpr double kSourceStandOffM = 0.02;
// No channel of a seen source's colour drops below this share of its luminance.
constexpr double kMinSourceChannel = 0.05;

// Fits a one-sided quad to the 3D points of a source region (normal along
// the direction of least variance, facing the camera).
LightSource quad_from_points(const std::vector<Vector3d>& points, const Vector3d& camera_centre) {
  Vector3d mean = Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Vector3d normal = eig.eigenvectors().col(0);
  if (normal.dot(camera_centre - mean) < 0) normal = -normal;
  Vector3d axis_u = eig.eigenvectors().col(2), axis_v = normal.cross(axis_u);
  double umin = 0, umax = 0, vmin = 0, vmax = 0;
  for (const auto& p : points) {
    const double u = (p - mean).dot(axis_u), v = (p - mean).dot(axis_v);
    umin = std::min(umin, u), umax = std::max(umax, u), vmin = std::min(vmin, v), vmax = std::max(vmax, v);
  }
  // Keep quads from degenerating to lines.
  const double min_extent = 0.02;
  if (umax - umin < min_extent) umin -= min_extent / 2, umax += min_extent / 2;
  if (vmax - vmin < min_extent) vmin -= min_extent / 2, vmax += min_extent / 2;
  LightSource l;
  l.type = LightSource::Type::Area;
  const Vector3d centre = mean + normal * kSourceStandOffM;
  l.corner = centre + umin * axis_u + vmin * axis_v;
  l.edge_u = (umax - umin) * axis_u;
  l.edge_v = (vmax - vmin) * axis_v;
  if (l.edge_u.cross(l.edge_v).dot(normal) < 0) std::swap(l.edge_u, l.edge_v);
  l.position = l.corner + 0.5 * (l.edge_u + l.edge_v);
  return l;
}

// Distant lights (suns, sky patches) are quads this far away.
constexpr double kSunDistanceM = 1000.0;
constexpr double kSunDiameterRad = 0.5 * std::numbers::pi / 180.0;
// Ranked panoramas' lamps and windows, by distance class (ibl_library.h).
constexpr double kCloseLightM = 1.0, kMediumLightM = 2.5, kFarLightM = 5.0;
constexpr double kMinLampSideM = 0.1, kMaxLampSideM = 2.0;
// A ranked light kept off the wall or ceiling its ray meets.
constexpr double kWallStandOffM = 0.05;
// Ranked lights further below the horizon than this lie on the floor.
constexpr double kMinRankedLightUp = -0.3;

// How many ranked panoramas lend their lights.
int ranked_panoramas(const LightingOptions& options, bool indoor) {
  if (options.ibl_candidates >= 0) return options.ibl_candidates;
  return indoor ? options.ibl_candidates_indoor : options.ibl_candidates_outdoor;
}

// A square emitter `side` across, `distance` from `from` along unit `dir`,
// emitting back toward `from`.
LightSource facing_quad(const Vector3d& from, const Vector3d& dir, double distance, double side) {
  const Vector3d centre = from + dir * distance;
  Vector3d u = dir.cross(Vector3d::UnitY());
  if (u.norm() < 1e-6) u = Vector3d::UnitX();  // straight up or down
  u.normalize();
  const Vector3d v = u.cross(dir);
  LightSource l;
  l.type = LightSource::Type::Area;
  l.edge_u = side * u;
  l.edge_v = side * v;
  if (l.edge_u.cross(l.edge_v).dot(dir) > 0) std::swap(l.edge_u, l.edge_v);  // face the scene
  l.corner = centre - 0.5 * (l.edge_u + l.edge_v);
  l.position = centre;
  return l;
}

Vector3d unit_luminance_colour(const Vector3d& rgb) {
  const double lum = luminance(rgb);
  if (!(lum > 0)) return Vector3d::Ones();
  return (rgb / lum).cwiseMax(kMinSourceChannel);
}

}  // namespace

cv::Mat environment_from_photo(const cv::Mat& photo_linear, const render::PinholeCamera& camera, int width) {
  width = std::max(8, width);
  const int height = width / 2;
  // A heavily blurred copy: the environment is seen only through glossy and diffuse reflection.
  cv::Mat small;
  cv::resize(photo_linear, small, cv::Size(64, std::max(2, 64 * photo_linear.rows / std::max(1, photo_linear.cols))),
             0, 0, cv::INTER_AREA);
  cv::GaussianBlur(small, small, cv::Size(0, 0), 2.0);
  const double sx = static_cast<double>(small.cols) / camera.width, sy = static_cast<double>(small.rows) / camera.height;
  cv::Mat env(height, width, CV_32FC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const Eigen::Vector3f dw = render::EnvironmentLight::uv_to_direction((x + 0.5f) / width, (y + 0.5f) / height);
      Vector3d dc = camera.R_world_from_cam.transpose() * dw.cast<double>();
      dc.z() = std::abs(dc.z());  // behind the camera: mirror
      dc.z() = std::max(dc.z(), 0.05);
      const double u = std::clamp((camera.fx * dc.x() / dc.z() + camera.cx + 0.5) * sx, 0.0, small.cols - 1.0);
      const double v = std::clamp((camera.fy * dc.y() / dc.z() + camera.cy + 0.5) * sy, 0.0, small.rows - 1.0);
      env.at<cv::Vec3f>(y, x) = small.at<cv::Vec3f>(static_cast<int>(v), static_cast<int>(u));
    }
  return env;
}

cv::Mat environment_with_sky(const cv::Mat& photo_linear, const render::PinholeCamera& camera, int width,
                             const SkyEstimate& sky) {
  cv::Mat env = environment_from_photo(photo_linear, camera, width);
  const cv::Vec3f colour(static_cast<float>(sky.mean_colour.x()), static_cast<float>(sky.mean_colour.y()),
                         static_cast<float>(sky.mean_colour.z()));
  for (int y = 0; y < env.rows; ++y) {
    const float up = render::EnvironmentLight::uv_to_direction(0.5f, (y + 0.5f) / env.rows).y();
    if (up <= 0.f) continue;
    for (int x = 0; x < env.cols; ++x) env.at<cv::Vec3f>(y, x) = colour;
  }
  return env;
}

std::vector<LightSource> out_of_view_candidates(const render::PinholeCamera& camera,
                                                const std::vector<SupportPlane>& planes, bool indoor,
                                                const LightingOptions& options) {
  std::vector<LightSource> out;
  // Horizontal frame turned with the camera: "ahead" is the view direction made level.
  Vector3d ahead = camera.R_world_from_cam.col(2);
  ahead.y() = 0;
  if (ahead.norm() < 1e-6) ahead = -Vector3d::UnitZ();
  ahead.normalize();
  const Vector3d side = ahead.cross(Vector3d::UnitY()).normalized();
  if (indoor) {
    double ceiling = 2.7;
    for (const auto& p : planes)
      if (p.name == "ceiling") ceiling = p.offset;
    const double half = options.ceiling_panel_m / 2;
    const int n = std::max(1, options.ceiling_grid);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        // From 1 m behind the camera to 4 m ahead, 3 m wide.
        const double along = n == 1 ? 1.0 : -1.0 + 5.0 * i / (n - 1);
        const double across = n == 1 ? 0.0 : -1.5 + 3.0 * j / (n - 1);
        Vector3d centre = along * ahead + across * side;
        // Keep panels inside the fitted walls.
        for (const auto& p : planes) {
          if (p.name == "floor" || p.name == "ceiling") continue;
          const double d = p.normal.dot(centre) + p.offset;  // > 0 inside
          if (d < half + 0.05) centre += p.normal * (half + 0.05 - d);
        }
        centre.y() = ceiling - 0.02;
        LightSource l;
        l.type = LightSource::Type::Area;
        l.corner = centre - half * ahead - half * side;
        l.edge_u = 2 * half * side;  // side x ahead points down
        l.edge_v = 2 * half * ahead;
        if (l.edge_u.cross(l.edge_v).y() > 0) std::swap(l.edge_u, l.edge_v);
        l.position = centre;
        out.push_back(l);
      }
  } else {
    // Suns as small far quads (0.5 degree across) facing the scene.
    for (int a = 0; a < options.sun_azimuths; ++a)
      for (double elevation_deg : options.sun_elevations_deg) {
        const double az = 2 * std::numbers::pi * a / options.sun_azimuths;
        const double el = elevation_deg * std::numbers::pi / 180.0;
        const Vector3d dir = std::cos(el) * (std::cos(az) * ahead + std::sin(az) * side) + std::sin(el) * Vector3d::UnitY();
        out.push_back(facing_quad(camera.center_world, dir, kSunDistanceM, kSunDistanceM * kSunDiameterRad));
      }
  }
  return out;
}

RankedLights ranked_ibl_candidates(const IblRanker& ranker, const IblViewFeatures& features,
                                   const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                                   bool indoor, const LightingOptions& options) {
  RankedLights out;
  const int k = ranked_panoramas(options, indoor);
  if (k == 0) return out;
  const Eigen::Matrix3d photo_heading = heading_frame(camera.R_world_from_cam);
  for (const IblMatch& m : ranker.rank(features, indoor ? SceneKind::Indoor : SceneKind::Outdoor, k)) {
    const IblRankerEntry& entry = ranker.entries[m.entry];
    const IblRankerView& view = ranker.views[m.view];
    int added = 0;
    for (const IblLightRegion& region : entry.lights) {
      if (added >= options.max_lights_per_ibl) break;
      const Vector3d dir = panorama_to_world(region.direction, view.heading, photo_heading).normalized();
      if (!dir.allFinite() || dir.y() < kMinRankedLightUp) continue;
      if (region.distance == LightDistance::Infinite) {
        // A disc of the region's solid angle, seen from the scene.
        const double diameter = std::max(kSunDiameterRad, 2.0 * std::sqrt(region.solid_angle_sr / std::numbers::pi));
        out.lights.push_back(facing_quad(camera.center_world, dir, kSunDistanceM, kSunDistanceM * diameter));
      } else {
        double distance = region.distance == LightDistance::Close ? kCloseLightM
                          : region.distance == LightDistance::Medium ? kMediumLightM : kFarLightM;
        // Inside the room: stop short of the first wall or ceiling the ray
        // meets, and lie on it (a ceiling panel shines down, not at the camera).
        const SupportPlane* on = nullptr;
        for (const auto& p : planes) {
          if (p.name == "floor") continue;
          const double inside = p.normal.dot(camera.center_world) + p.offset, toward = p.normal.dot(dir);
          if (inside > 0 && toward < 0 && -inside / toward - kWallStandOffM < distance) {
            distance = std::max(kWallStandOffM, -inside / toward - kWallStandOffM);
            on = &p;
          }
        }
        const double side = std::clamp(distance * std::sqrt(region.solid_angle_sr), kMinLampSideM, kMaxLampSideM);
        const Vector3d centre = camera.center_world + dir * distance;
        const Vector3d emits = on ? on->normal : Vector3d(-dir);  // a plane's normal faces the camera's side
        out.lights.push_back(facing_quad(centre + emits, -emits, 1.0, side));
      }
      ++added;
    }
    out.matches.push_back({{"panorama", entry.name}, {"score", m.score}, {"view_yaw_deg", view.yaw_deg},
                           {"view_pitch_deg", view.pitch_deg}, {"lights", added}});
  }
  return out;
}

namespace {

// --- Visible sources.

// The pixels bright enough to be a light source, and how they were found.
struct BrightPixels {
  cv::Mat mask;  // CV_8U
  double threshold = 0.0;
  std::string detector = "threshold";
  cv::Mat classifier_mask;  // also a feature of the IBL ranking
  StageReport report;       // the classifier fills in what it did
};

// Pixels above the brightness threshold. The light classifier keeps the
// bright pixels of superpixels that emit (a white wall or a lit floor is
// bright too).
BrightPixels bright_pixels(const cv::Mat& photo_linear, bool indoor, const LightingOptions& options) {
  BrightPixels b;
  const cv::Mat lum = luminance_image(photo_linear);
  double max_lum = 0;
  cv::minMaxLoc(lum, nullptr, &max_lum);
  b.threshold = std::max(options.min_source_luminance, options.bright_fraction_of_max * max_lum);
  b.mask = lum >= b.threshold;
  if (options.light_classifier != "none") {
    std::string why;
    const std::string path = options.light_classifier.empty() ? default_light_classifier_path() : options.light_classifier;
    // A missing or broken model is reported; the threshold then works alone.
    if (const auto model = load_once<LightClassifier>(path, why)) {
      LightClassifierOptions classifier = options.classifier;
      if (!indoor && options.outdoor_source_threshold) classifier.threshold = *options.outdoor_source_threshold;
      b.classifier_mask = model->source_mask(photo_linear, classifier, &b.report);
      b.mask &= b.classifier_mask;
      b.detector = "classifier";
    } else {
      b.detector = "threshold (" + why + ")";
    }
  }
  cv::morphologyEx(b.mask, b.mask, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));
  return b;
}

// The connected bright regions large enough to be a source, largest first
// and at most max_area_lights of them, as (area, label) in `labels`.
std::vector<std::pair<int, int>> bright_regions(const cv::Mat& bright, size_t photo_pixels,
                                                const LightingOptions& options, cv::Mat& labels) {
  cv::Mat stats, centroids;
  const int n = cv::connectedComponentsWithStats(bright, labels, stats, centroids, 8, CV_32S);
  std::vector<std::pair<int, int>> regions;
  const double min_area = options.min_source_area_fraction * photo_pixels;
  for (int i = 1; i < n; ++i)
    if (stats.at<int>(i, cv::CC_STAT_AREA) >= std::max(4.0, min_area)) regions.push_back({stats.at<int>(i, cv::CC_STAT_AREA), i});
  std::sort(regions.rbegin(), regions.rend());
  if (static_cast<int>(regions.size()) > options.max_area_lights) regions.resize(options.max_area_lights);
  return regions;
}

// A region's pixels short of the sky, lifted to 3D with depth.
struct LiftedRegion {
  std::vector<Vector3d> points;
  std::vector<cv::Point> pixels;
  Vector3d colour_sum = Vector3d::Zero(), centroid = Vector3d::Zero();
};

LiftedRegion lift_region(const cv::Mat& labels, int label, const cv::Mat& photo_linear, const cv::Mat& depth,
                         const render::PinholeCamera& camera) {
  LiftedRegion r;
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      if (labels.at<int>(y, x) != label) continue;
      const double d = depth.at<float>(y, x);
      if (!(d < render::kSkyDepthM)) continue;  // sky is the environment's
      r.pixels.push_back({x, y});
      const cv::Vec3f c = photo_linear.at<cv::Vec3f>(y, x);
      r.colour_sum += Vector3d(c[0], c[1], c[2]);
      const Vector3d dir_cam((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1.0);
      r.points.push_back(camera.center_world + camera.R_world_from_cam * (dir_cam * d));
      r.centroid += r.points.back();
    }
  return r;
}

// Bright connected regions, lifted to 3D with depth, become quad lights of
// their seen colour (in out.lights, colours and out.source_mask). Returns
// the classifier's mask for the IBL ranking.
cv::Mat add_visible_sources(const cv::Mat& photo_linear, const cv::Mat& depth, const render::PinholeCamera& camera,
                            bool indoor, const LightingOptions& options, LightingEstimate& out,
                            std::vector<Vector3d>& colours) {
  const auto start = Clock::now();
  BrightPixels bright = bright_pixels(photo_linear, indoor, options);
  cv::Mat labels;
  const std::vector<std::pair<int, int>> regions = bright_regions(bright.mask, photo_linear.total(), options, labels);
  out.source_mask = cv::Mat::zeros(photo_linear.size(), CV_8U);
  int on_floor = 0;
  for (const auto& [area, label] : regions) {
    const LiftedRegion r = lift_region(labels, label, photo_linear, depth, camera);
    if (r.points.empty()) continue;
    // A bright patch lying on the floor is lit, not a lamp (sunlight through
    // a window, a reflection): it stays part of the photo the fit explains.
    if (r.centroid.y() / r.points.size() < options.min_source_height_m) {
      ++on_floor;
      continue;
    }
    for (const auto& px : r.pixels) out.source_mask.at<uint8_t>(px) = 255;
    out.lights.push_back(quad_from_points(r.points, camera.center_world));
    colours.push_back(unit_luminance_colour(r.colour_sum));
  }
  StageReport& sources = bright.report;
  sources.stage = "light_sources";
  sources.usable = true;
  sources.why = out.lights.empty() ? "no bright region above the floor: light comes from outside the frame"
                                   : std::to_string(out.lights.size()) + " bright regions above " + std::to_string(bright.threshold);
  sources.seconds = seconds_since(start);
  sources.details["detector"] = bright.detector;
  sources.details["threshold"] = bright.threshold;
  sources.details["regions"] = regions.size();
  sources.details["rejected_on_floor"] = on_floor;
  out.reports.push_back(sources);
  return bright.classifier_mask;
}

// --- Out-of-view sources.

// The lights of the library's panoramas ranked best for this view; `ranking`
// says which, or why none.
std::vector<LightSource> ranked_library_lights(const cv::Mat& photo_linear, const render::PinholeCamera& camera,
                                               const std::vector<SupportPlane>& planes, bool indoor,
                                               const LightingOptions& options, const GeometryCues& cues,
                                               const cv::Mat& classifier_mask, StageReport& ranking) {
  std::vector<LightSource> lights;
  if (options.ibl_ranker == "none" || ranked_panoramas(options, indoor) <= 0) {
    ranking.usable = false;
    ranking.why = "switched off";
    return lights;
  }
  std::string why;
  const std::string path = options.ibl_ranker.empty() ? default_ibl_ranker_path() : options.ibl_ranker;
  if (const auto ranker = load_once<IblRanker>(path, why)) {
    IblFeatureInputs query{photo_linear, camera, cues.orientation, cues.sky_mask, classifier_mask};
    RankedLights ranked = ranked_ibl_candidates(*ranker, ibl_view_features(query), camera, planes, indoor, options);
    lights = std::move(ranked.lights);
    ranking.why = std::to_string(ranked.matches.size()) + " panoramas ranked best, " + std::to_string(lights.size()) +
                  " of their lights added";
    ranking.details["matches"] = ranked.matches;
  } else {
    ranking.usable = false;
    ranking.why = "no ranker (" + why + ")";
  }
  return lights;
}

// The ranked library's lights and the out-of-view hypotheses join
// out.lights (white: tinted only by the fit's global balance). When the sun
// is searched for instead, the ranked distant lights only lend it their
// directions, which are returned.
std::vector<Vector3d> add_unseen_sources(const cv::Mat& photo_linear, const render::PinholeCamera& camera,
                                         const std::vector<SupportPlane>& planes, bool indoor,
                                         const LightingOptions& options, const GeometryCues& cues,
                                         const cv::Mat& classifier_mask, bool search_sun, LightingEstimate& out,
                                         std::vector<Vector3d>& colours) {
  const auto start = Clock::now();
  StageReport ranking;
  ranking.stage = "ibl_ranking";
  std::vector<LightSource> unseen =
      ranked_library_lights(photo_linear, camera, planes, indoor, options, cues, classifier_mask, ranking);
  const size_t ranked_candidates = unseen.size();
  std::vector<Vector3d> ranked_sun_directions;
  if (search_sun) {
    for (const auto& l : unseen)
      if (const auto d = distant_light_direction(l, camera.center_world)) ranked_sun_directions.push_back(*d);
    unseen.clear();
  } else if (options.keep_hypotheses || unseen.empty()) {
    for (auto& candidate : out_of_view_candidates(camera, planes, indoor, options)) unseen.push_back(candidate);
  }
  ranking.seconds = seconds_since(start);
  ranking.details["ranked_candidates"] = ranked_candidates;
  ranking.details["hypotheses"] = search_sun ? 0 : unseen.size() - ranked_candidates;
  out.reports.push_back(ranking);
  for (auto& candidate : unseen) {
    out.lights.push_back(candidate);
    colours.push_back(Vector3d::Ones());  // unseen: white, tinted only by the global balance below
  }
  return ranked_sun_directions;
}

// --- Out-of-view light a sun patch shows: the sun through a window above
//     the patch (white, like every unseen light). Returns the albedo the fit
//     uses: the one passed in, or a copy without the patch's light.
cv::Mat add_sun_through_window(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                               const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                               bool indoor, const LightingOptions& options, const GeometryCues& cues,
                               LightingEstimate& out, std::vector<Vector3d>& colours) {
  const auto start = Clock::now();
  StageReport report;
  report.stage = "sun_patch";
  if (!indoor || !options.sun_from_patch) {
    report.usable = false;
    report.why = indoor ? "switched off" : "outdoors: the sun is the sky's";
    out.reports.push_back(report);
    return albedo;
  }
  const SunPatch patch =
      find_sun_patch(photo_linear, depth, camera, room_heights(planes), options.sun_patch, cues.orientation);
  report.usable = patch.found;
  report.why = patch.why;
  report.details = patch.details;
  cv::Mat fit_albedo = albedo;
  if (patch.found) {
    fit_albedo = albedo.clone();
    report.details["albedo_divided_by"] = take_sun_patch_out_of_albedo(fit_albedo, patch);
    out.albedo = fit_albedo;
    out.windows.push_back(patch.window);
    LightSource sun;
    sun.type = LightSource::Type::Sun;
    sun.direction = patch.sun_direction;
    sun.through_windows = true;
    out.lights.push_back(sun);
    colours.push_back(Vector3d::Ones());
  }
  report.seconds = seconds_since(start);
  out.reports.push_back(report);
  return fit_albedo;
}

// --- Out-of-view light the walls show: a lamp where the falloff of their
//     shading points (white, like every unseen light).
void add_lamp_from_lit_walls(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                             const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                             bool indoor, const LightingOptions& options, LightingEstimate& out,
                             std::vector<Vector3d>& colours) {
  const auto start = Clock::now();
  StageReport report;
  report.stage = "lit_wall_lamp";
  if (!indoor || !options.lamp_from_lit_walls) {
    report.usable = false;
    report.why = indoor ? "switched off" : "outdoors";
    out.reports.push_back(report);
    return;
  }
  const LitWallLamp lamp =
      find_lit_wall_lamp(photo_linear, depth, albedo, camera, planes, out.source_mask, options.lit_wall_lamp);
  report.usable = lamp.found;
  report.why = lamp.why;
  report.details = lamp.details;
  if (lamp.found) {
    LightSource bulb;
    bulb.type = LightSource::Type::Point;
    bulb.position = lamp.position;
    bulb.radius = options.lit_wall_lamp.bulb_radius_m;
    out.lights.push_back(bulb);
    colours.push_back(Vector3d::Ones());
  }
  report.seconds = seconds_since(start);
  out.reports.push_back(report);
}

// --- Out-of-view light: the photo wrapped onto a sphere (the sky's colour
//     above the horizon when it was seen). It is always the last light.
void add_environment(const cv::Mat& photo_linear, const render::PinholeCamera& camera, const LightingOptions& options,
                     const SkyEstimate* sky, bool sky_calibrated, LightingEstimate& out, std::vector<Vector3d>& colours) {
  const auto start = Clock::now();
  LightSource ibl;
  ibl.type = LightSource::Type::Ibl;
  ibl.environment = sky_calibrated ? environment_with_sky(photo_linear, camera, options.environment_width, *sky)
                                   : environment_from_photo(photo_linear, camera, options.environment_width);
  out.lights.push_back(ibl);
  colours.push_back(Vector3d::Ones());  // the map carries its own colours
  StageReport env;
  env.stage = "environment";
  env.why = sky_calibrated ? "sky colour above the horizon, photo wrapped below (measured: weight 1)"
                           : "photo wrapped onto a sphere (Khan et al.)";
  env.seconds = seconds_since(start);
  out.reports.push_back(env);
}

}  // namespace

LightingEstimate estimate_lighting(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                                   const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                                   bool indoor, const LightingOptions& options, const SkyEstimate* sky,
                                   const GeometryCues& cues) {
  LightingEstimate out;
  std::vector<Vector3d> colours;  // per light, unit luminance: what the fit may not change
  // --- Visible sources: bright connected regions, lifted to 3D with depth.
  const cv::Mat classifier_mask = add_visible_sources(photo_linear, depth, camera, indoor, options, out, colours);
  const size_t visible_sources = out.lights.size();
  // A visible sky is a radiance measurement: the environment's weight is 1.
  const bool sky_calibrated = sky && sky->fraction > 0 && sky->mean_colour.maxCoeff() > 0;
  // Outdoors the sun is searched for after the sky's basis render; the
  // ranked panoramas' distant lights lend it their directions.
  const bool search_sun = !indoor && sky_calibrated && options.sun_from_shadows;
  // --- Out-of-view sources: the ranked library's lights, and hypotheses.
  const std::vector<Vector3d> ranked_sun_directions =
      add_unseen_sources(photo_linear, camera, planes, indoor, options, cues, classifier_mask, search_sun, out, colours);
  // --- Out-of-view light a sun patch on the floor shows.
  const cv::Mat fit_albedo =
      add_sun_through_window(photo_linear, depth, albedo, camera, planes, indoor, options, cues, out, colours);
  // --- Out-of-view light the walls' shading shows.
  add_lamp_from_lit_walls(photo_linear, depth, fit_albedo, camera, planes, indoor, options, out, colours);
  // --- Out-of-view light: the photo wrapped onto a sphere.
  add_environment(photo_linear, camera, options, sky, sky_calibrated, out, colours);
  // --- Intensities: basis renders of the empty scene, one light at a time,
  //     then the paper's fit of intensities and camera response.
  const LightFitInputs inputs{photo_linear, depth, fit_albedo, camera, planes, indoor, options, cues,
                              sky_calibrated, search_sun, ranked_sun_directions, visible_sources};
  fit_light_intensities(inputs, colours, out);
  // The fit switched the patch's sun off: the scene keeps no window and the
  // albedo it had.
  if (std::none_of(out.lights.begin(), out.lights.end(), [](const LightSource& l) { return l.through_windows; })) {
    out.windows.clear();
    out.albedo = cv::Mat();
  }
  return out;
}

}  // namespace propcam::inference
