#include "propcam/inference/ibl_library.h"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <stdexcept>

#include "propcam/capture/image_file.h"
#include "luminance.h"

namespace propcam::inference {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// A light region must be brighter than both: a multiple of the mean radiance
// (so a uniformly lit panorama has no "light") and a fraction of the peak (so
// a sun does not drag the whole bright sky into its region).
constexpr double kMeanRadianceMultiple = 5.0;
constexpr double kPeakRadianceFraction = 0.05;
// Regions carrying less power than this are specular glints, not lights.
constexpr double kMinPowerShare = 0.01;
// Distance heuristic: a typical luminaire (ceiling panel, lamp shade, window
// pane) has ~0.36 m^2 of emitting area, so a region of solid angle W is about
// sqrt(A / W) metres away. Outdoors, anything at or above the horizon (sun,
// sky, clouds) is infinitely far for relighting a prop.
constexpr double kTypicalLightArea_m2 = 0.36;
constexpr double kCloseLimit_m = 1.5;
constexpr double kMediumLimit_m = 4.0;
constexpr double kHorizonSlack = -0.09;  // sin(-5 deg): horizon haze still belongs to the sky
// The sun disc is drawn with a 1.5 deg radius (the real one is 0.27 deg) so
// that it covers texels at the stored 256-wide resolution (1.4 deg/texel).
constexpr double kSunDiscRadius_rad = 1.5 * kDegToRad;
constexpr int kSkySupersampling = 4;
constexpr int kRoomSupersampling = 2;
constexpr double kPanelHalfSize_m = 0.3;
constexpr double kCameraHeight_m = 1.5;

// Same convention as render::EnvironmentLight::uv_to_direction.
Eigen::Vector3d uv_to_direction(double u, double v) {
  const double phi = u * 2.0 * kPi - kPi;
  const double theta = v * kPi;
  const double s = std::sin(theta);
  return {s * std::sin(phi), std::cos(theta), -s * std::cos(phi)};
}

// Solid angle of one texel in row y.
double texel_solid_angle(int y, int rows, int cols) {
  const double theta0 = kPi * y / rows, theta1 = kPi * (y + 1) / rows;
  return (2.0 * kPi / cols) * (std::cos(theta0) - std::cos(theta1));
}

int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

LightDistance classify_distance(const Eigen::Vector3d& direction, double solid_angle, SceneKind kind) {
  if (kind == SceneKind::Outdoor && direction.y() >= kHorizonSlack) return LightDistance::Infinite;
  const double distance = std::sqrt(kTypicalLightArea_m2 / std::max(solid_angle, 1e-12));
  if (distance < kCloseLimit_m) return LightDistance::Close;
  if (distance < kMediumLimit_m) return LightDistance::Medium;
  return LightDistance::Far;
}

// Deterministic uniform [0,1) from a 64-bit LCG (independent of the standard library).
struct Lcg {
  std::uint64_t state;
  double next() {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) / 9007199254740992.0;
  }
};

}  // namespace

const char* to_string(SceneKind kind) { return kind == SceneKind::Indoor ? "indoor" : "outdoor"; }

const char* to_string(LightDistance distance) {
  switch (distance) {
    case LightDistance::Close: return "close";
    case LightDistance::Medium: return "medium";
    case LightDistance::Far: return "far";
    case LightDistance::Infinite: return "infinite";
  }
  return "infinite";
}

cv::Mat sanitize_latlong(const cv::Mat& latlong) {
  if (latlong.empty() || latlong.depth() != CV_32F || latlong.channels() != 3)
    throw std::invalid_argument("panorama must be a non-empty 3-channel float image");
  cv::Mat out = latlong.clone();
  for (int y = 0; y < out.rows; ++y) {
    float* p = out.ptr<float>(y);
    for (int i = 0; i < out.cols * 3; ++i)
      if (!std::isfinite(p[i]) || p[i] < 0.f) p[i] = 0.f;
  }
  return out;
}

cv::Mat downsample_latlong(const cv::Mat& latlong, int width) {
  if (width < 4) throw std::invalid_argument("panorama width must be at least 4");
  cv::Mat clean = sanitize_latlong(latlong);
  cv::Mat out;
  // Area averaging when shrinking; enlarging a small map interpolates.
  cv::resize(clean, out, cv::Size(width, width / 2), 0, 0, width < clean.cols ? cv::INTER_AREA : cv::INTER_LINEAR);
  return out;
}

