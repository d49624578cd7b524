// Out-of-view light by IBL ranking (Karsch et al. 2014, "Illumination outside
// of the view frustum"): the photo is matched against rectilinear views of the
// annotated panoramas of the IBL library (ibl_library.h) with seven similarity
// features, scored by a linear ranking function trained with a 1-slack
// SVM-rank whose margin is the rendering-based IBL distance (ibl_distance.h);
// the best-ranked panoramas' light regions, turned so the matched view looks
// where the photo looks, become candidate sources for the intensity fit.
// Method, substitutes and measurements: docs/ibl.md.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/ibl_distance.h"
#include "propcam/inference/ibl_library.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

// The seven similarities of the paper, in its order: geometric context,
// orientation map, light classifier (normalised per-cell dot products), spatial
// pyramid, hue, saturation, value (histogram intersections). Each in [0, 1].
constexpr int kIblSimilarityCount = 7;
using IblSimilarity = Eigen::Matrix<double, kIblSimilarityCount, 1>;
const char* ibl_similarity_name(int index);

// What the features are computed from: the photo and what the geometry stage
// found in it. Empty maps count as "unknown" everywhere.
struct IblFeatureInputs {
  cv::Mat photo_linear;           // CV_32FC3
  render::PinholeCamera camera;   // the estimated camera (for the horizon and headings)
  cv::Mat orientation;            // CV_8U SurfaceOrientation labels (any size), or empty
  cv::Mat sky_mask;               // CV_8U, 255 on sky (any size), or empty
  cv::Mat light_mask;             // CV_8U, 255 on pixels the light classifier calls emitting, or empty
};

// Per-cell maps on a fixed grid (so any two photos compare cell by cell, the
// paper's "downsample to the same size"), and normalised histograms.
struct IblViewFeatures {
  cv::Mat gc;  // CV_32FC4 fractions: sky, support (horizontal, below the horizon), vertical, overhead
  cv::Mat om;  // CV_32FC4 fractions: unknown, horizontal, frontal (normal along the view), side
  cv::Mat lc;  // CV_32FC2 fractions: emitting pixels, the rest
  std::vector<float> sp;  // spatial pyramid of gradient words, Lazebnik-weighted, sums to 1
  std::vector<float> hue, saturation, value;  // each sums to 1
};

constexpr int kIblGridCols = 16, kIblGridRows = 12;

// Deterministic and finite for any input (black, saturated, tiny, NaN).
// Throws std::invalid_argument for an empty or non-CV_32FC3 photo.
IblViewFeatures ibl_view_features(const IblFeatureInputs& inputs);
IblSimilarity ibl_similarity(const IblViewFeatures& a, const IblViewFeatures& b);

// The camera's heading frame in world coordinates, as columns: right, up
// (world Y), back (the level view direction negated). In it the camera looks
// along -Z, as a panorama's yaw-0 view does. A camera looking straight up or
// down takes its image's up direction as its heading.
Eigen::Matrix3d heading_frame(const Eigen::Matrix3d& R_world_from_cam);

// Two views' lighting differ by ibl_render_distance(sh_a, heading_a, sh_b,
// heading_b): each map seen from its view's heading.

// --- 1-slack linear SVM-rank (Joachims 2006), cutting-plane training:
//     min_w,xi  1/2 |w|^2 + C xi   s.t. for every subset c of the pairs,
//     w . (1/n sum_c dx_p) >= 1/n sum_c margin_p - xi,  xi >= 0,
// where dx_p = x(better) - x(worse) and margin_p the pair's required margin.
struct SvmRankOptions {
  double C = 10.0;
  double epsilon = 1e-4;       // stop when the most violated constraint exceeds xi by less
  int max_iterations = 300;    // cutting planes
  int max_qp_iterations = 2000;
};
struct SvmRankResult {
  IblSimilarity w = IblSimilarity::Zero();
  double slack = 0;          // xi
  double objective = 0;      // 1/2 |w|^2 + C xi
  double violation = 0;      // of the most violated constraint at the end, minus xi
  int iterations = 0;
  bool converged = false;
};
// Throws std::invalid_argument for mismatched sizes or non-finite input; no
// pairs give w = 0 (converged).
SvmRankResult train_svm_rank(const std::vector<IblSimilarity>& differences, const std::vector<double>& margins,
                             const SvmRankOptions& options = {});

// --- The ranker: the library's views with their features, and the weights.
struct IblRankerEntry {
  std::string name;
  SceneKind kind = SceneKind::Indoor;
  std::vector<IblLightRegion> lights;  // brightest first, panorama frame
  ShRadiance sh = ShRadiance::Zero();
};
struct IblRankerView {
  int entry = 0;
  double yaw_deg = 0, pitch_deg = 0, fov_deg = 60;
  Eigen::Matrix3d heading = Eigen::Matrix3d::Identity();  // heading_frame of the view's camera (panorama frame)
  IblViewFeatures features;
};
struct IblMatch {
  int entry = 0;
  int view = 0;       // the entry's best-scoring view
  double score = 0;   // w . x
};

class IblRanker {
 public:
  IblSimilarity weights = IblSimilarity::Ones();
  std::vector<IblRankerEntry> entries;
  std::vector<IblRankerView> views;

  // Each entry once, best view first, only entries of `kind`; at most
  // `top_k` (k < 1: all). Deterministic (ties to the lower entry index).
  std::vector<IblMatch> rank(const IblViewFeatures& query, SceneKind kind, int top_k) const;

  // Throws std::runtime_error naming the file and the problem for a missing
  // or malformed file (bad sizes, non-finite numbers, unknown kinds).
  static IblRanker load(const std::string& path);
  void save(const std::string& path) const;  // atomic: temporary name, then rename
};

// Env PROPCAM_IBL_RANKER, else the model committed in inference/data.
std::string default_ibl_ranker_path();

// A matched panorama direction (panorama frame) seen from the photo: the
// matched view's heading is the photo's heading.
Eigen::Vector3d panorama_to_world(const Eigen::Vector3d& panorama_direction, const Eigen::Matrix3d& view_heading,
                                  const Eigen::Matrix3d& photo_heading);

}  // namespace propcam::inference
