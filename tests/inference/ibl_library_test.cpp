#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "propcam/inference/ibl_library.h"

namespace propcam::inference {
namespace {

constexpr double kPi = 3.14159265358979323846;

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / kPi;
}

TEST(IblLibrary, FindsTheSunOfAProceduralSky) {
  for (const auto& [elevation, azimuth, turbidity] :
       {std::tuple{10.0, 30.0, 3.0}, std::tuple{45.0, 200.0, 6.0}, std::tuple{70.0, 300.0, 9.0}}) {
    const cv::Mat sky = procedural_sky(elevation, azimuth, turbidity, 256);
    const auto lights = find_light_regions(sky, SceneKind::Outdoor);
    ASSERT_FALSE(lights.empty());
    EXPECT_LT(angle_deg(lights[0].direction, sun_direction(elevation, azimuth)), 2.0)
        << "elevation " << elevation << " azimuth " << azimuth;
    EXPECT_EQ(lights[0].distance, LightDistance::Infinite);
    EXPECT_GT(lights[0].power_share, 0.3);  // the sun dominates a clear sky
  }
}

TEST(IblLibrary, FindsTheCeilingPanelsOfAProceduralRoom) {
  for (unsigned seed : {500u, 503u, 507u}) {
    const ProceduralRoom room = procedural_room_params(seed);
    const cv::Mat pano = render_procedural_room(room, 256);
    const auto lights = find_light_regions(pano, SceneKind::Indoor);
    const auto panels = panel_directions(room);
    // Every panel is found; the only other light a room may have is its window (middle of the -Z wall,
    // at eye height).
    std::vector<Eigen::Vector3d> expected = panels;
    if (room.window) expected.push_back(-Eigen::Vector3d::UnitZ());
    ASSERT_GE(lights.size(), panels.size()) << "seed " << seed;
    ASSERT_LE(lights.size(), expected.size()) << "seed " << seed;
    for (const Eigen::Vector3d& p : panels) {
      double best = 180;
      for (const IblLightRegion& l : lights) best = std::min(best, angle_deg(l.direction, p));
      EXPECT_LT(best, 4.0) << "seed " << seed;
    }
    for (const IblLightRegion& l : lights) {
      double best = 180;
      for (const Eigen::Vector3d& p : expected) best = std::min(best, angle_deg(l.direction, p));
      EXPECT_LT(best, 6.0) << "seed " << seed;
    }
    for (const IblLightRegion& l : lights) EXPECT_NE(l.distance, LightDistance::Infinite);
  }
}

TEST(IblLibrary, BuildsSavesAndLoadsProceduralEntries) {
  IblLibraryOptions options;
  options.width = 64;
  options.blender_dir = "/nonexistent";
  options.procedural_skies = 2;
  options.procedural_rooms = 2;
  const IblLibrary library = build_ibl_library(options);
  ASSERT_EQ(library.entries.size(), 4u);
  const std::string dir = std::string(PROPCAM_BINARY_DIR) + "/test_ibl_library_roundtrip";
  std::filesystem::remove_all(dir);
  save_ibl_library(library, dir);
  const IblLibrary loaded = load_ibl_library(dir);
  ASSERT_EQ(loaded.entries.size(), library.entries.size());
  for (size_t i = 0; i < loaded.entries.size(); ++i) {
    EXPECT_EQ(loaded.entries[i].name, library.entries[i].name);
    EXPECT_EQ(loaded.entries[i].kind, library.entries[i].kind);
    ASSERT_EQ(loaded.entries[i].lights.size(), library.entries[i].lights.size());
    EXPECT_EQ(loaded.entries[i].latlong.size(), library.entries[i].latlong.size());
  }
}

TEST(IblLibrary, BlenderMapsAreAnnotatedWhenInstalled) {
  IblLibraryOptions options;
  options.width = 128;
  options.procedural_skies = 0;
  options.procedural_rooms = 0;
  if (!std::filesystem::exists(options.blender_dir)) GTEST_SKIP() << "blender-data is not installed";
  const IblLibrary library = build_ibl_library(options);
  EXPECT_EQ(library.entries.size(), 8u);
  for (const IblEntry& e : library.entries) {
    double min_value = 0;
    cv::minMaxLoc(e.latlong.reshape(1), &min_value);
    EXPECT_GE(min_value, 0.0) << e.name;  // DWAB negatives clamped
    EXPECT_FALSE(e.lights.empty()) << e.name;
  }
}

}  // namespace
}  // namespace propcam::inference
