#include "propcam/inference/ibl_ranking.h"
#include "propcam/inference/data_dir.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "atomic_file.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/orientation_map.h"
#include "propcam/render/panorama.h"
#include "luminance.h"

namespace propcam::inference {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

// Features are computed at this working size (4:3, as the cameras' frames;
// other aspects are stretched, which the per-cell comparison tolerates).
constexpr int kWorkCols = 64, kWorkRows = 48;
constexpr int kPyramidCols = 128, kPyramidRows = 96;
constexpr int kOrientationBins = 8;
// Gradient words: flat, or one of 8 orientations at a weak or a strong edge
// (encoded grey level per pixel).
constexpr int kGradientWords = 1 + 2 * kOrientationBins;
constexpr float kWeakEdge = 0.02f, kStrongEdge = 0.1f;
constexpr int kPyramidLevels = 3;  // 1x1, 2x2, 4x4 cells
constexpr int kHistogramBins = 16;
// A vector shorter than this is "nothing there" in a cosine.
constexpr double kTinyNorm = 1e-12;
const char* const kSimilarityNames[kIblSimilarityCount] = {"geometric_context", "orientation_map", "light_classifier",
                                                           "spatial_pyramid", "hue", "saturation", "value"};

int pyramid_size() {
  int n = 0;
  for (int l = 0; l < kPyramidLevels; ++l) n += (1 << l) * (1 << l) * kGradientWords;
  return n;
}

// Nearest lookup of a label/mask image at work pixel (u, v); 0 when empty.
uint8_t sample(const cv::Mat& m, int u, int v) {
  if (m.empty()) return 0;
  const int x = std::min(m.cols - 1, u * m.cols / kWorkCols), y = std::min(m.rows - 1, v * m.rows / kWorkRows);
  return m.at<uint8_t>(y, x);
}

cv::Mat to_grid(const cv::Mat& work) {
  cv::Mat grid;
  cv::resize(work, grid, {kIblGridCols, kIblGridRows}, 0, 0, cv::INTER_AREA);
  return grid;
}

void normalise(std::vector<float>& h) {
  const double s = std::accumulate(h.begin(), h.end(), 0.0);
  for (auto& v : h) v = s > 0 ? static_cast<float>(v / s) : 1.f / h.size();
}

// Lazebnik et al.'s pyramid of gradient words: per level the cells'
// histograms as shares of the image's pixels, level weights 1/4, 1/4, 1/2.
std::vector<float> spatial_pyramid(const cv::Mat& grey) {
  cv::Mat small, gx, gy;
  cv::resize(grey, small, {kPyramidCols, kPyramidRows}, 0, 0, cv::INTER_AREA);
  cv::Sobel(small, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(small, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  cv::Mat words(small.size(), CV_8U);
  for (int y = 0; y < small.rows; ++y)
    for (int x = 0; x < small.cols; ++x) {
      const float dx = gx.at<float>(y, x), dy = gy.at<float>(y, x), mag = std::hypot(dx, dy);
      int word = 0;
      if (mag >= kWeakEdge) {
        double angle = std::atan2(dy, dx);  // edges are unsigned: fold to [0, pi)
        if (angle < 0) angle += M_PI;
        const int bin = std::min(kOrientationBins - 1, static_cast<int>(angle / M_PI * kOrientationBins));
        word = 1 + bin + (mag >= kStrongEdge ? kOrientationBins : 0);
      }
      words.at<uint8_t>(y, x) = static_cast<uint8_t>(word);
    }
  std::vector<float> out(pyramid_size(), 0.f);
  const double total = static_cast<double>(small.total());
  int offset = 0;
  for (int l = 0; l < kPyramidLevels; ++l) {
    const int cells = 1 << l;
    const double weight = l == 0 ? 0.25 : (l == kPyramidLevels - 1 ? 0.5 : 0.25);
    for (int y = 0; y < small.rows; ++y)
      for (int x = 0; x < small.cols; ++x) {
        const int cell = (y * cells / small.rows) * cells + x * cells / small.cols;
        out[offset + cell * kGradientWords + words.at<uint8_t>(y, x)] += static_cast<float>(weight / total);
      }
    offset += cells * cells * kGradientWords;
  }
  return out;
}

double histogram_intersection(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) throw std::invalid_argument("IBL features: histogram sizes differ");
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += std::min(a[i], b[i]);
  return std::clamp(s, 0.0, 1.0);
}

// Mean over cells of the cosine between the two cells' vectors (0 where
// either is empty).
double normalised_dot(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) throw std::invalid_argument("IBL features: map sizes differ");
  const int channels = a.channels();
  double sum = 0;
  const int cells = static_cast<int>(a.total());
  const float* pa = a.ptr<float>();
  const float* pb = b.ptr<float>();
  for (int i = 0; i < cells; ++i) {
    double ab = 0, aa = 0, bb = 0;
    for (int c = 0; c < channels; ++c) {
      const double x = pa[i * channels + c], y = pb[i * channels + c];
      ab += x * y, aa += x * x, bb += y * y;
    }
    if (aa > kTinyNorm && bb > kTinyNorm) sum += ab / std::sqrt(aa * bb);
  }
  return std::clamp(sum / std::max(1, cells), 0.0, 1.0);
}

// The light map as (emitting, not emitting) per cell, so dark-on-dark agrees;
// built once per view, not per comparison.
cv::Mat two_channel(const cv::Mat& lc) {
  cv::Mat out(lc.size(), CV_32FC2);
  for (int i = 0; i < static_cast<int>(lc.total()); ++i) {
    const float p = lc.ptr<float>()[i];
    out.ptr<cv::Vec2f>()[i] = {p, 1.f - p};
  }
  return out;
}

}  // namespace

