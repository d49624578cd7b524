// SCENE.json: what it builds, and the errors it gives for broken files.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <cmath>
#include <numbers>

#include "propcam/capture/image_file.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene_file.h"

namespace propcam::render {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

fs::path test_folder() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path folder = fs::path(::testing::TempDir()) / "propcam_scene_file" / info->name();
  fs::remove_all(folder);
  fs::create_directories(folder / "assets");
  return folder;
}

// A unit quad facing +Y at y = 0 (two triangles).
void write_quad_obj(const fs::path& path) {
  std::ofstream(path) << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\nf 1 4 3\n";
}

json valid_scene() {
  return json::parse(R"({
    "camera": {"K": {"fx": 20, "fy": 20, "cx": 7.5, "cy": 5.5},
               "R_world_from_cam": [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
               "center": [0, 2, 0], "width": 16, "height": 12},
    "meshes": [{"file": "assets/quad.obj", "material": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}}],
    "lights": [{"type": "area", "position": [0, 3, 0], "normal": [0, -1, 0], "size": [1, 2], "intensity": [5, 5, 5]},
               {"type": "sphere", "position": [1, 1, 0], "radius": 0.1, "intensity": 3},
               {"type": "sun", "direction": [0, 2, 0], "intensity": [1, 1, 1]}]
  })");
}

json spot() {
  return json::parse(R"({"type": "spot", "position": [0, 2, 0], "direction": [0, -1, 0], "cone_angle_deg": 45,
                         "blend": 0.15, "radius": 0.1, "intensity": 10})");
}

json disc() {
  return json::parse(R"({"type": "disc", "position": [0, 2, 0], "normal": [0, -1, 0], "radius": 0.2, "intensity": 3})");
}

fs::path write_scene(const fs::path& folder, const json& scene, const std::string& name = "scene.json") {
  write_quad_obj(folder / "assets" / "quad.obj");
  const fs::path path = folder / name;
  std::ofstream(path) << scene.dump(2);
  return path;
}

// Loading throws a runtime_error whose message contains every `parts`.
void expect_error(const fs::path& path, std::initializer_list<const char*> parts) {
  try {
    load_scene_file(path.string());
    ADD_FAILURE() << "no error for " << path;
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    for (const char* part : parts) EXPECT_NE(message.find(part), std::string::npos) << message;
  }
}

TEST(SceneFile, LoadsCameraMeshesAndLights) {
  const fs::path folder = test_folder();
  const SceneFile file = load_scene_file(write_scene(folder, valid_scene()).string());
  EXPECT_EQ(file.camera.width, 16);
  EXPECT_EQ(file.camera.height, 12);
  EXPECT_DOUBLE_EQ(file.camera.fx, 20.0);
  EXPECT_DOUBLE_EQ(file.camera.center_world.y(), 2.0);
  // Camera z (forward) is world -Y: the camera looks down.
  EXPECT_NEAR((file.camera.R_world_from_cam * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, -1, 0)).norm(), 0, 1e-12);
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].materials.at(0).type, Material::Type::Diffuse);
  ASSERT_EQ(file.lights.area_lights.size(), 1u);
  const AreaLight& area = file.lights.area_lights[0];
  EXPECT_NEAR((area.normal() - Eigen::Vector3f(0, -1, 0)).norm(), 0.f, 1e-6f);
  EXPECT_NEAR(area.area(), 2.f, 1e-6f);
  EXPECT_NEAR((area.centre() - Eigen::Vector3f(0, 3, 0)).norm(), 0.f, 1e-6f);
  ASSERT_EQ(file.lights.sphere_lights.size(), 1u);
  EXPECT_EQ(file.lights.sphere_lights[0].radiance, Eigen::Vector3f::Constant(3.f));  // a number is grey
  ASSERT_EQ(file.lights.suns.size(), 1u);
  EXPECT_NEAR(file.lights.suns[0].direction.norm(), 1.f, 1e-6f);
  EXPECT_NEAR(file.lights.suns[0].angular_radius, 0.265 * std::numbers::pi / 180.0, 1e-12);  // the default
  const auto scene = build_scene(file);
  RenderSettings settings;
  settings.samples_per_pixel = 4;
  const cv::Mat image = render_image(*scene, file.camera, file.lights, settings);
  EXPECT_TRUE(cv::checkRange(image));
  EXPECT_GT(cv::mean(image)[0], 0.0);
}

