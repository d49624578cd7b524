// A depth target from where things meet the floor (Delage et al. 2005, the
// single-image Manhattan reasoning Karsch et al. 2014 build on): with the
// camera height known, the floor seen in the orientation map has exact depth,
// and every vertical surface standing on it (a wall, a cabinet's front, a
// building's facade) is the vertical plane through its floor contact. Unlike
// the room box, this puts furniture where its base is.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/render/camera.h"

namespace propcam::inference {

struct ContactDepth {
  cv::Mat depth;       // CV_32F metres at the labels' size; 0 where it has no opinion
  cv::Mat confidence;  // CV_32F in [0, 1]
  int columns_with_contact = 0;
};

// `labels`: orientation map (CV_8U SurfaceOrientation, any size); `camera`:
// full resolution, its centre at the camera height above the floor (y = 0);
// `box_normals` (optional CV_32FC3 world normals at the camera's size): which
// way a vertical surface faces where the map does not say.
ContactDepth contact_depth_target(const cv::Mat& labels, const render::PinholeCamera& camera,
                                  const cv::Mat& box_normals = cv::Mat());

// World points of the pixels `labels` marks as horizontal and below the
// horizon: the floor the orientation map sees (one per labelled pixel).
std::vector<Eigen::Vector3d> seen_floor_points(const cv::Mat& labels, const render::PinholeCamera& camera);

}  // namespace propcam::inference
