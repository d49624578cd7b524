// Helpers shared by the `propcam bench` commands: image errors over a region,
// gnuplot, their options and how they report a result.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

// A pixel counts as changed when its channels' absolute differences sum to more than this (linear).
constexpr double kChangedPixelThreshold = 1e-3;

// RMS over the pixels of `mask` (CV_8U) and over the three channels of a - b (CV_32FC3); 0 for an empty mask.
double rmse_in_mask(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask);
// CV_8U, 255 where a and b (CV_32FC3) differ by more than `threshold` (sum over channels).
cv::Mat changed_pixels(const cv::Mat& a, const cv::Mat& b, double threshold = kChangedPixelThreshold);

// Writes `script` to DIR/SCRIPT_NAME and runs gnuplot on it (its warnings go
// to DIR/gnuplot.log); creates DIR. Throws when gnuplot is missing or fails.
void run_gnuplot(const std::string& dir, const std::string& script_name, const std::string& script);

// `--size WxH` (or the `option` named) with both sides at least `min_side`,
// nothing after; throws std::invalid_argument naming the option.
void parse_bench_size(const std::string& text, int min_side, int& width, int& height, const std::string& option = "--size");
// `--sweeps a,b,c`: each name must be one of `known`; throws std::invalid_argument.
std::vector<std::string> parse_sweeps(const std::string& text, const std::vector<std::string>& known);

// What every bench command does with its result: plots it into `plot_dir`
// when one is given (and `plot` is set), then prints it on stdout as JSON or
// as its table. Returns the command's exit code, 0.
using BenchPlot = std::function<void(const nlohmann::json& result, const std::string& dir)>;
using BenchFormat = std::function<std::string(const nlohmann::json& result)>;
int report_bench_result(const nlohmann::json& result, bool json_out, const std::string& plot_dir,
                        const BenchPlot& plot, const BenchFormat& format);

}  // namespace propcam::firmware
