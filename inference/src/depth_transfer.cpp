#include "propcam/inference/depth_transfer.h"
#include "propcam/inference/data_dir.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <opencv2/imgproc.hpp>

#include "atomic_file.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

constexpr int kDescriptorSide = 128;
constexpr int kGrid = 4;
constexpr double kGaborWavelengthsPx[] = {4.0, 8.0, 16.0};
constexpr int kGaborOrientations = 6;
// A block norm below this is a flat image: the block stays zero, not NaN.
constexpr double kFlatNorm = 1e-9;

// File format: magic, version, then a header and fixed-size records.
constexpr char kMagic[8] = {'P', 'C', 'D', 'E', 'P', 'T', 'H', '\0'};
constexpr uint32_t kVersion = 1;
// Depth is stored as 16-bit log of (depth / camera height) over this range.
constexpr double kMinStoredDepth = 1e-3;
constexpr double kMaxStoredDepth = 1e4;
constexpr int kMaxStoredSide = 4096;
constexpr uint32_t kMaxExamples = 1u << 20;

void l2_normalise(float* v, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; ++i) s += static_cast<double>(v[i]) * v[i];
  const double norm = std::sqrt(s);
  for (size_t i = 0; i < n; ++i) v[i] = norm > kFlatNorm ? static_cast<float>(v[i] / norm) : 0.f;
}

uint16_t quantise(float d) {
  const double c = std::clamp(std::isfinite(d) && d > 0 ? static_cast<double>(d) : kMaxStoredDepth, kMinStoredDepth, kMaxStoredDepth);
  const double t = (std::log(c) - std::log(kMinStoredDepth)) / (std::log(kMaxStoredDepth) - std::log(kMinStoredDepth));
  return static_cast<uint16_t>(std::lround(t * 65535.0));
}

float dequantise(uint16_t q) {
  const double t = q / 65535.0;
  return static_cast<float>(std::exp(std::log(kMinStoredDepth) + t * (std::log(kMaxStoredDepth) - std::log(kMinStoredDepth))));
}

template <typename T>
void put(std::ostream& out, const T& v) {
  out.write(reinterpret_cast<const char*>(&v), sizeof v);
}

template <typename T>
T get(std::istream& in, const std::string& path, const char* what) {
  T v{};
  if (!in.read(reinterpret_cast<char*>(&v), sizeof v))
    throw std::runtime_error("depth database '" + path + "' is truncated (reading " + what + ")");
  return v;
}

// Query pixel (u, v) of `q` (out_size) to the example's pixel: undo roll,
// move the horizon, scale by the focal lengths, apply the example's roll.
cv::Mat warp_to_query(const DepthExample& e, const render::PinholeCamera& q, const HorizonFrame& qh, cv::Size out,
                      bool warp) {
  const cv::Mat& src = e.depth;
  cv::Mat inv;
  cv::divide(1.0, src, inv);
  if (!warp) {
    cv::Mat r;
    cv::resize(inv, r, out, 0, 0, cv::INTER_LINEAR);
    cv::divide(1.0, r, r);
    return r;
  }
  const render::PinholeCamera qs = q.resized(out.width, out.height);
  const double fe = e.fx_over_width * src.cols, cxe = 0.5 * (src.cols - 1), cye = 0.5 * (src.rows - 1);
  cv::Mat mapx(out, CV_32F), mapy(out, CV_32F);
  for (int v = 0; v < out.height; ++v)
    for (int u = 0; u < out.width; ++u) {
      const double x = (u - qs.cx) / qs.fx, y = (v - qs.cy) / qs.fy;
      // Roll-free coordinates: s across, t down (along minus the image's up).
      const double s = -qh.up_y * x + qh.up_x * y;
      const double t = -(qh.up_x * x + qh.up_y * y) - qh.horizon + e.horizon.horizon;
      const double xe = -e.horizon.up_y * s - e.horizon.up_x * t;
      const double ye = e.horizon.up_x * s - e.horizon.up_y * t;
      mapx.at<float>(v, u) = static_cast<float>(xe * fe + cxe);
      mapy.at<float>(v, u) = static_cast<float>(ye * fe + cye);
    }
  cv::Mat r;
  cv::remap(inv, r, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::divide(1.0, r, r);
  return r;
}

}  // namespace

