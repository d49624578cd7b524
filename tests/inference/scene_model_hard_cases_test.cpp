// scene.json inputs the fuzzer (tests/fuzz/fuzz_scene) turned up: each is
// rejected with a clear std::runtime_error, never undefined behaviour.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <unistd.h>

#include "propcam/inference/scene_model.h"

namespace propcam::inference {
namespace {
namespace fs = std::filesystem;

// A valid scene.json; each argument replaces one part of it.
std::string scene_json(const std::string& image = R"("width": 64, "height": 48)",
                       const std::string& light = R"({"type": "point", "intensity": [1, 1, 1]})",
                       const std::string& plane_pixels = "900", const std::string& iterations = "3") {
  return R"({"image": {)" + image + R"(}, "K": {"fx": 60, "fy": 60, "cx": 32, "cy": 24},
    "R_world_from_cam": [[1, 0, 0], [0, 0, 1], [0, -1, 0]], "camera_height_m": 1.5,
    "lights": [)" + light + R"(],
    "planes": [{"name": "floor", "normal": [0, 0, 1], "offset": 0, "pixels": )" + plane_pixels +
         R"(, "extent_min": [-2, 0, 0], "extent_max": [2, 4, 0]}],
    "reports": [{"stage": "geometry", "iterations": )" + iterations + "}]}";
}

class SceneJsonHardCases : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("propcam_scene_hard_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  SceneModel load(const std::string& text) {
    std::ofstream(dir_ / "scene.json") << text;
    return load_scene(dir_.string());
  }
  std::string error_of(const std::string& text) {
    try {
      load(text);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "(loaded)";
  }

  fs::path dir_;
};

TEST_F(SceneJsonHardCases, TheValidSceneLoads) {
  const SceneModel scene = load(scene_json());
  EXPECT_EQ(scene.width, 64);
  EXPECT_EQ(scene.planes.at(0).pixels, 900);
  EXPECT_EQ(scene.reports.at(0).iterations, 3);
}

// Found by fuzz_scene: nlohmann cast 1e300 to int (UBSan float-cast-overflow).
TEST_F(SceneJsonHardCases, AnImageWidthBeyondIntIsRejected) {
  EXPECT_NE(error_of(scene_json(R"("width": 1e300, "height": 48)")).find("image width"), std::string::npos);
  EXPECT_NE(error_of(scene_json(R"("width": 64, "height": 4294967296)")).find("image height"),
            std::string::npos);
  EXPECT_NE(error_of(scene_json(R"("width": 64.5, "height": 48)")).find("not an integer"), std::string::npos);
}

TEST_F(SceneJsonHardCases, PlanePixelsAndIterationsBeyondIntAreRejected) {
  const std::string light = R"({"type": "point", "intensity": [1, 1, 1]})";
  EXPECT_NE(error_of(scene_json(R"("width": 64, "height": 48)", light, "-1e300")).find("pixels"),
            std::string::npos);
  EXPECT_NE(error_of(scene_json(R"("width": 64, "height": 48)", light, "900", "1e19")).find("iterations"),
            std::string::npos);
}

TEST_F(SceneJsonHardCases, AnEnvironmentMapOutsideTheFolderIsRejected) {
  for (const char* file : {"../../etc/passwd", "/etc/passwd", "lights/../../x.exr", ""}) {
    const std::string light = std::string(R"({"type": "ibl", "intensity": [1, 1, 1], "file": ")") + file + "\"}";
    EXPECT_NE(error_of(scene_json(R"("width": 64, "height": 48)", light)).find("not inside the scene folder"),
              std::string::npos)
        << file;
  }
}

// Truth scenes carry bulbs of any size; a radius that is no bulb is refused.
TEST_F(SceneJsonHardCases, APointLightsRadiusLoadsDefaultsAndIsBounded) {
  const std::string image = R"("width": 64, "height": 48)";
  EXPECT_DOUBLE_EQ(load(scene_json(image)).lights.at(0).radius, kDefaultPointLightRadiusM);
  const SceneModel bulb = load(scene_json(image, R"({"type": "point", "intensity": [1, 1, 1], "radius": 0.012})"));
  EXPECT_DOUBLE_EQ(bulb.lights.at(0).radius, 0.012);
  EXPECT_FLOAT_EQ(bulb.light_rig().sphere_lights.at(0).radius, 0.012f);
  for (const char* radius : {"0", "-1", "1e300"})
    EXPECT_NE(error_of(scene_json(image, std::string(R"({"type": "point", "intensity": [1, 1, 1], "radius": )") +
                                             radius + "}"))
                  .find("radius"),
              std::string::npos)
        << radius;
  SceneModel saved = bulb;
  saved.lights.at(0).radius = 0.3;
  save_scene(saved, (dir_ / "again").string());
  EXPECT_DOUBLE_EQ(load_scene((dir_ / "again").string()).lights.at(0).radius, 0.3);
}

// The photo's imaging (render/photo_imaging.h) travels in scene.json: it
// loads back as saved, a file without it matches nothing, and values no
// camera gives are refused.
TEST_F(SceneJsonHardCases, ThePhotosImagingRoundTripsAndIsBounded) {
  SceneModel scene = load(scene_json());
  EXPECT_FALSE(scene.imaging.blur_measured) << "an older scene.json has no imaging: nothing is matched";
  scene.imaging.blur_measured = true;
  scene.imaging.blur_sigma_px = 1.25;
  scene.imaging.blur_read_through_noise = true;
  scene.imaging.noise_measured = true;
  scene.imaging.noise.sigma[3] = {0.01f, 0.02f, 0.03f};
  render::Defocus& defocus = scene.imaging.defocus;
  defocus.found = true;
  defocus.base_sigma_px = 0.4;
  defocus.focus_dioptres = 0.5;
  defocus.sigma_px_per_dioptre = 4.0;
  defocus.min_dioptres = 0.2;
  defocus.max_dioptres = 0.8;
  defocus.bands = {{0.2, 1.3, 120}, {0.5, 0.4, 300}, {0.8, 1.3, 90}};
  const fs::path saved = dir_ / "saved";
  save_scene(scene, saved.string());
  const SceneModel back = load_scene(saved.string());
  EXPECT_TRUE(back.imaging.blur_measured);
  EXPECT_DOUBLE_EQ(back.imaging.blur_sigma_px, 1.25);
  EXPECT_TRUE(back.imaging.blur_read_through_noise);
  EXPECT_FLOAT_EQ(back.imaging.noise.sigma[3][2], 0.03f);
  EXPECT_TRUE(back.imaging.defocus.found);
  EXPECT_DOUBLE_EQ(back.imaging.defocus.sigma_at(1.25), defocus.sigma_at(1.25));
  ASSERT_EQ(back.imaging.defocus.bands.size(), 3u);
  EXPECT_EQ(back.imaging.defocus.bands[2].edges, 90);
  EXPECT_DOUBLE_EQ(back.imaging.blur_sigma_at(5.0), defocus.sigma_at(5.0)) << "a depth's blur is the defocus's";
  const std::string base = scene_json();
  const auto with_imaging = [&](const std::string& imaging) {
    return base.substr(0, base.size() - 1) + R"(, "imaging": )" + imaging + "}";
  };
  EXPECT_NE(error_of(with_imaging(R"({"blur_sigma_px": 1e300})")).find("blur"), std::string::npos);
  EXPECT_NE(error_of(with_imaging(R"({"blur_sigma_px": -1})")).find("blur"), std::string::npos);
  EXPECT_NE(error_of(with_imaging(R"({"noise_sigma": [[0, 0, 0]]})")).find("bins"), std::string::npos);
  EXPECT_NE(error_of(with_imaging(R"({"defocus": {"found": true, "focus_dioptres": -1}})")).find("defocus"),
            std::string::npos);
  EXPECT_NE(error_of(with_imaging(R"({"defocus": {"min_dioptres": 2, "max_dioptres": 1}})")).find("min <= max"),
            std::string::npos);
  EXPECT_NE(error_of(with_imaging(R"({"defocus": {"bands": [{"dioptres": 0.5, "sigma_px": 99, "edges": 40}]}})"))
                .find("band"),
            std::string::npos);
  EXPECT_NE(error_of(with_imaging(R"({"noise_sigma": [[9,9,9],[0,0,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0],[0,0,0]]})"))
                .find("noise"),
            std::string::npos);
}

// A room's windows and the lights that come through them travel in
// scene.json and reach the renderer's rig; a window without area or with a
// non-finite corner, too many windows, or a room light marked as coming
// through them are refused.
TEST_F(SceneJsonHardCases, WindowsRoundTripAndReachTheRig) {
  const std::string window = R"({"corner": [0, 1, 3], "edge_u": [1, 0, 0], "edge_v": [0, 1, 0]})";
  const std::string sun = R"({"type": "sun", "intensity": [5, 5, 5], "direction": [0, 1, 1], "through_windows": true})";
  const auto with_windows = [&](const std::string& light, const std::string& windows) {
    const std::string base = scene_json(R"("width": 64, "height": 48)", light);
    return base.substr(0, base.size() - 1) + R"(, "windows": [)" + windows + "]}";
  };
  const SceneModel scene = load(with_windows(sun, window));
  ASSERT_EQ(scene.windows.size(), 1u);
  EXPECT_TRUE(scene.lights.at(0).through_windows);
  const render::LightRig rig = scene.light_rig();
  ASSERT_EQ(rig.portals.size(), 1u);
  EXPECT_TRUE(rig.suns.at(0).through_portals);
  EXPECT_TRUE(rig.arrives_from_outside({0.5f, 1.5f, 0.f}, {0.f, 0.f, 1.f}, true));
  save_scene(scene, (dir_ / "again").string());
  const SceneModel back = load_scene((dir_ / "again").string());
  ASSERT_EQ(back.windows.size(), 1u);
  EXPECT_EQ(back.windows[0].edge_v, scene.windows[0].edge_v);
  EXPECT_TRUE(back.lights.at(0).through_windows);
  EXPECT_TRUE(load(scene_json()).windows.empty()) << "a scene without windows lets light in everywhere";

  EXPECT_NE(error_of(with_windows(sun, R"({"corner": [0, 1, 3], "edge_u": [1, 0, 0], "edge_v": [2, 0, 0]})"))
                .find("window"), std::string::npos);
  EXPECT_NE(error_of(with_windows(sun, R"({"corner": [1e300, 1, 3], "edge_u": [1, 0, 0], "edge_v": [0, 1, 0]})"))
                .find("window"), std::string::npos);
  std::string many = window;
  for (size_t i = 0; i < kMaxWindows; ++i) many += "," + window;
  EXPECT_NE(error_of(with_windows(sun, many)).find("windows"), std::string::npos);
  EXPECT_NE(error_of(with_windows(R"({"type": "point", "intensity": [1, 1, 1], "through_windows": true})", window))
                .find("through windows"), std::string::npos);
}

}  // namespace
}  // namespace propcam::inference
