#include "propcam/render/props.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/scene.h"

#include <array>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

namespace propcam::render {
namespace {

using Eigen::Vector3f;

// Maps every position to a representative within `tolerance`, so parts that
// split vertices at hard edges or seams count as one surface.
std::vector<int> weld_positions(const std::vector<Vector3f>& positions, float tolerance) {
  std::map<std::array<long, 3>, std::vector<int>> cells;  // grid cell -> representative ids
  std::vector<Vector3f> representatives;
  std::vector<int> welded(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    const Vector3f& p = positions[i];
    const std::array<long, 3> cell = {std::lround(std::floor(p.x() / tolerance)),
                                      std::lround(std::floor(p.y() / tolerance)),
                                      std::lround(std::floor(p.z() / tolerance))};
    int found = -1;
    for (long dx = -1; dx <= 1 && found < 0; ++dx)
      for (long dy = -1; dy <= 1 && found < 0; ++dy)
        for (long dz = -1; dz <= 1 && found < 0; ++dz) {
          const auto it = cells.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
          if (it == cells.end()) continue;
          for (int r : it->second)
            if ((representatives[r] - p).norm() <= tolerance) {
              found = r;
              break;
            }
        }
    if (found < 0) {
      found = static_cast<int>(representatives.size());
      representatives.push_back(p);
      cells[cell].push_back(found);
    }
    welded[i] = found;
  }
  return welded;
}

double signed_volume(const Mesh& mesh) {
  double volume = 0.0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
    const Eigen::Vector3d b = mesh.positions[t[1]].cast<double>();
    const Eigen::Vector3d c = mesh.positions[t[2]].cast<double>();
    volume += a.dot(b.cross(c)) / 6.0;
  }
  return volume;
}

// "" when every edge (after welding positions within 1e-5) is used exactly once
// in each direction, i.e. by exactly two consistently wound triangles.
std::string closedness_problem(const Mesh& mesh) {
  const std::vector<int> welded = weld_positions(mesh.positions, 1e-5f);
  std::map<std::pair<int, int>, int> directed_edges;
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = welded[t[k]], b = welded[t[(k + 1) % 3]];
      if (a == b) return "degenerate triangle";
      ++directed_edges[{a, b}];
    }
  for (const auto& [edge, count] : directed_edges) {
    if (count != 1) return "edge used twice in the same direction (inconsistent winding)";
    if (!directed_edges.count({edge.second, edge.first})) return "open edge (hole)";
  }
  return "";
}

TEST(PropTestHelpers, ClosednessCheckCatchesHolesAndFlippedTriangles) {
  Mesh box = make_prop("cube");
  ASSERT_EQ(closedness_problem(box), "");
  Mesh open = box;
  open.triangles.pop_back();
  EXPECT_EQ(closedness_problem(open), "open edge (hole)");
  Mesh flipped = box;
  std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
  EXPECT_NE(closedness_problem(flipped), "");
}

class PresetTest : public ::testing::TestWithParam<PropPreset> {
 protected:
  void SetUp() override { mesh_ = make_prop(GetParam().name); }
  Mesh mesh_;
};

TEST_P(PresetTest, ValidatesWithFiniteNormals) {
  ASSERT_FALSE(mesh_.empty());
  EXPECT_NO_THROW(mesh_.validate());
  ASSERT_EQ(mesh_.normals.size(), mesh_.positions.size());
  for (const auto& p : mesh_.positions) ASSERT_TRUE(p.allFinite());
  for (const auto& n : mesh_.normals) {
    ASSERT_TRUE(n.allFinite());
    ASSERT_NEAR(n.norm(), 1.f, 1e-4f);
  }
}

TEST_P(PresetTest, HasNaturalHeightAndStandsCentredOnTheOrigin) {
  const Eigen::AlignedBox3f box = mesh_.bounds();
  const float height = box.max().y() - box.min().y();
  EXPECT_NEAR(height, GetParam().natural_height_m, 0.01f * GetParam().natural_height_m);
  EXPECT_NEAR(box.min().y(), 0.f, 1e-6f);
  EXPECT_NEAR(box.center().x(), 0.f, 1e-5f);
  EXPECT_NEAR(box.center().z(), 0.f, 1e-5f);
}

TEST_P(PresetTest, IsClosedWithConsistentOutwardWinding) {
  EXPECT_EQ(closedness_problem(mesh_), "");
  const double volume = signed_volume(mesh_);
  EXPECT_GT(volume, 0.0);
  EXPECT_LT(volume, mesh_.bounds().volume());
}

TEST_P(PresetTest, VertexNormalsAgreeWithWinding) {
  for (const auto& t : mesh_.triangles) {
    const Vector3f face =
        (mesh_.positions[t[1]] - mesh_.positions[t[0]]).cross(mesh_.positions[t[2]] - mesh_.positions[t[0]]);
    if (face.norm() < 1e-12f) continue;
    for (int k = 0; k < 3; ++k) ASSERT_GT(face.normalized().dot(mesh_.normals[t[k]]), 0.f);
  }
}