const char* ibl_similarity_name(int index) {
  return index >= 0 && index < kIblSimilarityCount ? kSimilarityNames[index] : "unknown";
}

Matrix3d heading_frame(const Matrix3d& R_world_from_cam) {
  Vector3d ahead = R_world_from_cam.col(2);
  ahead.y() = 0;
  if (ahead.norm() < 1e-6) {  // straight up or down: the image's up is the heading
    ahead = -R_world_from_cam.col(1);
    ahead.y() = 0;
  }
  if (!(ahead.norm() >= 1e-6)) ahead = -Vector3d::UnitZ();
  ahead.normalize();
  const Vector3d up = Vector3d::UnitY(), right = ahead.cross(up).normalized();
  Matrix3d h;
  h.col(0) = right;
  h.col(1) = up;
  h.col(2) = -ahead;
  return h;
}

Vector3d panorama_to_world(const Vector3d& panorama_direction, const Matrix3d& view_heading,
                           const Matrix3d& photo_heading) {
  return photo_heading * (view_heading.transpose() * panorama_direction);
}

IblViewFeatures ibl_view_features(const IblFeatureInputs& in) {
  if (in.photo_linear.empty() || in.photo_linear.type() != CV_32FC3)
    throw std::invalid_argument("IBL features need a non-empty CV_32FC3 photo");
  // The photo as the camera encoded it, finite and in [0, 1].
  cv::Mat photo;
  cv::resize(in.photo_linear, photo, {kPyramidCols, kPyramidRows}, 0, 0, cv::INTER_AREA);
  cv::patchNaNs(photo, 0.0);
  cv::Mat encoded(photo.size(), CV_32FC3);
  for (int i = 0; i < static_cast<int>(photo.total()); ++i) {
    const cv::Vec3f c = photo.ptr<cv::Vec3f>()[i];
    cv::Vec3f e;
    for (int k = 0; k < 3; ++k) e[k] = capture::linear_to_srgb(std::clamp(c[k], 0.f, 1.f));
    encoded.ptr<cv::Vec3f>()[i] = e;
  }
  IblViewFeatures f;
  // --- Geometric context, orientation map and light map, per work pixel.
  render::PinholeCamera cam = in.camera;
  const bool camera_ok = cam.width > 0 && cam.height > 0 && std::isfinite(cam.fx) && cam.fx > 0 &&
                         std::isfinite(cam.fy) && cam.fy > 0 && cam.R_world_from_cam.allFinite();
  const Matrix3d heading = camera_ok ? heading_frame(cam.R_world_from_cam) : Matrix3d::Identity();
  const Vector3d right = heading.col(0), ahead = -heading.col(2);
  cv::Mat gc(kWorkRows, kWorkCols, CV_32FC4, cv::Scalar::all(0)), om(kWorkRows, kWorkCols, CV_32FC4, cv::Scalar::all(0)),
      lc(kWorkRows, kWorkCols, CV_32F, cv::Scalar(0));
  for (int v = 0; v < kWorkRows; ++v)
    for (int u = 0; u < kWorkCols; ++u) {
      bool above = v < kWorkRows / 2;  // no camera: the middle row is the horizon
      if (camera_ok) {
        const double px = (u + 0.5) * cam.width / kWorkCols - 0.5, py = (v + 0.5) * cam.height / kWorkRows - 0.5;
        above = cam.ray_direction(px, py).y() > 0;
      }
      const bool sky = sample(in.sky_mask, u, v) != 0;
      const auto label = static_cast<SurfaceOrientation>(sample(in.orientation, u, v));
      cv::Vec4f& g = gc.at<cv::Vec4f>(v, u);
      cv::Vec4f& o = om.at<cv::Vec4f>(v, u);
      if (label == SurfaceOrientation::kNormalY) {
        o[1] = 1;
      } else if (label == SurfaceOrientation::kNormalX || label == SurfaceOrientation::kNormalZ) {
        const Vector3d axis = label == SurfaceOrientation::kNormalX ? Vector3d::UnitX() : Vector3d::UnitZ();
        (std::abs(axis.dot(ahead)) >= std::abs(axis.dot(right)) ? o[2] : o[3]) = 1;
      } else {
        o[0] = 1;
      }
      if (sky) g[0] = 1;
      else if (label == SurfaceOrientation::kNormalY) (above ? g[3] : g[1]) = 1;
      else if (label != SurfaceOrientation::kUnknown || above) g[2] = 1;
      else g[1] = 1;  // unknown below the horizon: most likely ground
      lc.at<float>(v, u) = sample(in.light_mask, u, v) != 0 ? 1.f : 0.f;
    }
  f.gc = to_grid(gc);
  f.om = to_grid(om);
  f.lc = two_channel(to_grid(lc));
  // --- Spatial pyramid of gradient words on the encoded grey image.
  f.sp = spatial_pyramid(luminance_image(encoded));
  // --- HSV histograms (OpenCV's float HSV: H in [0, 360), S and V in [0, 1]).
  cv::Mat hsv;
  cv::cvtColor(encoded, hsv, cv::COLOR_RGB2HSV);
  f.hue.assign(kHistogramBins, 0.f);
  f.saturation.assign(kHistogramBins, 0.f);
  f.value.assign(kHistogramBins, 0.f);
  auto bin = [](float x, float range) { return std::clamp(static_cast<int>(x / range * kHistogramBins), 0, kHistogramBins - 1); };
  for (int i = 0; i < static_cast<int>(hsv.total()); ++i) {
    const cv::Vec3f c = hsv.ptr<cv::Vec3f>()[i];
    f.hue[bin(c[0], 360.f)] += 1;
    f.saturation[bin(c[1], 1.f)] += 1;
    f.value[bin(c[2], 1.f)] += 1;
  }
  normalise(f.hue);
  normalise(f.saturation);
  normalise(f.value);
  return f;
}