cv::Mat replace_overflowed_texels(const cv::Mat& latlong) {
  if (latlong.empty() || latlong.type() != CV_32FC3) throw std::invalid_argument("panorama must be a non-empty CV_32FC3 image");
  float brightest = 0;
  for (int i = 0; i < static_cast<int>(latlong.total()); ++i)
    for (float v : latlong.ptr<cv::Vec3f>()[i].val)
      if (std::isfinite(v)) brightest = std::max(brightest, v);
  cv::Mat out = latlong.clone();
  for (int i = 0; i < static_cast<int>(out.total()); ++i) {
    cv::Vec3f& t = out.ptr<cv::Vec3f>()[i];
    const auto overflowed = [](float v) { return std::isinf(v) && v > 0; };
    if (overflowed(t[0]) || overflowed(t[1]) || overflowed(t[2])) t = cv::Vec3f::all(brightest);
  }
  return out;
}

IblLibraryOptions::ExtraPanorama parse_extra_panorama(const std::string& spec) {
  const size_t eq = spec.rfind('=');
  if (eq == std::string::npos || eq == 0)
    throw std::invalid_argument("panorama '" + spec + "': expected PATH=indoor or PATH=outdoor");
  const std::string kind = spec.substr(eq + 1);
  if (kind != "indoor" && kind != "outdoor")
    throw std::invalid_argument("panorama '" + spec + "': the label must be indoor or outdoor, not '" + kind + "'");
  return {spec.substr(0, eq), kind == "indoor" ? SceneKind::Indoor : SceneKind::Outdoor};
}

std::vector<IblLightRegion> find_light_regions(const cv::Mat& latlong_in, SceneKind kind) {
  const cv::Mat latlong = sanitize_latlong(latlong_in);
  const int rows = latlong.rows, cols = latlong.cols;
  std::vector<double> lum(static_cast<size_t>(rows) * cols);
  double total_power = 0, total_solid_angle = 0, peak = 0;
  for (int y = 0; y < rows; ++y) {
    const double w = texel_solid_angle(y, rows, cols);
    for (int x = 0; x < cols; ++x) {
      const double l = luminance(latlong.at<cv::Vec3f>(y, x));
      lum[static_cast<size_t>(y) * cols + x] = l;
      total_power += l * w;
      total_solid_angle += w;
      peak = std::max(peak, l);
    }
  }
  if (!(total_power > 0)) return {};
  const double threshold = std::max(kMeanRadianceMultiple * total_power / total_solid_angle,
                                    kPeakRadianceFraction * peak);

  // Union-find over bright texels, 4-connected, wrapping across the seam.
  std::vector<int> parent(lum.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto bright = [&](int y, int x) { return lum[static_cast<size_t>(y) * cols + x] > threshold; };
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      if (!bright(y, x)) continue;
      const int i = y * cols + x;
      const int right = (x + 1) % cols;
      if (bright(y, right)) parent[find_root(parent, i)] = find_root(parent, y * cols + right);
      if (y + 1 < rows && bright(y + 1, x)) parent[find_root(parent, i)] = find_root(parent, (y + 1) * cols + x);
    }

  struct Accumulator {
    Eigen::Vector3d weighted_direction = Eigen::Vector3d::Zero();
    double power = 0, solid_angle = 0;
  };
  std::vector<int> root_to_region(lum.size(), -1);
  std::vector<Accumulator> acc;
  for (int y = 0; y < rows; ++y) {
    const double w = texel_solid_angle(y, rows, cols);
    for (int x = 0; x < cols; ++x) {
      if (!bright(y, x)) continue;
      const int root = find_root(parent, y * cols + x);
      if (root_to_region[root] < 0) {
        root_to_region[root] = static_cast<int>(acc.size());
        acc.emplace_back();
      }
      Accumulator& a = acc[root_to_region[root]];
      const double p = lum[static_cast<size_t>(y) * cols + x] * w;
      a.weighted_direction += p * uv_to_direction((x + 0.5) / cols, (y + 0.5) / rows);
      a.power += p;
      a.solid_angle += w;
    }
  }
  std::vector<IblLightRegion> regions;
  for (const Accumulator& a : acc) {
    const double share = a.power / total_power;
    if (share < kMinPowerShare || a.weighted_direction.norm() <= 0) continue;
    IblLightRegion r;
    r.direction = a.weighted_direction.normalized();
    r.solid_angle_sr = a.solid_angle;
    r.power_share = share;
    r.distance = classify_distance(r.direction, r.solid_angle_sr, kind);
    regions.push_back(r);
  }
  std::sort(regions.begin(), regions.end(),
            [](const IblLightRegion& a, const IblLightRegion& b) { return a.power_share > b.power_share; });
  return regions;
}

