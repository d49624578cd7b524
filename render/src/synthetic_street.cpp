#include "propcam/render/synthetic_street.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include "propcam/render/mesh_shapes.h"

namespace propcam::render {
namespace {

using V = Eigen::Vector3f;
constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr float kStoreyM = 3.2f;
constexpr float kBayM = 2.6f;          // window spacing along a facade
constexpr float kStreetStartZ = 15.f;  // the street runs from behind the camera ...
constexpr float kStreetEndZ = -160.f;  // ... far ahead (-Z)
constexpr float kWindowInset = 0.02f;  // windows sit just in front of the facade (no z-fighting)
// The sun's irradiance and the sky's radiance scale (relative units of the
// renderer): a sunlit 0.5-albedo wall is about 4x its shadowed neighbour.
constexpr float kSunIrradiance = 3.0f;
constexpr float kSkyRadiance = 0.35f;
constexpr int kSkyWidth = 128, kSkyHeight = 64;

Material plain(const std::string& name, const Eigen::Vector3f& albedo) {
  Material m;
  m.name = name;
  m.albedo = albedo;
  return m;
}

// A blue sky brighter at the horizon, the ground's bounce below it.
cv::Mat sky_latlong(float overcast) {
  cv::Mat img(kSkyHeight, kSkyWidth, CV_32FC3);
  for (int y = 0; y < kSkyHeight; ++y)
    for (int x = 0; x < kSkyWidth; ++x) {
      const Eigen::Vector3f d = EnvironmentLight::uv_to_direction((x + 0.5f) / kSkyWidth, (y + 0.5f) / kSkyHeight);
      Eigen::Vector3f c;
      if (d.y() >= 0) {
        const float t = std::sqrt(d.y());
        const Eigen::Vector3f horizon(0.80f, 0.88f, 1.0f), zenith(0.25f, 0.45f, 0.95f), grey(0.85f, 0.87f, 0.9f);
        c = (1 - overcast) * ((1 - t) * horizon + t * zenith) + overcast * grey;
      } else {
        c = Eigen::Vector3f(0.25f, 0.24f, 0.22f);
      }
      c *= kSkyRadiance;
      img.at<cv::Vec3f>(y, x) = cv::Vec3f(c.x(), c.y(), c.z());
    }
  return img;
}

struct Materials {
  int road, sidewalk, kerb, window, door, cornice, car, first_facade;
};

// One building's facade facing the street at x = face_x (normal along
// `side`, +1: faces +X), spanning [z0, z1] (z0 > z1), `storeys` high.
void add_building(Mesh& m, const Materials& mat, int facade, float face_x, float side, float z0, float z1, int storeys,
                  float depth, std::mt19937_64& rng) {
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  const float h = storeys * kStoreyM;
  const float back = face_x - side * depth;
  const V lo(std::min(face_x, back), 0, z1), hi(std::max(face_x, back), h, z0);
  add_box(m, lo, hi, facade);
  // Cornice: a ledge along the roofline, sticking out towards the street.
  const float ledge = 0.35f;
  add_box(m, V(std::min(face_x, face_x + side * ledge), h - 0.4f, z1), V(std::max(face_x, face_x + side * ledge), h, z0),
          mat.cornice);
  // Windows on every storey above the ground floor, a door and shop windows below.
  const float fx = face_x + side * kWindowInset;
  const int bays = std::max(1, static_cast<int>((z0 - z1) / kBayM));
  const float bay = (z0 - z1) / bays;
  const float win_w = bay * (0.45f + 0.2f * unit(rng)), win_h = 1.2f + 0.4f * unit(rng);
  auto quad_on_facade = [&](float zc, float y0, float y1, float w, int material) {
    const float za = zc + 0.5f * w, zb = zc - 0.5f * w;
    if (side > 0) add_quad(m, V(fx, y0, za), V(fx, y0, zb), V(fx, y1, zb), V(fx, y1, za), material, 1.f);
    else add_quad(m, V(fx, y0, zb), V(fx, y0, za), V(fx, y1, za), V(fx, y1, zb), material, 1.f);
  };
  for (int b = 0; b < bays; ++b) {
    const float zc = z0 - (b + 0.5f) * bay;
    for (int s = 1; s < storeys; ++s) quad_on_facade(zc, s * kStoreyM + 0.8f, s * kStoreyM + 0.8f + win_h, win_w, mat.window);
    quad_on_facade(zc, 0.f, 2.2f, b == bays / 2 ? 1.2f : win_w * 1.2f, b == bays / 2 ? mat.door : mat.window);
  }
}

// The street's random draws, in a fixed order (a seed gives the same street).
struct Dice {
  std::mt19937_64& rng;
  std::uniform_real_distribution<float> unit_distribution{0.f, 1.f};
  float unit() { return unit_distribution(rng); }
  float between(float a, float b) { return a + (b - a) * unit(); }
};

// The fixed materials, a car colour and `facades` facade tones.
Materials add_materials(Mesh& m, int facades, Dice& dice) {
  m.materials.push_back(plain("road", {0.12f, 0.12f, 0.13f}));
  m.materials.push_back(plain("sidewalk", {0.45f, 0.44f, 0.42f}));
  m.materials.push_back(plain("kerb", {0.6f, 0.6f, 0.58f}));
  m.materials.push_back(plain("window", {0.05f, 0.06f, 0.08f}));
  m.materials.push_back(plain("door", {0.2f, 0.12f, 0.07f}));
  m.materials.push_back(plain("cornice", {0.75f, 0.74f, 0.7f}));
  m.materials.push_back(plain("car", {dice.between(0.1f, 0.7f), dice.between(0.1f, 0.5f), dice.between(0.1f, 0.5f)}));
  const Materials mat{0, 1, 2, 3, 4, 5, 6, static_cast<int>(m.materials.size())};
  for (int i = 0; i < facades; ++i) {
    const float tone = dice.between(0.35f, 0.8f);
    m.materials.push_back(plain("facade", {tone * dice.between(0.85f, 1.1f), tone * dice.between(0.8f, 1.f),
                                           tone * dice.between(0.7f, 0.95f)}));
  }
  return mat;
}

// The street runs along Z; road |x| < road_half, sidewalks beyond, buildings behind them.
struct StreetLayout {
  float road_half, walk;
  bool left_open;  // a square or a park edge on one side
  bool crossing;
  float cross_z, cross_w;
};

StreetLayout draw_layout(Dice& dice) {
  StreetLayout l{};
  l.road_half = dice.between(4.f, 15.f);
  l.walk = dice.between(2.f, 4.f);
  l.left_open = dice.unit() < 0.2f;
  l.crossing = dice.unit() < 0.5f;
  l.cross_z = dice.between(-60.f, -25.f);
  l.cross_w = dice.between(8.f, 16.f);
  return l;
}

// A row of buildings with small setbacks along one side; a gap where a crossing street runs.
void add_building_row(Mesh& m, const Materials& mat, int facades, const StreetLayout& layout, float side, Dice& dice) {
  float z = kStreetStartZ;
  while (z > kStreetEndZ + 5.f) {
    const float width = dice.between(8.f, 25.f);
    float z1 = std::max(z - width, kStreetEndZ);
    if (layout.crossing && z > layout.cross_z && z1 < layout.cross_z) z1 = layout.cross_z;
    if (layout.crossing && z <= layout.cross_z && z > layout.cross_z - layout.cross_w) {
      z = layout.cross_z - layout.cross_w;
      continue;
    }
    const float face = side * (layout.road_half + layout.walk + dice.between(0.f, 1.5f));
    const int storeys = 2 + static_cast<int>(dice.unit() * 7.f);
    // The compiler orders the two draws in these arguments: they stay in one
    // call so that every seed keeps its street.
    add_building(m, mat, mat.first_facade + static_cast<int>(dice.unit() * facades) % facades, face, -side, z, z1,
                 storeys, dice.between(8.f, 14.f), dice.rng);
    z = z1;
  }
}

// The road, and on each side a sidewalk, a kerb and (unless open) buildings.
void add_street(Mesh& m, const Materials& mat, int facades, const StreetLayout& layout, Dice& dice) {
  const float road_half = layout.road_half;
  add_quad(m, V(-road_half, 0, kStreetStartZ), V(road_half, 0, kStreetStartZ), V(road_half, 0, kStreetEndZ),
           V(-road_half, 0, kStreetEndZ), mat.road, 2.f);
  for (float side : {-1.f, 1.f}) {
    const float x_in = side * road_half, x_out = side * (road_half + layout.walk + 40.f);
    const V a(std::min(x_in, x_out), 0.f, kStreetStartZ), b(std::max(x_in, x_out), 0.f, kStreetEndZ);
    add_quad(m, V(a.x(), 0.005f, a.z()), V(b.x(), 0.005f, a.z()), V(b.x(), 0.005f, b.z()), V(a.x(), 0.005f, b.z()),
             mat.sidewalk, 1.5f);
    add_box(m, V(std::min(x_in, x_in + side * 0.3f), 0, kStreetEndZ), V(std::max(x_in, x_in + side * 0.3f), 0.12f, kStreetStartZ),
            mat.kerb);
    if (side < 0 && layout.left_open) continue;
    add_building_row(m, mat, facades, layout, side, dice);
  }
}

using Box = std::pair<V, V>;  // lower and upper corners

// Parked cars along the kerbs; their footprints.
std::vector<Box> add_parked_cars(Mesh& m, const Materials& mat, float road_half, Dice& dice) {
  std::vector<Box> cars;
  for (int i = 0; i < 6; ++i) {
    const float side = dice.unit() < 0.5f ? -1.f : 1.f;
    const float z = dice.between(-70.f, -16.f);  // clear of the free ground point
    const float x = side * (road_half - 1.2f);
    add_box(m, V(x - 0.9f, 0, z - 2.1f), V(x + 0.9f, 1.5f, z + 2.1f), mat.car);
    cars.emplace_back(V(x - 0.9f, 0, z - 2.1f), V(x + 0.9f, 1.5f, z + 2.1f));
  }
  return cars;
}

void add_sun_and_sky(LightRig& lights, Dice& dice) {
  const float overcast = dice.unit() < 0.25f ? dice.between(0.5f, 0.9f) : 0.f;
  const double elevation = dice.between(12.f, 65.f) * kDegToRad, azimuth = dice.between(0.f, 360.f) * kDegToRad;
  SunLight sun;
  sun.direction = V(static_cast<float>(std::cos(elevation) * std::sin(azimuth)), static_cast<float>(std::sin(elevation)),
                    static_cast<float>(std::cos(elevation) * std::cos(azimuth)));
  sun.irradiance = V(1.f, 0.95f, 0.85f) * kSunIrradiance * (1.f - overcast);
  lights.suns.push_back(sun);
  lights.environment = std::make_shared<EnvironmentLight>(sky_latlong(overcast));
}

// Camera on the sidewalk or the road's edge, looking down the street,
// diagonally or across it.
PinholeCamera place_camera(const SyntheticStreetSpec& spec, float road_half, Dice& dice) {
  PinholeCamera cam =
      pinhole_with_fov(spec.width, spec.height, spec.horizontal_fov_deg > 0 ? spec.horizontal_fov_deg : dice.between(50.f, 75.f));
  const float view = dice.unit();
  // The compiler orders the draws within this expression: it stays one
  // expression so that every seed keeps its camera.
  const double yaw = (view < 0.55f   ? dice.between(-25.f, 25.f)
                      : view < 0.85f ? dice.between(30.f, 55.f) * (dice.unit() < 0.5f ? -1 : 1)
                                     : dice.between(65.f, 85.f) * (dice.unit() < 0.5f ? -1 : 1)) *
                     kDegToRad;
  const double pitch = dice.between(-10.f, 10.f) * kDegToRad, roll = dice.between(-3.f, 3.f) * kDegToRad;
  cam.R_world_from_cam = rotation_from_yaw_pitch_roll(yaw, pitch, roll);
  // Looking across, stand on the far sidewalk so the facade is not at arm's length.
  const double cam_x = std::abs(yaw) > 60 * kDegToRad ? -std::copysign(road_half + 1.0, std::sin(-yaw)) : dice.between(-road_half * 0.7f, road_half * 0.7f);
  cam.center_world = {cam_x, spec.camera_height_m, 0.0};
  return cam;
}

// The segment from the camera to p against each box grown by half a metre (slab test).
bool segment_clear_of(const Eigen::Vector3d& o, const Eigen::Vector3d& p, const std::vector<Box>& obstacles) {
  for (const auto& [lo, hi] : obstacles) {
    const Eigen::Vector3d blo = lo.cast<double>() - Eigen::Vector3d(0.5, 0.5, 0.5), bhi = hi.cast<double>() + Eigen::Vector3d(0.5, 0.05, 0.5);
    const Eigen::Vector3d d = p - o;
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 3 && t0 <= t1; ++k) {
      if (std::abs(d[k]) < 1e-12) {
        if (o[k] < blo[k] || o[k] > bhi[k]) t1 = -1;
        continue;
      }
      double ta = (blo[k] - o[k]) / d[k], tb = (bhi[k] - o[k]) / d[k];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    }
    if (t0 <= t1) return false;
  }
  return true;
}

// A ground point seen low in the frame (the ray through the bottom tenth),
// on the road or sidewalk, clear of cars. It must be seen: in the frame, off
// the kerbs and parked cars, and not hidden behind them (a 0.12 m kerb hides
// a strip of ground beyond it). Farther along the ray (higher in the frame)
// or nearer if need be.
V free_ground_point(const PinholeCamera& cam, const SyntheticStreetSpec& spec, const StreetLayout& layout,
                    const std::vector<Box>& cars) {
  const float road_half = layout.road_half, walk = layout.walk;
  const Eigen::Vector3d low_ray = cam.ray_direction(cam.cx, 0.9 * (cam.height - 1));
  const double reach = low_ray.y() < -1e-3 ? std::min(spec.camera_height_m / -low_ray.y(), 40.0) : 4.0;
  std::vector<Box> obstacles = cars;
  for (float side : {-1.f, 1.f})
    obstacles.emplace_back(V(std::min(side * road_half, side * (road_half + 0.3f)), 0, kStreetEndZ),
                           V(std::max(side * road_half, side * (road_half + 0.3f)), 0.12f, kStreetStartZ));
  auto seen = [&](const Eigen::Vector3d& p) {
    Eigen::Vector2d px;
    if (!cam.project(p, px) || px.x() < 0.02 * cam.width || px.x() > 0.98 * cam.width || px.y() < 0.02 * cam.height ||
        px.y() > 0.98 * cam.height)
      return false;
    return segment_clear_of(cam.center_world, p, obstacles);
  };
  const Eigen::Vector3d flat = Eigen::Vector3d(low_ray.x(), 0, low_ray.z()).normalized() * std::hypot(low_ray.x(), low_ray.z());
  auto candidate = [&](double t) {
    Eigen::Vector3d p = cam.center_world + flat * (reach * t);
    p.x() = std::clamp(p.x(), -(road_half + walk - 0.5), road_half + walk - 0.5);
    p.y() = 0.0;
    return p;
  };
  Eigen::Vector3d ahead = candidate(1.0);
  for (double t : {1.0, 1.15, 1.3, 1.5, 1.75, 2.0, 0.9, 0.8, 2.5, 3.0, 0.7, 4.0})
    if (seen(candidate(t))) {
      ahead = candidate(t);
      break;
    }
  return V(static_cast<float>(ahead.x()), 0.f, static_cast<float>(ahead.z()));
}

}  // namespace

SyntheticStreet make_synthetic_street(const SyntheticStreetSpec& spec) {
  std::mt19937_64 rng(spec.seed * 0x9E3779B97F4A7C15ull + 77);
  Dice dice{rng};
  SyntheticStreet out;
  Mesh& m = out.scene;
  const int facades = 5;
  const Materials mat = add_materials(m, facades, dice);
  const StreetLayout layout = draw_layout(dice);
  add_street(m, mat, facades, layout, dice);
  const std::vector<Box> cars = add_parked_cars(m, mat, layout.road_half, dice);
  m.compute_vertex_normals();
  m.normals.clear();  // flat shading
  const float far_x = layout.road_half + layout.walk + 60.f;
  out.scene_min = V(-far_x, 0, kStreetEndZ);
  out.scene_max = V(far_x, 40.f, kStreetStartZ);
  add_sun_and_sky(out.lights, dice);
  out.camera = place_camera(spec, layout.road_half, dice);
  out.free_ground_point = free_ground_point(out.camera, spec, layout, cars);
  return out;
}

}  // namespace propcam::render