std::vector<float> appearance_descriptor(const cv::Mat& photo_linear) {
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3)
    throw std::invalid_argument("appearance_descriptor: a non-empty CV_32FC3 photo is needed");
  cv::Mat rgb;
  cv::resize(photo_linear, rgb, cv::Size(kDescriptorSide, kDescriptorSide), 0, 0, cv::INTER_AREA);
  cv::patchNaNs(rgb, 0.0);
  cv::max(rgb, 0.0, rgb);
  cv::min(rgb, 1.0, rgb);
  cv::pow(rgb, 1.0 / 2.2, rgb);
  cv::Mat gray;
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
  gray -= cv::mean(gray)[0];  // energies of structure, not of overall brightness
  std::vector<float> d;
  d.reserve(kAppearanceDescriptorLength);
  const int cell = kDescriptorSide / kGrid;
  for (double lambda : kGaborWavelengthsPx) {
    const size_t scale_start = d.size();
    for (int o = 0; o < kGaborOrientations; ++o) {
      const double theta = o * std::numbers::pi / kGaborOrientations;
      const int ksize = static_cast<int>(2 * std::ceil(lambda) + 1);
      const cv::Mat k = cv::getGaborKernel(cv::Size(ksize, ksize), 0.56 * lambda, theta, lambda, 1.0, 0, CV_32F);
      cv::Mat response;
      cv::filter2D(gray, response, CV_32F, k, cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
      response = cv::abs(response);
      for (int gy = 0; gy < kGrid; ++gy)
        for (int gx = 0; gx < kGrid; ++gx)
          d.push_back(static_cast<float>(cv::mean(response(cv::Rect(gx * cell, gy * cell, cell, cell)))[0]));
    }
    l2_normalise(d.data() + scale_start, d.size() - scale_start);
  }
  const size_t colour_start = d.size();
  for (int gy = 0; gy < kGrid; ++gy)
    for (int gx = 0; gx < kGrid; ++gx) {
      const cv::Scalar m = cv::mean(rgb(cv::Rect(gx * cell, gy * cell, cell, cell)));
      for (int c = 0; c < 3; ++c) d.push_back(static_cast<float>(m[c]));
    }
  l2_normalise(d.data() + colour_start, d.size() - colour_start);
  l2_normalise(d.data(), d.size());
  return d;
}

HorizonFrame horizon_frame(const Eigen::Matrix3d& R_world_from_cam) {
  const Eigen::Vector3d up = R_world_from_cam.transpose() * Eigen::Vector3d::UnitY();
  HorizonFrame h;
  const double in_image = std::hypot(up.x(), up.y());
  // Looking straight up or down: no horizon; keep it far away, level.
  constexpr double kMinInImage = 1e-6;
  constexpr double kFarHorizon = 1e3;
  if (in_image < kMinInImage) {
    h.horizon = up.z() > 0 ? kFarHorizon : -kFarHorizon;
    return h;
  }
  h.up_x = up.x() / in_image;
  h.up_y = up.y() / in_image;
  h.horizon = std::clamp(up.z() / in_image, -kFarHorizon, kFarHorizon);
  return h;
}

