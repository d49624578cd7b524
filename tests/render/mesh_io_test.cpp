#include "propcam/render/mesh_io.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "propcam/render/props.h"

namespace propcam::render {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3f;

// A fresh folder per test under the gtest temp dir.
fs::path test_folder() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string("propcam_mesh_io_") + info->test_suite_name() + "_" + info->name();
  for (char& c : name)
    if (c == '/') c = '_';
  const fs::path folder = fs::path(::testing::TempDir()) / name;
  fs::remove_all(folder);
  fs::create_directories(folder);
  return folder;
}

void write_file(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

// The message of the std::runtime_error `action` throws, or "" if it does not.
std::string runtime_error_of(const std::function<void()>& action) {
  try {
    action();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

float srgb_to_linear(float encoded) {
  return encoded <= 0.04045f ? encoded / 12.92f : std::pow((encoded + 0.055f) / 1.055f, 2.4f);
}

TEST(MeshIo, PresetsSurviveAnObjRoundTrip) {
  const fs::path folder = test_folder();
  for (const auto& preset : prop_presets()) {
    SCOPED_TRACE(preset.name);
    const Mesh original = make_prop(preset.name);
    const fs::path path = folder / (preset.name + ".obj");
    save_obj(original, path.string());
    const Mesh loaded = load_mesh_file(path.string());
    ASSERT_NO_THROW(loaded.validate());
    ASSERT_EQ(loaded.triangles.size(), original.triangles.size());
    EXPECT_LT((loaded.bounds().max() - original.bounds().max()).norm(), 1e-4f);
    EXPECT_LT((loaded.bounds().min() - original.bounds().min()).norm(), 1e-4f);
    ASSERT_EQ(loaded.normals.size(), loaded.positions.size());
    for (size_t t = 0; t < original.triangles.size(); ++t) {
      const Material& a = original.materials[original.material_ids[t]];
      const Material& b = loaded.materials[loaded.material_ids[t]];
      ASSERT_EQ(a.type, b.type) << a.name;
      ASSERT_LT((a.albedo - b.albedo).norm(), 1e-5f) << a.name;
      ASSERT_EQ(a.name, b.name);
      for (int k = 0; k < 3; ++k) {
        ASSERT_LT((original.positions[original.triangles[t][k]] - loaded.positions[loaded.triangles[t][k]]).norm(),
                  1e-6f);
        ASSERT_LT((original.normals[original.triangles[t][k]] - loaded.normals[loaded.triangles[t][k]]).norm(), 1e-5f);
      }
    }
  }
}

TEST(MeshIo, RoundTripKeepsMaterialParametersTexturesAndUvs) {
  const fs::path folder = test_folder();
  Mesh quad;
  // A textured quad and two separate triangles.
  quad.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 0},
                    {3, 0, 0}, {3, 1, 0}, {4, 0, 0}, {5, 0, 0}, {5, 1, 0}};
  quad.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.25f, 0.75f}, {0, 0}, {0, 0}, {0, 0}, {0, 0}, {0, 0}};
  quad.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  quad.compute_vertex_normals();
  Material textured;
  textured.name = "printed paper";  // a space must not break the MTL
  textured.type = Material::Type::Glossy;
  textured.albedo = {1.f, 1.f, 1.f};
  textured.specular = 0.05f;
  textured.roughness = 0.3f;
  cv::Mat texture(2, 3, CV_32FC3);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x)
      texture.at<cv::Vec3f>(y, x) = cv::Vec3f(0.1f * static_cast<float>(x), 0.5f, 0.9f * static_cast<float>(y));
  textured.texture = std::make_shared<const cv::Mat>(texture);
  Material lamp;
  lamp.name = "lamp";
  lamp.type = Material::Type::Emissive;
  lamp.emission = {5.f, 4.f, 3.f};
  Material gold;
  gold.name = "gold";
  gold.type = Material::Type::Metal;
  gold.albedo = {1.f, 0.71f, 0.29f};
  gold.roughness = 0.15f;
  quad.materials = {textured, lamp, gold};
  quad.material_ids = {0, 0, 1, 2};

  const fs::path path = folder / "quad.obj";
  save_obj(quad, path.string());
  // Only the final files remain: no temporaries.
  std::set<std::string> files;
  for (const auto& entry : fs::directory_iterator(folder)) files.insert(entry.path().filename().string());
  EXPECT_EQ(files, (std::set<std::string>{"quad.obj", "quad.mtl", "quad_printed_paper.png"}));

  const Mesh loaded = load_mesh_file(path.string());
  ASSERT_EQ(loaded.triangles.size(), 4u);
  ASSERT_EQ(loaded.uvs.size(), loaded.positions.size());
  for (size_t t = 0; t < 4; ++t)
    for (int k = 0; k < 3; ++k)
      EXPECT_LT((loaded.uvs[loaded.triangles[t][k]] - quad.uvs[quad.triangles[t][k]]).norm(), 1e-6f);
  const Material& paper = loaded.materials[loaded.material_ids[0]];
  EXPECT_EQ(paper.type, Material::Type::Glossy);
  EXPECT_NEAR(paper.specular, 0.05f, 1e-6f);
  EXPECT_NEAR(paper.roughness, 0.3f, 1e-5f);
  ASSERT_TRUE(paper.texture);
  ASSERT_EQ(paper.texture->type(), CV_32FC3);
  ASSERT_EQ(paper.texture->size(), texture.size());
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(paper.texture->at<cv::Vec3f>(y, x)[c], texture.at<cv::Vec3f>(y, x)[c], 0.005f);
  const Material& loaded_lamp = loaded.materials[loaded.material_ids[2]];
  EXPECT_EQ(loaded_lamp.type, Material::Type::Emissive);
  EXPECT_LT((loaded_lamp.emission - lamp.emission).norm(), 1e-6f);
  const Material& loaded_gold = loaded.materials[loaded.material_ids[3]];
  EXPECT_EQ(loaded_gold.type, Material::Type::Metal);
  EXPECT_LT((loaded_gold.albedo - gold.albedo).norm(), 1e-6f);
  EXPECT_NEAR(loaded_gold.roughness, 0.15f, 1e-5f);
}