Eigen::Vector3d sun_direction(double sun_elevation_deg, double sun_azimuth_deg) {
  const double e = sun_elevation_deg * kDegToRad, a = sun_azimuth_deg * kDegToRad;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

cv::Mat procedural_sky(double sun_elevation_deg, double sun_azimuth_deg, double turbidity, int width) {
  if (width < 4) throw std::invalid_argument("panorama width must be at least 4");
  const double t = std::clamp(turbidity, 1.0, 12.0);
  const Eigen::Vector3d sun = sun_direction(sun_elevation_deg, sun_azimuth_deg);
  const double sin_elev = std::max(std::sin(sun_elevation_deg * kDegToRad), 0.05);
  const double airmass = 1.0 / sin_elev;
  // Sun radiance attenuated along the air mass; blue is lost first (low suns redden).
  const Eigen::Vector3d sun_radiance =
      4.0e4 * Eigen::Vector3d(std::exp(-0.02 * t * airmass), std::exp(-0.04 * t * airmass),
                              std::exp(-0.07 * t * airmass));
  const double sky_level = 0.3 + 0.7 * sin_elev;
  const Eigen::Vector3d zenith(0.25, 0.45, 0.9), horizon(0.8, 0.85, 0.95);
  const double glow_width = 0.05 + 0.03 * t, glow_gain = 2.0 + 0.5 * t;
  const double sun_solid_angle = 2 * kPi * (1 - std::cos(kSunDiscRadius_rad));
  // Ground: grey Lambertian lit by the sun and ~0.6 of an overcast-equivalent sky.
  const Eigen::Vector3d ground =
      0.2 / kPi * (sun_radiance * sun_solid_angle * std::max(sun.y(), 0.0) +
                   Eigen::Vector3d::Constant(kPi * 0.6 * sky_level));

  const int height = width / 2;
  cv::Mat out(height, width, CV_32FC3);
  const double cos_disc = std::cos(kSunDiscRadius_rad);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int sy = 0; sy < kSkySupersampling; ++sy)
        for (int sx = 0; sx < kSkySupersampling; ++sx) {
          const Eigen::Vector3d d = uv_to_direction((x + (sx + 0.5) / kSkySupersampling) / width,
                                                    (y + (sy + 0.5) / kSkySupersampling) / height);
          if (d.y() < 0) {
            sum += ground;
            continue;
          }
          const double cos_gamma = std::clamp(d.dot(sun), -1.0, 1.0);
          if (cos_gamma >= cos_disc) {
            sum += sun_radiance;
            continue;
          }
          const double blend = std::pow(1.0 - d.y(), 3.0);
          const double glow = glow_gain * std::exp(-std::acos(cos_gamma) / glow_width);
          sum += sky_level * ((1 - blend) * zenith + blend * horizon + glow * Eigen::Vector3d(1.0, 0.95, 0.85));
        }
      sum /= kSkySupersampling * kSkySupersampling;
      out.at<cv::Vec3f>(y, x) = cv::Vec3f(float(sum.x()), float(sum.y()), float(sum.z()));
    }
  return out;
}

ProceduralRoom procedural_room_params(unsigned seed) {
  Lcg rng{0x9E3779B97F4A7C15ull ^ (static_cast<std::uint64_t>(seed) * 0x100000001B3ull)};
  for (int i = 0; i < 4; ++i) rng.next();
  ProceduralRoom room;
  room.width_m = 3.5 + 3.0 * rng.next();
  room.depth_m = 3.0 + 3.0 * rng.next();
  room.height_m = 2.4 + 0.8 * rng.next();
  room.panel_radiance = 20 + 30 * rng.next();
  room.window = rng.next() < 0.5;
  room.wall_albedo = Eigen::Vector3d(0.4 + 0.4 * rng.next(), 0.4 + 0.35 * rng.next(), 0.35 + 0.35 * rng.next());
  const int panels = 1 + static_cast<int>(rng.next() * 3.0);
  // Panels at least 1.2 m apart so each one is its own region.
  for (int attempt = 0; attempt < 200 && static_cast<int>(room.panel_xz.size()) < panels; ++attempt) {
    const Eigen::Vector2d p((rng.next() - 0.5) * (room.width_m - 1.0), (rng.next() - 0.5) * (room.depth_m - 1.0));
    bool far_enough = true;
    for (const Eigen::Vector2d& q : room.panel_xz) far_enough = far_enough && (p - q).norm() >= 1.2;
    if (far_enough) room.panel_xz.push_back(p);
  }
  return room;
}

