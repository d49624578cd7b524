#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include "propcam/inference/ibl_ranking.h"
#include "propcam/inference/lighting.h"
#include "propcam/inference/orientation_map.h"
#include "propcam/render/panorama.h"
#include "files_in_dir.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

render::PinholeCamera view(double yaw_deg, double pitch_deg = 0, double fov = 60) {
  return render::view_camera(render::view_spec(yaw_deg, pitch_deg, fov, 160, 120));
}

// A photo with a bright left half, a textured floor band and a coloured wall.
cv::Mat test_photo(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  cv::Mat p(120, 160, CV_32FC3);
  for (int y = 0; y < p.rows; ++y)
    for (int x = 0; x < p.cols; ++x) {
      const float base = x < 80 ? 0.7f : 0.2f;
      const float stripe = y > 80 && (x / 8) % 2 ? 0.3f : 0.f;
      p.at<cv::Vec3f>(y, x) = cv::Vec3f(base + stripe, base * 0.8f, base * (0.5f + 0.5f * u(rng)));
    }
  return p;
}

IblFeatureInputs inputs(const cv::Mat& photo, const render::PinholeCamera& camera) {
  IblFeatureInputs in;
  in.photo_linear = photo;
  in.camera = camera;
  in.orientation = cv::Mat(60, 80, CV_8U, cv::Scalar(static_cast<int>(SurfaceOrientation::kNormalZ)));
  in.orientation.rowRange(40, 60).setTo(static_cast<int>(SurfaceOrientation::kNormalY));
  in.sky_mask = cv::Mat::zeros(photo.size(), CV_8U);
  in.light_mask = cv::Mat::zeros(photo.size(), CV_8U);
  in.light_mask(cv::Rect(10, 0, 30, 20)).setTo(255);
  return in;
}

TEST(IblRanking, HeadingFrameOfAPanoramaViewIsItsYaw) {
  for (double yaw : {0.0, 37.0, 90.0, 200.0}) {
    const Eigen::Matrix3d h = heading_frame(view(yaw, 20).R_world_from_cam);
    // The heading looks along -Z turned by the yaw about +Y.
    const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw * std::numbers::pi / 180, Vector3d::UnitY()).toRotationMatrix();
    EXPECT_LT((h - r).norm(), 1e-9) << yaw;
    EXPECT_NEAR(h.determinant(), 1.0, 1e-12);
  }
  // Straight down: still a rotation, and finite.
  const Eigen::Matrix3d down = heading_frame(view(30, -90).R_world_from_cam);
  EXPECT_TRUE(down.allFinite());
  EXPECT_NEAR(down.determinant(), 1.0, 1e-9);
}

TEST(IblRanking, AMatchedLightKeepsItsPlaceRelativeToTheView) {
  // A lamp 30 degrees right of a view at yaw 120 appears 30 degrees right of the photo's heading.
  const render::PinholeCamera matched = view(120);
  const Vector3d in_view = view(120 - 30).ray_direction(79.5, 59.5);  // yaw decreases to the right
  const Eigen::Matrix3d photo = heading_frame(view(-45, 10).R_world_from_cam);
  const Vector3d world = panorama_to_world(in_view, heading_frame(matched.R_world_from_cam), photo);
  const Vector3d expected = view(-45 - 30).ray_direction(79.5, 59.5);
  EXPECT_LT((world - expected).norm(), 1e-9);
}

TEST(IblRanking, SimilarityIsOneForTheSameImageSymmetricAndBounded) {
  const IblViewFeatures a = ibl_view_features(inputs(test_photo(1), view(0)));
  const IblViewFeatures b = ibl_view_features(inputs(test_photo(2) * 0.3, view(0, 25)));
  const IblSimilarity self = ibl_similarity(a, a), ab = ibl_similarity(a, b), ba = ibl_similarity(b, a);
  for (int i = 0; i < kIblSimilarityCount; ++i) {
    EXPECT_NEAR(self[i], 1.0, 1e-4) << ibl_similarity_name(i);  // float histograms
    EXPECT_NEAR(ab[i], ba[i], 1e-9) << ibl_similarity_name(i);
    EXPECT_GE(ab[i], 0.0);
    EXPECT_LE(ab[i], 1.0);
  }
  EXPECT_LT(ab[6], 0.9);  // value: the second photo is much darker
}

