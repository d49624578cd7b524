// Hard cases of the IBL ranking's features: degenerate photos and missing
// cues give finite, deterministic features (each computed twice).
#include <gtest/gtest.h>

#include <limits>

#include "propcam/inference/ibl_ranking.h"
#include "propcam/inference/lighting.h"
#include "propcam/render/panorama.h"

namespace propcam::inference {
namespace {

render::PinholeCamera camera_for(const cv::Mat& photo) {
  render::ViewSpec spec;
  spec.width = photo.cols;
  spec.height = photo.rows;
  return render::view_camera(spec);
}

void expect_finite_and_deterministic(const IblFeatureInputs& in, const char* what) {
  const IblViewFeatures a = ibl_view_features(in), b = ibl_view_features(in);
  const IblSimilarity self = ibl_similarity(a, b);
  EXPECT_TRUE(self.allFinite()) << what;
  for (int i = 0; i < kIblSimilarityCount; ++i) {
    EXPECT_GE(self[i], 0.0) << what;
    EXPECT_LE(self[i], 1.0) << what;
  }
  EXPECT_EQ(a.sp, b.sp) << what;
  EXPECT_EQ(a.hue, b.hue) << what;
  EXPECT_EQ(cv::norm(a.gc, b.gc, cv::NORM_INF), 0.0) << what;
  EXPECT_TRUE(cv::checkRange(a.gc) && cv::checkRange(a.om) && cv::checkRange(a.lc)) << what;
}

TEST(IblRankingHardCases, BlackSaturatedTinyAndNaNPhotos) {
  const cv::Mat black(120, 160, CV_32FC3, cv::Scalar::all(0));
  const cv::Mat saturated(120, 160, CV_32FC3, cv::Scalar::all(50));
  const cv::Mat tiny(16, 16, CV_32FC3, cv::Scalar(0.2, 0.4, 0.6));
  cv::Mat nan = saturated.clone() * 0.01;
  nan.at<cv::Vec3f>(5, 5) = cv::Vec3f(std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -3.f);
  for (const auto& [photo, what] : {std::pair{black, "black"}, std::pair{saturated, "saturated"}, std::pair{tiny, "16x16"},
                                    std::pair{nan, "NaN/Inf/negative pixels"}}) {
    IblFeatureInputs in;
    in.photo_linear = photo;
    in.camera = camera_for(photo);
    expect_finite_and_deterministic(in, what);
  }
}

TEST(IblRankingHardCases, BrokenCameraAndMismatchedMaskSizes) {
  IblFeatureInputs in;
  in.photo_linear = cv::Mat(90, 200, CV_32FC3, cv::Scalar(0.3, 0.3, 0.3));  // not 4:3
  in.camera.fx = std::numeric_limits<double>::quiet_NaN();                    // no usable camera
  in.orientation = cv::Mat(7, 5, CV_8U, cv::Scalar(200));                     // labels out of range, odd size
  in.sky_mask = cv::Mat(3, 3, CV_8U, cv::Scalar(255));
  in.light_mask = cv::Mat(1, 1, CV_8U, cv::Scalar(255));
  expect_finite_and_deterministic(in, "broken camera, odd masks");
}

TEST(IblRankingHardCases, EmptyOrWrongTypePhotoIsAClearError) {
  IblFeatureInputs in;
  EXPECT_THROW(ibl_view_features(in), std::invalid_argument);
  in.photo_linear = cv::Mat(10, 10, CV_8UC3, cv::Scalar::all(0));
  EXPECT_THROW(ibl_view_features(in), std::invalid_argument);
}

TEST(IblRankingHardCases, MismatchedFeaturesAreAClearError) {
  IblFeatureInputs in;
  in.photo_linear = cv::Mat(48, 64, CV_32FC3, cv::Scalar::all(0.5));
  in.camera = camera_for(in.photo_linear);
  const IblViewFeatures a = ibl_view_features(in);
  IblViewFeatures b = a;
  b.hue.pop_back();
  EXPECT_THROW(ibl_similarity(a, b), std::invalid_argument);
}

// Ranked lights straight overhead, straight below, at the horizon, tiny
// and as large as the sphere: finite quads with area, or skipped (below).
TEST(IblRankingHardCases, DegenerateRankedLightsGiveFiniteQuads) {
  IblRanker r;
  IblRankerEntry e{"odd", SceneKind::Indoor, {}, ShRadiance::Zero()};
  const std::pair<Eigen::Vector3d, double> odd[] = {{Eigen::Vector3d::UnitY(), 0.05},  {-Eigen::Vector3d::UnitY(), 0.05},
                                                    {Eigen::Vector3d::UnitX(), 1e-12}, {-Eigen::Vector3d::UnitZ(), 4 * M_PI}};
  for (const auto& [direction, solid_angle] : odd) {
    IblLightRegion l;
    l.direction = direction;
    l.solid_angle_sr = solid_angle;
    l.power_share = 0.25;
    l.distance = LightDistance::Close;
    e.lights.push_back(l);
  }
  IblLightRegion sun = e.lights[0];
  sun.distance = LightDistance::Infinite;  // a sun at the zenith
  e.lights.push_back(sun);
  r.entries.push_back(e);
  IblRankerView v;
  IblFeatureInputs in;
  in.photo_linear = cv::Mat(48, 64, CV_32FC3, cv::Scalar::all(0.4));
  in.camera = camera_for(in.photo_linear);
  v.features = ibl_view_features(in);
  r.views.push_back(v);
  LightingOptions options;
  options.max_lights_per_ibl = 5;
  const render::PinholeCamera photo = camera_for(in.photo_linear);
  for (int run = 0; run < 2; ++run) {
    const RankedLights lights = ranked_ibl_candidates(r, v.features, photo, {}, true, options);
    ASSERT_EQ(lights.lights.size(), 4u);  // the one below the floor is skipped
    for (const auto& l : lights.lights) {
      EXPECT_TRUE(l.corner.allFinite() && l.edge_u.allFinite() && l.edge_v.allFinite() && l.position.allFinite());
      EXPECT_GT(l.edge_u.cross(l.edge_v).norm(), 1e-4);
    }
  }
}

}  // namespace
}  // namespace propcam::inference