std::vector<Eigen::Vector3d> panel_directions(const ProceduralRoom& room) {
  std::vector<Eigen::Vector3d> dirs;
  for (const Eigen::Vector2d& p : room.panel_xz)
    dirs.push_back(Eigen::Vector3d(p.x(), room.height_m - kCameraHeight_m, p.y()).normalized());
  return dirs;
}

cv::Mat render_procedural_room(const ProceduralRoom& room, int width) {
  if (width < 4) throw std::invalid_argument("panorama width must be at least 4");
  const double hw = room.width_m / 2, hd = room.depth_m / 2, h = room.height_m;
  const Eigen::Vector3d eye(0, kCameraHeight_m, 0);
  const Eigen::Vector3d panel_colour = room.panel_radiance * Eigen::Vector3d(1.0, 0.95, 0.85);
  const Eigen::Vector3d window_radiance(1.8, 2.4, 3.6);  // overcast sky seen through glass
  const double panel_area = 4 * kPanelHalfSize_m * kPanelHalfSize_m;
  constexpr double kWindowHalfWidth = 0.8, kWindowBottom = 0.9, kWindowTop = 2.1;
  const double window_area = 2 * kWindowHalfWidth * (kWindowTop - kWindowBottom);

  auto in_panel = [&](const Eigen::Vector3d& p) {
    for (const Eigen::Vector2d& c : room.panel_xz)
      if (std::abs(p.x() - c.x()) <= kPanelHalfSize_m && std::abs(p.z() - c.y()) <= kPanelHalfSize_m) return true;
    return false;
  };
  auto in_window = [&](const Eigen::Vector3d& p) {
    return room.window && std::abs(p.x()) <= kWindowHalfWidth && p.y() >= kWindowBottom && p.y() <= kWindowTop;
  };
  // Irradiance at a surface point from small area emitters (point approximation, no occlusion inside a box).
  // Returns a Vector3d, not auto: `e + Constant(0.5)` is an Eigen expression that would
  // read `e` after the lambda returned (stack-use-after-scope, found by ASan).
  auto irradiance = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& n) -> Eigen::Vector3d {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    auto add = [&](const Eigen::Vector3d& centre, const Eigen::Vector3d& emitter_normal, double area,
                   const Eigen::Vector3d& radiance) {
      const Eigen::Vector3d to = centre - p;
      const double r2 = std::max(to.squaredNorm(), 0.05);
      const Eigen::Vector3d w = to / std::sqrt(r2);
      const double cos_surface = std::max(n.dot(w), 0.0), cos_emitter = std::max(-emitter_normal.dot(w), 0.0);
      e += radiance * area * cos_surface * cos_emitter / r2;
    };
    for (const Eigen::Vector2d& c : room.panel_xz)
      add({c.x(), h, c.y()}, -Eigen::Vector3d::UnitY(), panel_area, panel_colour);
    if (room.window) add({0, (kWindowBottom + kWindowTop) / 2, -hd}, Eigen::Vector3d::UnitZ(), window_area, window_radiance);
    return e + Eigen::Vector3d::Constant(0.5);  // inter-reflections, roughly
  };

  const int height = width / 2;
  cv::Mat out(height, width, CV_32FC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int sy = 0; sy < kRoomSupersampling; ++sy)
        for (int sx = 0; sx < kRoomSupersampling; ++sx) {
          const Eigen::Vector3d d = uv_to_direction((x + (sx + 0.5) / kRoomSupersampling) / width,
                                                    (y + (sy + 0.5) / kRoomSupersampling) / height);
          // Exit distance from inside the box along each axis.
          double t = std::numeric_limits<double>::infinity();
          int axis = 0;
          const double bounds_hi[3] = {hw, h, hd}, bounds_lo[3] = {-hw, 0, -hd};
          for (int a = 0; a < 3; ++a) {
            if (d[a] == 0) continue;
            const double ta = ((d[a] > 0 ? bounds_hi[a] : bounds_lo[a]) - eye[a]) / d[a];
            if (ta < t) { t = ta; axis = a; }
          }
          const Eigen::Vector3d p = eye + t * d;
          Eigen::Vector3d n = Eigen::Vector3d::Zero();
          n[axis] = d[axis] > 0 ? -1 : 1;
          if (axis == 1 && d.y() > 0 && in_panel(p)) { sum += panel_colour; continue; }
          if (axis == 2 && d.z() < 0 && in_window(p)) { sum += window_radiance; continue; }
          Eigen::Vector3d albedo = room.wall_albedo;
          if (axis == 1) albedo = d.y() > 0 ? Eigen::Vector3d::Constant(0.8) : Eigen::Vector3d(0.35, 0.25, 0.18);
          sum += albedo.cwiseProduct(irradiance(p, n)) / kPi;
        }
      sum /= kRoomSupersampling * kRoomSupersampling;
      out.at<cv::Vec3f>(y, x) = cv::Vec3f(float(sum.x()), float(sum.y()), float(sum.z()));
    }
  return out;
}

