#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "propcam/render/depth_mesh.h"
#include "propcam/render/lights.h"
#include "propcam/render/panorama.h"

namespace propcam::render {
namespace {

TEST(Panorama, ViewOfAUniformPanoramaIsUniform) {
  const cv::Mat pano(64, 128, CV_32FC3, cv::Scalar(0.25, 0.5, 0.75));
  const cv::Mat view = rectilinear_view(pano, view_camera({32, 24, 70, 30, -10, 5, 1.5}));
  double min_v, max_v;
  cv::minMaxLoc(view.reshape(1), &min_v, &max_v);
  EXPECT_NEAR(min_v, 0.25, 1e-5);
  EXPECT_NEAR(max_v, 0.75, 1e-5);
}

TEST(Panorama, TheViewCentreSeesTheDirectionTheCameraFaces) {
  // One bright texel block around the direction yaw 90 (toward -X), level.
  cv::Mat pano(90, 180, CV_32FC3, cv::Scalar(0, 0, 0));
  const Eigen::Vector2f uv = EnvironmentLight::direction_to_uv(Eigen::Vector3f(-1, 0, 0));
  const cv::Point c(static_cast<int>(uv.x() * pano.cols), static_cast<int>(uv.y() * pano.rows));
  cv::rectangle(pano, {c.x - 2, c.y - 2}, {c.x + 2, c.y + 2}, cv::Scalar(1, 1, 1), cv::FILLED);
  ViewSpec spec;
  spec.width = 41;
  spec.height = 41;
  spec.horizontal_fov_deg = 40;
  spec.yaw_deg = 90;
  const PinholeCamera cam = view_camera(spec);
  EXPECT_LT((cam.R_world_from_cam.col(2) - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-9);
  const cv::Mat view = rectilinear_view(pano, cam);
  EXPECT_GT(view.at<cv::Vec3f>(20, 20)[0], 0.9f);
  EXPECT_EQ(view.at<cv::Vec3f>(2, 2)[0], 0.f);
}

TEST(Panorama, PitchUpLooksUp) {
  ViewSpec spec;
  spec.pitch_deg = 30;
  const PinholeCamera cam = view_camera(spec);
  EXPECT_NEAR(cam.R_world_from_cam.col(2).y(), std::sin(30 * M_PI / 180), 1e-9);
}

TEST(Panorama, BadTexelsAndBadSpecsAreHandled) {
  cv::Mat pano(16, 32, CV_32FC3, cv::Scalar(-5, std::numeric_limits<float>::quiet_NaN(),
                                            std::numeric_limits<float>::infinity()));
  const cv::Mat view = rectilinear_view(pano, view_camera({8, 8, 60, 0, 0, 0, 1.5}));
  EXPECT_TRUE(cv::checkRange(view, true, nullptr, 0.0, 1e-30)) << "negative, NaN and Inf texels become 0";
  EXPECT_THROW(view_camera({0, 8, 60, 0, 0, 0, 1.5}), std::invalid_argument);
  EXPECT_THROW(view_camera({8, 8, 180, 0, 0, 0, 1.5}), std::invalid_argument);
  EXPECT_THROW(rectilinear_view(cv::Mat(), view_camera({8, 8, 60, 0, 0, 0, 1.5})), std::invalid_argument);
}

TEST(Panorama, AutoExposurePutsThePercentileAtTheTarget) {
  cv::Mat img(10, 10, CV_32FC3, cv::Scalar(2, 2, 2));
  EXPECT_NEAR(auto_expose(img, 0.5, 0.5), 0.25, 1e-9);
  EXPECT_NEAR(img.at<cv::Vec3f>(3, 3)[1], 0.5f, 1e-6);
  cv::Mat black(10, 10, CV_32FC3, cv::Scalar(0, 0, 0));
  EXPECT_EQ(auto_expose(black), 1.0) << "a black frame is left alone";
}

TEST(DepthMesh, SkyPixelsGetNoSurface) {
  PinholeCamera cam;
  cam.width = 8;
  cam.height = 8;
  cam.fx = cam.fy = 8;
  cam.cx = cam.cy = 3.5;
  cv::Mat depth(8, 8, CV_32F, cv::Scalar(2.f));
  depth.rowRange(0, 4).setTo(kSkyDepthM);
  const cv::Mat albedo(8, 8, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  DepthMeshOptions o;
  o.step_pixels = 1;
  const Mesh sky_half = mesh_from_depth(depth, albedo, cam, o);
  const Mesh full = mesh_from_depth(cv::Mat(8, 8, CV_32F, cv::Scalar(2.f)), albedo, cam, o);
  EXPECT_GT(sky_half.triangles.size(), 0u);
  EXPECT_LT(sky_half.triangles.size(), full.triangles.size() / 2 + 1);
  for (const auto& p : sky_half.positions) EXPECT_LT(p.norm(), 10.f);
}

}  // namespace
}  // namespace propcam::render