void DepthDatabase::add(DepthExample e) {
  if (e.descriptor.size() != static_cast<size_t>(kAppearanceDescriptorLength))
    throw std::invalid_argument("DepthDatabase::add: descriptor of the wrong length");
  if (e.depth.empty() || e.depth.type() != CV_32F || e.depth.cols > kMaxStoredSide || e.depth.rows > kMaxStoredSide)
    throw std::invalid_argument("DepthDatabase::add: depth must be a CV_32F map");
  if (!examples_.empty() && e.depth.size() != examples_.front().depth.size())
    throw std::invalid_argument("DepthDatabase::add: every example needs the same depth size");
  if (!(e.fx_over_width > 0) || !std::isfinite(e.horizon.horizon))
    throw std::invalid_argument("DepthDatabase::add: bad camera");
  examples_.push_back(std::move(e));
}

void DepthDatabase::save(const std::string& path) const {
  write_binary_atomically(path, [&](std::ostream& out) {
    out.write(kMagic, sizeof kMagic);
    put(out, kVersion);
    put(out, static_cast<uint32_t>(examples_.size()));
    put(out, static_cast<uint32_t>(kAppearanceDescriptorLength));
    const cv::Size s = examples_.empty() ? cv::Size(0, 0) : examples_.front().depth.size();
    put(out, static_cast<uint32_t>(s.width));
    put(out, static_cast<uint32_t>(s.height));
    for (const auto& e : examples_) {
      put(out, e.fx_over_width);
      put(out, e.horizon.up_x);
      put(out, e.horizon.up_y);
      put(out, e.horizon.horizon);
      put(out, static_cast<uint8_t>(e.indoor));
      out.write(reinterpret_cast<const char*>(e.descriptor.data()), sizeof(float) * e.descriptor.size());
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x) put(out, quantise(e.depth.at<float>(y, x)));
    }
  });
}

DepthDatabase DepthDatabase::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("no depth database at '" + path + "'");
  char magic[sizeof kMagic];
  if (!in.read(magic, sizeof magic) || std::memcmp(magic, kMagic, sizeof kMagic) != 0)
    throw std::runtime_error("'" + path + "' is not a PropCam depth database");
  const auto version = get<uint32_t>(in, path, "version");
  if (version != kVersion)
    throw std::runtime_error("depth database '" + path + "' has version " + std::to_string(version) + "; this build reads " +
                             std::to_string(kVersion));
  const auto count = get<uint32_t>(in, path, "count");
  const auto length = get<uint32_t>(in, path, "descriptor length");
  const auto w = get<uint32_t>(in, path, "width");
  const auto h = get<uint32_t>(in, path, "height");
  if (count > kMaxExamples || length != static_cast<uint32_t>(kAppearanceDescriptorLength) || w > kMaxStoredSide ||
      h > kMaxStoredSide || (count > 0 && (w == 0 || h == 0)))
    throw std::runtime_error("depth database '" + path + "' has a corrupt header");
  DepthDatabase db;
  for (uint32_t i = 0; i < count; ++i) {
    DepthExample e;
    e.fx_over_width = get<double>(in, path, "focal");
    e.horizon.up_x = get<double>(in, path, "up");
    e.horizon.up_y = get<double>(in, path, "up");
    e.horizon.horizon = get<double>(in, path, "horizon");
    e.indoor = get<uint8_t>(in, path, "class") != 0;
    e.descriptor.resize(length);
    if (!in.read(reinterpret_cast<char*>(e.descriptor.data()), sizeof(float) * length))
      throw std::runtime_error("depth database '" + path + "' is truncated (reading a descriptor)");
    for (float v : e.descriptor)
      if (!std::isfinite(v)) throw std::runtime_error("depth database '" + path + "' has a non-finite descriptor");
    if (!(e.fx_over_width > 0) || !std::isfinite(e.fx_over_width) || !std::isfinite(e.horizon.horizon) ||
        !std::isfinite(e.horizon.up_x) || !std::isfinite(e.horizon.up_y))
      throw std::runtime_error("depth database '" + path + "' has a corrupt camera in example " + std::to_string(i));
    e.depth = cv::Mat(static_cast<int>(h), static_cast<int>(w), CV_32F);
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) e.depth.at<float>(y, x) = dequantise(get<uint16_t>(in, path, "depth"));
    db.examples_.push_back(std::move(e));
  }
  if (in.peek() != std::char_traits<char>::eof())
    throw std::runtime_error("depth database '" + path + "' has trailing bytes");
  return db;
}