TEST_P(PresetTest, EveryTriangleHasANamedMaterialWithinBudget) {
  EXPECT_LT(mesh_.triangles.size(), 20000u);
  ASSERT_EQ(mesh_.material_ids.size(), mesh_.triangles.size());
  std::set<int> used(mesh_.material_ids.begin(), mesh_.material_ids.end());
  for (const auto& m : mesh_.materials) {
    EXPECT_FALSE(m.name.empty());
    EXPECT_TRUE((m.albedo.array() >= 0.f).all() && (m.albedo.array() <= 1.f).all()) << m.name;
    EXPECT_GE(m.roughness, 0.02f);
    EXPECT_LE(m.roughness, 1.f);
  }
  EXPECT_EQ(used.size(), mesh_.materials.size()) << "unused material";
}

INSTANTIATE_TEST_SUITE_P(Props, PresetTest, ::testing::ValuesIn(prop_presets()),
                         [](const ::testing::TestParamInfo<PropPreset>& info) { return info.param.name; });

TEST(PropPresets, ListsTheRequiredPresetsInAStableOrder) {
  const auto& presets = prop_presets();
  std::set<std::string> names;
  for (const auto& p : presets) {
    EXPECT_TRUE(names.insert(p.name).second) << "duplicate " << p.name;
    EXPECT_FALSE(p.description.empty());
    EXPECT_GT(p.natural_height_m, 0.f);
  }
  for (const char* required : {"chair", "vase", "sphere_plinth", "mug", "table"})
    EXPECT_TRUE(names.count(required)) << required;
  EXPECT_EQ(&prop_presets(), &presets);
  EXPECT_EQ(presets.front().name, "chair");
}

TEST(PropPresets, MugHandlePointsToPlusX) {
  const Mesh mug = make_prop("mug");
  // The round body sets the depth (z) and the left edge; the handle sticks out on +x only.
  const Eigen::AlignedBox3f box = mug.bounds();
  const float body_radius = 0.5f * (box.max().z() - box.min().z());
  const float axis_x = box.min().x() + body_radius;
  EXPECT_NEAR(box.center().z(), 0.f, 1e-5f);
  EXPECT_GT(box.max().x() - axis_x, body_radius + 0.02f);
}

TEST(PropPresets, SphereIsSmoothShadedWithRadialNormals) {
  const Mesh prop = make_prop("sphere_plinth");
  int metal = -1;
  for (size_t m = 0; m < prop.materials.size(); ++m)
    if (prop.materials[m].type == Material::Type::Metal) metal = static_cast<int>(m);
  ASSERT_GE(metal, 0);
  std::set<int> ball;
  for (size_t t = 0; t < prop.triangles.size(); ++t)
    if (prop.material_ids[t] == metal)
      for (int k = 0; k < 3; ++k) ball.insert(prop.triangles[t][k]);
  ASSERT_GT(ball.size(), 1000u);
  Eigen::AlignedBox3f ball_box;
  for (int v : ball) ball_box.extend(prop.positions[v]);
  const Vector3f centre = ball_box.center();
  EXPECT_NEAR(ball_box.max().y(), prop.bounds().max().y(), 1e-6f);  // the ball is the top
  for (int v : ball) {
    const Vector3f radial = (prop.positions[v] - centre).normalized();
    ASSERT_LT((prop.normals[v] - radial).norm(), 1e-4f) << prop.positions[v].transpose();
  }
}

TEST(PropPresets, ChairBackrestIsAtMinusZ) {
  const Mesh chair = make_prop("chair");
  // Everything above the seat belongs to the backrest.
  float z_sum = 0.f;
  int count = 0;
  for (const auto& p : chair.positions)
    if (p.y() > 0.6f) {
      z_sum += p.z();
      ++count;
    }
  ASSERT_GT(count, 0);
  EXPECT_LT(z_sum / static_cast<float>(count), -0.1f);
}

TEST(PropPresets, UnknownNameThrowsListingValidNames) {
  try {
    make_prop("teapot");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("teapot"), std::string::npos) << message;
    for (const auto& p : prop_presets()) EXPECT_NE(message.find(p.name), std::string::npos) << message;
  }
}

TEST(PropPresets, AtLeastEightIncludingGlassAndLamp) {
  std::set<std::string> names;
  for (const auto& p : prop_presets()) names.insert(p.name);
  EXPECT_GE(prop_presets().size(), 8u);
  EXPECT_TRUE(names.count("glass"));
  EXPECT_TRUE(names.count("lamp"));
}

TEST(PropPresets, GlassIsAClosedOutwardWoundDielectric) {
  const Mesh glass = make_prop("glass");
  EXPECT_EQ(closedness_problem(glass), "");
  EXPECT_GT(signed_volume(glass), 0.0);
  for (const auto& m : glass.materials) {
    EXPECT_EQ(m.type, Material::Type::Dielectric) << m.name;
    EXPECT_FLOAT_EQ(m.ior, 1.5f);
  }
  const float height = glass.bounds().sizes().y();
  EXPECT_GE(height, 0.15f - 1e-4f);
  EXPECT_LE(height, 0.3f);
}