TEST(IblRanking, HistogramsAndMapsAreNormalised) {
  const IblViewFeatures f = ibl_view_features(inputs(test_photo(3), view(10)));
  for (const auto* h : {&f.sp, &f.hue, &f.saturation, &f.value}) {
    double s = 0;
    for (float v : *h) s += v;
    EXPECT_NEAR(s, 1.0, 1e-4);
  }
  EXPECT_EQ(f.gc.size(), cv::Size(kIblGridCols, kIblGridRows));
  for (int i = 0; i < static_cast<int>(f.gc.total()); ++i) {
    const cv::Vec4f g = f.gc.ptr<cv::Vec4f>()[i], o = f.om.ptr<cv::Vec4f>()[i];
    EXPECT_NEAR(g[0] + g[1] + g[2] + g[3], 1.0, 1e-4);
    EXPECT_NEAR(o[0] + o[1] + o[2] + o[3], 1.0, 1e-4);
  }
  // The floor rows (orientation Y, below the horizon) are support.
  EXPECT_GT(f.gc.at<cv::Vec4f>(kIblGridRows - 1, 3)[1], 0.9f);
  EXPECT_GT(f.lc.at<cv::Vec2f>(1, 2)[0], 0.5f);
  EXPECT_FLOAT_EQ(f.lc.at<cv::Vec2f>(1, 2)[0] + f.lc.at<cv::Vec2f>(1, 2)[1], 1.f);
}

TEST(IblRanking, SvmRankLearnsWhichFeatureOrdersThePairs) {
  // Feature 2 decides the truth; the others are noise.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<IblSimilarity> diffs;
  std::vector<double> margins;
  for (int p = 0; p < 400; ++p) {
    IblSimilarity better, worse;
    for (int i = 0; i < kIblSimilarityCount; ++i) better[i] = u(rng), worse[i] = u(rng);
    if (better[2] < worse[2]) std::swap(better, worse);
    diffs.push_back(better - worse);
    margins.push_back(0.1 * (better[2] - worse[2]));
  }
  const SvmRankResult r = train_svm_rank(diffs, margins, {});
  EXPECT_TRUE(r.converged);
  EXPECT_LE(r.iterations, SvmRankOptions{}.max_iterations);
  for (int i = 0; i < kIblSimilarityCount; ++i)
    if (i != 2) {
      EXPECT_GT(r.w[2], 3 * std::abs(r.w[i])) << i;
    }
  int ordered = 0;
  for (const auto& d : diffs) ordered += r.w.dot(d) > 0;
  EXPECT_GT(ordered, 390);
}

TEST(IblRanking, SvmRankRejectsBadInputAndTakesNoPairs) {
  EXPECT_THROW(train_svm_rank({IblSimilarity::Ones()}, {}, {}), std::invalid_argument);
  IblSimilarity nan = IblSimilarity::Ones();
  nan[3] = std::nan("");
  EXPECT_THROW(train_svm_rank({nan}, {0.1}, {}), std::invalid_argument);
  SvmRankOptions bad;
  bad.C = 0;
  EXPECT_THROW(train_svm_rank({IblSimilarity::Ones()}, {0.1}, bad), std::invalid_argument);
  const SvmRankResult none = train_svm_rank({}, {}, {});
  EXPECT_TRUE(none.converged);
  EXPECT_EQ(none.w, IblSimilarity::Zero());
  // Contradicting pairs (each pair and its reverse): finite, bounded, w ~ 0.
  const IblSimilarity d = IblSimilarity::Constant(0.2);
  const SvmRankResult contradiction = train_svm_rank({d, -d}, {0.5, 0.5}, {});
  EXPECT_TRUE(contradiction.w.allFinite());
  EXPECT_LT(contradiction.w.norm(), 1e-3);
}

