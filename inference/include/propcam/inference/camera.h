// Camera stage: line segments, three orthogonal vanishing directions, focal
// length and the camera's rotation relative to gravity (Hartley & Zisserman).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/scene_model.h"

namespace propcam::inference {

struct LineSegment {
  Eigen::Vector2d a, b;  // pixel coordinates, (0,0) the centre of the top-left pixel
  double length() const { return (b - a).norm(); }
};

struct LineDetectionOptions {
  double min_length_fraction = 0.025;  // of the image diagonal
  int max_lines = 500;                 // longest kept
};

// OpenCV LSD on the photo's luminance.
std::vector<LineSegment> detect_lines(const cv::Mat& photo_linear, const LineDetectionOptions& options,
                                      StageReport& report);

// Reads `x1,y1,x2,y2` rows (a header line and blank lines are skipped).
std::vector<LineSegment> read_lines_csv(const std::string& path);

// Reads the NYU-VP / YUD line tables of Kluger et al. (CONSAC): a header that
// names space-separated columns, endpoints in point1_x point1_y point1_z and
// point2_x point2_y point2_z (homogeneous, pixels, y down). Other columns are
// ignored; rows with non-finite or coincident endpoints are dropped. Throws
// std::runtime_error on a missing file, a header without those columns or a
// short row.
std::vector<LineSegment> read_lines_nyu(const std::string& path);

struct CameraOptions {
  double prior_focal_px = 0.0;   // 0: 0.85 * max(width, height), a typical 60-degree lens
  int focal_hypotheses = 15;     // log-spaced over [0.4, 2.5] x prior
  int ransac_iterations = 400;   // minimal samples per focal hypothesis
  double inlier_angle_deg = 1.5; // line-to-direction consistency
  int min_support_lines = 4;     // lines a vanishing direction needs to count
  int max_refine_iterations = 50;
  uint64_t seed = 7;
};

enum class CameraCase { ThreeVanishingPoints, TwoVanishingPoints, VerticalOnly, NoVanishingPoints };
const char* to_string(CameraCase c);

struct CameraEstimate {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Eigen::Matrix3d R_world_from_cam = Eigen::Matrix3d::Identity();
  std::array<Eigen::Vector3d, 3> directions_cam;  // world X, Y(up), Z in camera coordinates
  std::array<double, 3> support{};               // length-weighted inlier support per direction
  std::vector<int> line_labels;                  // per input line: 0,1,2 (world X,Y,Z) or -1
  CameraCase which = CameraCase::NoVanishingPoints;
  bool focal_from_vanishing_points = false;
  StageReport report;
};

CameraEstimate estimate_camera(const std::vector<LineSegment>& lines, int width, int height,
                               const CameraOptions& options = {});

}  // namespace propcam::inference
