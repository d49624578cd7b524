#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <unistd.h>

#include "world_bench/panorama_world.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/ibl_ranking.h"
#include "propcam/inference/infer.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/panorama.h"
#include "worlds/real_views.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;

const inference::InferenceOptions kDefaults;

bool have_blender_data() { return fs::exists(panorama_path("courtyard")); }

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("propcam_panorama_world_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A world the size of a unit test.
PanoramaWorldOptions small_options(int width = 160, int height = 120) {
  PanoramaWorldOptions o;
  o.width = width;
  o.height = height;
  o.views_per_panorama = 1;
  o.spp = 8;
  o.probe_face_px = 12;
  o.probe_spp = 4;
  o.quiet = true;
  return o;
}

// The truth as a scene model: the view's exact camera, a level grey floor
// at y = 0 (sky elsewhere) and the panorama itself (exposed as the photo,
// turned by `turn_deg` about Y) as the light.
inference::SceneModel floor_scene(const PanoramaView& v, double turn_deg = 0, bool floor = true) {
  inference::SceneModel s;
  const render::PinholeCamera& cam = v.camera;
  s.width = cam.width, s.height = cam.height;
  s.fx = cam.fx, s.fy = cam.fy, s.cx = cam.cx, s.cy = cam.cy;
  s.R_world_from_cam = cam.R_world_from_cam;
  s.camera_height_m = cam.center_world.y();
  s.gamma = 2.2;
  s.indoor = v.indoor;
  s.depth = cv::Mat(cam.height, cam.width, CV_32F, cv::Scalar(render::kSkyDepthM));
  s.albedo = cv::Mat(cam.height, cam.width, CV_32FC3, cv::Scalar::all(0.4));
  s.normals = cv::Mat(cam.height, cam.width, CV_32FC3, cv::Scalar(0, 1, 0));
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const Eigen::Vector3d d = cam.ray_direction(x, y);
      if (!floor || d.y() > -1e-3) continue;
      const double t = cam.center_world.y() / -d.y();
      s.depth.at<float>(y, x) = static_cast<float>(t * (cam.R_world_from_cam.transpose() * d).z());
    }
  inference::SupportPlane plane;
  plane.name = "floor";
  plane.normal = Eigen::Vector3d::UnitY();
  plane.offset = 0;
  s.planes.push_back(plane);
  cv::Mat pano = capture::read_image_float(v.panorama_file), small;
  cv::resize(pano, small, {128, 64}, 0, 0, cv::INTER_AREA);
  const int shift = static_cast<int>(std::lround(turn_deg / 360.0 * small.cols));
  if (shift != 0) {
    cv::Mat turned;
    cv::hconcat(small.colRange(shift, small.cols), small.colRange(0, shift), turned);
    small = turned;
  }
  cv::max(small, 0.0, small);
  inference::LightSource ibl;
  ibl.type = inference::LightSource::Type::Ibl;
  ibl.environment = small;
  ibl.intensity = Eigen::Vector3d::Constant(v.exposure);
  ibl.file = "ibl.exr";
  s.lights.push_back(ibl);
  return s;
}