IblRanker two_entry_ranker() {
  IblRanker r;
  r.weights = IblSimilarity::Ones();
  IblRankerEntry room{"room", SceneKind::Indoor, {}, ShRadiance::Zero()};
  IblLightRegion lamp;
  lamp.direction = Vector3d(0, 1, -1).normalized();  // ahead and up of a yaw-0 view
  lamp.solid_angle_sr = 0.05;
  lamp.power_share = 0.6;
  lamp.distance = LightDistance::Medium;
  room.lights.push_back(lamp);
  room.sh(0, 0) = room.sh(0, 1) = room.sh(0, 2) = 1.0;
  IblRankerEntry sky{"sky", SceneKind::Outdoor, {}, ShRadiance::Zero()};
  IblLightRegion sun;
  sun.direction = Vector3d(1, 1, 0).normalized();
  sun.solid_angle_sr = 6e-5;
  sun.power_share = 0.9;
  sun.distance = LightDistance::Infinite;
  sky.lights.push_back(sun);
  r.entries = {room, sky};
  for (int e = 0; e < 2; ++e)
    for (double yaw : {0.0, 180.0}) {
      IblRankerView v;
      v.entry = e;
      v.yaw_deg = yaw;
      v.pitch_deg = 5;
      v.fov_deg = 70;
      v.heading = heading_frame(view(yaw, 5, 70).R_world_from_cam);
      v.features = ibl_view_features(inputs(test_photo(10 + e * 2 + (yaw > 0)), view(yaw)));
      r.views.push_back(std::move(v));
    }
  return r;
}

TEST(IblRanking, RankKeepsTheSceneKindAndTheBestViewPerPanorama) {
  const IblRanker r = two_entry_ranker();
  const IblViewFeatures q = r.views[1].features;  // room's yaw-180 view itself
  const auto indoor = r.rank(q, SceneKind::Indoor, 3);
  ASSERT_EQ(indoor.size(), 1u);
  EXPECT_EQ(indoor[0].entry, 0);
  EXPECT_EQ(indoor[0].view, 1);
  const auto outdoor = r.rank(q, SceneKind::Outdoor, 0);
  ASSERT_EQ(outdoor.size(), 1u);
  EXPECT_EQ(outdoor[0].entry, 1);
  EXPECT_EQ(r.rank(q, SceneKind::Indoor, 3)[0].score, indoor[0].score);  // deterministic
}

TEST(IblRanking, SaveLoadRoundTripsAndLoadRejectsBrokenFiles) {
  const IblRanker r = two_entry_ranker();
  const auto dir = std::filesystem::temp_directory_path() / "propcam_ibl_ranker_test";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "ranker.yml.gz").string();
  r.save(path);
  const IblRanker back = IblRanker::load(path);
  ASSERT_EQ(back.entries.size(), 2u);
  ASSERT_EQ(back.views.size(), 4u);
  EXPECT_EQ(back.entries[1].name, "sky");
  EXPECT_EQ(back.entries[1].lights[0].distance, LightDistance::Infinite);
  EXPECT_LT((back.views[3].heading - r.views[3].heading).norm(), 1e-9);
  const IblViewFeatures q = r.views[2].features;
  const auto a = r.rank(q, SceneKind::Outdoor, 1), b = back.rank(q, SceneKind::Outdoor, 1);
  EXPECT_EQ(a[0].view, b[0].view);
  EXPECT_NEAR(a[0].score, b[0].score, 0.05);  // maps are stored as 8-bit fractions
  expect_only_files(dir.string(), {"ranker.yml.gz"});

  const auto expect_error = [&](const std::string& text, const std::string& what) {
    const std::string bad = (dir / "bad.yml").string();
    std::ofstream(bad) << text;
    try {
      IblRanker::load(bad);
      ADD_FAILURE() << "accepted: " << what;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  };
  expect_error("not yaml at all {{{", "garbage");
  expect_error("%YAML:1.0\nformat: other\nversion: 1\n", "wrong format");
  expect_error("%YAML:1.0\nformat: propcam-ibl-ranker\nversion: 1\nweights: [1, 2]\n", "short weights");
  expect_error("%YAML:1.0\nformat: propcam-ibl-ranker\nversion: 1\nweights: [1, 1, 1, 1, 1, 1, 1]\nentries: []\n",
               "no entries");
  EXPECT_THROW(IblRanker::load((dir / "missing.yml.gz").string()), std::runtime_error);
  std::filesystem::remove_all(dir);
}