IblLibrary build_ibl_library(const IblLibraryOptions& options) {
  IblLibrary library;
  auto add = [&](std::string name, std::string source, SceneKind kind, cv::Mat latlong) {
    IblEntry e;
    e.name = std::move(name);
    e.source = std::move(source);
    e.kind = kind;
    e.latlong = latlong.cols == options.width ? sanitize_latlong(latlong) : downsample_latlong(latlong, options.width);
    e.lights = find_light_regions(e.latlong, kind);
    library.entries.push_back(std::move(e));
  };
  // Debian's blender-data maps; indoor/outdoor is a label per map, as in the paper.
  const std::pair<const char*, SceneKind> blender_maps[] = {
      {"city", SceneKind::Outdoor},   {"courtyard", SceneKind::Outdoor}, {"forest", SceneKind::Outdoor},
      {"interior", SceneKind::Indoor}, {"night", SceneKind::Outdoor},    {"studio", SceneKind::Indoor},
      {"sunrise", SceneKind::Outdoor}, {"sunset", SceneKind::Outdoor}};
  for (const auto& [name, kind] : blender_maps) {
    const std::filesystem::path file = std::filesystem::path(options.blender_dir) / (std::string(name) + ".exr");
    if (!std::filesystem::exists(file)) continue;
    add(std::string("blender_") + name, "blender-data:" + file.string(), kind,
        capture::load_photo_linear(file.string()));
  }
  for (const auto& extra : options.extra_panoramas) {
    const std::filesystem::path file(extra.path);
    cv::Mat latlong = capture::load_photo_linear(file.string());
    add("file_" + file.stem().string(), "file:" + file.string(), extra.kind, replace_overflowed_texels(latlong));
  }
  // Skies: elevations from dawn to noon, clear to hazy, sun all around.
  for (int i = 0; i < options.procedural_skies; ++i) {
    const double elevation = 5.0 + 70.0 * ((i * 37) % 16) / 15.0;
    const double azimuth = std::fmod(i * 137.5, 360.0);
    const double turbidity = 2.0 + 8.0 * ((i * 5) % 8) / 7.0;
    char source[160];
    std::snprintf(source, sizeof source, "procedural:sky elevation=%.1f azimuth=%.1f turbidity=%.2f", elevation,
                  azimuth, turbidity);
    add("sky_" + std::to_string(i), source, SceneKind::Outdoor,
        procedural_sky(elevation, azimuth, turbidity, options.width));
  }
  for (int i = 0; i < options.procedural_rooms; ++i) {
    const unsigned seed = 500 + static_cast<unsigned>(i);
    add("room_" + std::to_string(i), "procedural:room seed=" + std::to_string(seed), SceneKind::Indoor,
        render_procedural_room(procedural_room_params(seed), options.width));
  }
  return library;
}