TEST(PanoramaWorld, ViewsAreWhatPropcamViewShoots) {
  if (!have_blender_data()) GTEST_SKIP() << "blender-data is not installed";
  PanoramaWorldOptions o = small_options(96, 72);
  o.panoramas = {"courtyard"};
  o.views_per_panorama = 2;
  const auto views = make_panorama_views(o);
  ASSERT_EQ(views.size(), 2u);
  EXPECT_EQ(views[0].name, "courtyard_yaw0");
  EXPECT_EQ(views[1].name, "courtyard_yaw180");
  EXPECT_FALSE(views[0].indoor);
  EXPECT_EQ(views[0].group, "courtyard");
  EXPECT_DOUBLE_EQ(views[0].pitch_deg, -8);
  EXPECT_DOUBLE_EQ(views[1].pitch_deg, -20);
  for (const auto& v : views) {
    const RealView shot = shoot_panorama_view(v.panorama_file, render::view_spec(v.yaw_deg, v.pitch_deg, 60, 96, 72));
    EXPECT_EQ(cv::norm(shot.photo_linear, v.photo_linear, cv::NORM_INF), 0.0) << v.name;
    EXPECT_TRUE(shot.camera.R_world_from_cam.isApprox(v.camera.R_world_from_cam));
    EXPECT_GT(v.exposure, 0.0);
    // The exposure puts the 97th luminance percentile at 0.9: the photo is
    // exposure * radiance, clipped (checked where a pixel is mid-grey).
    const cv::Mat linear = render::rectilinear_view(capture::read_image_float(v.panorama_file), v.camera) * v.exposure;
    const cv::Vec3f a = linear.at<cv::Vec3f>(36, 48), b = v.photo_linear.at<cv::Vec3f>(36, 48);
    if (a[1] > 0.05 && a[1] < 0.9) {
      EXPECT_NEAR(a[1], b[1], 0.02 * a[1] + 0.003);
    }
    // Emitters are saturated in the photo.
    for (int y = 0; y < v.emitters.rows; ++y)
      for (int x = 0; x < v.emitters.cols; ++x)
        if (v.emitters.at<uint8_t>(y, x)) {
          EXPECT_EQ(v.photo_linear.at<cv::Vec3f>(y, x)[1], 1.f);
        }
  }
}

TEST(PanoramaWorld, NamesGroupsAndMissingFiles) {
  const fs::path dir = temp_dir("names");
  PanoramaWorldOptions o = small_options(32, 24);
  o.pmndrs_dir = dir.string();
  o.panoramas = {"pmndrs_sunrise"};
  try {
    make_panorama_views(o);
    ADD_FAILURE() << "a missing pmndrs panorama must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("fetch_pmndrs_hdri.sh"), std::string::npos) << e.what();
  }
  // The run goes on: the panorama is a row saying why.
  const nlohmann::json run = run_panorama_world(o);
  ASSERT_EQ(run["scenes"].size(), 1u);
  EXPECT_NE(run["scenes"][0].value("error", "").find("fetch_pmndrs_hdri.sh"), std::string::npos) << run.dump();
  EXPECT_EQ(run["summary"]["placed"].get<int>(), 0);
  EXPECT_EQ(panorama_world_names().size(), 26u);
  capture::write_image((dir / "sunrise.exr").string(), cv::Mat(16, 32, CV_32FC3, cv::Scalar(0.2, 0.3, 0.4)));
  capture::write_image((dir / "lobby.exr").string(), cv::Mat(16, 32, CV_32FC3, cv::Scalar(0.2, 0.3, 0.4)));
  o.panoramas = {"pmndrs_sunrise", (dir / "lobby.exr").string(), "pmndrs/lobby"};
  const auto views = make_panorama_views(o);
  ASSERT_EQ(views.size(), 3u);
  // pmndrs' sunrise is blender-data's: one group for leave-one-out.
  EXPECT_EQ(views[0].panorama, "pmndrs_sunrise");
  EXPECT_EQ(views[0].group, "sunrise");
  EXPECT_FALSE(views[0].indoor);
  EXPECT_TRUE(views[0].known);
  EXPECT_EQ(views[1].panorama, "pmndrs_lobby");
  EXPECT_TRUE(views[1].indoor);
  EXPECT_EQ(views[2].group, "pmndrs_lobby");
  // A file that is none of the 26 is a new panorama, labelled by its suffix.
  fs::create_directories(dir / "other");
  capture::write_image((dir / "other" / "x.exr").string(), cv::Mat(16, 32, CV_32FC3, cv::Scalar::all(1)));
  o.panoramas = {(dir / "other" / "x.exr").string() + "=indoor"};
  const auto other = make_panorama_views(o);
  ASSERT_EQ(other.size(), 1u);
  EXPECT_FALSE(other[0].known);
  EXPECT_TRUE(other[0].indoor);
  const inference::InferenceOptions same = leave_one_out_options(other[0], o, kDefaults);
  EXPECT_TRUE(same.lighting.light_classifier.empty());
  EXPECT_TRUE(same.scene_class_left_out.empty());
  o.panoramas = {"atlantis"};
  EXPECT_THROW(make_panorama_views(o), std::invalid_argument);
}

