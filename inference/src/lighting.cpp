#include "propcam/inference/lighting.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "propcam/capture/image_file.h"
#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/intensity_fit.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/inference/sun_choice.h"
#include "load_once.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"
#include "luminance.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using Clock = std::chrono::steady_clock;

// Source quads are pulled this far toward the camera off the surface they were seen on.
constexpr double kSourceStandOffM = 0.02;
constexpr double kSaturatedLinear = 0.98;
// A channel whose fitted lights carry less energy than this gets no gain.
constexpr double kMinBasisEnergy = 1e-12;
// The per-channel balance may tint the fitted lights this much, no more.
constexpr double kMinChannelGain = 0.25, kMaxChannelGain = 4.0;
// No channel of a seen source's colour drops below this share of its luminance.
constexpr double kMinSourceChannel = 0.05;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

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
// The albedo's scale the seen sky may imply (LightingOptions::
// albedo_scale_from_sky): a mean albedo of 0.5 (the assumed one) times 0.1
// is coal, times 1.9 is snow. Below kMinMeanAlbedo an albedo image is black
// and says nothing of its mean.
constexpr double kMinAlbedoScale = 0.1, kMaxAlbedoScale = 1.9, kMinMeanAlbedo = 1e-4;
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

// The layout's floor and ceiling heights (world y), where it has them.
RoomHeights room_heights(const std::vector<SupportPlane>& planes) {
  RoomHeights h;
  for (const auto& p : planes) {
    if (!(std::abs(p.normal.y()) > 0.5)) continue;
    const double y = -p.offset / p.normal.y();
    if (p.name == "floor") h.floor_y = y;
    if (p.name == "ceiling") h.ceiling_y = y;
  }
  return h;
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

LightingEstimate estimate_lighting(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                                   const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                                   bool indoor, const LightingOptions& options, const SkyEstimate* sky,
                                   const GeometryCues& cues) {
  LightingEstimate out;
  // --- Visible sources: bright connected regions, lifted to 3D with depth.
  auto start = Clock::now();
  const cv::Mat lum = luminance_image(photo_linear);
  double max_lum = 0;
  cv::minMaxLoc(lum, nullptr, &max_lum);
  const double threshold = std::max(options.min_source_luminance, options.bright_fraction_of_max * max_lum);
  cv::Mat bright = lum >= threshold;
  // The light classifier keeps the bright pixels of superpixels that emit
  // (a white wall or a lit floor is bright too).
  std::string detector = "threshold";
  StageReport sources;
  cv::Mat classifier_mask;  // also a feature of the IBL ranking
  if (options.light_classifier != "none") {
    std::string why;
    const std::string path = options.light_classifier.empty() ? default_light_classifier_path() : options.light_classifier;
    // A missing or broken model is reported; the threshold then works alone.
    if (const auto model = load_once<LightClassifier>(path, why)) {
      LightClassifierOptions classifier = options.classifier;
      if (!indoor && options.outdoor_source_threshold) classifier.threshold = *options.outdoor_source_threshold;
      classifier_mask = model->source_mask(photo_linear, classifier, &sources);
      bright &= classifier_mask;
      detector = "classifier";
    } else {
      detector = "threshold (" + why + ")";
    }
  }
  cv::morphologyEx(bright, bright, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(bright, labels, stats, centroids, 8, CV_32S);
  std::vector<std::pair<int, int>> regions;  // (area, label)
  const double min_area = options.min_source_area_fraction * photo_linear.total();
  for (int i = 1; i < n; ++i)
    if (stats.at<int>(i, cv::CC_STAT_AREA) >= std::max(4.0, min_area)) regions.push_back({stats.at<int>(i, cv::CC_STAT_AREA), i});
  std::sort(regions.rbegin(), regions.rend());
  if (static_cast<int>(regions.size()) > options.max_area_lights) regions.resize(options.max_area_lights);
  out.source_mask = cv::Mat::zeros(photo_linear.size(), CV_8U);
  std::vector<Vector3d> colours;  // per light, unit luminance: what the fit may not change
  int on_floor = 0;
  for (const auto& [area, label] : regions) {
    std::vector<Vector3d> points;
    std::vector<cv::Point> pixels;
    Vector3d colour_sum = Vector3d::Zero(), centroid = Vector3d::Zero();
    for (int y = 0; y < labels.rows; ++y)
      for (int x = 0; x < labels.cols; ++x) {
        if (labels.at<int>(y, x) != label) continue;
        const double d = depth.at<float>(y, x);
        if (!(d < render::kSkyDepthM)) continue;  // sky is the environment's
        pixels.push_back({x, y});
        const cv::Vec3f c = photo_linear.at<cv::Vec3f>(y, x);
        colour_sum += Vector3d(c[0], c[1], c[2]);
        const Vector3d dir_cam((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1.0);
        points.push_back(camera.center_world + camera.R_world_from_cam * (dir_cam * d));
        centroid += points.back();
      }
    if (points.empty()) continue;
    // A bright patch lying on the floor is lit, not a lamp (sunlight through
    // a window, a reflection): it stays part of the photo the fit explains.
    if (centroid.y() / points.size() < options.min_source_height_m) {
      ++on_floor;
      continue;
    }
    for (const auto& px : pixels) out.source_mask.at<uint8_t>(px) = 255;
    out.lights.push_back(quad_from_points(points, camera.center_world));
    colours.push_back(unit_luminance_colour(colour_sum));
  }
  sources.stage = "light_sources";
  sources.usable = true;
  sources.why = out.lights.empty() ? "no bright region above the floor: light comes from outside the frame"
                                   : std::to_string(out.lights.size()) + " bright regions above " + std::to_string(threshold);
  sources.seconds = seconds_since(start);
  sources.details["detector"] = detector;
  sources.details["threshold"] = threshold;
  sources.details["regions"] = regions.size();
  sources.details["rejected_on_floor"] = on_floor;
  out.reports.push_back(sources);

  const size_t visible_sources = out.lights.size();
  // --- Out-of-view sources: the ranked library's lights, and hypotheses.
  start = Clock::now();
  StageReport ranking;
  ranking.stage = "ibl_ranking";
  std::vector<LightSource> unseen;
  if (options.ibl_ranker == "none" || ranked_panoramas(options, indoor) <= 0) {
    ranking.usable = false;
    ranking.why = "switched off";
  } else {
    std::string why;
    const std::string path = options.ibl_ranker.empty() ? default_ibl_ranker_path() : options.ibl_ranker;
    if (const auto ranker = load_once<IblRanker>(path, why)) {
      IblFeatureInputs query{photo_linear, camera, cues.orientation, cues.sky_mask, classifier_mask};
      RankedLights ranked = ranked_ibl_candidates(*ranker, ibl_view_features(query), camera, planes, indoor, options);
      unseen = std::move(ranked.lights);
      ranking.why = std::to_string(ranked.matches.size()) + " panoramas ranked best, " + std::to_string(unseen.size()) +
                    " of their lights added";
      ranking.details["matches"] = ranked.matches;
    } else {
      ranking.usable = false;
      ranking.why = "no ranker (" + why + ")";
    }
  }
  const size_t ranked_candidates = unseen.size();
  // A visible sky is a radiance measurement: the environment's weight is 1.
  const bool sky_calibrated = sky && sky->fraction > 0 && sky->mean_colour.maxCoeff() > 0;
  // Outdoors the sun is searched for after the sky's basis render; the
  // ranked panoramas' distant lights lend it their directions.
  const bool search_sun = !indoor && sky_calibrated && options.sun_from_shadows;
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

  // --- Out-of-view light: the photo wrapped onto a sphere.
  start = Clock::now();
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

  // --- Intensities: basis renders of the empty scene, one light at a time,
  //     then the paper's fit of intensities and camera response.
  start = Clock::now();
  const int fit_w = std::min(options.fit_width, camera.width);
  const int fit_h = std::max(1, static_cast<int>(std::lround(static_cast<double>(fit_w) * camera.height / camera.width)));
  const render::PinholeCamera fit_camera = camera.resized(fit_w, fit_h);
  cv::Mat fit_photo, fit_depth, fit_albedo, fit_mask;
  cv::resize(photo_linear, fit_photo, {fit_w, fit_h}, 0, 0, cv::INTER_AREA);
  cv::resize(depth, fit_depth, {fit_w, fit_h}, 0, 0, cv::INTER_NEAREST);
  cv::resize(albedo, fit_albedo, {fit_w, fit_h}, 0, 0, cv::INTER_AREA);
  cv::resize(out.source_mask, fit_mask, {fit_w, fit_h}, 0, 0, cv::INTER_NEAREST);
  render::Scene scene;
  render::DepthMeshOptions mesh_options;
  mesh_options.step_pixels = 1;
  scene.add_mesh(render::mesh_from_depth(fit_depth, fit_albedo, fit_camera, mesh_options), render::Layer::Background);
  // Outdoors the buildings that shade the street nearest the camera are
  // mostly out of the frame: the seen facades are continued out of it.
  std::vector<HiddenFacade>& facades = out.hidden_facades;
  if (!indoor && options.hidden_facades && !cues.normals.empty() && cues.normals.size() == depth.size()) {
    facades = find_hidden_facades(depth, cues.normals, albedo, camera, options.facades);
    render::Mesh hidden = hidden_facade_mesh(facades, fit_depth, fit_camera, options.facades);
    if (!hidden.empty()) scene.add_mesh(hidden, render::Layer::Background);
  }
  if (indoor && options.enclose_room) {
    std::vector<Vector3d> light_positions;
    for (const LightSource& l : out.lights)
      if (l.type != LightSource::Type::Ibl && !distant_light_direction(l, camera.center_world)) light_positions.push_back(l.position);
    out.enclosure = enclose_room(depth, albedo, camera, room_heights(planes), light_positions, options.enclosure);
    render::Mesh enclosure = room_enclosure_mesh(out.enclosure, fit_depth, fit_camera, options.enclosure);
    if (!enclosure.empty()) scene.add_mesh(enclosure, render::Layer::Background);
  }
  scene.commit();
  // Area lights first, the environment last: the same order as out.lights,
  // so basis render i belongs to out.lights[i].
  const render::LightRig rig = make_light_rig(out.lights, true);
  render::RenderSettings settings;
  settings.samples_per_pixel = options.fit_samples_per_pixel;
  settings.max_bounces = options.fit_bounces;
  settings.seed = options.seed;
  int k = rig.count();
  // One set of paths for all lights (render_background_light_images): about
  // half the time of a render per light.
  std::vector<cv::Mat> basis = render::render_background_light_images(scene, fit_camera, rig, settings);
  // Pixels that inform the fit: not the sources themselves, not clipped.
  std::vector<cv::Point> used;
  for (int y = 0; y < fit_h; ++y)
    for (int x = 0; x < fit_w; ++x) {
      const cv::Vec3f c = fit_photo.at<cv::Vec3f>(y, x);
      if (fit_mask.at<uint8_t>(y, x) == 0 && fit_depth.at<float>(y, x) < render::kSkyDepthM && c[0] < kSaturatedLinear && c[1] < kSaturatedLinear && c[2] < kSaturatedLinear)
        used.push_back({x, y});
    }
  // The searched sun (LightingOptions::sun_from_shadows) goes just before the
  // environment, with its own basis render; -1: none.
  int searched_sun = -1;
  double sun_per_sky = 0.0;
  nlohmann::json sun_search_report;
  if (search_sun) {
    const auto search_start = Clock::now();
    cv::Mat usable = cv::Mat::zeros(fit_h, fit_w, CV_8U);  // the fit's pixels
    for (const cv::Point& p : used) usable.at<uint8_t>(p) = 255;
    const SunFromShadows found =
        sun_from_shadows(scene, fit_camera, fit_photo, fit_albedo, basis.back(), usable, options.sun_search, ranked_sun_directions);
    sun_search_report = {{"found", found.found}, {"direction", {found.direction.x(), found.direction.y(), found.direction.z()}},
                         {"irradiance_per_sky", found.irradiance_per_sky},
                         {"best_direction", {found.best_direction.x(), found.best_direction.y(), found.best_direction.z()}},
                         {"best_irradiance_per_sky", found.best_irradiance_per_sky},
                         {"variance_ambient", found.variance_ambient}, {"variance_no_sun", found.variance_no_sun},
                         {"variance", found.variance}, {"pixels", found.pixels}, {"groups", found.groups},
                         {"hypotheses", found.hypotheses}, {"ranked_directions", ranked_sun_directions.size()}};
    const bool tied = options.sun_strength_from_shadows;
    if (found.found || (!tied && found.hypotheses > 0 && found.best_irradiance_per_sky > 0)) {
      LightSource sun;
      sun.type = LightSource::Type::Sun;
      sun.direction = found.found ? found.direction : found.best_direction;
      const int at = k - 1;
      out.lights.insert(out.lights.begin() + at, sun);
      colours.insert(colours.begin() + at, Vector3d::Ones());
      std::vector<cv::Mat> sun_basis =
          render::render_background_light_images(scene, fit_camera, make_light_rig({sun}, true), settings);
      basis.insert(basis.begin() + at, sun_basis.front());
      if (tied) {
        searched_sun = at;
        sun_per_sky = found.irradiance_per_sky;
      }
      ++k;
    }
    sun_search_report["seconds"] = seconds_since(search_start);
  }
  const double basis_seconds = seconds_since(start);
  const auto fit_start = Clock::now();
  // Channel c in 0..2, or 3 for luminance.
  auto basis_value = [&](int i, const cv::Point& p, int c) -> double {
    const cv::Vec3f v = basis[i].at<cv::Vec3f>(p);
    return c < 3 ? v[c] : luminance(v);
  };
  auto photo_value = [&](const cv::Point& p, int c) -> double {
    const cv::Vec3f v = fit_photo.at<cv::Vec3f>(p);
    return c < 3 ? v[c] : luminance(v);
  };
  std::vector<double> lower(k, 0.0), upper(k, std::numeric_limits<double>::infinity());
  // The environment is last; a seen sky is measured: weight 1, or, when it
  // sets the albedo's scale, the scale (see LightingOptions).
  const bool scale_from_sky = sky_calibrated && options.albedo_scale_from_sky;
  if (scale_from_sky) {
    // The scale that brings the seen surfaces' mean albedo to the floor.
    double albedo_sum = 0;
    for (const cv::Point& p : used) albedo_sum += luminance(fit_albedo.at<cv::Vec3f>(p));
    const double mean_albedo = used.empty() ? 0.0 : albedo_sum / static_cast<double>(used.size());
    const double floor_scale = mean_albedo > kMinMeanAlbedo ? options.min_mean_albedo / mean_albedo : kMinAlbedoScale;
    lower[k - 1] = std::clamp(floor_scale, kMinAlbedoScale, kMaxAlbedoScale);
    upper[k - 1] = kMaxAlbedoScale;
  } else if (sky_calibrated) {
    lower[k - 1] = upper[k - 1] = 1.0;
  }
  // Which lights, how bright, and the camera response: the paper's fit
  // (intensity_fit.h) on luminance, the photo as the camera encoded it
  // (fitting each channel on its own lets a light turn a colour no lamp has,
  // e.g. a blue-only sun).
  std::vector<cv::Point> fit_pixels;  // at most max_fit_pixels of them, evenly spread
  const size_t max_pixels = static_cast<size_t>(std::max(1, options.max_fit_pixels));
  const size_t stride = std::max<size_t>(1, (used.size() + max_pixels - 1) / max_pixels);
  for (size_t i = 0; i < used.size(); i += stride) fit_pixels.push_back(used[i]);
  IntensityFitProblem problem;
  problem.lower = lower;
  problem.upper = upper;
  problem.basis.assign(k, std::vector<float>(fit_pixels.size()));
  for (int i = 0; i < k; ++i) {
    for (size_t n = 0; n < fit_pixels.size(); ++n) problem.basis[i][n] = static_cast<float>(basis_value(i, fit_pixels[n], 3));
    problem.noise.push_back(basis_noise(basis[i], {}));
  }
  // The searched sun is weighed with the sky, at the ratio its shadows set:
  // the sky's column becomes sky + ratio * sun, and the sun's own is off.
  if (searched_sun >= 0) {
    for (size_t n = 0; n < fit_pixels.size(); ++n)
      problem.basis[k - 1][n] += static_cast<float>(sun_per_sky * problem.basis[searched_sun][n]);
    problem.lower[searched_sun] = problem.upper[searched_sun] = upper[searched_sun] = 0.0;
  }
  for (const auto& p : fit_pixels)
    problem.target.push_back(capture::linear_to_srgb(static_cast<float>(photo_value(p, 3))));
  // Outdoors there is one sun, and the ground alone cannot tell its
  // azimuth: the fit weighs only the sun the photo calls for (sun_choice.h:
  // the one that lights what the measured sky alone cannot make so bright,
  // and whose shading agrees best with the photo).
  const int suns_begin = static_cast<int>(visible_sources), suns_end = k - 1;
  nlohmann::json sun_choice_report;
  if (!indoor && options.sun_from_shading && suns_end - suns_begin > 1) {
    const std::vector<cv::Mat> suns(basis.begin() + suns_begin, basis.begin() + suns_end);
    const SunChoice choice = choose_sun(suns, basis[k - 1], fit_albedo, fit_photo, used, options.sun_choice);
    sun_choice_report = {{"must_be_sunlit_pixels", choice.must_be_sunlit},
                         {"sunlit_share", choice.sunlit_share},
                         {"agreement", choice.agreement},
                         {"chosen", choice.chosen}};
    for (int i = suns_begin; i < suns_end; ++i)
      if (i != suns_begin + choice.chosen) upper[i] = 0.0;
  }
  IntensityFitOptions fit_options = options.fit;
  fit_options.max_seconds = std::max(0.05, options.fit.max_seconds);
  const auto solve = [&](const std::vector<double>& upper_bounds, const IntensityFitOptions& o) {
    problem.upper = upper_bounds;
    return fit_intensities(problem, o);
  };
  IntensityFitResult chosen = solve(upper, fit_options);
  if (searched_sun >= 0) chosen.weights[searched_sun] = sun_per_sky * chosen.weights[k - 1];
  // Outdoors there is one sun: of the sun hypotheses the fit used, keep the
  // one that alone (with the other lights) explains the photo best.
  int suns_used = 0;
  for (int i = suns_begin; i < suns_end; ++i) suns_used += chosen.weights[i] > 0;
  if (!indoor && suns_used > 1) {
    // The response is settled: each one-sun refit keeps it.
    IntensityFitOptions one_sun = fit_options;
    one_sun.fit_gamma = false;
    one_sun.gamma0 = chosen.gamma;
    IntensityFitResult best;
    double best_error = std::numeric_limits<double>::infinity();
    int iterations = chosen.iterations;
    for (int sun = suns_begin; sun < suns_end; ++sun) {
      if (!(chosen.weights[sun] > 0)) continue;
      std::vector<double> bound = upper;
      for (int i = suns_begin; i < suns_end; ++i)
        if (i != sun) bound[i] = 0.0;
      IntensityFitResult one = solve(bound, one_sun);
      iterations += one.iterations;
      if (one.data_error < best_error) {
        best_error = one.data_error;
        best = std::move(one);
      }
    }
    best.iterations = iterations;
    chosen = std::move(best);
  }
  // The photo, linear under the fitted response: what the gains and the
  // error below compare against (and what the compositor relights).
  const double response = 1.0 / chosen.gamma;
  std::vector<Eigen::Vector3d> photo_response(used.size());  // per used pixel
  for (size_t n = 0; n < used.size(); ++n)
    for (int c = 0; c < 3; ++c)
      photo_response[n][c] =
          std::pow(static_cast<double>(capture::linear_to_srgb(static_cast<float>(photo_value(used[n], c)))), response);
  std::vector<bool> active(k);
  for (int i = 0; i < k; ++i) active[i] = chosen.weights[i] > 0;
  const int max_iterations_used = chosen.iterations;
  const bool converged = chosen.converged;
  double residual = 0, signal = 0;
  // Colour: each light keeps its own colour (a seen source the colour it has
  // in the photo, unseen ones white) and one gain per channel balances the
  // fitted lights against the photo, like a white balance. A measured sky
  // keeps its fitted weight (1, or the albedo's scale).
  const int fixed = sky_calibrated ? k - 1 : -1;
  const double sky_weight = fixed < 0 ? 0.0 : std::clamp(chosen.weights[fixed], lower[fixed], upper[fixed]);
  std::vector<Eigen::Vector3d> weights(k, Eigen::Vector3d::Zero());
  Eigen::Vector3d gains = Eigen::Vector3d::Ones();
  for (int c = 0; c < 3; ++c) {
    double oo = 0, oy = 0;
    for (size_t n = 0; n < used.size(); ++n) {
      const cv::Point& p = used[n];
      double others = 0;
      for (int i = 0; i < k; ++i)
        if (i != fixed && active[i]) others += chosen.weights[i] * colours[i][c] * basis_value(i, p, c);
      const double target = photo_response[n][c] - (fixed >= 0 ? sky_weight * basis_value(fixed, p, c) : 0.0);
      oo += others * others;
      oy += others * target;
    }
    gains[c] = oo > kMinBasisEnergy ? std::clamp(oy / oo, kMinChannelGain, kMaxChannelGain) : 1.0;
  }
  // A searched sun's strength is the shadows' (weighed with the sky): the
  // balance may tint it, not rescale it.
  if (searched_sun >= 0) {
    const double level = luminance(gains);
    if (level > 0) gains /= level;
  }
  // The balance may tint the lights only so far: the estimated albedo already
  // carries the room's colour cast (interreflections), so a strong tint
  // double-counts it (a warm room fitted blue lights, and a grey prop came
  // out blue).
  {
    const double level = luminance(gains);
    const double max_tint = std::max(1.0, options.max_light_tint);
    if (level > 0)
      for (int c = 0; c < 3; ++c) gains[c] = level * std::clamp(gains[c] / level, 1.0 / max_tint, max_tint);
  }
  // Nor against the photo's own cast: a camera's white balance leaves the
  // light it saw neutral or with the cast the photo shows, never the
  // opposite one (a warm hotel room fitted pale-blue lights, and a white
  // plinth came out blue). Each channel's tint lies between neutral and the
  // cast of the fit's pixels.
  if (options.tint_within_photo_cast) {
    Eigen::Vector3d photo_sum = Eigen::Vector3d::Zero();
    for (const auto& v : photo_response) photo_sum += v;
    const double level = luminance(gains), photo_level = luminance(photo_sum);
    if (level > 0 && photo_level > 0)
      for (int c = 0; c < 3; ++c) {
        const double cast = photo_sum[c] / photo_level;
        gains[c] = level * std::clamp(gains[c] / level, std::min(1.0, cast), std::max(1.0, cast));
      }
  }
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < k; ++i)
      weights[i][c] = i == fixed ? sky_weight : (active[i] ? chosen.weights[i] * colours[i][c] * gains[c] : 0.0);
    for (size_t n = 0; n < used.size(); ++n) {
      double predicted = 0;
      for (int i = 0; i < k; ++i) predicted += weights[i][c] * basis_value(i, used[n], c);
      const double observed = photo_response[n][c];
      residual += (observed - predicted) * (observed - predicted);
      signal += observed * observed;
    }
  }
  // The sky's weight is the albedo's scale: lights in the scaled albedo's
  // units render the same image with the sky at its measured radiance.
  if (scale_from_sky) {
    out.albedo_scale = sky_weight;
    for (auto& w : weights) w /= sky_weight;
  }
  bool any_light = false;
  for (int i = 0; i < k; ++i) {
    out.lights[i].intensity = weights[i];
    any_light = any_light || weights[i].maxCoeff() > 0;
  }
  // Pruning (the point of the sparsity prior): lights the fit switched off
  // cost render time and add nothing. The environment is always kept.
  const size_t hypotheses = out.lights.size();
  std::vector<LightSource> kept;
  for (auto& l : out.lights)
    if (l.type == LightSource::Type::Ibl || l.intensity.maxCoeff() > 0) kept.push_back(std::move(l));
  out.lights = std::move(kept);
  if (!any_light && !out.lights.empty()) {
    // A black photo or a fit that switched everything off: keep a dim
    // environment so the prop is still visible rather than pure black.
    out.lights.back().intensity = Eigen::Vector3d::Constant(1.0);
  }
  StageReport fit;
  fit.stage = "light_intensities";
  fit.usable = !used.empty() && any_light;
  fit.why = used.empty() ? "no unclipped pixels to fit" : (any_light ? "fitted to basis renders" : "no light explains the photo");
  fit.iterations = max_iterations_used;
  fit.seconds = seconds_since(start);
  fit.error = signal > 0 ? std::sqrt(residual / signal) : 0.0;  // relative RMS of the re-render
  fit.details = {{"basis_renders", k}, {"resolution", {fit_w, fit_h}}, {"samples_per_pixel", settings.samples_per_pixel},
                 {"converged", converged}, {"termination", chosen.termination}, {"pixels", used.size()},
                 {"fit_pixels", fit_pixels.size()}, {"gamma_solves", chosen.solves},
                 {"camera_response_gamma", chosen.gamma}, {"response_exponent", response},
                 {"albedo_scale", out.albedo_scale},
                 {"fit_error_encoded", chosen.data_error},
                 {"basis_render_seconds", basis_seconds}, {"fit_seconds", seconds_since(fit_start)},
                 {"sun_choice", sun_choice_report}, {"sun_from_shadows", sun_search_report},
                 {"hidden_facades", facades.size()}, {"enclosed", !out.enclosure.empty()},
                 {"visible_sources", visible_sources}, {"hypotheses", hypotheses}, {"kept", out.lights.size()}};
  out.reports.push_back(fit);
  out.gamma = response;
  return out;
}

}  // namespace propcam::inference