TEST(IblRanking, RankedLightsTurnWithTheMatchAndStayInsideTheRoom) {
  const IblRanker r = two_entry_ranker();
  const render::PinholeCamera photo = view(90, 0, 60);
  std::vector<SupportPlane> planes;
  planes.push_back({"ceiling", -Vector3d::UnitY(), 2.0, {}, {}, 0});  // -y + 2 = 0: 0.5 m above the camera
  LightingOptions options;
  const RankedLights lights = ranked_ibl_candidates(r, r.views[0].features, photo, planes, true, options);
  ASSERT_EQ(lights.lights.size(), 1u);
  const LightSource& lamp = lights.lights[0];
  // Ahead and up of the photo (the view matched at yaw 0 saw the lamp ahead and up).
  const Vector3d dir = (lamp.position - photo.center_world).normalized();
  const Vector3d expected = heading_frame(photo.R_world_from_cam) * Vector3d(0, 1, -1).normalized();
  EXPECT_LT((dir - expected).norm(), 1e-6);
  EXPECT_LT(lamp.position.y(), 2.0);  // below the ceiling
  EXPECT_GT(lamp.position.y(), 1.9);  // and on it, shining down into the room
  EXPECT_LT(lamp.edge_u.cross(lamp.edge_v).normalized().y(), -0.99);
  EXPECT_EQ(lights.matches.size(), 1u);
  // Outdoors: the sun is a far quad facing the scene.
  const RankedLights sun = ranked_ibl_candidates(r, r.views[2].features, photo, {}, false, options);
  ASSERT_EQ(sun.lights.size(), 1u);
  EXPECT_GT((sun.lights[0].position - photo.center_world).norm(), 900.0);
  EXPECT_LT(sun.lights[0].edge_u.cross(sun.lights[0].edge_v).dot(sun.lights[0].position - photo.center_world), 0.0);
  // Switched off.
  options.ibl_candidates = 0;
  EXPECT_TRUE(ranked_ibl_candidates(r, r.views[0].features, photo, planes, true, options).lights.empty());
}

TEST(IblRanking, RotatedDistanceFollowsTheViews) {
  const ShRadiance sky = project_radiance_sh(procedural_sky(30, 0, 3, 128));
  const Eigen::Matrix3d h0 = heading_frame(view(0).R_world_from_cam), h90 = heading_frame(view(90).R_world_from_cam);
  EXPECT_NEAR(ibl_render_distance(sky, h90, sky, h90), 0.0, 1e-12);
  EXPECT_GT(ibl_render_distance(sky, h0, sky, h90), 0.05);  // the sun moves 90 degrees in the view
  Eigen::Matrix3d nan = h0;
  nan(0, 0) = std::nan("");
  EXPECT_THROW(ibl_render_distance(sky, nan, sky, h0), std::invalid_argument);
}

TEST(IblRanking, TheCommittedRankerLoadsWithBothKinds) {
  const IblRanker r = IblRanker::load(default_ibl_ranker_path());
  EXPECT_GE(r.entries.size(), 20u);
  int indoor = 0, outdoor = 0;
  for (const auto& e : r.entries) (e.kind == SceneKind::Indoor ? indoor : outdoor)++;
  EXPECT_GE(indoor, 5);
  EXPECT_GE(outdoor, 5);
  EXPECT_GE(r.views.size(), 10 * r.entries.size());
  EXPECT_TRUE(r.weights.allFinite());
  EXPECT_GT(r.weights.norm(), 0.0);
}

}  // namespace
}  // namespace propcam::inference