TEST(MeshIo, RoundTripKeepsGlassAndItsIndex) {
  const fs::path folder = test_folder();
  Mesh cube = make_prop("cube");
  for (auto& m : cube.materials) {
    m.type = Material::Type::Dielectric;
    m.ior = 1.33f;
    m.roughness = 0.1f;
  }
  save_obj(cube, (folder / "glass.obj").string());
  const Mesh loaded = load_mesh_file((folder / "glass.obj").string());
  for (const Material& m : loaded.materials) {
    EXPECT_EQ(m.type, Material::Type::Dielectric);
    EXPECT_NEAR(m.ior, 1.33f, 1e-5f);
    EXPECT_NEAR(m.roughness, 0.1f, 1e-5f);
  }
  // Hand-written MTL: illum 7 without Ni is glass of index 1.5.
  write_file(folder / "g.obj", "mtllib g.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl g\nf 1 2 3\n");
  write_file(folder / "g.mtl", "newmtl g\nKd 1 1 1\nillum 7\n");
  const Mesh hand = load_mesh_file((folder / "g.obj").string());
  EXPECT_EQ(hand.materials.at(hand.material_ids.at(0)).type, Material::Type::Dielectric);
  EXPECT_NEAR(hand.materials.at(hand.material_ids.at(0)).ior, 1.5f, 1e-6f);
}

TEST(MeshIo, RoundTripHandlesSpacesInFileNames) {
  const fs::path folder = test_folder();
  Mesh mesh = make_prop("cube");
  cv::Mat texture(1, 1, CV_32FC3, cv::Scalar(0.25f, 0.5f, 0.75f));
  mesh.materials[0].texture = std::make_shared<const cv::Mat>(texture);
  const fs::path path = folder / "my cube.obj";
  save_obj(mesh, path.string());
  EXPECT_TRUE(fs::exists(folder / "my cube.mtl"));
  const Mesh loaded = load_mesh_file(path.string());
  ASSERT_EQ(loaded.materials.size(), 1u);
  EXPECT_EQ(loaded.materials[0].name, mesh.materials[0].name);
  ASSERT_TRUE(loaded.materials[0].texture);
  EXPECT_NEAR(loaded.materials[0].texture->at<cv::Vec3f>(0, 0)[2], 0.75f, 0.005f);
}