IblSimilarity ibl_similarity(const IblViewFeatures& a, const IblViewFeatures& b) {
  IblSimilarity x;
  x << normalised_dot(a.gc, b.gc), normalised_dot(a.om, b.om), normalised_dot(a.lc, b.lc),
      histogram_intersection(a.sp, b.sp), histogram_intersection(a.hue, b.hue),
      histogram_intersection(a.saturation, b.saturation), histogram_intersection(a.value, b.value);
  return x;
}

// --- SVM-rank --------------------------------------------------------------

namespace {

// Euclidean projection onto {a >= 0, sum a <= C}.
void project_capped(std::vector<double>& a, double C) {
  for (auto& v : a) v = std::max(0.0, v);
  const double sum = std::accumulate(a.begin(), a.end(), 0.0);
  if (sum <= C) return;
  // Onto the simplex sum = C (Held et al.: sort, find the threshold).
  std::vector<double> s = a;
  std::sort(s.rbegin(), s.rend());
  double cumulative = 0, theta = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    cumulative += s[i];
    const double t = (cumulative - C) / static_cast<double>(i + 1);
    if (i + 1 == s.size() || s[i + 1] <= t) {
      theta = t;
      break;
    }
  }
  for (auto& v : a) v = std::max(0.0, v - theta);
}

}  // namespace

