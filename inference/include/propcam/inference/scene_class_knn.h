// Indoor/outdoor by k nearest neighbours (the paper classifies with k-NN on
// GIST): the photo's appearance descriptor (depth_transfer.h) is compared
// with the depth-transfer database's rendered rooms and streets, which carry
// their class; the majority of the k nearest decides.
#pragma once

#include <opencv2/core.hpp>

#include "propcam/inference/depth_transfer.h"

namespace propcam::inference {

struct KnnSceneClass {
  bool indoor = true;
  double indoor_share = 0;  // fraction of the k neighbours that are indoor
  int k = 0;                // neighbours used (min(k, database size))
};

// Deterministic (ties in distance go to the lower database index). Throws
// std::invalid_argument for an empty database, k < 1 or a bad photo.
KnnSceneClass classify_indoor_knn(const cv::Mat& photo_linear, const DepthDatabase& db, int k = 7);

}  // namespace propcam::inference
