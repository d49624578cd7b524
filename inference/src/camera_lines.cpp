// The camera stage's line segments (camera.h): detected in a photo, or read
// from a file of segments found elsewhere (CSV, NYU-VP).
#include "propcam/inference/camera.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace propcam::inference {

std::vector<LineSegment> detect_lines(const cv::Mat& photo_linear, const LineDetectionOptions& options,
                                      StageReport& report) {
  const auto start = std::chrono::steady_clock::now();
  report.stage = "lines";
  std::vector<LineSegment> out;
  if (photo_linear.empty() || photo_linear.cols < 8 || photo_linear.rows < 8) {
    report.usable = false;
    report.why = "image too small for line detection";
    return out;
  }
  cv::Mat grey;
  cv::cvtColor(photo_linear, grey, cv::COLOR_RGB2GRAY);
  // LSD works on display-referred intensities: gamma-encode and scale to 8 bits.
  cv::Mat encoded;
  cv::pow(cv::max(grey, 0.0), 1.0 / 2.2, encoded);
  encoded.convertTo(encoded, CV_8U, 255.0);
  auto lsd = cv::createLineSegmentDetector(cv::LSD_REFINE_STD);
  std::vector<cv::Vec4f> raw;
  lsd->detect(encoded, raw);
  const double min_length = options.min_length_fraction * std::hypot(photo_linear.cols, photo_linear.rows);
  for (const auto& r : raw) {
    LineSegment l{{r[0] - 0.5, r[1] - 0.5}, {r[2] - 0.5, r[3] - 0.5}};  // LSD: pixel corners at integers
    if (l.length() >= min_length && l.a.allFinite() && l.b.allFinite()) out.push_back(l);
  }
  std::sort(out.begin(), out.end(), [](const auto& p, const auto& q) { return p.length() > q.length(); });
  if (static_cast<int>(out.size()) > options.max_lines) out.resize(options.max_lines);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report.usable = !out.empty();
  report.why = out.empty() ? "no line segments found" : std::to_string(out.size()) + " segments";
  report.details = {{"raw_segments", raw.size()}, {"kept", out.size()}};
  return out;
}

std::vector<LineSegment> read_lines_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open lines file '" + path + "'");
  std::vector<LineSegment> lines;
  std::string row;
  int line_number = 0;
  while (std::getline(in, row)) {
    ++line_number;
    if (row.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::replace(row.begin(), row.end(), ',', ' ');
    std::istringstream fields(row);
    double v[4];
    if (!(fields >> v[0] >> v[1] >> v[2] >> v[3])) {
      if (line_number == 1) continue;  // header
      throw std::runtime_error(path + ":" + std::to_string(line_number) + ": expected x1,y1,x2,y2");
    }
    LineSegment l{{v[0], v[1]}, {v[2], v[3]}};
    if (l.a.allFinite() && l.b.allFinite() && l.length() > 0) lines.push_back(l);
  }
  return lines;
}

std::vector<LineSegment> read_lines_nyu(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open lines file '" + path + "'");
  std::string row;
  if (!std::getline(in, row)) throw std::runtime_error(path + ": empty file (expected a header)");
  // Column positions from the header.
  std::vector<std::string> names;
  {
    std::istringstream header(row);
    for (std::string name; header >> name;) names.push_back(name);
  }
  const auto column = [&](const char* name, bool required) {
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
      if (required) throw std::runtime_error(path + ": header has no column '" + name + "'");
      return -1;
    }
    return static_cast<int>(it - names.begin());
  };
  const int x1 = column("point1_x", true), y1 = column("point1_y", true), z1 = column("point1_z", false);
  const int x2 = column("point2_x", true), y2 = column("point2_y", true), z2 = column("point2_z", false);
  const int needed = std::max({x1, y1, z1, x2, y2, z2}) + 1;
  std::vector<LineSegment> lines;
  std::vector<double> v;
  int line_number = 1;
  while (std::getline(in, row)) {
    ++line_number;
    if (row.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream fields(row);
    v.clear();
    for (double x; static_cast<int>(v.size()) < needed && fields >> x;) v.push_back(x);
    if (static_cast<int>(v.size()) < needed)
      throw std::runtime_error(path + ":" + std::to_string(line_number) + ": expected " + std::to_string(needed) +
                               " numbers");
    const double w1 = z1 >= 0 ? v[z1] : 1.0, w2 = z2 >= 0 ? v[z2] : 1.0;
    if (w1 == 0.0 || w2 == 0.0) continue;  // an endpoint at infinity is no segment
    LineSegment l{{v[x1] / w1, v[y1] / w1}, {v[x2] / w2, v[y2] / w2}};
    if (l.a.allFinite() && l.b.allFinite() && l.length() > 0) lines.push_back(l);
  }
  return lines;
}

}  // namespace propcam::inference