std::string default_depth_database_path() {
  if (const char* env = std::getenv("PROPCAM_DEPTH_DB"); env && *env) return env;
  return data_file("inference/depth_db.bin").string();
}

TransferredDepth transfer_depth(const cv::Mat& photo_linear, const render::PinholeCamera& camera, double camera_height_m,
                                bool indoor, const DepthDatabase& db, cv::Size out_size, const DepthTransferOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  if (out_size.width < 1 || out_size.height < 1) throw std::invalid_argument("transfer_depth: empty output size");
  if (!(camera_height_m > 0) || camera.width < 1 || camera.height < 1)
    throw std::invalid_argument("transfer_depth: bad camera");
  const std::vector<float> q = appearance_descriptor(photo_linear);
  std::vector<std::pair<double, size_t>> ranked;
  for (size_t i = 0; i < db.size(); ++i) {
    const DepthExample& e = db.at(i);
    if (o.same_scene_class && e.indoor != indoor) continue;
    double d2 = 0;
    for (size_t j = 0; j < q.size(); ++j) d2 += (q[j] - e.descriptor[j]) * (q[j] - e.descriptor[j]);
    ranked.emplace_back(d2, i);
  }
  if (ranked.empty())
    throw std::invalid_argument(std::string("transfer_depth: the database has no ") + (indoor ? "indoor" : "outdoor") + " example");
  const size_t k = std::min(ranked.size(), static_cast<size_t>(std::max(1, o.k)));
  std::partial_sort(ranked.begin(), ranked.begin() + k, ranked.end());
  // Weights fall off with descriptor distance on the scale of the matches' own spread.
  const double scale = std::max(1e-6, ranked[k - 1].first);
  TransferredDepth t;
  double total = 0;
  const HorizonFrame qh = horizon_frame(camera.R_world_from_cam);
  for (size_t i = 0; i < k; ++i) {
    t.indices.push_back(ranked[i].second);
    t.weights.push_back(std::exp(-ranked[i].first / scale));
    total += t.weights.back();
    cv::Mat c = warp_to_query(db.at(ranked[i].second), camera, qh, out_size, o.warp) * camera_height_m;
    cv::min(c, render::kSkyDepthM, c);
    t.candidates.push_back(c);
  }
  for (double& w : t.weights) w /= total;
  // Weighted median per pixel (the minimiser of the paper's L1 transfer term).
  t.median = cv::Mat(out_size, CV_32F);
  std::vector<std::pair<float, double>> v(k);
  for (int y = 0; y < out_size.height; ++y)
    for (int x = 0; x < out_size.width; ++x) {
      for (size_t i = 0; i < k; ++i) v[i] = {t.candidates[i].at<float>(y, x), t.weights[i]};
      std::sort(v.begin(), v.end());
      double acc = 0;
      float m = v.back().first;
      for (const auto& [d, w] : v)
        if ((acc += w) >= 0.5) {
          m = d;
          break;
        }
      t.median.at<float>(y, x) = m;
    }
  StageReport& r = t.report;
  r.stage = "depth_transfer";
  r.why = std::to_string(k) + " nearest of " + std::to_string(ranked.size()) + (o.warp ? ", warped" : ", resized");
  r.iterations = 1;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  nlohmann::json matches = nlohmann::json::array();
  for (size_t i = 0; i < k; ++i)
    matches.push_back({{"example", ranked[i].second}, {"distance", std::sqrt(ranked[i].first)}, {"weight", t.weights[i]}});
  r.details = {{"matches", matches}, {"database_size", db.size()}};
  return t;
}

}  // namespace propcam::inference