TEST(MeshIo, MapsHandWrittenMtlMaterials) {
  const fs::path folder = test_folder();
  // The MTL lives in a subfolder; its texture path is relative to that folder.
  write_file(folder / "scene.obj",
             "mtllib materials/scene.mtl\n"
             "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
             "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
             "f 1 2 3\n"  // before any usemtl: default material
             "usemtl matte\nf 1 2 3 4\n"
             "usemtl glossy\nf 1 2 3\n"
             "usemtl chrome\nf 1 2 3\n"
             "usemtl dark_bright\nf 1 2 3\n"
             "usemtl lamp\nf 1 2 3\n"
             "usemtl textured\nf 1/1 2/2 3/3\n");
  write_file(folder / "materials" / "scene.mtl",
             "newmtl matte\nKd 0.5 0.25 0.125\nKs 0 0 0\n\n"
             "newmtl glossy\nKd 0.1 0.2 0.3\nKs 0.04 0.05 0.04\nNs 98\nillum 2\n\n"
             "newmtl chrome\nKd 0.5 0.5 0.5\nKs 0.55 0.56 0.57\nNs 2000\nillum 3\n\n"
             "newmtl dark_bright\nKd 0.02 0.02 0.02\nKs 0.9 0.8 0.7\nNs 200\nillum 2\n\n"
             "newmtl lamp\nKd 0.8 0.8 0.8\nKe 10 9 8\n\n"
             "newmtl textured\nKd 1 1 1\nmap_Kd textures/tex.png\n");
  cv::Mat bgr(1, 2, CV_8UC3);
  bgr.at<cv::Vec3b>(0, 0) = cv::Vec3b(0, 0, 255);      // pure red in BGR order
  bgr.at<cv::Vec3b>(0, 1) = cv::Vec3b(128, 128, 128);  // sRGB mid grey
  fs::create_directories(folder / "materials" / "textures");
  ASSERT_TRUE(cv::imwrite((folder / "materials" / "textures" / "tex.png").string(), bgr));

  const Mesh mesh = load_mesh_file((folder / "scene.obj").string());
  ASSERT_EQ(mesh.triangles.size(), 8u);  // the quad is split in two
  const auto material_of = [&](int triangle) -> const Material& { return mesh.materials[mesh.material_ids[triangle]]; };

  EXPECT_EQ(material_of(0).type, Material::Type::Diffuse);
  EXPECT_EQ(material_of(0).name, "default_grey");

  EXPECT_EQ(material_of(1).type, Material::Type::Diffuse);
  EXPECT_EQ(material_of(2).name, "matte");
  EXPECT_LT((material_of(1).albedo - Vector3f(0.5f, 0.25f, 0.125f)).norm(), 1e-6f);

  const Material& glossy = material_of(3);
  EXPECT_EQ(glossy.type, Material::Type::Glossy);
  EXPECT_LT((glossy.albedo - Vector3f(0.1f, 0.2f, 0.3f)).norm(), 1e-6f);
  EXPECT_NEAR(glossy.specular, 0.05f, 1e-6f);
  EXPECT_NEAR(glossy.roughness, std::sqrt(2.f / 100.f), 1e-5f);

  const Material& chrome = material_of(4);
  EXPECT_EQ(chrome.type, Material::Type::Metal);
  EXPECT_LT((chrome.albedo - Vector3f(0.55f, 0.56f, 0.57f)).norm(), 1e-6f);
  EXPECT_NEAR(chrome.roughness, std::sqrt(2.f / 2002.f), 1e-5f);

  EXPECT_EQ(material_of(5).type, Material::Type::Metal);  // bright Ks over dark Kd
  EXPECT_LT((material_of(5).albedo - Vector3f(0.9f, 0.8f, 0.7f)).norm(), 1e-6f);

  const Material& lamp = material_of(6);
  EXPECT_EQ(lamp.type, Material::Type::Emissive);
  EXPECT_LT((lamp.emission - Vector3f(10.f, 9.f, 8.f)).norm(), 1e-6f);

  const Material& textured = material_of(7);
  ASSERT_TRUE(textured.texture);
  ASSERT_EQ(textured.texture->type(), CV_32FC3);
  const cv::Vec3f red = textured.texture->at<cv::Vec3f>(0, 0);
  const cv::Vec3f grey = textured.texture->at<cv::Vec3f>(0, 1);
  EXPECT_NEAR(red[0], 1.f, 1e-6f);  // RGB order after conversion
  EXPECT_NEAR(red[1], 0.f, 1e-6f);
  EXPECT_NEAR(red[2], 0.f, 1e-6f);
  EXPECT_NEAR(grey[1], srgb_to_linear(128.f / 255.f), 1e-5f);
  EXPECT_NEAR(grey[1], 0.2158605f, 1e-4f);
  // OBJ's v runs up, the mesh's (image rows) down.
  ASSERT_EQ(mesh.uvs.size(), mesh.positions.size());
  const Eigen::Vector3i& corners = mesh.triangles[7];
  EXPECT_LT((mesh.uvs[corners[0]] - Eigen::Vector2f(0.f, 1.f)).norm(), 1e-6f);
  EXPECT_LT((mesh.uvs[corners[1]] - Eigen::Vector2f(1.f, 1.f)).norm(), 1e-6f);
  EXPECT_LT((mesh.uvs[corners[2]] - Eigen::Vector2f(1.f, 0.f)).norm(), 1e-6f);
}