// Leave one out on small training specs: the classifier is the one
// train_light_classifier makes without the panorama, the ranker has neither
// its entry nor its views and the weights trained without them, and both are
// cached.
TEST(PanoramaWorld, LeaveOneOutModelsNeverSawThePanorama) {
  if (!have_blender_data()) GTEST_SKIP() << "blender-data is not installed";
  const fs::path cache = temp_dir("loo");
  PanoramaWorldOptions o = small_options(96, 72);
  o.cache_dir = cache.string();
  o.panoramas = {"interior"};
  LightTrainingSpec light;
  light.panoramas = {"courtyard", "interior", "studio"};
  light.views_per_turn = 2;
  light.pitches_deg = {0.0, 40.0};
  light.trees = 6;
  light.depth = 8;
  light.quiet = true;
  o.light_training = light;
  IblTrainingSpec ibl;
  ibl.library.width = 128;
  ibl.library.procedural_skies = 1;
  ibl.library.procedural_rooms = 1;
  ibl.views_per_entry = 1;
  ibl.width = 96;
  ibl.height = 72;
  ibl.pairs_per_query = 50;
  ibl.quiet = true;
  o.ibl_training = ibl;
  const PanoramaView view = make_panorama_views(o).at(0);

  nlohmann::json report;
  const inference::InferenceOptions loo = leave_one_out_options(view, o, kDefaults, &report);
  EXPECT_EQ(loo.scene_class_left_out, "interior");
  EXPECT_FALSE(report["light_classifier"]["cached"].get<bool>());
  ASSERT_TRUE(fs::exists(loo.lighting.light_classifier));
  ASSERT_TRUE(fs::exists(loo.lighting.ibl_ranker));

  // The classifier: the same forest as training without "interior".
  LightTrainingSpec without = light;
  without.panoramas = {"courtyard", "studio"};
  const inference::LightClassifier reference = train_light_classifier(without);
  const inference::LightClassifier loaded = inference::LightClassifier::load(loo.lighting.light_classifier);
  const inference::SuperpixelFeatures f = inference::superpixel_features(view.photo_linear, light.classifier);
  EXPECT_EQ(loaded.scores(f.features), reference.scores(f.features));

  // The ranker: no entry or view of "interior"; weights as train_ibl_weights holding it out.
  const inference::IblRanker ranker = inference::IblRanker::load(loo.lighting.ibl_ranker);
  const IblTrainingSet set = build_ibl_training_set(ibl);
  int held = -1;
  for (size_t e = 0; e < set.ranker.entries.size(); ++e)
    if (set.ranker.entries[e].name == "blender_interior") held = static_cast<int>(e);
  ASSERT_GE(held, 0);
  EXPECT_EQ(ranker.entries.size(), set.ranker.entries.size() - 1);
  for (const auto& e : ranker.entries) EXPECT_NE(e.name, "blender_interior");
  EXPECT_EQ(ranker.views.size(), set.ranker.views.size() - 1);
  for (const auto& v : ranker.views) {
    ASSERT_GE(v.entry, 0);
    ASSERT_LT(v.entry, static_cast<int>(ranker.entries.size()));
  }
  const inference::SvmRankResult w = train_ibl_weights(set, held, ibl);
  EXPECT_LT((ranker.weights - w.w).norm(), 1e-6 * (1 + w.w.norm()));

  // Inference with them never ranks the panorama itself.
  const inference::SceneModel est = inference::infer_scene(view.photo_linear, loo);
  for (const auto& r : est.reports) {
    if (r.stage != "ibl_ranking" || !r.details.contains("matches")) continue;
    for (const auto& m : r.details["matches"]) {
      EXPECT_NE(m.value("panorama", ""), "blender_interior");
    }
  }

  // Cached: the second call trains nothing.
  const auto start = std::chrono::steady_clock::now();
  nlohmann::json again;
  const inference::InferenceOptions cached = leave_one_out_options(view, o, kDefaults, &again);
  EXPECT_TRUE(again["light_classifier"]["cached"].get<bool>());
  EXPECT_TRUE(again["ibl_ranker"]["cached"].get<bool>());
  EXPECT_EQ(cached.lighting.light_classifier, loo.lighting.light_classifier);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);

  // Another spec is another model.
  o.light_training->trees = 5;
  nlohmann::json changed;
  leave_one_out_options(view, o, kDefaults, &changed);
  EXPECT_FALSE(changed["light_classifier"]["cached"].get<bool>());

  // Strict: the ranker's training set rebuilt with the leave-one-out models.
  o.strict_ibl_features = true;
  nlohmann::json strict;
  const inference::InferenceOptions s = leave_one_out_options(view, o, kDefaults, &strict);
  EXPECT_FALSE(strict["ibl_ranker"]["cached"].get<bool>());
  EXPECT_NE(strict["ibl_ranker"]["training_set"].get<std::string>().find("strict"), std::string::npos);
  const inference::IblRanker strict_ranker = inference::IblRanker::load(s.lighting.ibl_ranker);
  EXPECT_EQ(strict_ranker.entries.size(), ranker.entries.size());
  for (const auto& e : strict_ranker.entries) EXPECT_NE(e.name, "blender_interior");

  // Off: the committed models.
  o.leave_one_out = false;
  const inference::InferenceOptions committed = leave_one_out_options(view, o, kDefaults);
  EXPECT_TRUE(committed.lighting.light_classifier.empty());
  EXPECT_TRUE(committed.lighting.ibl_ranker.empty());
  EXPECT_TRUE(committed.scene_class_left_out.empty());
}

