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
  // Focal-length prior in pixels; 0: 0.85 * max(width, height), a typical
  // 60-degree lens. It is the focal length whenever the lines cannot fix it
  // (see focal_from_vanishing_points), it centres the search range
  // [0.4, 2.5] x prior and it breaks near-ties. A board whose lens is
  // calibrated passes its fx here (board calibration prior, e.g. the `fx` of
  // an OpenCV calibrateCamera run at the capture resolution, scaled by the
  // photo's width over the calibration width); with `fixed_focal` the stage
  // then estimates the rotation only.
  double prior_focal_px = 0.0;
  bool fixed_focal = false;       // use the prior as the focal length (calibrated lens)
  std::string prior_source;       // where prior_focal_px came from (reported): "calibration", "exif", ...
  int ransac_iterations = 300;    // line pairs sampled (length-weighted) as vanishing-point candidates
  int candidate_vps = 12;         // distinct best candidates kept; each pair of them is a Manhattan frame hypothesis
  int focal_hypotheses = 11;      // log-spaced focal values tried for a pair that does not fix the focal length
  double inlier_distance_px = 0;  // line-to-VP consistency (endpoint distance); 0: 0.25% of the image diagonal
  int min_support_lines = 4;      // inlier lines a vanishing direction needs to count
  int max_refine_iterations = 50; // per Ceres solve (label, solve, relabel: at most three solves)
  double max_refine_seconds = 0.5; // per Ceres solve
  // Estimate the principal point from three finite vanishing points (with a
  // prior at the image centre; kept at the centre unless the lines fix it
  // well). Off: always the image centre.
  bool estimate_principal_point = true;
  uint64_t seed = 7;
};

// Which vanishing directions the lines support (>= min_support_lines inliers):
// all three; two (the third follows); only the vertical (yaw unknown: world Z
// faces the camera); only one horizontal (up: the level direction orthogonal
// to it, i.e. no roll); none (a level camera).
enum class CameraCase { ThreeVanishingPoints, TwoVanishingPoints, VerticalOnly, HorizontalOnly, NoVanishingPoints };
const char* to_string(CameraCase c);

struct CameraEstimate {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Eigen::Matrix3d R_world_from_cam = Eigen::Matrix3d::Identity();
  std::array<Eigen::Vector3d, 3> directions_cam;  // world X, Y(up), Z in camera coordinates
  std::array<double, 3> support{};               // summed length (px) of each direction's inlier lines
  std::vector<int> line_labels;                  // per input line: 0,1,2 (world X,Y,Z) or -1
  CameraCase which = CameraCase::NoVanishingPoints;
  // fx came from the lines: all three directions supported, two vanishing
  // points finite and the lines fix log(fx) to 8%. Otherwise fx is the prior.
  bool focal_from_vanishing_points = false;
  StageReport report;
};

// The principal point is the image centre unless three finite vanishing
// points fix it (see CameraOptions::estimate_principal_point). Vanishing
// points are found in the image (homogeneous: points at infinity are
// ordinary) and the frame refined on endpoint distances; the method and its NYU-VP evaluation are in
// docs/camera_stage.md. Deterministic for a seed, bounded in time, always
// finite; throws std::invalid_argument for a non-positive size.
CameraEstimate estimate_camera(const std::vector<LineSegment>& lines, int width, int height,
                               const CameraOptions& options = {});

}  // namespace propcam::inference