TEST(SceneFile, TransformsMeshesAndKeepsMirroredOnesOutward) {
  const fs::path folder = test_folder();
  json scene = valid_scene();
  scene["meshes"][0]["transform"] = json::parse("[[2, 0, 0, 1], [0, 1, 0, 0.5], [0, 0, 1, 0], [0, 0, 0, 1]]");
  json mirrored = scene["meshes"][0];
  mirrored["transform"] = json::parse("[[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]");
  scene["meshes"].push_back(mirrored);
  const SceneFile file = load_scene_file(write_scene(folder, scene).string());
  const Eigen::AlignedBox3f box = file.meshes[0].bounds();
  EXPECT_NEAR(box.min().x(), -1.f, 1e-6f);
  EXPECT_NEAR(box.max().x(), 3.f, 1e-6f);
  EXPECT_NEAR(box.min().y(), 0.5f, 1e-6f);
  // Mirrored in x, the quad (facing +Y) must still face +Y: the winding is flipped with it.
  const Mesh& m = file.meshes[1];
  const Eigen::Vector3i t = m.triangles[0];
  const Eigen::Vector3f n = (m.positions[t[1]] - m.positions[t[0]]).cross(m.positions[t[2]] - m.positions[t[0]]);
  EXPECT_GT(n.y(), 0.f);
}

TEST(SceneFile, MaterialTypesAndParameters) {
  const fs::path folder = test_folder();
  json scene = valid_scene();
  scene["meshes"][0]["material"] = json::parse(R"({"type": "glass", "ior": 1.33, "roughness": 0.1})");
  json plastic = scene["meshes"][0];
  plastic["material"] = json::parse(R"({"type": "plastic", "albedo": 0.3, "ior": 1.5, "roughness": 0.2})");
  json lamp = scene["meshes"][0];
  lamp["material"] = json::parse(R"({"type": "emissive", "emission": [2, 1, 0]})");
  json from_mtl = scene["meshes"][0];
  from_mtl.erase("material");
  scene["meshes"].insert(scene["meshes"].end(), {plastic, lamp, from_mtl});
  const SceneFile file = load_scene_file(write_scene(folder, scene).string());
  const Material& glass = file.meshes[0].materials[0];
  EXPECT_EQ(glass.type, Material::Type::Dielectric);
  EXPECT_FLOAT_EQ(glass.ior, 1.33f);
  EXPECT_FLOAT_EQ(glass.roughness, 0.1f);
  const Material& coat = file.meshes[1].materials[0];
  EXPECT_EQ(coat.type, Material::Type::Plastic);
  EXPECT_NEAR(coat.specular, 0.04f, 1e-6f);
  EXPECT_NEAR(coat.albedo.x(), 0.3f, 1e-6f);
  EXPECT_EQ(file.meshes[2].materials[0].type, Material::Type::Emissive);
  EXPECT_EQ(file.meshes[3].materials[0].name, "default_grey");  // no material, no MTL: the OBJ loader's default
}

TEST(SceneFile, EnvironmentFromAnExrNextToTheScene) {
  const fs::path folder = test_folder();
  cv::Mat sky(8, 16, CV_32FC3, cv::Scalar::all(0.5));
  ASSERT_NO_THROW(capture::write_image((folder / "assets" / "sky.exr").string(), sky));
  json scene = valid_scene();
  scene["lights"].push_back(json::parse(R"({"type": "ibl", "file": "assets/sky.exr", "intensity": [2, 2, 2]})"));
  const SceneFile file = load_scene_file(write_scene(folder, scene).string());
  ASSERT_TRUE(file.lights.environment);
  EXPECT_NEAR(file.lights.environment->radiance(Eigen::Vector3f::UnitY()).x(), 1.f, 1e-6f);
  EXPECT_EQ(file.lights.count(), 4);
  scene["lights"].push_back(scene["lights"].back());
  expect_error(write_scene(folder, scene), {"lights[4]", "one ibl"});
}

