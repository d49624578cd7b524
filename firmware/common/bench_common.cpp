#include "common/bench_common.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>

namespace propcam::firmware {

double rmse_in_mask(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f d = a.at<cv::Vec3f>(y, x) - b.at<cv::Vec3f>(y, x);
      sum += d.dot(d) / 3.0;
      ++n;
    }
  return n ? std::sqrt(sum / n) : 0.0;
}

cv::Mat changed_pixels(const cv::Mat& a, const cv::Mat& b, double threshold) {
  cv::Mat diff, grey;
  cv::absdiff(a, b, diff);
  cv::transform(diff, grey, cv::Matx13f(1.f, 1.f, 1.f));
  return grey > threshold;
}

void run_gnuplot(const std::string& dir, const std::string& script_name, const std::string& script) {
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0)
    throw std::runtime_error("gnuplot is not installed (scripts/setup.sh installs gnuplot-nox)");
  namespace fs = std::filesystem;
  fs::create_directories(dir);
  const fs::path script_path = fs::path(dir) / script_name;
  {
    std::ofstream gp(script_path);
    gp << script;
    if (!gp) throw std::runtime_error("cannot write " + script_path.string());
  }
  // gnuplot's warnings (e.g. a flat range on tiny benches) go to a log, not the user's terminal.
  const std::string cmd = "gnuplot '" + script_path.string() + "' 2>'" + (fs::path(dir) / "gnuplot.log").string() + "'";
  if (std::system(cmd.c_str()) != 0) throw std::runtime_error("gnuplot failed on " + script_path.string());
}

void parse_bench_size(const std::string& text, int min_side, int& width, int& height, const std::string& option) {
  char x = 0;
  std::istringstream size(text);
  if (!(size >> width >> x >> height) || x != 'x' || size.peek() != EOF || width < min_side || height < min_side)
    throw std::invalid_argument(option + " expects WxH of at least " + std::to_string(min_side) + "x" +
                                std::to_string(min_side));
}

std::vector<std::string> parse_sweeps(const std::string& text, const std::vector<std::string>& known) {
  std::vector<std::string> out;
  std::istringstream sweeps(text);
  for (std::string s; std::getline(sweeps, s, ',');) {
    if (s.empty()) continue;
    if (std::find(known.begin(), known.end(), s) == known.end())
      throw std::invalid_argument("--sweeps: unknown sweep '" + s + "'");
    out.push_back(s);
  }
  return out;
}

int report_bench_result(const nlohmann::json& result, bool json_out, const std::string& plot_dir,
                        const BenchPlot& plot, const BenchFormat& format) {
  if (plot && !plot_dir.empty()) plot(result, plot_dir);
  if (json_out) std::cout << result.dump(2) << std::endl;
  else std::cout << format(result);
  return 0;
}

}  // namespace propcam::firmware