TEST(PropPresets, LampHasEmissiveTrianglesAndOneEnclosingLight) {
  const Mesh lamp = make_prop("lamp");
  int emissive = 0;
  for (size_t t = 0; t < lamp.triangles.size(); ++t)
    emissive += lamp.materials[lamp.material_ids[t]].type == Material::Type::Emissive;
  EXPECT_GT(emissive, 100);
  const Eigen::Affine3f xf = Eigen::Translation3f(1.f, 2.f, 3.f) * Eigen::Scaling(2.f);
  const std::vector<SphereLight> lights = prop_lights(lamp, xf);
  ASSERT_EQ(lights.size(), 1u);
  const SphereLight& l = lights[0];
  EXPECT_TRUE(l.prop_only);
  EXPECT_NEAR(l.radius, 2.f * 0.07f, 0.01f);  // the 7 cm globe, scaled
  EXPECT_NEAR(l.center.y(), 2.f + 2.f * (0.38f - 0.07f), 0.01f);
  EXPECT_NEAR(l.center.x(), 1.f, 1e-3f);
  for (size_t t = 0; t < lamp.triangles.size(); ++t)  // encloses the globe (never shadows its own light)
    if (lamp.materials[lamp.material_ids[t]].type == Material::Type::Emissive) {
      for (int k = 0; k < 3; ++k) EXPECT_LT((xf * lamp.positions[lamp.triangles[t][k]] - l.center).norm(), l.radius);
    }
  EXPECT_GT(l.radiance.minCoeff(), 0.f);
  EXPECT_TRUE(prop_lights(make_prop("cube"), xf).empty());
}

TEST(PropThumbnails, EveryPresetRendersFiniteAndNotBlack) {
  for (const auto& p : prop_presets()) {
    const cv::Mat t = render_prop_thumbnail(p.name, 48, 4);
    ASSERT_EQ(t.type(), CV_32FC3) << p.name;
    ASSERT_EQ(t.cols, 48);
    ASSERT_EQ(t.rows, 48);
    EXPECT_TRUE(cv::checkRange(t)) << p.name;
    const cv::Scalar mean = cv::mean(t);
    EXPECT_GT(mean[0] + mean[1] + mean[2], 0.05) << p.name;
  }
}

// The lamp next to a floor: its light reaches the floor in the world with the
// prop (and in the differential change), never in the world without it.
TEST(PropLights, TheLampLightsTheFloorOnlyWithTheProp) {
  Mesh floor;
  Material grey;
  grey.name = "floor";
  grey.albedo = Eigen::Vector3f::Constant(0.5f);
  floor.materials.push_back(grey);
  using V = Eigen::Vector3f;
  add_quad(floor, V(-3, 0, 3), V(3, 0, 3), V(3, 0, -3), V(-3, 0, -3), 0, 1.f);
  Scene scene;
  scene.add_mesh(floor, Layer::Background);
  const Mesh lamp = make_prop("lamp");
  const Eigen::Affine3f at(Eigen::Translation3f(0.f, 0.f, 0.f));
  scene.add_prop(lamp, at);
  scene.commit();

  // Looking straight down from 1.5 m: the lamp in the centre, floor around it.
  PinholeCamera camera;
  camera.width = camera.height = 48;
  camera.fx = camera.fy = 40.0;
  camera.cx = camera.cy = 23.5;
  camera.center_world = Eigen::Vector3d(0, 1.5, 0);
  camera.R_world_from_cam.col(0) = Eigen::Vector3d::UnitX();
  camera.R_world_from_cam.col(1) = Eigen::Vector3d::UnitZ();
  camera.R_world_from_cam.col(2) = -Eigen::Vector3d::UnitY();
  LightRig rig;
  rig.environment = std::make_shared<EnvironmentLight>(cv::Mat(8, 16, CV_32FC3, cv::Scalar::all(0.1)));
  for (const SphereLight& l : prop_lights(lamp, at)) rig.sphere_lights.push_back(l);
  RenderSettings settings;
  settings.samples_per_pixel = 8;
  const cv::Mat with = render_image(scene, camera, rig, settings);
  const cv::Mat without = render_background_image(scene, camera, rig, settings);
  const DifferentialRender diff = render_differential(scene, camera, rig, settings);
  // A floor ring around the lamp, outside its 7 cm globe and base (about 3-9 px at this scale).
  cv::Mat ring(48, 48, CV_8U, cv::Scalar(0));
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 48; ++x) {
      const double r = std::hypot(x - 23.5, y - 23.5);
      if (r > 6.0 && r < 14.0) ring.at<uint8_t>(y, x) = 255;
    }
  const double lum_with = cv::mean(with, ring)[1], lum_without = cv::mean(without, ring)[1];
  const double change = cv::mean(diff.change, ring)[1];
  EXPECT_GT(lum_with, 1.5 * lum_without) << lum_with << " vs " << lum_without;
  EXPECT_NEAR(lum_without, 0.5 * 0.1, 0.02);  // the sky alone: albedo x E / pi, E = pi * 0.1
  EXPECT_GT(change, 0.5 * (lum_with - lum_without));
}

}  // namespace
}  // namespace propcam::render