// A room's windows: `portals` (rectangles as area lights are given), and a
// sun or sky marked `through_portals` that reaches the floor only through
// them; a portal without area is an error naming it.
TEST(SceneFile, PortalsAndTheLightsThatComeThroughThem) {
  const fs::path folder = test_folder();
  json scene = valid_scene();
  scene["lights"] = json::parse(R"([{"type": "sun", "direction": [0, 1, 0], "intensity": [2, 2, 2], "through_portals": true}])");
  scene["portals"] = json::parse(R"([{"position": [0, 1, 0], "normal": [0, -1, 0], "size": [0.5, 0.5]}])");
  const SceneFile file = load_scene_file(write_scene(folder, scene).string());
  ASSERT_EQ(file.lights.portals.size(), 1u);
  EXPECT_TRUE(file.lights.suns.at(0).through_portals);
  EXPECT_TRUE(file.lights.arrives_from_outside({0.f, 0.f, 0.f}, Eigen::Vector3f::UnitY(), true));
  EXPECT_FALSE(file.lights.arrives_from_outside({0.5f, 0.f, 0.f}, Eigen::Vector3f::UnitY(), true));
  // The camera 2 m up looks down on the quad: lit only under the 0.5 m window.
  const auto built = build_scene(file);
  RenderSettings settings;
  settings.samples_per_pixel = 4;
  const cv::Mat image = render_image(*built, file.camera, file.lights, settings);
  EXPECT_GT(image.at<cv::Vec3f>(5, 7)[0], 0.1f);  // the middle of the floor
  EXPECT_EQ(image.at<cv::Vec3f>(0, 0)[0], 0.f);   // a corner, beside the window's light
  scene["portals"][0]["size"] = {0.5, 0};
  expect_error(write_scene(folder, scene), {"portals[0].size", "area"});
  scene["portals"] = json::parse(R"([{"position": [0, 1, 0], "normal": [0, -1, 0], "size": [1, 1], "colour": 1}])");
  expect_error(write_scene(folder, scene), {"portals[0].colour", "unknown field"});
}

