// Golden images: small renders of fixed scenes compared with references
// committed under tests/render/golden/, so a renderer change that moves
// pixels is seen (Embree's tutorials and pbrt's test scenes keep such
// references). Each case takes a different path through the renderer: area
// light and shadow on diffuse surfaces, metal and white paint under an
// environment, a plastic prop under a spot point light and a sun, and a
// differential composite from a progressive session with tile culling and
// the denoiser.
//
// PROPCAM_UPDATE_GOLDEN=1 rewrites the references instead of comparing
// (render/README.md, "Golden images").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <stdexcept>
#include <numbers>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/props.h"
#include "propcam/render/render_session.h"

namespace propcam::render {
namespace {

namespace fs = std::filesystem;

const fs::path kGoldenFolder = fs::path(PROPCAM_SOURCE_DIR) / "tests/render/golden";

constexpr int kWidth = 96;
constexpr int kHeight = 72;

// ---------------------------------------------------------------------------
// Storage: a 16-bit PNG of sqrt(v / (1 + v)) per linear channel. The curve
// keeps any radiance (a light seen directly) finite and gives dark pixels
// finer steps; the square root makes the file look right in an ordinary
// viewer. A fresh render is put through the same encoding before it is
// compared, so an unchanged renderer differs from its reference by exactly 0.

uint16_t encode_channel(float linear) {
  const double v = std::max(0.0, static_cast<double>(linear));
  return static_cast<uint16_t>(std::lround(std::sqrt(v / (1.0 + v)) * 65535.0));
}

float decode_channel(uint16_t stored) {
  const double e = stored / 65535.0;
  const double e2 = e * e;
  return static_cast<float>(e2 / std::max(1.0 - e2, 1e-12));
}

cv::Mat encode(const cv::Mat& linear_rgb) {
  cv::Mat out(linear_rgb.size(), CV_16UC3);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x)
      for (int c = 0; c < 3; ++c) out.at<cv::Vec3w>(y, x)[c] = encode_channel(linear_rgb.at<cv::Vec3f>(y, x)[c]);
  return out;
}

cv::Mat decode(const cv::Mat& stored_rgb) {
  cv::Mat out(stored_rgb.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x)
      for (int c = 0; c < 3; ++c) out.at<cv::Vec3f>(y, x)[c] = decode_channel(stored_rgb.at<cv::Vec3w>(y, x)[c]);
  return out;
}

// The render at the reference's precision.
cv::Mat quantized(const cv::Mat& linear_rgb) { return decode(encode(linear_rgb)); }

void write_golden(const fs::path& path, const cv::Mat& linear_rgb) {
  cv::Mat bgr;
  cv::cvtColor(encode(linear_rgb), bgr, cv::COLOR_RGB2BGR);
  fs::create_directories(path.parent_path());
  if (!cv::imwrite(path.string(), bgr, {cv::IMWRITE_PNG_COMPRESSION, 9}))
    throw std::runtime_error("cannot write " + path.string());
}

cv::Mat read_golden(const fs::path& path) {
  const cv::Mat bgr = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  if (bgr.empty() || bgr.type() != CV_16UC3) return {};
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return decode(rgb);
}

// ---------------------------------------------------------------------------
// The comparison. Both images are blurred a little first (Gaussian, sigma
// 1 px): a harmless change that alters the samples of some pixels (another
// compiler's rounding turning a path at a Russian roulette or lobe choice)
// moves single pixels by their noise, which the blur spreads and lowers more
// than it lowers a real change (a brighter light, an edge moved along its
// length). Then, per channel, relative to the reference's mean of that
// channel (so one threshold fits a dark and a bright scene):
// - the mean absolute difference: a global change in light or colour;
// - the 99.9th percentile of the absolute difference: a local change (a
//   prop's edge and shadow moved by a pixel touch about 1% of the image,
//   which a mean dilutes), above the few pixels a diverging path can spoil.
// The thresholds sit above what the same scene rendered with another seed
// differs by (every sample different, more than any rounding can make;
// measured, worst case and channel: mean 0.015, percentile 0.22) and below
// what a 5% brighter light (mean 0.050) or the prop moved by one pixel
// (percentile 0.46) makes; the tests below check all three.

struct ImageDifference {
  cv::Vec3d mean_abs;         // per channel, relative to the reference's channel mean
  cv::Vec3d high_percentile;  // likewise
};

struct GoldenThresholds {
  double blur_sigma_px = 1.0;
  double percentile = 0.999;
  double max_mean_abs = 0.025;
  double max_high_percentile = 0.3;
};

double percentile_of(std::vector<float> values, double p) {
  if (values.empty()) return 0.0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(p * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

ImageDifference measure_difference(const cv::Mat& reference, const cv::Mat& image, const GoldenThresholds& t) {
  cv::Mat a, b;
  cv::GaussianBlur(reference, a, cv::Size(), t.blur_sigma_px, t.blur_sigma_px, cv::BORDER_REFLECT);
  cv::GaussianBlur(image, b, cv::Size(), t.blur_sigma_px, t.blur_sigma_px, cv::BORDER_REFLECT);
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  std::vector<cv::Mat> diff_channels;
  cv::split(diff, diff_channels);
  const cv::Scalar reference_mean = cv::mean(reference);
  ImageDifference d;
  for (int c = 0; c < 3; ++c) {
    const double scale = std::max(reference_mean[c], 1e-6);
    std::vector<float> values = diff_channels[c].reshape(1, 1);
    d.mean_abs[c] = cv::mean(diff_channels[c])[0] / scale;
    d.high_percentile[c] = percentile_of(std::move(values), t.percentile) / scale;
  }
  return d;
}

bool within(const ImageDifference& d, const GoldenThresholds& t) {
  for (int c = 0; c < 3; ++c)
    if (!(d.mean_abs[c] <= t.max_mean_abs && d.high_percentile[c] <= t.max_high_percentile)) return false;
  return true;
}

std::string describe(const ImageDifference& d) {
  std::string s = "mean abs (r,g,b) ";
  for (int c = 0; c < 3; ++c) s += std::to_string(d.mean_abs[c]) + (c < 2 ? ", " : "");
  s += "; high percentile ";
  for (int c = 0; c < 3; ++c) s += std::to_string(d.high_percentile[c]) + (c < 2 ? ", " : "");
  return s + " (relative to the reference's channel means)";
}

// ---------------------------------------------------------------------------
// The scenes.

PinholeCamera camera_at(const Eigen::Vector3d& centre, double pitch_deg, double hfov_deg) {
  PinholeCamera camera = pinhole_with_fov(kWidth, kHeight, hfov_deg);
  camera.R_world_from_cam = rotation_from_yaw_pitch_roll(0.0, pitch_deg * std::numbers::pi / 180.0, 0.0);
  camera.center_world = centre;
  return camera;
}

// A floor and a back wall, each its own diffuse grey.
Mesh floor_and_wall(const Eigen::Vector3f& floor_albedo, const Eigen::Vector3f& wall_albedo) {
  Mesh m;
  m.materials.resize(2);
  m.materials[0].albedo = floor_albedo;
  m.materials[1].albedo = wall_albedo;
  add_quad(m, {-4, 0, 3}, {4, 0, 3}, {4, 0, -1.5f}, {-4, 0, -1.5f}, 0, 1.f);
  add_quad(m, {-4, 0, -1.5f}, {4, 0, -1.5f}, {4, 3, -1.5f}, {-4, 3, -1.5f}, 1, 1.f);
  return m;
}

// A preset standing at `base` on the floor, scaled, turned about Y.
Eigen::Affine3f standing_at(const Eigen::Vector3f& base, float scale, float yaw_deg) {
  return Eigen::Translation3f(base) * Eigen::AngleAxisf(yaw_deg * std::numbers::pi_v<float> / 180.f,
                                                       Eigen::Vector3f::UnitY()) *
         Eigen::Scaling(scale);
}

RenderSettings settings_with_spp(int spp) {
  RenderSettings s;
  s.samples_per_pixel = spp;
  s.max_bounces = 3;
  return s;
}

// What a case may vary for the tests that prove the check works.
struct Variation {
  uint64_t seed = RenderSettings{}.seed;
  float light_scale = 1.f;                                // on the case's lights
  Eigen::Vector3f prop_offset = Eigen::Vector3f::Zero();  // world metres
};

// An 18% grey card cube on a grey floor before a wall, lit by a square area
// light above and to the right: soft shadow on the floor, bounce light.
cv::Mat render_diffuse_area_shadow(const Variation& v) {
  Scene scene;
  scene.add_mesh(floor_and_wall({0.5f, 0.5f, 0.5f}, {0.6f, 0.55f, 0.5f}), Layer::Background);
  scene.add_prop(make_prop("cube"), standing_at(Eigen::Vector3f(0.f, 0.f, 0.f) + v.prop_offset, 2.f, 30.f));
  scene.commit();
  LightRig lights;
  AreaLight key;
  key.corner = {0.6f, 1.6f, 0.1f};
  key.edge_u = {0.5f, 0.f, 0.f};
  key.edge_v = {0.f, 0.f, 0.5f};  // u x v = -Y: shines down
  key.radiance = Eigen::Vector3f(24.f, 22.f, 18.f) * v.light_scale;
  lights.area_lights.push_back(key);
  RenderSettings s = settings_with_spp(32);
  s.seed = v.seed;
  return render_image(scene, camera_at({0.0, 1.1, 2.2}, -22.0, 50.0), lights, s);
}

// A latitude-longitude sky: blue above, a brown ground below the horizon and
// a small bright warm patch (a low sun) to give the chrome a highlight and
// the plinth a shadow.
std::shared_ptr<EnvironmentLight> studio_sky(float scale) {
  cv::Mat latlong(32, 64, CV_32FC3);
  for (int y = 0; y < latlong.rows; ++y)
    for (int x = 0; x < latlong.cols; ++x) {
      const float up = 1.f - (y + 0.5f) / latlong.rows * 2.f;  // +1 zenith, -1 nadir
      latlong.at<cv::Vec3f>(y, x) = up > 0 ? cv::Vec3f(0.35f + 0.3f * up, 0.5f + 0.3f * up, 0.9f)
                                           : cv::Vec3f(0.25f, 0.18f, 0.12f);
    }
  // Broad and moderate, so the chrome's highlight of it spans pixels (a tiny
  // bright one would make its edge pixels' noise the image's largest).
  for (int y = 8; y < 12; ++y)
    for (int x = 39; x < 44; ++x) latlong.at<cv::Vec3f>(y, x) = cv::Vec3f(8.f, 7.f, 5.5f);
  return std::make_shared<EnvironmentLight>(latlong, Eigen::Vector3f::Constant(scale));
}

// The sphere plinth (white paint, chrome ball) on a floor under the sky alone.
cv::Mat render_metal_under_environment(const Variation& v) {
  Scene scene;
  Mesh floor;
  floor.materials.resize(1);
  floor.materials[0].albedo = {0.45f, 0.45f, 0.45f};
  add_quad(floor, {-20, 0, 20}, {20, 0, 20}, {20, 0, -20}, {-20, 0, -20}, 0, 1.f);
  scene.add_mesh(floor, Layer::Background);
  scene.add_prop(make_prop("sphere_plinth"), standing_at(Eigen::Vector3f(0.f, 0.f, 0.f) + v.prop_offset, 1.f, 0.f));
  scene.commit();
  LightRig lights;
  lights.environment = studio_sky(v.light_scale);
  RenderSettings s = settings_with_spp(32);
  s.seed = v.seed;
  return render_image(scene, camera_at({0.0, 0.7, 1.6}, -12.0, 45.0), lights, s);
}

// The glazed vase (plastic: a diffuse base under a glossy coat) under a warm
// spot point light and a low cool sun, each casting its own hard shadow.
cv::Mat render_plastic_under_point_and_sun(const Variation& v) {
  Scene scene;
  scene.add_mesh(floor_and_wall({0.55f, 0.5f, 0.45f}, {0.5f, 0.55f, 0.6f}), Layer::Background);
  scene.add_prop(make_prop("vase"), standing_at(Eigen::Vector3f(0.f, 0.f, 0.f) + v.prop_offset, 2.f, 0.f));
  scene.commit();
  LightRig lights;
  PointLight spot;
  spot.position = {-0.8f, 1.5f, 0.8f};
  spot.intensity = Eigen::Vector3f(3.f, 2.4f, 1.6f) * v.light_scale;
  spot.spot = SpotCone{Eigen::Vector3f(0.8f, -1.5f, -0.8f), 0.6, 0.3};
  lights.point_lights.push_back(spot);
  SunLight sun;
  sun.direction = {1.f, 0.6f, 0.5f};
  sun.irradiance = Eigen::Vector3f(0.6f, 0.7f, 0.9f) * v.light_scale;
  lights.suns.push_back(sun);
  RenderSettings s = settings_with_spp(32);
  s.seed = v.seed;
  return render_image(scene, camera_at({0.0, 1.0, 2.0}, -20.0, 45.0), lights, s);
}

// A cube composited into a rendered photo of a corner of a room (an area
// light above, a dim sky) by the progressive differential session (tile
// culling, denoised), as `propcam composite` does. The room is built here,
// not by make_synthetic_room, whose colours come out of its random draws in
// an order another compiler may change.
cv::Mat render_differential_composite(const Variation& v) {
  Scene scene;
  scene.add_mesh(floor_and_wall({0.45f, 0.33f, 0.22f}, {0.7f, 0.68f, 0.62f}), Layer::Background);
  const int prop =
      scene.add_prop(make_prop("cube"), standing_at(Eigen::Vector3f(0.3f, 0.f, 0.2f) + v.prop_offset, 1.5f, 20.f));
  scene.commit();
  LightRig lights;
  AreaLight panel;
  panel.corner = {-0.6f, 2.2f, -0.6f};
  panel.edge_u = {0.6f, 0.f, 0.f};
  panel.edge_v = {0.f, 0.f, 0.6f};  // u x v = -Y: shines down
  panel.radiance = Eigen::Vector3f(14.f, 13.f, 11.f) * v.light_scale;
  lights.area_lights.push_back(panel);
  lights.environment = std::make_shared<EnvironmentLight>(cv::Mat(8, 16, CV_32FC3, cv::Scalar(0.15, 0.17, 0.2)),
                                                          Eigen::Vector3f::Constant(v.light_scale));
  const PinholeCamera camera = camera_at({0.0, 1.3, 2.6}, -25.0, 55.0);
  // The photo is this renderer's too: a brighter light brightens it as well.
  RenderSettings photo_settings = settings_with_spp(16);
  photo_settings.seed = 7;  // the photo keeps its noise whatever the variation's seed
  const cv::Mat photo = render_background_image(scene, camera, lights, photo_settings);
  SessionSettings session_settings;
  session_settings.render = settings_with_spp(16);
  session_settings.render.seed = v.seed;
  session_settings.max_samples_per_pixel = 16;
  session_settings.denoise = true;
  RenderSession session(scene, camera, lights, photo, scene.world_bounds(prop), session_settings);
  while (!session.finished()) session.run_pass();
  return session.composite();
}

struct GoldenCase {
  std::string name;
  cv::Mat (*render)(const Variation&);
};

// gtest prints a parameter in the test's listed name: the case's name, not its bytes.
void PrintTo(const GoldenCase& c, std::ostream* out) { *out << c.name; }

const std::vector<GoldenCase>& golden_cases() {
  static const std::vector<GoldenCase> cases = {
      {"diffuse_area_shadow", render_diffuse_area_shadow},
      {"metal_under_environment", render_metal_under_environment},
      {"plastic_under_point_and_sun", render_plastic_under_point_and_sun},
      {"differential_composite", render_differential_composite},
  };
  return cases;
}

// Each case's render with nothing varied, made once for all the tests here.
const cv::Mat& plain_render(const GoldenCase& c) {
  static std::map<std::string, cv::Mat> renders;
  auto it = renders.find(c.name);
  if (it == renders.end()) it = renders.emplace(c.name, quantized(c.render(Variation{}))).first;
  return it->second;
}

const GoldenCase& golden_case(const std::string& name) {
  for (const GoldenCase& c : golden_cases())
    if (c.name == name) return c;
  throw std::invalid_argument("no golden case " + name);
}

bool updating_references() {
  const char* flag = std::getenv("PROPCAM_UPDATE_GOLDEN");
  return flag && std::string(flag) == "1";
}

// Where a failing case leaves its render, to look at beside the reference.
fs::path failure_path(const std::string& name) {
  return fs::path(PROPCAM_BINARY_DIR) / "golden_failures" / (name + ".png");
}

class GoldenImage : public ::testing::TestWithParam<GoldenCase> {};

TEST_P(GoldenImage, MatchesTheReference) {
  const GoldenCase& c = GetParam();
  const fs::path reference_path = kGoldenFolder / (c.name + ".png");
  const cv::Mat& rendered = plain_render(c);
  ASSERT_EQ(rendered.size(), cv::Size(kWidth, kHeight));
  ASSERT_TRUE(cv::checkRange(rendered));
  if (updating_references()) {
    write_golden(reference_path, rendered);
    std::cout << "rewrote " << reference_path << "\n";
    return;
  }
  const cv::Mat reference = read_golden(reference_path);
  ASSERT_FALSE(reference.empty()) << reference_path << " is missing or not a 16-bit RGB PNG; "
                                  << "PROPCAM_UPDATE_GOLDEN=1 writes it";
  ASSERT_EQ(reference.size(), rendered.size());
  const GoldenThresholds thresholds;
  const ImageDifference d = measure_difference(reference, rendered, thresholds);
  std::cout << c.name << ": max abs difference " << cv::norm(reference, rendered, cv::NORM_INF) << "; "
            << describe(d) << "\n";
  if (!within(d, thresholds)) {
    write_golden(failure_path(c.name), rendered);
    ADD_FAILURE() << c.name << " moved: " << describe(d) << "; the render is in " << failure_path(c.name)
                  << ", the reference in " << reference_path;
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, GoldenImage, ::testing::ValuesIn(golden_cases()),
                         [](const ::testing::TestParamInfo<GoldenCase>& info) { return info.param.name; });

// ---------------------------------------------------------------------------
// The check itself: it must let noise through and stop a visible change.

TEST(GoldenImageCheck, TheEncodingKeepsRadianceToAFractionOfAPercent) {
  for (float v : {0.f, 1e-3f, 0.05f, 0.5f, 1.f, 8.f, 60.f}) {
    const float back = decode_channel(encode_channel(v));
    EXPECT_NEAR(back, v, 1e-4f + v * 2e-3f) << v;
  }
}

TEST(GoldenImageCheck, IdenticalImagesDifferByNothing) {
  const cv::Mat& image = plain_render(golden_cases().front());
  const ImageDifference d = measure_difference(image, image, GoldenThresholds{});
  EXPECT_EQ(cv::norm(d.mean_abs), 0.0);
  EXPECT_EQ(cv::norm(d.high_percentile), 0.0);
}

// Another seed changes every sample of every pixel: more than a compiler's or
// CPU's rounding can, so the thresholds must let it through.
TEST(GoldenImageCheck, AnotherSeedPasses) {
  for (const GoldenCase& c : golden_cases()) {
    Variation other;
    other.seed = 0xfeed;
    const ImageDifference d = measure_difference(plain_render(c), quantized(c.render(other)), GoldenThresholds{});
    std::cout << c.name << " with another seed: " << describe(d) << "\n";
    EXPECT_TRUE(within(d, GoldenThresholds{})) << c.name << ": " << describe(d);
  }
}

TEST(GoldenImageCheck, AFivePercentBrighterLightFails) {
  for (const GoldenCase& c : golden_cases()) {
    Variation brighter;
    brighter.light_scale = 1.05f;
    const ImageDifference d = measure_difference(plain_render(c), quantized(c.render(brighter)), GoldenThresholds{});
    std::cout << c.name << " with a 5% brighter light: " << describe(d) << "\n";
    EXPECT_FALSE(within(d, GoldenThresholds{})) << c.name << ": " << describe(d);
  }
}

// The prop moved sideways by what one pixel spans at its distance.
TEST(GoldenImageCheck, APropMovedByOnePixelFails) {
  const struct {
    const char* name;
    double distance_m, hfov_deg;  // the prop's from the camera, the camera's field of view
  } moved[] = {{"diffuse_area_shadow", 2.45, 50.0}, {"metal_under_environment", 1.6, 45.0}};
  for (const auto& m : moved) {
    const double metres_per_pixel = 2.0 * m.distance_m * std::tan(m.hfov_deg * std::numbers::pi / 360.0) / kWidth;
    Variation shifted;
    shifted.prop_offset = {static_cast<float>(metres_per_pixel), 0.f, 0.f};
    const GoldenCase& c = golden_case(m.name);
    const ImageDifference d = measure_difference(plain_render(c), quantized(c.render(shifted)), GoldenThresholds{});
    std::cout << m.name << " with the prop a pixel to the right: " << describe(d) << "\n";
    EXPECT_FALSE(within(d, GoldenThresholds{})) << m.name << ": " << describe(d);
  }
}

}  // namespace
}  // namespace propcam::render