TEST(PanoramaWorld, StrictIblTrainingSetIsTheSharedOneWithTheCommittedModels) {
  if (!have_blender_data()) GTEST_SKIP() << "blender-data is not installed";
  IblTrainingSpec ibl;
  ibl.library.width = 128;
  ibl.library.procedural_skies = 1;
  ibl.library.procedural_rooms = 1;
  ibl.views_per_entry = 1;
  ibl.width = 96;
  ibl.height = 72;
  ibl.quiet = true;
  const IblTrainingSet shared = build_ibl_training_set(ibl);
  const inference::LightClassifier committed = inference::LightClassifier::load(inference::default_light_classifier_path());
  const IblTrainingSet same = build_ibl_training_set_with(ibl, kDefaults, committed);
  ASSERT_EQ(same.ranker.views.size(), shared.ranker.views.size());
  EXPECT_LT((same.distance - shared.distance).norm(), 1e-12);
  for (size_t q = 0; q < same.similarity.size(); ++q)
    for (size_t j = 0; j < same.similarity.size(); ++j)
      ASSERT_LT((same.similarity[q][j] - shared.similarity[q][j]).norm(), 1e-12) << q << "," << j;
  // Dropping an entry drops its views only; the others' views are sampled as before.
  const IblTrainingSet dropped = build_ibl_training_set_with(ibl, kDefaults, committed, {"blender_city"});
  EXPECT_EQ(dropped.ranker.entries.size(), shared.ranker.entries.size() - 1);
  ASSERT_EQ(dropped.ranker.views.size(), shared.ranker.views.size() - 1);
  EXPECT_DOUBLE_EQ(dropped.ranker.views.back().yaw_deg, shared.ranker.views.back().yaw_deg);
}