SvmRankResult train_svm_rank(const std::vector<IblSimilarity>& differences, const std::vector<double>& margins,
                             const SvmRankOptions& options) {
  if (differences.size() != margins.size()) throw std::invalid_argument("SVM-rank: differences and margins differ in size");
  if (!(options.C > 0) || !std::isfinite(options.C)) throw std::invalid_argument("SVM-rank: C must be positive");
  for (size_t p = 0; p < differences.size(); ++p)
    if (!differences[p].allFinite() || !std::isfinite(margins[p]))
      throw std::invalid_argument("SVM-rank: pair " + std::to_string(p) + " is not finite");
  SvmRankResult r;
  const size_t n = differences.size();
  if (n == 0) {
    r.converged = true;
    return r;
  }
  // Working set of 1-slack constraints  w . a_c >= b_c - xi.
  std::vector<IblSimilarity> a;
  std::vector<double> b, alpha;
  for (r.iterations = 1; r.iterations <= options.max_iterations; ++r.iterations) {
    // The most violated constraint: every pair whose margin w misses.
    IblSimilarity ac = IblSimilarity::Zero();
    double bc = 0;
    for (size_t p = 0; p < n; ++p)
      if (margins[p] - r.w.dot(differences[p]) > 0) ac += differences[p], bc += margins[p];
    ac /= static_cast<double>(n);
    bc /= static_cast<double>(n);
    r.violation = bc - r.w.dot(ac) - r.slack;
    if (r.violation <= options.epsilon) {
      r.converged = true;
      break;
    }
    a.push_back(ac);
    b.push_back(bc);
    alpha.push_back(0.0);
    // Dual over the working set: max_alpha  alpha.b - 1/2 |sum alpha_c a_c|^2,
    // alpha >= 0, sum alpha <= C; accelerated projected gradient (FISTA).
    const size_t m = a.size();
    Eigen::MatrixXd G(m, m);
    for (size_t i = 0; i < m; ++i)
      for (size_t j = 0; j < m; ++j) G(i, j) = a[i].dot(a[j]);
    const double lipschitz = std::max(G.trace(), 1e-12);
    std::vector<double> x = alpha, y = alpha, prev = alpha;
    double t = 1;
    for (int it = 0; it < options.max_qp_iterations; ++it) {
      for (size_t i = 0; i < m; ++i) {
        double g = b[i];
        for (size_t j = 0; j < m; ++j) g -= G(i, j) * y[j];
        x[i] = y[i] + g / lipschitz;
      }
      project_capped(x, options.C);
      const double t_next = (1 + std::sqrt(1 + 4 * t * t)) / 2;
      double change = 0;
      for (size_t i = 0; i < m; ++i) {
        y[i] = x[i] + (t - 1) / t_next * (x[i] - prev[i]);
        change = std::max(change, std::abs(x[i] - prev[i]));
      }
      prev = x;
      t = t_next;
      if (change < 1e-12 * std::max(1.0, options.C)) break;
    }
    alpha = x;
    r.w.setZero();
    for (size_t i = 0; i < m; ++i) r.w += alpha[i] * a[i];
    r.slack = 0;
    for (size_t i = 0; i < m; ++i) r.slack = std::max(r.slack, b[i] - r.w.dot(a[i]));
  }
  r.iterations = std::min(r.iterations, options.max_iterations);
  r.objective = 0.5 * r.w.squaredNorm() + options.C * r.slack;
  return r;
}

// --- The ranker ------------------------------------------------------------

std::vector<IblMatch> IblRanker::rank(const IblViewFeatures& query, SceneKind kind, int top_k) const {
  std::vector<IblMatch> best(entries.size(), IblMatch{-1, -1, -std::numeric_limits<double>::infinity()});
  for (size_t v = 0; v < views.size(); ++v) {
    const int e = views[v].entry;
    if (e < 0 || e >= static_cast<int>(entries.size()) || entries[e].kind != kind) continue;
    const double score = weights.dot(ibl_similarity(query, views[v].features));
    if (score > best[e].score) best[e] = {e, static_cast<int>(v), score};
  }
  std::vector<IblMatch> out;
  for (const auto& m : best)
    if (m.entry >= 0) out.push_back(m);
  std::stable_sort(out.begin(), out.end(), [](const IblMatch& x, const IblMatch& y) { return x.score > y.score; });
  if (top_k > 0 && static_cast<int>(out.size()) > top_k) out.resize(top_k);
  return out;
}