TEST(MeshIo, SplitsVerticesByIndexTripleAndComputesMissingNormals) {
  const fs::path folder = test_folder();
  const std::string cube_positions =
      "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n";
  write_file(folder / "with_normals.obj", cube_positions +
                                              "vn 0 0 -1\nvn 0 0 1\nvn 0 -1 0\nvn 0 1 0\nvn -1 0 0\nvn 1 0 0\n"
                                              "f 1//1 4//1 3//1 2//1\nf 5//2 6//2 7//2 8//2\nf 1//3 2//3 6//3 5//3\n"
                                              "f 4//4 8//4 7//4 3//4\nf 1//5 5//5 8//5 4//5\nf 2//6 3//6 7//6 6//6\n");
  write_file(folder / "without_normals.obj",
             cube_positions + "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n");
  for (const char* name : {"with_normals.obj", "without_normals.obj"}) {
    SCOPED_TRACE(name);
    const Mesh cube = load_mesh_file((folder / name).string());
    ASSERT_EQ(cube.triangles.size(), 12u);
    EXPECT_EQ(cube.positions.size(), 24u);  // 8 corners x 3 faces each
    ASSERT_EQ(cube.materials.size(), 1u);   // no MTL: one default material
    EXPECT_EQ(cube.materials[0].type, Material::Type::Diffuse);
    EXPECT_TRUE(cube.uvs.empty());
    for (const auto& t : cube.triangles) {
      const Vector3f face =
          (cube.positions[t[1]] - cube.positions[t[0]]).cross(cube.positions[t[2]] - cube.positions[t[0]]).normalized();
      for (int k = 0; k < 3; ++k) EXPECT_LT((cube.normals[t[k]] - face).norm(), 1e-5f);  // flat faces
    }
  }

  // A zero normal in the file counts as missing.
  write_file(folder / "zero_normal.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n");
  const Mesh zero_normal = load_mesh_file((folder / "zero_normal.obj").string());
  EXPECT_LT((zero_normal.normals[0] - Vector3f::UnitZ()).norm(), 1e-6f);

  // A shallow fold is smoothed: the shared edge keeps one vertex per position.
  write_file(folder / "fold.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.2\nf 1 2 3\nf 2 4 3\n");
  const Mesh fold = load_mesh_file((folder / "fold.obj").string());
  EXPECT_EQ(fold.positions.size(), 4u);
}

