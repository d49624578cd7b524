// Degenerate inputs to the room enclosure (room_enclosure.h): no box or a
// clear error, never a crash, a NaN or an unbounded mesh.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <unistd.h>

#include "propcam/inference/room_enclosure.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

render::PinholeCamera level_camera(int w = 80, int h = 60) {
  render::PinholeCamera c = render::pinhole_with_fov(w, h, 60);
  c.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0, 0, 0);  // along -Z
  c.center_world = {0, 1.6, 0};
  return c;
}

cv::Mat grey_albedo(const render::PinholeCamera& c) { return cv::Mat(c.height, c.width, CV_32FC3, cv::Scalar::all(0.5)); }

TEST(RoomEnclosureHardCases, NoSeenSurfaceGivesNoBox) {
  const render::PinholeCamera c = level_camera();
  for (float d : {render::kSkyDepthM, 0.f, -1.f, kNaN, kInf}) {
    const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(d));
    const RoomEnclosure box = enclose_room(depth, grey_albedo(c), c, {}, {});
    EXPECT_TRUE(box.empty()) << d;
    EXPECT_TRUE(room_enclosure_mesh(box, depth, c).empty()) << d;
  }
}

// Stripes of broken depth and albedo among a wall 4 m ahead: the box is
// finite and holds the wall.
TEST(RoomEnclosureHardCases, BrokenPixelsAreSkipped) {
  const render::PinholeCamera c = level_camera();
  cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(4.f));
  cv::Mat albedo = grey_albedo(c);
  for (int x = 0; x < c.width; x += 4) {
    depth.col(x).setTo(x % 8 ? kNaN : -kInf);
    albedo.col(x + 1).setTo(cv::Scalar::all(kNaN));
  }
  const RoomEnclosure box = enclose_room(depth, albedo, c, {}, {{kNaN, 0, 0}});
  ASSERT_FALSE(box.empty());
  EXPECT_NO_THROW(box.validate());
  EXPECT_NEAR(box.min.z(), -4.1, 1e-3);
  EXPECT_NEAR(box.albedo.x(), 0.5f, 1e-6f);
}

// Depths just short of what counts as sky (half its depth) and a light a
// kilometre away: the box stops at kMaxEnclosureExtentM and its mesh at
// kMaxEnclosureCellsPerSide^2 cells a face.
TEST(RoomEnclosureHardCases, FarDepthsAndLightsAreBounded) {
  const render::PinholeCamera c = level_camera();
  const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(0.49f * render::kSkyDepthM));
  const RoomEnclosure box = enclose_room(depth, grey_albedo(c), c, {}, {{1000.0, 5.0, 0.0}});
  ASSERT_FALSE(box.empty());
  EXPECT_NO_THROW(box.validate());
  EXPECT_LE((box.max - box.min).maxCoeff(), kMaxEnclosureExtentM);
  const render::Mesh mesh = room_enclosure_mesh(box, depth, c);
  EXPECT_LE(mesh.triangles.size(), 6u * 2u * kMaxEnclosureCellsPerSide * kMaxEnclosureCellsPerSide);
  EXPECT_NO_THROW(mesh.validate());
}

TEST(RoomEnclosureHardCases, MapsOfTheWrongTypeOrSizeAreRejected) {
  const render::PinholeCamera c = level_camera();
  const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(3.f));
  const auto message = [](auto&& call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_NE(message([&] { enclose_room(cv::Mat(10, 10, CV_32F, 3.f), grey_albedo(c), c, {}, {}); }).find("depth"),
            std::string::npos);
  EXPECT_NE(message([&] { enclose_room(depth, cv::Mat(c.height, c.width, CV_32F, 0.5f), c, {}, {}); }).find("albedo"),
            std::string::npos);
  RoomEnclosure box;
  box.min = {-1, 0, -1}, box.max = {1, 2, 1};
  EXPECT_NE(message([&] { room_enclosure_mesh(box, cv::Mat(c.height, c.width, CV_64F, 3.0), c); }).find("depth"),
            std::string::npos);
}

TEST(RoomEnclosureHardCases, ABadBoxIsRejectedBeforeAnyMeshIsBuilt) {
  const render::PinholeCamera c = level_camera();
  const cv::Mat depth(c.height, c.width, CV_32F, cv::Scalar(3.f));
  RoomEnclosure box;
  box.min = {-1, 0, -1}, box.max = {1, 2, 1e9};
  EXPECT_THROW(room_enclosure_mesh(box, depth, c), std::runtime_error);
  box.max = {1, 2, 1};
  box.albedo = {0.5f, kNaN, 0.5f};
  EXPECT_THROW(room_enclosure_mesh(box, depth, c), std::runtime_error);
}

class RoomEnclosureInSceneJson : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("propcam_enclosure_hard_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string error_of(const std::string& enclosure) {
    std::ofstream(dir_ / "scene.json")
        << R"({"image": {"width": 64, "height": 48}, "K": {"fx": 60, "fy": 60, "cx": 32, "cy": 24},
              "R_world_from_cam": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "camera_height_m": 1.5, "indoor": true,
              "lights": [], "enclosure": )"
        << enclosure << "}";
    try {
      const SceneModel s = load_scene(dir_.string());
      return s.enclosure.empty() ? "(open)" : "(closed)";
    } catch (const std::runtime_error& e) {
      return e.what();
    }
  }
  std::filesystem::path dir_;
};

TEST_F(RoomEnclosureInSceneJson, AGoodBoxLoadsAndABadOneIsNamed) {
  const std::string good = R"({"min": [-3, -0.1, -5], "max": [3, 2.9, 2], "albedo": [0.6, 0.5, 0.4]})";
  EXPECT_EQ(error_of(good), "(closed)");
  std::string inside_out = good;
  inside_out.replace(inside_out.find("[3, 2.9, 2]"), 11, "[3, -1.0, 2]");
  EXPECT_NE(error_of(inside_out).find("enclosure"), std::string::npos) << error_of(inside_out);
  std::string huge = good;
  huge.replace(huge.find("[3, 2.9, 2]"), 11, "[3e9, 2.9, 2]");
  EXPECT_NE(error_of(huge).find("enclosure"), std::string::npos) << error_of(huge);
  std::string white_hot = good;
  white_hot.replace(white_hot.find("[0.6, 0.5, 0.4]"), 15, "[60, 0.5, 0.4]");
  EXPECT_NE(error_of(white_hot).find("albedo"), std::string::npos) << error_of(white_hot);
  std::string missing = good;
  missing.replace(missing.find("\"albedo\""), 26, "\"colour\": [0.6, 0.5, 0.4]");
  EXPECT_NE(error_of(missing).find("scene.json"), std::string::npos) << error_of(missing);
}

}  // namespace
}  // namespace propcam::inference