namespace {

constexpr const char* kFormat = "propcam-ibl-ranker";
constexpr int kFormatVersion = 1;
constexpr int kMaxStored = 1 << 16;

cv::Mat histogram_row(const std::vector<float>& h) { return cv::Mat(h, true).reshape(1, 1); }

std::vector<float> read_row(const cv::FileNode& node, size_t expected, const std::string& what) {
  cv::Mat m;
  node >> m;
  if (m.type() != CV_32F || m.total() != expected) throw std::runtime_error(what + " has the wrong size");
  std::vector<float> out(m.begin<float>(), m.end<float>());
  for (float v : out)
    if (!std::isfinite(v) || v < 0) throw std::runtime_error(what + " is not finite and non-negative");
  return out;
}

cv::Mat read_map(const cv::FileNode& node, int channels, const std::string& what) {
  cv::Mat stored;
  node >> stored;  // CV_8U fractions x 255, channels side by side
  if (stored.type() != CV_8U || stored.rows != kIblGridRows || stored.cols != kIblGridCols * channels)
    throw std::runtime_error(what + " has the wrong size");
  cv::Mat f;
  stored.convertTo(f, CV_32F, 1.0 / 255);
  return f.reshape(channels, kIblGridRows);
}

// The file keeps the light map's first channel; the second is 1 minus it.
cv::Mat emitting_channel(const cv::Mat& lc) {
  cv::Mat channel;
  cv::extractChannel(lc, channel, 0);
  return channel;
}

cv::Mat write_map(const cv::Mat& map) {
  cv::Mat flat = map.reshape(1, kIblGridRows), stored;
  flat.convertTo(stored, CV_8U, 255.0);
  return stored;
}

}  // namespace

void IblRanker::save(const std::string& path) const {
  write_atomically(path, [&](const std::string& tmp) {
    cv::FileStorage fs(tmp, cv::FileStorage::WRITE);
    if (!fs.isOpened()) throw std::runtime_error("cannot write " + tmp);
    fs << "format" << kFormat << "version" << kFormatVersion;
    fs << "weights" << std::vector<double>(weights.data(), weights.data() + kIblSimilarityCount);
    fs << "entries" << "[";
    for (const auto& e : entries) {
      fs << "{" << "name" << e.name << "kind" << to_string(e.kind);
      cv::Mat sh(9, 3, CV_64F);
      for (int i = 0; i < 9; ++i)
        for (int c = 0; c < 3; ++c) sh.at<double>(i, c) = e.sh(i, c);
      fs << "sh" << sh << "lights" << "[";
      for (const auto& l : e.lights)
        fs << "{" << "direction" << std::vector<double>{l.direction.x(), l.direction.y(), l.direction.z()}
           << "solid_angle_sr" << l.solid_angle_sr << "power_share" << l.power_share << "distance"
           << to_string(l.distance) << "}";
      fs << "]" << "}";
    }
    fs << "]" << "views" << "[";
    for (const auto& v : views) {
      fs << "{" << "entry" << v.entry << "yaw_deg" << v.yaw_deg << "pitch_deg" << v.pitch_deg << "fov_deg" << v.fov_deg
         << "gc" << write_map(v.features.gc) << "om" << write_map(v.features.om) << "lc" << write_map(emitting_channel(v.features.lc))
         << "sp" << histogram_row(v.features.sp) << "hue" << histogram_row(v.features.hue) << "saturation"
         << histogram_row(v.features.saturation) << "value" << histogram_row(v.features.value) << "}";
    }
    fs << "]";
  });
}

