#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "propcam/inference/infer.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/inference/sky.h"
#include "scene_class_fixtures.h"

namespace propcam::inference {
namespace {

void expect_finite_model(const SceneModel& s) {
  EXPECT_NO_THROW(s.validate());
  EXPECT_TRUE(std::isfinite(s.fx) && s.fx > 0);
  EXPECT_TRUE(cv::checkRange(s.depth));
  EXPECT_TRUE(cv::checkRange(s.albedo));
  double min_depth = 0;
  cv::minMaxLoc(s.depth, &min_depth);
  EXPECT_GT(min_depth, 0.0);
  for (const auto& l : s.lights) EXPECT_TRUE(l.intensity.allFinite());
  EXPECT_FALSE(s.reports.empty());
}

// 160x120: a smooth blue sky over the top 50 rows, textured ground below.
cv::Mat blue_sky_over_ground() {
  cv::Mat photo(120, 160, CV_32FC3);
  cv::RNG rng(3);
  for (int y = 0; y < photo.rows; ++y)
    for (int x = 0; x < photo.cols; ++x)
      photo.at<cv::Vec3f>(y, x) = y < 50 ? cv::Vec3f(0.3f, 0.5f, 0.9f)
                                          : cv::Vec3f(0.2f, 0.25f, 0.1f) * static_cast<float>(rng.uniform(0.5, 1.5));
  return photo;
}

// A tiny room drawn by hand: floor below, wall above, a few edges.
cv::Mat simple_room(int w, int h) {
  cv::Mat img(h, w, CV_32FC3, cv::Scalar(0.3f, 0.3f, 0.28f));
  img.rowRange(h / 2, h).setTo(cv::Scalar(0.2f, 0.12f, 0.06f));
  for (int x = w / 8; x < w; x += w / 4) img.colRange(x, x + 2).rowRange(0, h / 2).setTo(cv::Scalar(0.05f, 0.05f, 0.05f));
  return img;
}

TEST(InferHardCases, BlackFrameGivesAFiniteModel) {
  const SceneModel s = infer_scene(cv::Mat(120, 160, CV_32FC3, cv::Scalar::all(0)));
  expect_finite_model(s);
}

TEST(InferHardCases, SaturatedFrameGivesAFiniteModel) {
  const SceneModel s = infer_scene(cv::Mat(120, 160, CV_32FC3, cv::Scalar::all(1.0)));
  expect_finite_model(s);
}

TEST(InferHardCases, NonFinitePixelsAreNeutralised) {
  cv::Mat img = simple_room(160, 120);
  img.at<cv::Vec3f>(10, 10) = cv::Vec3f(std::numeric_limits<float>::quiet_NaN(), 1.f / 0.f, -5.f);
  expect_finite_model(infer_scene(img));
}

TEST(InferHardCases, SmallestAcceptedFrame) {
  expect_finite_model(infer_scene(simple_room(kMinPhotoSide, kMinPhotoSide)));
}

TEST(InferHardCases, TooSmallOrEmptyFrameIsAClearError) {
  EXPECT_THROW(infer_scene(cv::Mat(8, 8, CV_32FC3, cv::Scalar::all(0.5))), std::invalid_argument);
  EXPECT_THROW(infer_scene(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(infer_scene(cv::Mat(64, 64, CV_8UC3)), std::invalid_argument);
}

TEST(InferScene, IsDeterministic) {
  const cv::Mat img = simple_room(160, 120);
  const SceneModel a = infer_scene(img), b = infer_scene(img);
  EXPECT_EQ(a.R_world_from_cam, b.R_world_from_cam);
  EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0.0);
  ASSERT_EQ(a.lights.size(), b.lights.size());
  for (size_t i = 0; i < a.lights.size(); ++i) EXPECT_EQ(a.lights[i].intensity, b.lights[i].intensity);
}

TEST(InferScene, FloorDepthFollowsFromCameraHeight) {
  // A level camera (no lines) 1.5 m up: a floor pixel r rows below the
  // horizon is at depth f * h / r.
  InferenceOptions options;
  options.camera_height_m = 1.5;
  options.given_lines = std::vector<LineSegment>{};
  const cv::Mat img(240, 320, CV_32FC3, cv::Scalar::all(0.2));
  const SceneModel s = infer_scene(img, options);
  const double rows_below = 200 - s.cy;
  // 0.5%: the depth solve's priors pull a little at the floor-wall crease.
  EXPECT_NEAR(s.depth.at<float>(200, 160), s.fx * 1.5 / rows_below, 5e-3 * s.depth.at<float>(200, 160));
  EXPECT_NEAR(s.normals.at<cv::Vec3f>(200, 160)[1], 1.0, 1e-4);
}

// The albedo method follows the scene class: Retinex indoors, the blur
// outdoors (albedo.h), unless one method is asked for everywhere.
TEST(InferScene, AlbedoMethodFollowsTheSceneClass) {
  const auto albedo_why = [](const SceneModel& s) {
    for (const auto& r : s.reports)
      if (r.stage == "albedo") return r.why;
    return std::string("no albedo report");
  };
  const cv::Mat street = blue_sky_over_ground();
  const SceneModel outdoor = infer_scene(street);
  ASSERT_FALSE(outdoor.indoor) << "a blue sky over a third of the frame";
  EXPECT_NE(albedo_why(outdoor).find("blurred"), std::string::npos) << albedo_why(outdoor);
  InferenceOptions everywhere;
  everywhere.albedo.outdoor_method.reset();
  EXPECT_NE(albedo_why(infer_scene(street, everywhere)).find("Retinex"), std::string::npos);

  if (!std::filesystem::exists(std::string(testing::kBlenderPanoramaDir) + "/interior.exr"))
    GTEST_SKIP() << "install blender-data (scripts/setup.sh does)";
  // A real room: a view of blender-data's hotel room.
  const auto views = panorama_views(testing::blender_panorama("interior"), 1, {5.0}, 60.0, 160, 120);
  const SceneModel room = infer_scene(views.at(0).photo_linear);
  ASSERT_TRUE(room.indoor);
  EXPECT_NE(albedo_why(room).find("Retinex"), std::string::npos) << albedo_why(room);
}

TEST(SceneModelFolder, RoundTripsEverything) {
  SceneModel s = infer_scene(simple_room(96, 72));
  s.source_photo = "room.png";
  HiddenFacade facade;  // a room has none; a street's are kept as they are
  facade.normal = -Eigen::Vector3d::UnitZ();
  facade.offset = 7.25, facade.bottom_m = -0.1, facade.top_m = 9.5;
  facade.along_min = -40, facade.seen_min = -3.5, facade.seen_max = 12.25, facade.along_max = 40;
  facade.albedo = {0.6f, 0.5f, 0.25f};
  facade.pixels = 321;
  s.hidden_facades = {facade};
  s.enclosure.min = {-3.25, -0.1, -6.5};  // a room's (LightingOptions::enclose_room)
  s.enclosure.max = {2.75, 2.9, 1.125};
  s.enclosure.albedo = {0.6f, 0.5f, 0.4f};
  const std::string dir = ::testing::TempDir() + "/scene_roundtrip";
  std::filesystem::remove_all(dir);
  save_scene(s, dir);
  for (const char* f : {"scene.json", "depth.exr", "albedo.exr", "normals.exr"})
    EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(dir) / f)) << f;
  const SceneModel t = load_scene(dir);
  EXPECT_EQ(t.width, s.width);
  EXPECT_DOUBLE_EQ(t.fx, s.fx);
  EXPECT_TRUE(t.R_world_from_cam.isApprox(s.R_world_from_cam, 1e-12));
  EXPECT_EQ(cv::norm(t.depth, s.depth, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(t.albedo, s.albedo, cv::NORM_INF), 0.0);
  ASSERT_EQ(t.lights.size(), s.lights.size());
  for (size_t i = 0; i < s.lights.size(); ++i) {
    EXPECT_EQ(t.lights[i].type, s.lights[i].type);
    EXPECT_TRUE(t.lights[i].intensity.isApprox(s.lights[i].intensity));
    if (s.lights[i].type == LightSource::Type::Ibl) {
      EXPECT_EQ(cv::norm(t.lights[i].environment, s.lights[i].environment, cv::NORM_INF), 0.0);
    }
  }
  EXPECT_EQ(t.reports.size(), s.reports.size());
  EXPECT_EQ(t.source_photo, "room.png");
  ASSERT_EQ(t.hidden_facades.size(), 1u);
  const HiddenFacade& f = t.hidden_facades[0];
  EXPECT_TRUE(f.normal.isApprox(facade.normal));
  for (auto [a, b] : {std::pair{f.offset, facade.offset}, {f.bottom_m, facade.bottom_m}, {f.top_m, facade.top_m},
                      {f.along_min, facade.along_min}, {f.seen_min, facade.seen_min}, {f.seen_max, facade.seen_max},
                      {f.along_max, facade.along_max}})
    EXPECT_DOUBLE_EQ(a, b);
  EXPECT_TRUE(f.albedo.isApprox(facade.albedo));
  EXPECT_EQ(f.pixels, 321);
  EXPECT_EQ(t.enclosure.min, s.enclosure.min);
  EXPECT_EQ(t.enclosure.max, s.enclosure.max);
  EXPECT_EQ(t.enclosure.albedo, s.enclosure.albedo);
}

TEST(SceneModelFolder, MissingOrBrokenFolderIsAClearError) {
  EXPECT_THROW(load_scene(::testing::TempDir() + "/no_such_scene"), std::runtime_error);
  const std::string dir = ::testing::TempDir() + "/broken_scene";
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/scene.json") << "{\"K\": 3}";
  EXPECT_THROW(load_scene(dir), std::runtime_error);
}

}  // namespace
}  // namespace propcam::inference

namespace propcam::inference {
namespace {

render::PinholeCamera level_camera(int w, int h) {
  render::PinholeCamera c;
  c.width = w;
  c.height = h;
  c.fx = c.fy = 0.8 * w;
  c.cx = (w - 1) / 2.0;
  c.cy = (h - 1) / 2.0;
  c.R_world_from_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  c.center_world = {0, 1.5, 0};
  return c;
}

TEST(Sky, ABlueSmoothTopOverTexturedGroundIsOutdoor) {
  const cv::Mat photo = blue_sky_over_ground();
  StageReport report;
  SkyEstimate sky;
  EXPECT_FALSE(classify_indoor(photo, level_camera(160, 120), report, &sky));
  EXPECT_GT(sky.fraction, 0.3);
  EXPECT_TRUE(sky.blue);
  EXPECT_EQ(sky.mask.size(), photo.size());
}

TEST(Sky, HardCasesGiveAnAnswerNotACrash) {
  StageReport report;
  for (const cv::Mat& photo : {cv::Mat(cv::Size(64, 48), CV_32FC3, cv::Scalar(0, 0, 0)),
                               cv::Mat(cv::Size(64, 48), CV_32FC3, cv::Scalar(1, 1, 1)),
                               cv::Mat(cv::Size(1, 1), CV_32FC3, cv::Scalar(0.5, 0.5, 0.5)),
                               cv::Mat(cv::Size(3, 2), CV_32FC3, cv::Scalar(0.2, 0.3, 0.9))}) {
    SkyEstimate sky;
    const bool indoor = classify_indoor(photo, level_camera(photo.cols, photo.rows), report, &sky);
    EXPECT_TRUE(std::isfinite(sky.fraction));
    EXPECT_TRUE(sky.mean_colour.allFinite());
    EXPECT_EQ(classify_indoor(photo, level_camera(photo.cols, photo.rows), report), indoor) << "deterministic";
  }
  SkyEstimate black;
  classify_indoor(cv::Mat(cv::Size(64, 48), CV_32FC3, cv::Scalar(0, 0, 0)), level_camera(64, 48), report, &black);
  EXPECT_EQ(black.fraction, 0.0) << "a black frame shows no sky";
}

}  // namespace
}  // namespace propcam::inference
