// Degenerate inputs to the hidden facades (hidden_facades.h): no facade or a
// clear error, never a crash, a NaN or an unbounded mesh.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <unistd.h>

#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

render::PinholeCamera level_camera(int w = 80, int h = 60) {
  render::PinholeCamera c = render::pinhole_with_fov(w, h, 60);
  c.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, 0, 0);
  c.center_world = {0, 1.6, 0};
  return c;
}

// A wall facing the camera 10 m ahead (z = -10) filling the frame.
void wall_ahead(const render::PinholeCamera& c, cv::Mat& depth, cv::Mat& normals) {
  depth = cv::Mat(c.height, c.width, CV_32F, cv::Scalar(10.f));
  normals = cv::Mat(c.height, c.width, CV_32FC3, cv::Scalar(0.f, 0.f, 1.f));
}

TEST(HiddenFacadesHardCases, AllSkyOrNothingHitGivesNoFacade) {
  const render::PinholeCamera c = level_camera();
  const cv::Mat normals(c.height, c.width, CV_32FC3, cv::Scalar(0.f, 0.f, 1.f));
  for (float d : {render::kSkyDepthM, 0.f, -1.f, kNaN, std::numeric_limits<float>::infinity()}) {
    const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(d));
    EXPECT_TRUE(find_hidden_facades(depth, normals, cv::Mat(), c).empty()) << d;
  }
}

TEST(HiddenFacadesHardCases, NonFiniteNormalsAreSkipped) {
  const render::PinholeCamera c = level_camera();
  cv::Mat depth, normals;
  wall_ahead(c, depth, normals);
  normals.setTo(cv::Scalar(kNaN, kNaN, kNaN));
  EXPECT_TRUE(find_hidden_facades(depth, normals, cv::Mat(), c).empty());
}

TEST(HiddenFacadesHardCases, AFloorSeenFromAboveHasNoFacade) {
  render::PinholeCamera c = level_camera();
  c.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, -1.5, 0);  // nearly straight down
  const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(1.6f));
  const cv::Mat normals(c.height, c.width, CV_32FC3, cv::Scalar(0.f, 1.f, 0.f));
  EXPECT_TRUE(find_hidden_facades(depth, normals, cv::Mat(), c).empty());
}

// A wall lower than a storey (a kerb, a car) is not continued.
TEST(HiddenFacadesHardCases, ALowWallIsNotAFacade) {
  const render::PinholeCamera c = level_camera();
  cv::Mat depth, normals;
  wall_ahead(c, depth, normals);
  // Only the rows between 0 and 1 m high stay wall; the rest is sky.
  for (int y = 0; y < c.height; ++y)
    if (const double h = 1.6 - (y - c.cy) / c.fy * 10.0; h > 1.0 || h < 0.0) depth.row(y).setTo(render::kSkyDepthM);
  EXPECT_TRUE(find_hidden_facades(depth, normals, cv::Mat(), c).empty());
}

TEST(HiddenFacadesHardCases, ATinyFrameIsHandled) {
  const render::PinholeCamera c = level_camera(1, 1);
  cv::Mat depth, normals;
  wall_ahead(c, depth, normals);
  const auto facades = find_hidden_facades(depth, normals, cv::Mat(), c);
  EXPECT_TRUE(facades.empty());  // one pixel is never a facade's share of the frame... nor 2 m high
  EXPECT_TRUE(hidden_facade_mesh(facades, depth, c).empty());
}

TEST(HiddenFacadesHardCases, MapsOfTheWrongTypeOrSizeAreRejected) {
  const render::PinholeCamera c = level_camera();
  cv::Mat depth, normals;
  wall_ahead(c, depth, normals);
  EXPECT_THROW(find_hidden_facades(depth(cv::Rect(0, 0, 10, 10)), normals, cv::Mat(), c), std::invalid_argument);
  EXPECT_THROW(find_hidden_facades(depth, cv::Mat(c.height, c.width, CV_32F), cv::Mat(), c), std::invalid_argument);
  EXPECT_THROW(find_hidden_facades(depth, normals, cv::Mat(4, 4, CV_8UC3), c), std::invalid_argument);
  EXPECT_THROW(hidden_facade_mesh({}, cv::Mat(4, 4, CV_32F), c), std::invalid_argument);
  HiddenFacadeOptions o;
  o.cell_m = 0;
  EXPECT_THROW(hidden_facade_mesh({}, depth, c, o), std::invalid_argument);
}