TEST(PanoramaWorld, TrueLightScoresBetterThanATurnedOne) {
  if (!have_blender_data()) GTEST_SKIP() << "blender-data is not installed";
  PanoramaWorldOptions o = small_options();
  o.panoramas = {"courtyard"};
  o.pitch_first_deg = o.pitch_last_deg = -15;
  const PanoramaView view = make_panorama_views(o).at(0);
  const ProbeResult right = score_light_probe(view, floor_scene(view), o);
  const ProbeResult turned = score_light_probe(view, floor_scene(view, 180), o);
  ASSERT_TRUE(right.placed) << right.why;
  ASSERT_TRUE(turned.placed) << turned.why;
  ASSERT_EQ(right.spheres.size(), 3u);
  EXPECT_EQ(right.spheres[0].material, "diffuse");
  EXPECT_EQ(right.spheres[2].material, "mirror");
  for (const auto& s : right.spheres) {
    EXPECT_GE(s.pixels, 20) << s.material;
    EXPECT_TRUE(std::isfinite(s.rmse) && std::isfinite(s.si_rmse)) << s.material;
    EXPECT_LE(s.si_rmse, s.rmse + 0.05) << s.material;
  }
  // The probe stands near the bottom centre, pixel-aligned in both images.
  EXPECT_NEAR(right.at.x(), 0.5 * (o.width - 1), 0.2 * o.width);
  EXPECT_GT(right.at.y(), 0.6 * o.height);
  EXPECT_EQ(right.mask.size(), cv::Size(o.width, o.height));
  EXPECT_GT(cv::mean(right.truth, right.mask > 0)[1], 0.05);
  // The right light: the dominant direction within a few tens of degrees
  // (our floor is not the panorama's ground), and closer than the turned one.
  EXPECT_LT(right.direction_deg, 30.0);
  EXPECT_GT(turned.direction_deg, right.direction_deg + 30.0);
  EXPECT_LT(right.spheres[0].rmse, turned.spheres[0].rmse);
  EXPECT_LT(right.spheres[2].rmse, turned.spheres[2].rmse);
  EXPECT_GT(right.seconds, 0.0);
  // The Khan-style baseline at the same spot sees only the frame: the
  // panorama itself as the light shows the mirror sphere closer to the
  // truth. (Not the diffuse one: after its best scale, the baseline's is as
  // close here, 0.099 against 0.102; both spheres stand on our floor, whose
  // bounce the truth lacks.)
  ASSERT_EQ(right.khan_spheres.size(), 3u);
  for (const auto& s : right.khan_spheres) EXPECT_TRUE(std::isfinite(s.si_rmse)) << s.material;
  EXPECT_LT(right.spheres[2].si_rmse, right.khan_spheres[2].si_rmse);
}

TEST(PanoramaWorld, NoFloorSeenIsASkippedProbeWithWhy) {
  if (!have_blender_data()) GTEST_SKIP() << "blender-data is not installed";
  PanoramaWorldOptions o = small_options(96, 72);
  o.panoramas = {"courtyard"};
  o.pitch_first_deg = o.pitch_last_deg = 35;  // looking up: sky and facades
  const PanoramaView view = make_panorama_views(o).at(0);
  const ProbeResult r = score_light_probe(view, floor_scene(view, 0, /*floor=*/false), o);
  EXPECT_FALSE(r.placed);
  EXPECT_NE(r.why.find("no level support"), std::string::npos) << r.why;
  EXPECT_TRUE(r.spheres.empty());
}

TEST(PanoramaWorld, BlackPanoramaGivesFiniteRows) {
  const fs::path dir = temp_dir("black");
  const std::string file = (dir / "black.exr").string();
  capture::write_image(file, cv::Mat(32, 64, CV_32FC3, cv::Scalar::all(0)));
  PanoramaWorldOptions o = small_options();
  o.panoramas = {file + "=indoor"};
  o.cache_dir = (dir / "cache").string();
  const PanoramaView view = make_panorama_views(o).at(0);
  EXPECT_EQ(view.exposure, 1.0);
  EXPECT_EQ(cv::countNonZero(view.emitters), 0);
  EXPECT_EQ(cv::norm(view.photo_linear, cv::NORM_INF), 0.0);
  const ProbeResult r = score_light_probe(view, floor_scene(view), o);
  ASSERT_TRUE(r.placed) << r.why;
  for (const auto& spheres : {r.spheres, r.khan_spheres}) {
    ASSERT_EQ(spheres.size(), 3u);
    for (const auto& s : spheres) {
      EXPECT_EQ(s.rmse, 0.0) << s.material;
      EXPECT_EQ(s.si_rmse, 0.0) << s.material;
    }
  }
  EXPECT_TRUE(std::isnan(r.direction_deg)) << "no light, no direction";
  // The whole run: inference on a black photo, then the probe; JSON without NaN.
  o.width = 96, o.height = 72;
  const nlohmann::json result = run_panorama_world(o);
  ASSERT_EQ(result["scenes"].size(), 1u);
  const nlohmann::json& row = result["scenes"][0];
  EXPECT_FALSE(row.contains("error")) << row.dump();
  EXPECT_TRUE(row.contains("probe"));
  EXPECT_TRUE(nlohmann::json::accept(result.dump()));
  EXPECT_EQ(result["summary"]["scenes"].get<int>(), 1);
  EXPECT_FALSE(format_panorama_world(result).empty());
}