// The newer light kinds and fields: spot (a sphere, or with radius 0 a
// point, in a cone), point, disc, a rectangle turned about its normal, and
// visible_to_camera on every light; rig order area, sphere, sun, disc, point.
TEST(SceneFile, SpotPointDiscRotationAndCameraVisibility) {
  const fs::path folder = test_folder();
  cv::Mat sky(8, 16, CV_32FC3, cv::Scalar::all(0.5));
  ASSERT_NO_THROW(capture::write_image((folder / "assets" / "sky.exr").string(), sky));
  json scene = valid_scene();
  scene["lights"][0]["rotation_deg"] = 90;
  scene["lights"][0]["visible_to_camera"] = false;
  scene["lights"][2]["visible_to_camera"] = false;
  scene["lights"].push_back(json::parse(R"({"type": "spot", "position": [0, 2, 0], "direction": [0, -2, 0],
      "cone_angle_deg": 60, "blend": 0.25, "radius": 0.05, "intensity": [40, 30, 20], "visible_to_camera": false})"));
  scene["lights"].push_back(json::parse(R"({"type": "spot", "position": [0.5, 2, 0], "direction": [1, -1, 0],
      "cone_angle_deg": 180, "radius": 0, "intensity": 7})"));
  scene["lights"].push_back(json::parse(R"({"type": "point", "position": [-0.5, 1.5, 0], "intensity": [1, 2, 3]})"));
  scene["lights"].push_back(json::parse(R"({"type": "disc", "position": [0, 2.5, 0.5], "normal": [0, -1, 0],
      "radius": 0.3, "intensity": 4, "visible_to_camera": true})"));
  scene["lights"].push_back(json::parse(R"({"type": "ibl", "file": "assets/sky.exr", "visible_to_camera": false})"));
  const SceneFile file = load_scene_file(write_scene(folder, scene).string());
  const LightRig& rig = file.lights;
  // The rectangle turned 90 degrees about its normal (-Y, counter-clockwise
  // from below): its 1 m width now runs along +Z; centre, area and facing kept.
  ASSERT_EQ(rig.area_lights.size(), 1u);
  const AreaLight& area = rig.area_lights[0];
  EXPECT_NEAR((area.edge_u - Eigen::Vector3f(0, 0, 1)).norm(), 0.f, 1e-6f);
  EXPECT_NEAR((area.normal() - Eigen::Vector3f(0, -1, 0)).norm(), 0.f, 1e-6f);
  EXPECT_NEAR((area.centre() - Eigen::Vector3f(0, 3, 0)).norm(), 0.f, 1e-6f);
  EXPECT_NEAR(area.area(), 2.f, 1e-6f);
  EXPECT_FALSE(area.visible_to_camera);
  // Spheres: the plain one, then the spot of radius 0.05 (a sphere with a cone).
  ASSERT_EQ(rig.sphere_lights.size(), 2u);
  EXPECT_TRUE(rig.sphere_lights[0].visible_to_camera);
  EXPECT_FALSE(rig.sphere_lights[0].spot);
  const SphereLight& spot = rig.sphere_lights[1];
  ASSERT_TRUE(spot.spot);
  EXPECT_FLOAT_EQ(spot.radius, 0.05f);
  EXPECT_EQ(spot.radiance, Eigen::Vector3f(40, 30, 20));
  EXPECT_NEAR((spot.spot->direction - Eigen::Vector3f(0, -1, 0)).norm(), 0.f, 1e-6f);
  EXPECT_NEAR(spot.spot->half_angle, std::numbers::pi / 6, 1e-12);
  EXPECT_DOUBLE_EQ(spot.spot->blend, 0.25);
  EXPECT_FALSE(spot.visible_to_camera);
  ASSERT_EQ(rig.suns.size(), 1u);
  EXPECT_FALSE(rig.suns[0].visible_to_camera);
  ASSERT_EQ(rig.disc_lights.size(), 1u);
  EXPECT_NEAR((rig.disc_lights[0].centre - Eigen::Vector3f(0, 2.5f, 0.5f)).norm(), 0.f, 1e-6f);
  EXPECT_FLOAT_EQ(rig.disc_lights[0].radius, 0.3f);
  EXPECT_EQ(rig.disc_lights[0].radiance, Eigen::Vector3f::Constant(4.f));
  EXPECT_TRUE(rig.disc_lights[0].visible_to_camera);
  // Points: the spot of radius 0 (intensity in W/sr, a hemisphere; blend defaults to Blender's 0.15), then the point.
  ASSERT_EQ(rig.point_lights.size(), 2u);
  ASSERT_TRUE(rig.point_lights[0].spot);
  EXPECT_NEAR(rig.point_lights[0].spot->half_angle, std::numbers::pi / 2, 1e-12);
  EXPECT_DOUBLE_EQ(rig.point_lights[0].spot->blend, 0.15);
  EXPECT_EQ(rig.point_lights[0].intensity, Eigen::Vector3f::Constant(7.f));
  EXPECT_FALSE(rig.point_lights[1].spot);
  EXPECT_EQ(rig.point_lights[1].intensity, Eigen::Vector3f(1, 2, 3));
  ASSERT_TRUE(rig.environment);
  EXPECT_FALSE(rig.environment->visible_to_camera());
  EXPECT_EQ(rig.count(), 1 + 2 + 1 + 1 + 2 + 1);
  const auto built = build_scene(file);
  RenderSettings settings;
  settings.samples_per_pixel = 4;
  const cv::Mat image = render_image(*built, file.camera, file.lights, settings);
  EXPECT_TRUE(cv::checkRange(image));
  EXPECT_GT(cv::mean(image)[0], 0.0);
}

struct BrokenCase {
  std::string name;
  std::function<void(json&)> edit;
  std::vector<std::string> expected;  // substrings of the error
};