HiddenFacade good_facade() {
  HiddenFacade f;
  f.normal = Eigen::Vector3d::UnitX();
  f.offset = 8;
  f.top_m = 10;
  f.seen_min = 14, f.seen_max = 90, f.along_min = -40, f.along_max = 90;
  return f;
}

TEST(HiddenFacadesHardCases, ABadFacadeIsRejectedBeforeAnyMeshIsBuilt) {
  const render::PinholeCamera c = level_camera();
  const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(render::kSkyDepthM));
  EXPECT_NO_THROW(good_facade().validate());
  std::vector<HiddenFacade> bad(6, good_facade());
  bad[0].offset = std::numeric_limits<double>::quiet_NaN();
  bad[1].normal = Eigen::Vector3d(0, 1, 0);           // not vertical
  bad[2].normal = Eigen::Vector3d(2, 0, 0);           // not unit
  bad[3].top_m = bad[3].bottom_m;                     // no height
  bad[4].along_max = bad[4].along_min + 1e9;           // would not fit in memory
  bad[5].seen_min = bad[5].along_min - 1;             // seen where it is not
  for (const HiddenFacade& f : bad) {
    EXPECT_THROW(f.validate(), std::runtime_error);
    EXPECT_THROW(hidden_facade_mesh({f}, depth, c), std::runtime_error);
  }
}

// The largest facades a scene file may hold still give a bounded mesh.
TEST(HiddenFacadesHardCases, TheMeshIsBoundedWhateverTheFacades) {
  const render::PinholeCamera c = level_camera();
  const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(render::kSkyDepthM));
  HiddenFacade f = good_facade();
  f.bottom_m = 0, f.top_m = kMaxFacadeHeightM;
  f.along_min = f.seen_min = -kMaxFacadeSpanM / 2, f.along_max = f.seen_max = kMaxFacadeSpanM / 2;
  const render::Mesh mesh = hidden_facade_mesh(std::vector<HiddenFacade>(kMaxHiddenFacades, f), depth, c);
  EXPECT_LE(mesh.triangles.size(), 200000u);
  EXPECT_NO_THROW(mesh.validate());
}

class HiddenFacadesInSceneJson : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("propcam_facades_hard_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string error_of(const std::string& facade) {
    std::ofstream(dir_ / "scene.json")
        << R"({"image": {"width": 64, "height": 48}, "K": {"fx": 60, "fy": 60, "cx": 32, "cy": 24},
              "R_world_from_cam": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "camera_height_m": 1.5, "indoor": false,
              "lights": [], "hidden_facades": [)"
        << facade << "]}";
    try {
      const SceneModel s = load_scene(dir_.string());
      return "(loaded " + std::to_string(s.hidden_facades.size()) + ")";
    } catch (const std::runtime_error& e) {
      return e.what();
    }
  }
  std::filesystem::path dir_;
};

TEST_F(HiddenFacadesInSceneJson, AGoodFacadeLoadsAndABadOneIsNamed) {
  const std::string good = R"({"normal": [1, 0, 0], "offset": 8, "bottom_m": 0, "top_m": 10, "seen": [14, 90],
                               "continued": [-40, 90], "albedo": [0.6, 0.5, 0.4], "pixels": 1200})";
  EXPECT_EQ(error_of(good), "(loaded 1)");
  std::string vertical = good;
  vertical.replace(vertical.find("[1, 0, 0]"), 9, "[0, 1, 0]");
  EXPECT_NE(error_of(vertical).find("horizontal"), std::string::npos) << error_of(vertical);
  std::string huge = good;
  huge.replace(huge.find("[-40, 90]"), 9, "[-1e300, 90]");
  EXPECT_NE(error_of(huge).find("extent"), std::string::npos) << error_of(huge);
  std::string missing = good;
  missing.replace(missing.find("\"top_m\": 10, "), 13, "");
  EXPECT_NE(error_of(missing).find("bad scene.json"), std::string::npos) << error_of(missing);
}

}  // namespace
}  // namespace propcam::inference