void save_ibl_library(const IblLibrary& library, const std::string& dir) {
  std::filesystem::create_directories(dir);
  nlohmann::json j;
  j["format"] = "propcam-ibl-library";
  j["version"] = 1;
  j["entries"] = nlohmann::json::array();
  for (const IblEntry& e : library.entries) {
    nlohmann::json entry;
    entry["name"] = e.name;
    entry["source"] = e.source;
    entry["kind"] = to_string(e.kind);
    entry["file"] = e.name + ".exr";
    entry["width"] = e.latlong.cols;
    entry["height"] = e.latlong.rows;
    entry["lights"] = nlohmann::json::array();
    for (const IblLightRegion& r : e.lights)
      entry["lights"].push_back({{"direction", {r.direction.x(), r.direction.y(), r.direction.z()}},
                                 {"solid_angle_sr", r.solid_angle_sr},
                                 {"power_share", r.power_share},
                                 {"distance", to_string(r.distance)}});
    j["entries"].push_back(entry);
    capture::write_image((std::filesystem::path(dir) / (e.name + ".exr")).string(), e.latlong);
  }
  const std::filesystem::path json_path = std::filesystem::path(dir) / "library.json";
  const std::filesystem::path tmp = json_path.string() + ".tmp";
  {
    std::ofstream out(tmp);
    out << j.dump(1) << "\n";
    if (!out) throw std::runtime_error("cannot write " + tmp.string());
  }
  std::filesystem::rename(tmp, json_path);
}

namespace {

SceneKind parse_kind(const std::string& s) {
  if (s == "indoor") return SceneKind::Indoor;
  if (s == "outdoor") return SceneKind::Outdoor;
  throw std::runtime_error("unknown kind '" + s + "'");
}

LightDistance parse_distance(const std::string& s) {
  for (LightDistance d : {LightDistance::Close, LightDistance::Medium, LightDistance::Far, LightDistance::Infinite})
    if (s == to_string(d)) return d;
  throw std::runtime_error("unknown distance class '" + s + "'");
}

}  // namespace

IblLibrary load_ibl_library(const std::string& dir) {
  const std::filesystem::path json_path = std::filesystem::path(dir) / "library.json";
  std::ifstream in(json_path);
  if (!in) throw std::runtime_error("IBL library: cannot open " + json_path.string());
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("IBL library: " + json_path.string() + " is not valid JSON: " + e.what());
  }
  IblLibrary library;
  std::string current = "(header)";
  try {
    if (j.at("format").get<std::string>() != "propcam-ibl-library" || j.at("version").get<int>() != 1)
      throw std::runtime_error("unsupported format or version");
    for (const nlohmann::json& entry : j.at("entries")) {
      IblEntry e;
      e.name = entry.at("name").get<std::string>();
      current = "entry '" + e.name + "'";
      e.source = entry.at("source").get<std::string>();
      e.kind = parse_kind(entry.at("kind").get<std::string>());
      const std::string file = entry.at("file").get<std::string>();
      if (file.empty() || file.find('/') != std::string::npos || file.find("..") != std::string::npos)
        throw std::runtime_error("bad file name '" + file + "'");
      const int width = entry.at("width").get<int>(), height = entry.at("height").get<int>();
      if (width < 4 || height * 2 != width) throw std::runtime_error("bad panorama size");
      for (const nlohmann::json& l : entry.at("lights")) {
        IblLightRegion r;
        const auto d = l.at("direction").get<std::vector<double>>();
        if (d.size() != 3) throw std::runtime_error("light direction needs 3 components");
        r.direction = Eigen::Vector3d(d[0], d[1], d[2]);
        r.solid_angle_sr = l.at("solid_angle_sr").get<double>();
        r.power_share = l.at("power_share").get<double>();
        r.distance = parse_distance(l.at("distance").get<std::string>());
        constexpr double kUnitTolerance = 1e-3;  // directions are stored with full double precision
        if (!r.direction.allFinite() || std::abs(r.direction.norm() - 1) > kUnitTolerance ||
            !(r.solid_angle_sr > 0 && r.solid_angle_sr <= 4 * kPi) || !(r.power_share >= 0 && r.power_share <= 1))
          throw std::runtime_error("light annotation out of range");
        e.lights.push_back(r);
      }
      const std::filesystem::path image_path = std::filesystem::path(dir) / file;
      if (!std::filesystem::exists(image_path)) throw std::runtime_error("missing panorama " + image_path.string());
      cv::Mat image = capture::load_photo_linear(image_path.string());
      if (image.cols != width || image.rows != height) throw std::runtime_error("panorama size differs from library.json");
      e.latlong = sanitize_latlong(image);
      library.entries.push_back(std::move(e));
    }
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("IBL library: " + json_path.string() + ", " + current + ": " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("IBL library: " + json_path.string() + ", " + current + ": " + e.what());
  }
  if (library.entries.empty()) throw std::runtime_error("IBL library: " + json_path.string() + " has no entries");
  return library;
}

}  // namespace propcam::inference