TEST(MeshIo, MissingMtlFallsBackToDefaultGrey) {
  const fs::path folder = test_folder();
  write_file(folder / "lonely.obj", "mtllib nowhere.mtl\nusemtl wood\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const Mesh mesh = load_mesh_file((folder / "lonely.obj").string());
  ASSERT_EQ(mesh.materials.size(), 1u);
  EXPECT_EQ(mesh.materials[0].type, Material::Type::Diffuse);
  EXPECT_LT((mesh.materials[0].albedo - Vector3f::Constant(0.5f)).norm(), 1e-6f);
  ASSERT_EQ(mesh.normals.size(), 3u);
  EXPECT_LT((mesh.normals[0] - Vector3f::UnitZ()).norm(), 1e-6f);
}

TEST(MeshIo, LoadErrorsNameTheFile) {
  const fs::path folder = test_folder();
  const std::string missing = (folder / "missing.obj").string();
  std::string message = runtime_error_of([&] { load_mesh_file(missing); });
  EXPECT_NE(message.find(missing), std::string::npos) << message;
  EXPECT_NE(message.find("no such file"), std::string::npos) << message;

  const std::string no_faces = (folder / "points.obj").string();
  write_file(no_faces, "# only vertices\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
  message = runtime_error_of([&] { load_mesh_file(no_faces); });
  EXPECT_NE(message.find(no_faces), std::string::npos) << message;
  EXPECT_NE(message.find("no triangles"), std::string::npos) << message;
}

TEST(MeshIo, RejectsBrokenFilesNamingThem) {
  const fs::path folder = test_folder();
  std::string message;
  const std::string bad_index = (folder / "bad_index.obj").string();
  write_file(bad_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  message = runtime_error_of([&] { load_mesh_file(bad_index); });
  EXPECT_NE(message.find(bad_index), std::string::npos) << message;

  const std::string zero_index = (folder / "zero_index.obj").string();
  write_file(zero_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  message = runtime_error_of([&] { load_mesh_file(zero_index); });
  EXPECT_NE(message.find(zero_index), std::string::npos) << message;

  const std::string huge = (folder / "huge.obj").string();
  write_file(huge, "v 1e999 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  message = runtime_error_of([&] { load_mesh_file(huge); });
  EXPECT_NE(message.find("non-finite"), std::string::npos) << message;

  const std::string missing_texture = (folder / "missing_texture.obj").string();
  write_file(missing_texture, "mtllib missing_texture.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_file(folder / "missing_texture.mtl", "newmtl m\nKd 1 1 1\nmap_Kd nope.png\n");
  message = runtime_error_of([&] { load_mesh_file(missing_texture); });
  EXPECT_NE(message.find("nope.png"), std::string::npos) << message;

  const std::string ply = (folder / "mesh.ply").string();
  write_file(ply, "ply\n");
  message = runtime_error_of([&] { load_mesh_file(ply); });
  EXPECT_NE(message.find("unsupported"), std::string::npos) << message;
}

// A cone's apex (at y = height) among `segments` faces over a unit circle, without normals in the file.
std::string cone_obj(int segments, float height) {
  std::string obj = "v 0 " + std::to_string(height) + " 0\n";
  for (int i = 0; i < segments; ++i) {
    const double a = 2 * std::numbers::pi * i / segments;
    obj += "v " + std::to_string(std::cos(a)) + " 0 " + std::to_string(-std::sin(a)) + "\n";
  }
  for (int i = 0; i < segments; ++i)
    obj += "f 1 " + std::to_string(i + 2) + " " + std::to_string((i + 1) % segments + 2) + "\n";
  return obj;
}

TEST(MeshIo, ManyFacesSharingThreeVerticesLoad) {
  // Every corner's smooth normal sums the faces around its position: once per direction, not per face.
  const fs::path folder = test_folder();
  constexpr int kFaces = 200000;
  std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  obj.reserve(obj.size() + 8 * kFaces);
  for (int i = 0; i < kFaces; ++i) obj += i % 2 ? "f 1 2 3\n" : "f 1 3 2\n";  // both windings
  write_file(folder / "shared.obj", obj);
  const Mesh mesh = load_mesh_file((folder / "shared.obj").string());
  ASSERT_EQ(mesh.triangles.size(), static_cast<size_t>(kFaces));
  EXPECT_EQ(mesh.positions.size(), 6u);  // each position once per winding: the two sides are 180 degrees apart
  for (const auto& t : mesh.triangles) {
    const Vector3f face =
        (mesh.positions[t[1]] - mesh.positions[t[0]]).cross(mesh.positions[t[2]] - mesh.positions[t[0]]).normalized();
    for (int k = 0; k < 3; ++k) ASSERT_LT((mesh.normals[t[k]] - face).norm(), 1e-6f);
  }
}

TEST(MeshIo, AnApexAmongManyFacesGetsTheSmoothNormal) {
  // Up to 64 face directions at a position are summed exactly, more are binned by direction: a shallow
  // cone's apex points up either way, and its rim stays smooth.
  const fs::path folder = test_folder();
  for (const int segments : {48, 2000}) {
    SCOPED_TRACE(segments);
    const fs::path path = folder / ("cone" + std::to_string(segments) + ".obj");
    write_file(path, cone_obj(segments, 0.2f));
    const Mesh cone = load_mesh_file(path.string());
    ASSERT_EQ(cone.triangles.size(), static_cast<size_t>(segments));
    for (const auto& t : cone.triangles) {
      ASSERT_LT((cone.normals[t[0]] - Vector3f::UnitY()).norm(), 2e-3f);  // the apex
      for (int k = 1; k < 3; ++k) {
        const Vector3f& p = cone.positions[t[k]];
        const Vector3f slope = Vector3f(0.2f * p.x(), 1.f, 0.2f * p.z()).normalized();  // the rim's true normal
        ASSERT_LT((cone.normals[t[k]] - slope).norm(), 1e-3f);
      }
    }
  }
}

TEST(MeshIo, AHugePolygonIsSplitAsAFan) {
  // tinyobjloader's ear clipping is quadratic in a polygon's corners; past 64 they are split as a fan.
  const fs::path folder = test_folder();
  constexpr int kCorners = 100000;
  std::string obj, face = "f";
  for (int i = 0; i < kCorners; ++i) {
    const double a = 2 * std::numbers::pi * i / kCorners;
    obj += "v " + std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " 0\n";
    face += " " + std::to_string(i + 1);
  }
  write_file(folder / "disc.obj", obj + face + "\n");
  const Mesh disc = load_mesh_file((folder / "disc.obj").string());
  ASSERT_EQ(disc.triangles.size(), static_cast<size_t>(kCorners - 2));
  double area = 0;
  for (const auto& t : disc.triangles)
    area += 0.5 * (disc.positions[t[1]] - disc.positions[t[0]]).cross(disc.positions[t[2]] - disc.positions[t[0]]).z();
  EXPECT_NEAR(area, std::numbers::pi, 1e-3);  // counter-clockwise, no overlaps
}

TEST(MeshIo, AMeshOverTheTriangleBudgetIsRefusedUnparsed) {
  const fs::path folder = test_folder();
  const std::string path = (folder / "too_many.obj").string();
  {
    std::ofstream out(path, std::ios::binary);
    out << "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    const std::string faces = [] {
      std::string block;
      for (int i = 0; i < 4096; ++i) block += "f 1 2 3\n";
      return block;
    }();
    for (std::uint64_t written = 0; written <= kMaxMeshTriangles; written += 4096) out << faces;
  }
  const std::string message = runtime_error_of([&] { load_mesh_file(path); });
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("triangles"), std::string::npos) << message;
  EXPECT_NE(message.find(std::to_string(kMaxMeshTriangles + 4096)), std::string::npos) << message;
  EXPECT_NE(message.find("limit is " + std::to_string(kMaxMeshTriangles)), std::string::npos) << message;

  // Materials count too: a tinyobj material is nearly 2 KB, so a small MTL could otherwise fill memory.
  std::string mtl;
  for (std::uint64_t i = 0; i <= kMaxMeshMaterials; ++i) mtl += "newmtl m" + std::to_string(i) + "\nKd 1 1 1\n";
  write_file(folder / "many.mtl", mtl);
  write_file(folder / "many.obj", "mtllib many.mtl\nusemtl m0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const std::string many = runtime_error_of([&] { load_mesh_file((folder / "many.obj").string()); });
  EXPECT_NE(many.find("many.obj"), std::string::npos) << many;
  EXPECT_NE(many.find("materials (the limit is " + std::to_string(kMaxMeshMaterials)), std::string::npos) << many;
}

TEST(MeshIo, TexturesAreReducedToTheSideLimitAndHugeOnesRefusedUndecoded) {
  const fs::path folder = test_folder();
  const std::string obj = "mtllib t.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n";
  write_file(folder / "t.obj", obj);
  write_file(folder / "t.mtl", "newmtl t\nKd 1 1 1\nmap_Kd wide.png\n");
  // Wider than the limit: reduced while read, aspect kept, a uniform colour unchanged.
  const cv::Mat wide(4, 2 * kMaxTextureSide + 2, CV_8UC3, cv::Scalar(10, 128, 250));
  ASSERT_TRUE(cv::imwrite((folder / "wide.png").string(), wide));
  const Mesh mesh = load_mesh_file((folder / "t.obj").string());
  ASSERT_TRUE(mesh.materials.at(0).texture);
  const cv::Mat& texture = *mesh.materials[0].texture;
  EXPECT_EQ(texture.cols, kMaxTextureSide);
  EXPECT_EQ(texture.rows, 2);
  // (Averaged in linear light by the photo reader; at the last column, within a part in a thousand.)
  const cv::Vec3f texel = texture.at<cv::Vec3f>(1, kMaxTextureSide - 1);
  EXPECT_NEAR(texel[0], srgb_to_linear(250.f / 255.f), 1e-3f);
  EXPECT_NEAR(texel[1], srgb_to_linear(128.f / 255.f), 1e-3f);
  EXPECT_NEAR(texel[2], srgb_to_linear(10.f / 255.f), 1e-3f);

  // A 69-byte PNG whose header claims 60000 x 60000 RGBA16: refused before its pixels are allocated.
  const unsigned char png[] = {
      0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
      0xea, 0x60, 0x00, 0x00, 0xea, 0x60, 0x10, 0x06, 0x00, 0x00, 0x00, 0xd0, 0x42, 0xa9, 0x01, 0x00, 0x00, 0x00,
      0x0c, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x60, 0xa0, 0x0c, 0x00, 0x00, 0x00, 0x40, 0x00, 0x01, 0xb7,
      0x34, 0x7c, 0xef, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82,
  };
  std::ofstream(folder / "huge.png", std::ios::binary).write(reinterpret_cast<const char*>(png), sizeof png);
  write_file(folder / "t.mtl", "newmtl t\nKd 1 1 1\nmap_Kd huge.png\n");
  const std::string message = runtime_error_of([&] { load_mesh_file((folder / "t.obj").string()); });
  EXPECT_NE(message.find("t.obj"), std::string::npos) << message;
  EXPECT_NE(message.find("huge.png"), std::string::npos) << message;
  EXPECT_NE(message.find("60000x60000"), std::string::npos) << message;
  EXPECT_NE(message.find(std::to_string(kMaxTextureFilePixels)), std::string::npos) << message;
}

TEST(MeshIo, SaveErrorsNameTheFile) {
  const fs::path folder = test_folder();
  const std::string unwritable = (folder / "no_such_folder" / "out.obj").string();
  const std::string message = runtime_error_of([&] { save_obj(make_prop("mug"), unwritable); });
  EXPECT_NE(message.find(unwritable), std::string::npos) << message;
  EXPECT_NE(runtime_error_of([&] { save_obj(Mesh{}, (folder / "empty.obj").string()); }), "");
}

// load_mesh_file alone on the OBJ named by PROPCAM_OBJ_BENCH, for the figures in docs/budgets.md (peak memory:
// run it under /usr/bin/time -v).
TEST(MeshIo, DISABLED_MeasureLoadTime) {
  const char* file = std::getenv("PROPCAM_OBJ_BENCH");
  if (!file) GTEST_SKIP() << "PROPCAM_OBJ_BENCH names no .obj";
  const auto start = std::chrono::steady_clock::now();
  const Mesh mesh = load_mesh_file(file);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("load_mesh_file: %.3f s, %zu triangles, %zu vertices\n", seconds, mesh.triangles.size(),
              mesh.positions.size());
}

}  // namespace
}  // namespace propcam::render