// One test over all broken files (a process per case would cost more than the cases).
TEST(SceneFile, BrokenFilesNameTheFieldAndTheFile) {
  const fs::path folder = test_folder();
  const std::vector<BrokenCase> cases = {
      BrokenCase{"missing_camera", [](json& s) { s.erase("camera"); }, {"camera", "missing"}},
      BrokenCase{"missing_fx", [](json& s) { s["camera"]["K"].erase("fx"); }, {"camera.K.fx", "missing"}},
      BrokenCase{"fx_string", [](json& s) { s["camera"]["K"]["fx"] = "20"; }, {"camera.K.fx", "expected a number"}},
      BrokenCase{"fx_negative", [](json& s) { s["camera"]["K"]["fx"] = -1; }, {"camera.K.fx", "positive"}},
      BrokenCase{"width_fraction", [](json& s) { s["camera"]["width"] = 16.5; }, {"camera.width", "integer"}},
      BrokenCase{"not_a_rotation", [](json& s) { s["camera"]["R_world_from_cam"][0][0] = 2; },
         {"R_world_from_cam", "not a rotation"}},
      BrokenCase{"short_row", [](json& s) { s["camera"]["R_world_from_cam"][1] = json::array({0, 1}); },
         {"R_world_from_cam[1]", "3 numbers"}},
      BrokenCase{"center_null", [](json& s) { s["camera"]["center"][2] = nullptr; }, {"camera.center[2]", "number"}},
      BrokenCase{"meshes_object", [](json& s) { s["meshes"] = json::object(); }, {"meshes", "expected an array"}},
      BrokenCase{"missing_file", [](json& s) { s["meshes"][0]["file"] = "assets/none.obj"; },
         {"meshes[0].file", "no such file"}},
      BrokenCase{"absolute_path", [](json& s) { s["meshes"][0]["file"] = "/etc/passwd"; },
         {"meshes[0].file", "relative"}},
      BrokenCase{"escaping_path", [](json& s) { s["meshes"][0]["file"] = "assets/../../quad.obj"; },
         {"meshes[0].file", "leaves"}},
      BrokenCase{"unknown_material", [](json& s) { s["meshes"][0]["material"]["type"] = "velvet"; },
         {"meshes[0].material.type", "velvet"}},
      BrokenCase{"albedo_above_one", [](json& s) { s["meshes"][0]["material"]["albedo"] = {0.5, 2, 0.5}; },
         {"meshes[0].material.albedo", "outside"}},
      BrokenCase{"typo_field", [](json& s) { s["meshes"][0]["material"]["roughnes"] = 0.5; },
         {"meshes[0].material.roughnes", "unknown field"}},
      BrokenCase{"emissive_without_emission", [](json& s) { s["meshes"][0]["material"]["type"] = "emissive"; },
         {"meshes[0].material.emission", "missing"}},
      BrokenCase{"bad_transform", [](json& s) { s["meshes"][0]["transform"] = json::array({1, 2}); },
         {"meshes[0].transform"}},
      BrokenCase{"singular_transform",
                   [](json& s) {
                     s["meshes"][0]["transform"] =
                         json::parse("[[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]");
                   },
         {"meshes[0].transform", "singular"}},
      BrokenCase{"unknown_light", [](json& s) { s["lights"][0]["type"] = "laser"; }, {"lights[0].type", "laser"}},
      BrokenCase{"zero_normal", [](json& s) { s["lights"][0]["normal"] = {0, 0, 0}; },
         {"lights[0].normal", "zero"}},
      BrokenCase{"negative_radius", [](json& s) { s["lights"][1]["radius"] = -1; }, {"lights[1].radius"}},
      BrokenCase{"missing_intensity", [](json& s) { s["lights"][2].erase("intensity"); },
         {"lights[2].intensity", "missing"}},
      BrokenCase{"wide_sun", [](json& s) { s["lights"][2]["angle_deg"] = 60; }, {"lights[2].angle_deg"}},
      BrokenCase{"missing_ibl_file", [](json& s) { s["lights"].push_back({{"type", "ibl"}, {"file", "sky.exr"}}); },
         {"lights[3].file", "no such file"}},
      BrokenCase{"zero_sphere", [](json& s) { s["lights"][1]["radius"] = 0; }, {"lights[1].radius", "type point"}},
      BrokenCase{"tiny_sphere", [](json& s) { s["lights"][1]["radius"] = 1e-8; }, {"lights[1].radius", "at least"}},
      BrokenCase{"rotation_string", [](json& s) { s["lights"][0]["rotation_deg"] = "30"; },
         {"lights[0].rotation_deg", "expected a number"}},
      BrokenCase{"rotation_huge", [](json& s) { s["lights"][0]["rotation_deg"] = 400; },
         {"lights[0].rotation_deg", "outside"}},
      BrokenCase{"visible_not_bool", [](json& s) { s["lights"][2]["visible_to_camera"] = 1; },
         {"lights[2].visible_to_camera", "true or false"}},
      BrokenCase{"spot_negative_radius", [](json& s) { s["lights"].push_back(spot()); s["lights"][3]["radius"] = -0.1; },
         {"lights[3].radius", "outside"}},
      BrokenCase{"spot_cone_too_wide", [](json& s) { s["lights"].push_back(spot()); s["lights"][3]["cone_angle_deg"] = 181; },
         {"lights[3].cone_angle_deg", "outside [0, 180]"}},
      BrokenCase{"spot_cone_negative", [](json& s) { s["lights"].push_back(spot()); s["lights"][3]["cone_angle_deg"] = -1; },
         {"lights[3].cone_angle_deg", "outside"}},
      BrokenCase{"spot_cone_nan",  // JSON has no NaN: it is written as null
         [](json& s) { s["lights"].push_back(spot()); s["lights"][3]["cone_angle_deg"] = std::nan(""); },
         {"lights[3].cone_angle_deg", "expected a number"}},
      BrokenCase{"spot_blend", [](json& s) { s["lights"].push_back(spot()); s["lights"][3]["blend"] = 1.5; },
         {"lights[3].blend", "outside [0, 1]"}},
      BrokenCase{"spot_typo", [](json& s) { s["lights"].push_back(spot()); s["lights"][3]["spot_size"] = 45; },
         {"lights[3].spot_size", "unknown field"}},
      BrokenCase{"spot_no_cone", [](json& s) { s["lights"].push_back(spot()); s["lights"][3].erase("cone_angle_deg"); },
         {"lights[3].cone_angle_deg", "missing"}},
      BrokenCase{"spot_zero_direction", [](json& s) { s["lights"].push_back(spot()); s["lights"][3]["direction"] = {0, 0, 0}; },
         {"lights[3].direction", "zero"}},
      BrokenCase{"point_radius",
         [](json& s) { s["lights"].push_back({{"type", "point"}, {"position", {0, 1, 0}}, {"intensity", 1}, {"radius", 0.1}}); },
         {"lights[3].radius", "unknown field"}},
      BrokenCase{"point_infinite", [](json& s) {
                   s["lights"].push_back({{"type", "point"}, {"position", {0, 1, 0}}, {"intensity", 1e300 * 1e300}}); },
         {"lights[3].intensity"}},
      BrokenCase{"disc_negative_radius", [](json& s) { s["lights"].push_back(disc()); s["lights"][3]["radius"] = -1; },
         {"lights[3].radius", "outside"}},
      BrokenCase{"disc_no_normal", [](json& s) { s["lights"].push_back(disc()); s["lights"][3].erase("normal"); },
         {"lights[3].normal", "missing"}}};
  for (const BrokenCase& c : cases) {
    SCOPED_TRACE(c.name);
    json scene = valid_scene();
    c.edit(scene);
    const fs::path path = write_scene(folder, scene, c.name + ".json");
    try {
      load_scene_file(path.string());
      ADD_FAILURE() << "no error";
    } catch (const std::runtime_error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path.string()), std::string::npos) << message;
      for (const auto& part : c.expected) EXPECT_NE(message.find(part), std::string::npos) << message;
    }
  }
}

TEST(SceneFile, UnreadableAndInvalidJsonAreClearErrors) {
  const fs::path folder = test_folder();
  expect_error(folder / "nothing.json", {"nothing.json", "cannot open"});
  std::ofstream(folder / "broken.json") << "{\"camera\": {";
  expect_error(folder / "broken.json", {"broken.json", "invalid JSON"});
  // Numbers beyond double range are refused by the parser (nothing non-finite gets through).
  std::ofstream(folder / "overflow.json") << R"({"camera": {"K": {"fx": 1e999}}})";
  expect_error(folder / "overflow.json", {"overflow.json", "invalid JSON", "1e999"});
  std::ofstream(folder / "array.json") << "[1, 2]";
  expect_error(folder / "array.json", {"array.json", "expected an object"});
}

}  // namespace
}  // namespace propcam::render