IblRanker IblRanker::load(const std::string& path) {
  const auto fail = [&](const std::string& why) -> std::runtime_error {
    return std::runtime_error("IBL ranker " + path + ": " + why);
  };
  if (!std::filesystem::exists(path)) throw fail("no such file");
  IblRanker r;
  try {
    cv::FileStorage fs(path, cv::FileStorage::READ);
    if (!fs.isOpened()) throw fail("not a readable model");
    if (static_cast<std::string>(fs["format"]) != kFormat || static_cast<int>(fs["version"]) != kFormatVersion)
      throw fail("not a propcam-ibl-ranker version 1 file");
    std::vector<double> w;
    fs["weights"] >> w;
    if (w.size() != kIblSimilarityCount) throw fail("weights must have 7 numbers");
    for (int i = 0; i < kIblSimilarityCount; ++i) {
      if (!std::isfinite(w[i])) throw fail("weights are not finite");
      r.weights[i] = w[i];
    }
    const cv::FileNode entries = fs["entries"];
    if (!entries.isSeq() || entries.size() < 1 || entries.size() > kMaxStored) throw fail("no entries");
    for (const auto& node : entries) {
      IblRankerEntry e;
      e.name = static_cast<std::string>(node["name"]);
      const std::string kind = node["kind"];
      if (kind == "indoor") e.kind = SceneKind::Indoor;
      else if (kind == "outdoor") e.kind = SceneKind::Outdoor;
      else throw fail("entry '" + e.name + "': unknown kind '" + kind + "'");
      cv::Mat sh;
      node["sh"] >> sh;
      if (sh.type() != CV_64F || sh.rows != 9 || sh.cols != 3 || !cv::checkRange(sh))
        throw fail("entry '" + e.name + "': bad SH coefficients");
      for (int i = 0; i < 9; ++i)
        for (int c = 0; c < 3; ++c) e.sh(i, c) = sh.at<double>(i, c);
      for (const auto& ln : node["lights"]) {
        IblLightRegion l;
        std::vector<double> d;
        ln["direction"] >> d;
        if (d.size() != 3) throw fail("entry '" + e.name + "': a light direction needs 3 numbers");
        l.direction = {d[0], d[1], d[2]};
        if (!l.direction.allFinite() || std::abs(l.direction.norm() - 1) > 1e-3)
          throw fail("entry '" + e.name + "': a light direction is not a unit vector");
        l.solid_angle_sr = static_cast<double>(ln["solid_angle_sr"]);
        l.power_share = static_cast<double>(ln["power_share"]);
        if (!(l.solid_angle_sr > 0 && l.solid_angle_sr <= 4 * M_PI) || !(l.power_share >= 0 && l.power_share <= 1))
          throw fail("entry '" + e.name + "': a light's solid angle or power share is out of range");
        const std::string dist = ln["distance"];
        if (dist == "close") l.distance = LightDistance::Close;
        else if (dist == "medium") l.distance = LightDistance::Medium;
        else if (dist == "far") l.distance = LightDistance::Far;
        else if (dist == "infinite") l.distance = LightDistance::Infinite;
        else throw fail("entry '" + e.name + "': unknown distance class '" + dist + "'");
        e.lights.push_back(l);
      }
      r.entries.push_back(std::move(e));
    }
    const cv::FileNode views = fs["views"];
    if (!views.isSeq() || views.size() < 1 || views.size() > kMaxStored) throw fail("no views");
    int index = 0;
    for (const auto& node : views) {
      const std::string what = "view " + std::to_string(index++);
      IblRankerView v;
      v.entry = static_cast<int>(node["entry"]);
      if (v.entry < 0 || v.entry >= static_cast<int>(r.entries.size())) throw fail(what + ": entry out of range");
      v.yaw_deg = static_cast<double>(node["yaw_deg"]);
      v.pitch_deg = static_cast<double>(node["pitch_deg"]);
      v.fov_deg = static_cast<double>(node["fov_deg"]);
      if (!std::isfinite(v.yaw_deg) || !(std::abs(v.pitch_deg) <= 90) || !(v.fov_deg > 0 && v.fov_deg < 180))
        throw fail(what + ": bad yaw, pitch or field of view");
      render::ViewSpec spec;
      spec.yaw_deg = v.yaw_deg;
      spec.pitch_deg = v.pitch_deg;
      spec.horizontal_fov_deg = v.fov_deg;
      v.heading = heading_frame(render::view_camera(spec).R_world_from_cam);
      v.features.gc = read_map(node["gc"], 4, what + " gc");
      v.features.om = read_map(node["om"], 4, what + " om");
      v.features.lc = two_channel(read_map(node["lc"], 1, what + " lc"));
      v.features.sp = read_row(node["sp"], pyramid_size(), what + " sp");
      v.features.hue = read_row(node["hue"], kHistogramBins, what + " hue");
      v.features.saturation = read_row(node["saturation"], kHistogramBins, what + " saturation");
      v.features.value = read_row(node["value"], kHistogramBins, what + " value");
      r.views.push_back(std::move(v));
    }
  } catch (const cv::Exception& e) {
    throw fail(std::string("malformed: ") + e.what());
  }
  return r;
}

std::string default_ibl_ranker_path() {
  if (const char* env = std::getenv("PROPCAM_IBL_RANKER"); env && *env) return env;
  return data_file("inference/ibl_ranker.yml.gz").string();
}

}  // namespace propcam::inference