// Optional (PROPCAM_SLOW_TESTS=1, minutes): the committed specs rebuild the
// committed models from the 26 panoramas, so leaving one out changes only
// that panorama.
TEST(PanoramaWorld, CommittedSpecsReproduceTheCommittedModels) {
  const char* slow = std::getenv("PROPCAM_SLOW_TESTS");
  if (!slow || std::string(slow) != "1") GTEST_SKIP() << "set PROPCAM_SLOW_TESTS=1 (minutes)";
  const std::string pmndrs = std::string(PROPCAM_SOURCE_DIR) + "/build/pmndrs_hdri";
  if (!fs::exists(pmndrs + "/sunrise.exr")) GTEST_SKIP() << "run scripts/fetch_pmndrs_hdri.sh first";
  const IblTrainingSpec ibl = committed_ibl_training_spec(pmndrs);
  const IblTrainingSet set = build_ibl_training_set(ibl);
  const inference::IblRanker committed = inference::IblRanker::load(inference::default_ibl_ranker_path());
  ASSERT_EQ(set.ranker.entries.size(), committed.entries.size());
  for (size_t e = 0; e < committed.entries.size(); ++e) {
    EXPECT_EQ(set.ranker.entries[e].name, committed.entries[e].name);
    // The panoramas' entries are as committed. (The procedural rooms are
    // not: commit 1b6298d fixed their irradiance after the ranker was
    // trained, so today's retrain differs from the committed weights.)
    if (committed.entries[e].name.rfind("room_", 0) != 0) {
      EXPECT_LT((set.ranker.entries[e].sh - committed.entries[e].sh).norm(), 1e-4 * (1 + committed.entries[e].sh.norm()))
          << committed.entries[e].name;
    }
  }
  const inference::SvmRankResult w = train_ibl_weights(set, -1, ibl);
  RecordProperty("ranker_weight_change", std::to_string((w.w - committed.weights).norm() / committed.weights.norm()));
  std::printf("retrained ranker weights %s vs committed %s\n", nlohmann::json(std::vector<double>(w.w.data(), w.w.data() + 7)).dump().c_str(),
              nlohmann::json(std::vector<double>(committed.weights.data(), committed.weights.data() + 7)).dump().c_str());

  // The committed classifier also learnt from the Blender world's tune photos.
  const std::string blender_world = std::string(PROPCAM_SOURCE_DIR) + "/build/worlds/blender";
  if (!fs::exists(blender_world + "/world.json")) GTEST_SKIP() << "make the Blender world first (scripts/make_blender_world.sh)";
  const inference::LightClassifier retrained = train_light_classifier(committed_light_training_spec(pmndrs, blender_world));
  const inference::LightClassifier classifier = inference::LightClassifier::load(inference::default_light_classifier_path());
  PanoramaWorldOptions o = small_options(320, 240);
  o.panoramas = {"interior", "pmndrs_lobby"};
  for (const auto& v : make_panorama_views(o)) {
    const inference::SuperpixelFeatures f = inference::superpixel_features(v.photo_linear);
    EXPECT_EQ(retrained.scores(f.features), classifier.scores(f.features)) << v.name;
  }
}

}  // namespace
}  // namespace propcam::firmware
