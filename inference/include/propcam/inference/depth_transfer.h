// Depth transfer (Karsch et al., ECCV 2012; the data term of Karsch et al.
// 2014): the database scenes that look most like the photo (a GIST-like
// global descriptor) lend their depth, warped to the photo's camera. The
// paper's database is NYUv2; ours is rendered by the project itself
// (`propcam build-depth-db`, generator scenes with exact depth), and the warp
// uses both known cameras (horizon and roll aligned, focal length scaled)
// where the paper used SIFT flow, which is too slow on the device.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

// Oriented Gabor energies (3 scales x 6 orientations) averaged on a 4x4 grid
// of the gamma-encoded grey image at 128x128, and the 4x4 mean colour
// layout; each block L2-normalised, then the whole. Fixed length
// (kAppearanceDescriptorLength), finite for any finite image.
std::vector<float> appearance_descriptor(const cv::Mat& photo_linear);
constexpr int kAppearanceDescriptorLength = 3 * 6 * 16 + 3 * 16;

// How a camera sees the horizon: the image's up direction (unit, pixels,
// y down) and the horizon's offset from the principal point along it, in
// focal lengths (positive: below the centre, i.e. the camera looks up).
struct HorizonFrame {
  double up_x = 0, up_y = -1;
  double horizon = 0;
};
HorizonFrame horizon_frame(const Eigen::Matrix3d& R_world_from_cam);

struct DepthExample {
  std::vector<float> descriptor;
  cv::Mat depth;          // CV_32F depth / camera height (scale-free), at the database resolution; sky: kSkyDepthM / height
  double fx_over_width = 0.85;
  HorizonFrame horizon;
  bool indoor = true;
};

class DepthDatabase {
 public:
  // Throws std::runtime_error naming the problem for a missing, truncated or
  // corrupt file, a wrong magic or version.
  static DepthDatabase load(const std::string& path);
  void save(const std::string& path) const;  // atomic: temporary file, then rename
  void add(DepthExample e);                   // throws std::invalid_argument when it does not fit the others
  size_t size() const { return examples_.size(); }
  const DepthExample& at(size_t i) const { return examples_.at(i); }

 private:
  std::vector<DepthExample> examples_;
};

// PROPCAM_DEPTH_DB (environment) if set, else the database in the source tree.
std::string default_depth_database_path();

struct DepthTransferOptions {
  int k = 7;                     // candidates (the paper's depth transfer uses 7)
  bool same_scene_class = true;  // indoor photos borrow from indoor examples only (and outdoor from outdoor)
  bool warp = true;              // align horizon, roll and focal length; false: resize only
};

struct TransferredDepth {
  std::vector<cv::Mat> candidates;  // CV_32F metres at out_size
  std::vector<double> weights;      // sum 1
  std::vector<size_t> indices;      // which examples
  cv::Mat median;                   // CV_32F per-pixel weighted median of the candidates
  StageReport report;               // stage "depth_transfer"
};

// Throws std::invalid_argument for an empty database (or no example of the
// photo's class), a bad photo or out_size.
TransferredDepth transfer_depth(const cv::Mat& photo_linear, const render::PinholeCamera& camera, double camera_height_m,
                                bool indoor, const DepthDatabase& db, cv::Size out_size,
                                const DepthTransferOptions& options = {});

}  // namespace propcam::inference
