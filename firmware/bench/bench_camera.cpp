#include "bench/bench_camera.h"

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>

#include "common/bench_common.h"
#include "common/progress.h"
#include "propcam/inference/camera.h"

namespace propcam::firmware {
namespace {

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using nlohmann::json;

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
// Ground-truth vanishing points whose directions (true intrinsics) are this
// close to 90 degrees apart count as one Manhattan frame. The labels are
// clicked by hand: orthogonal pairs scatter by a few degrees (a wider window
// would pair a wall with rotated furniture).
constexpr double kOrthogonalToleranceDeg = 5.0;
// Focal-error shares reported.
constexpr double kFocalBands[] = {0.05, 0.10, 0.20};
// The sweep: line-pair samples (RANSAC iterations) for each number of
// candidate vanishing points kept, then the focal hypotheses tried for pairs
// that do not fix the focal length.
constexpr int kSweepIterations[] = {25, 50, 100, 200, 400, 800};
constexpr int kSweepCandidates[] = {4, 8, 12, 20};
constexpr int kSweepFocalHypotheses[] = {1, 3, 5, 7, 11, 15};

struct Image {
  std::string id;
  std::vector<inference::LineSegment> lines;
  std::vector<Vector3d> gt_dirs;  // unit, true camera coordinates
};

// `idx X Y` rows after a header.
std::vector<Eigen::Vector2d> read_vps(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open '" + path.string() + "'");
  std::string row;
  std::getline(in, row);  // header
  std::vector<Eigen::Vector2d> vps;
  while (std::getline(in, row)) {
    std::istringstream f(row);
    double idx, x, y;
    if (f >> idx >> x >> y && std::isfinite(x) && std::isfinite(y)) vps.emplace_back(x, y);
  }
  return vps;
}

Matrix3d k_matrix(double fx, double fy, double cx, double cy) {
  Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

double line_angle_deg(const Vector3d& a, const Vector3d& b) {
  return std::acos(std::clamp(std::abs(a.normalized().dot(b.normalized())), 0.0, 1.0)) * kRadToDeg;
}

// The largest set (3, else 2) of ground-truth directions that are mutually
// orthogonal within the tolerance, the most orthogonal such set; empty if none.
std::vector<Vector3d> orthogonal_subset(const std::vector<Vector3d>& d) {
  const auto dev = [&](size_t i, size_t j) { return std::abs(90.0 - line_angle_deg(d[i], d[j])); };
  std::vector<Vector3d> best;
  double best_dev = kOrthogonalToleranceDeg;
  for (size_t i = 0; i < d.size(); ++i)
    for (size_t j = i + 1; j < d.size(); ++j)
      for (size_t k = j + 1; k < d.size(); ++k) {
        const double worst = std::max({dev(i, j), dev(i, k), dev(j, k)});
        if (worst <= best_dev) {
          best_dev = worst;
          best = {d[i], d[j], d[k]};
        }
      }
  if (!best.empty()) return best;
  for (size_t i = 0; i < d.size(); ++i)
    for (size_t j = i + 1; j < d.size(); ++j)
      if (dev(i, j) <= best_dev) {
        best_dev = dev(i, j);
        best = {d[i], d[j]};
      }
  return best;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = p * (v.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - lo) * (v[hi] - v[lo]);
}

double mean(const std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  double s = 0;
  for (double x : v) s += x;
  return s / v.size();
}

json summary(const std::vector<double>& v) {
  return {{"median", percentile(v, 0.5)}, {"mean", mean(v)}, {"p90", percentile(v, 0.9)}, {"count", v.size()}};
}

struct Evaluation {
  json images = json::array();
  std::vector<double> focal_err, focal_err_from_vps, axis_err, axis_err_own_k, seconds;
  // Distance (px) of the principal point from the truth: every image, the
  // images where it was estimated, and the image centre on those images.
  std::vector<double> principal_err, principal_err_estimated, centre_err_estimated;
  std::map<std::string, int> cases;
};

Evaluation evaluate(const std::vector<Image>& images, const inference::CameraOptions& co, const CameraBenchOptions& o,
                    size_t stride, Progress* progress) {
  Evaluation ev;
  for (const auto& name : {"three_vanishing_points", "two_vanishing_points", "vertical_only", "no_vanishing_points"})
    ev.cases[name] = 0;
  const TrueIntrinsics& t = o.truth;
  const Matrix3d k_true_inv = k_matrix(t.fx, t.fy, t.cx, t.cy).inverse();
  for (size_t n = 0; n < images.size(); n += stride) {
    const Image& im = images[n];
    if (progress && n % 50 == 0) progress->stage("bench camera: image " + im.id);
    const auto start = std::chrono::steady_clock::now();
    const inference::CameraEstimate est = inference::estimate_camera(im.lines, o.width, o.height, co);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ev.seconds.push_back(seconds);
    const double focal_err = std::abs(est.fx / t.fx - 1.0);
    ev.focal_err.push_back(focal_err);
    if (est.focal_from_vanishing_points) ev.focal_err_from_vps.push_back(focal_err);
    ev.cases[est.report.why] += 1;
    const double principal_err = std::hypot(est.cx - t.cx, est.cy - t.cy);
    ev.principal_err.push_back(principal_err);
    const bool principal_estimated = est.report.details.value("principal_point_estimated", false);
    if (principal_estimated) {
      ev.principal_err_estimated.push_back(principal_err);
      ev.centre_err_estimated.push_back(std::hypot((o.width - 1) / 2.0 - t.cx, (o.height - 1) / 2.0 - t.cy));
    }
    json entry = {{"id", im.id}, {"lines", im.lines.size()}, {"fx", est.fx}, {"focal_err", focal_err},
                  {"focal_from_vps", est.focal_from_vanishing_points}, {"case", est.report.why}, {"seconds", seconds},
                  {"principal_point", {est.cx, est.cy}}, {"principal_point_estimated", principal_estimated},
                  {"principal_err_px", principal_err}};
    json vps = json::array();  // homogeneous pixels (x, y, w): the point is (x/w, y/w), at infinity when w = 0
    for (const Vector3d& d : est.directions_cam)
      vps.push_back({est.fx * d.x() + est.cx * d.z(), est.fy * d.y() + est.cy * d.z(), d.z()});
    entry["vps"] = vps;
    entry["support_px"] = est.support;
    entry["focal_log_std"] = est.report.details.value("focal_log_std", json(nullptr));
    entry["inliers"] = est.report.details.value("inliers_per_axis", json::array());
    const std::vector<Vector3d> gt = orthogonal_subset(im.gt_dirs);
    if (!gt.empty()) {
      // Estimated axes as vanishing points (estimated K), back-projected with
      // the true K: the same frame as the ground truth, so this measures where
      // the vanishing points are, apart from the focal error.
      const Matrix3d k_est = k_matrix(est.fx, est.fy, est.cx, est.cy);
      double worst = 0, worst_own = 0;
      for (const Vector3d& g : gt) {
        double best = 180, best_own = 180;
        for (const Vector3d& d : est.directions_cam) {
          best = std::min(best, line_angle_deg(k_true_inv * (k_est * d), g));
          best_own = std::min(best_own, line_angle_deg(d, g));
        }
        worst = std::max(worst, best);
        worst_own = std::max(worst_own, best_own);
      }
      ev.axis_err.push_back(worst);
      ev.axis_err_own_k.push_back(worst_own);
      entry["axis_err_deg"] = worst;
      entry["axis_err_own_k_deg"] = worst_own;
      entry["gt_orthogonal_vps"] = gt.size();
    }
    ev.images.push_back(entry);
  }
  return ev;
}

json focal_json(const std::vector<double>& e) {
  json j = summary(e);
  for (double band : kFocalBands) {
    const auto within = std::count_if(e.begin(), e.end(), [&](double x) { return x <= band; });
    char key[32];
    std::snprintf(key, sizeof key, "within_%d", static_cast<int>(std::lround(band * 100)));
    j[key] = e.empty() ? 0.0 : static_cast<double>(within) / e.size();
  }
  return j;
}

}  // namespace

json run_camera_bench(const CameraBenchOptions& o) {
  Progress progress(o.quiet);
  if (o.nyu_dir.empty() || !fs::is_directory(o.nyu_dir))
    throw std::invalid_argument("bench camera: --nyu needs a folder of lsd_lines_NNNN.csv and vps_NNNN.csv");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(o.nyu_dir)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("lsd_lines_", 0) == 0 && e.path().extension() == ".csv") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (o.max_images > 0 && static_cast<int>(files.size()) > o.max_images) files.resize(o.max_images);
  progress.stage("bench camera: reading " + std::to_string(files.size()) + " images");
  const TrueIntrinsics& t = o.truth;
  const Matrix3d k_true_inv = k_matrix(t.fx, t.fy, t.cx, t.cy).inverse();
  std::vector<Image> images;
  int missing_vps = 0;
  for (const auto& f : files) {
    const std::string stem = f.stem().string();
    Image im;
    im.id = stem.substr(std::string("lsd_lines_").size());
    const fs::path vps = f.parent_path() / ("vps_" + im.id + ".csv");
    if (!fs::exists(vps)) {
      ++missing_vps;
      continue;
    }
    im.lines = inference::read_lines_nyu(f.string());
    for (const auto& v : read_vps(vps)) im.gt_dirs.push_back((k_true_inv * Vector3d(v.x(), v.y(), 1.0)).normalized());
    images.push_back(std::move(im));
  }
  if (images.empty()) throw std::invalid_argument("bench camera: no lsd_lines_NNNN.csv with a vps_NNNN.csv in " + o.nyu_dir);

  json result;
  inference::CameraOptions defaults;
  defaults.prior_focal_px = o.prior_focal_px;
  defaults.fixed_focal = o.fixed_focal;
  defaults.estimate_principal_point = !o.centre_principal_point;
  result["dataset"] = {{"dir", o.nyu_dir}, {"images", images.size()}, {"skipped_without_vps", missing_vps},
                       {"size", {o.width, o.height}},
                       {"true_intrinsics", {{"fx", t.fx}, {"fy", t.fy}, {"cx", t.cx}, {"cy", t.cy}}}};
  result["options"] = {{"ransac_iterations", defaults.ransac_iterations},
                       {"candidate_vps", defaults.candidate_vps},
                       {"focal_hypotheses", defaults.focal_hypotheses},
                       {"inlier_distance_px", defaults.inlier_distance_px},
                       {"prior_focal_px", defaults.prior_focal_px},
                       {"fixed_focal", defaults.fixed_focal},
                       {"estimate_principal_point", defaults.estimate_principal_point},
                       {"seed", defaults.seed}};
  const Evaluation ev = evaluate(images, defaults, o, 1, &progress);
  result["focal_rel_error"] = focal_json(ev.focal_err);
  // The prior alone scores well when it happens to match the lens (NYU:
  // 0.85 x 640 = 544 px, 4.8% off), so the images whose focal length came
  // from vanishing points are reported apart.
  result["focal_rel_error_from_vps"] = focal_json(ev.focal_err_from_vps);
  result["axis_error_deg"] = summary(ev.axis_err);
  result["axis_error_deg"]["metric"] =
      "per image: the max, over its mutually orthogonal ground-truth VPs (3, else 2, within " +
      std::to_string(kOrthogonalToleranceDeg).substr(0, 3) +
      " deg of 90), of the angle between the VP's direction (true K) and the nearest estimated axis, "
      "itself taken to the image with the estimated K and back with the true K";
  result["axis_error_own_k_deg"] = summary(ev.axis_err_own_k);
  result["axis_error_own_k_deg"]["metric"] = "as axis_error_deg, the estimated axes compared in their own (estimated) camera frame";
  result["cases"] = ev.cases;
  result["principal_point_error_px"] = summary(ev.principal_err);
  result["principal_point_error_px"]["estimated"] = summary(ev.principal_err_estimated);
  result["principal_point_error_px"]["centre_on_estimated"] = summary(ev.centre_err_estimated);
  result["seconds_per_image"] = {{"mean", mean(ev.seconds)}, {"median", percentile(ev.seconds, 0.5)},
                                 {"max", *std::max_element(ev.seconds.begin(), ev.seconds.end())}};
  result["images"] = ev.images;

  json sweep = json::array();
  if (o.sweep_images > 0) {
    const size_t stride = std::max<size_t>(1, (images.size() + o.sweep_images - 1) / o.sweep_images);
    const auto point = [&](const std::string& series, int value, const inference::CameraOptions& co) {
      progress.stage("bench camera: sweep " + series + ", " + std::to_string(value));
      const Evaluation s = evaluate(images, co, o, stride, nullptr);
      const json f = focal_json(s.focal_err);
      sweep.push_back({{"series", series}, {"value", value}, {"ransac_iterations", co.ransac_iterations},
                       {"candidate_vps", co.candidate_vps}, {"focal_hypotheses", co.focal_hypotheses},
                       {"images", s.focal_err.size()}, {"seconds_per_image", mean(s.seconds)},
                       {"focal_err_median", f["median"]}, {"focal_within_10", f["within_10"]},
                       {"axis_err_median_deg", percentile(s.axis_err, 0.5)},
                       {"axis_err_p90_deg", percentile(s.axis_err, 0.9)}});
    };
    for (int c : kSweepCandidates)
      for (int it : kSweepIterations) {
        inference::CameraOptions co = defaults;
        co.candidate_vps = c;
        co.ransac_iterations = it;
        point(std::to_string(c) + " candidates, samples", it, co);
      }
    for (int h : kSweepFocalHypotheses) {
      inference::CameraOptions co = defaults;
      co.focal_hypotheses = h;
      point("focal hypotheses", h, co);
    }
  }
  result["sweep"] = sweep;
  return result;
}

std::string format_camera_bench(const json& r) {
  std::ostringstream out;
  char line[320];
  const json& f = r["focal_rel_error"];
  const json& a = r["axis_error_deg"];
  const json& ao = r["axis_error_own_k_deg"];
  out << "Camera stage on " << r["dataset"]["images"] << " images of " << r["dataset"]["dir"].get<std::string>()
      << " (" << r["options"]["ransac_iterations"] << " line-pair samples, " << r["options"]["candidate_vps"]
      << " candidate VPs, " << r["options"]["focal_hypotheses"] << " focal hypotheses, focal prior " << (r["options"]["prior_focal_px"].get<double>() > 0
                                               ? std::to_string(r["options"]["prior_focal_px"].get<int>()) + " px"
                                               : std::string("default")) << ")\n";
  std::snprintf(line, sizeof line,
                "  focal |f/f_true - 1|: median %.3f  mean %.3f  p90 %.3f  within 5%%: %.0f%%  10%%: %.0f%%  20%%: %.0f%%\n",
                f["median"].get<double>(), f["mean"].get<double>(), f["p90"].get<double>(),
                100 * f["within_5"].get<double>(), 100 * f["within_10"].get<double>(), 100 * f["within_20"].get<double>());
  out << line;
  const auto num = [](const json& j) { return j.is_number() ? j.get<double>() : std::nan(""); };
  const json& fv = r["focal_rel_error_from_vps"];
  std::snprintf(line, sizeof line, "  focal from VPs (%d images): median %.3f  p90 %.3f  within 10%%: %.0f%%\n",
                fv["count"].get<int>(), num(fv["median"]), num(fv["p90"]), 100 * fv["within_10"].get<double>());
  out << line;
  std::snprintf(line, sizeof line, "  axis error (deg, %d images): median %.2f  p90 %.2f  mean %.2f   own-K frame: median %.2f  p90 %.2f\n",
                a["count"].get<int>(), num(a["median"]), num(a["p90"]), num(a["mean"]), num(ao["median"]), num(ao["p90"]));
  out << line;
  const json& pp = r["principal_point_error_px"];
  std::snprintf(line, sizeof line,
                "  principal point error (px): all median %.1f  p90 %.1f;  estimated on %d images: median %.1f  p90 %.1f "
                "(image centre there: median %.1f)\n",
                num(pp["median"]), num(pp["p90"]), pp["estimated"]["count"].get<int>(), num(pp["estimated"]["median"]),
                num(pp["estimated"]["p90"]), num(pp["centre_on_estimated"]["median"]));
  out << line << "  cases:";
  for (const auto& [k, v] : r["cases"].items()) out << " " << k << " " << v;
  std::snprintf(line, sizeof line, "\n  seconds per image: mean %.4f  median %.4f  max %.4f\n",
                r["seconds_per_image"]["mean"].get<double>(), r["seconds_per_image"]["median"].get<double>(),
                r["seconds_per_image"]["max"].get<double>());
  out << line;
  if (!r["sweep"].empty()) {
    out << "\nSweep (" << r["sweep"][0]["images"] << " images): error vs time\n"
        << "  samples  candidates  focal_hyp  s/image   focal_med  focal<=10%  axis_med  axis_p90\n";
    for (const auto& s : r["sweep"]) {
      std::snprintf(line, sizeof line, "  %7d  %10d  %9d  %7.4f   %9.3f  %9.0f%%  %8.2f  %8.2f\n",
                    s["ransac_iterations"].get<int>(), s["candidate_vps"].get<int>(), s["focal_hypotheses"].get<int>(),
                    s["seconds_per_image"].get<double>(),
                    s["focal_err_median"].get<double>(), 100 * s["focal_within_10"].get<double>(),
                    num(s["axis_err_median_deg"]), num(s["axis_err_p90_deg"]));
      out << line;
    }
  }
  return out.str();
}

void plot_camera_bench(const json& r, const std::string& dir) {
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0)
    throw std::runtime_error("gnuplot is not installed (scripts/setup.sh installs gnuplot-nox)");
  fs::create_directories(dir);
  const fs::path d(dir);
  {
    // One gnuplot data block per series (blank-line separated, titled by its
    // first line): value, seconds per image, median focal and axis errors.
    std::ofstream dat(d / "camera_sweep.dat");
    std::string last;
    for (const auto& s : r["sweep"]) {
      const std::string series = s["series"].get<std::string>();
      if (series != last)
        dat << (last.empty() ? "" : "\n\n") << "\"" << series
            << "\" seconds focal_median focal_within_10 axis_median axis_p90\n";
      last = series;
      const auto num = [](const json& j) { return j.is_number() ? j.get<double>() : 0.0; };
      dat << s["value"] << " " << s["seconds_per_image"] << " " << num(s["focal_err_median"]) << " "
          << num(s["focal_within_10"]) << " " << num(s["axis_err_median_deg"]) << " " << num(s["axis_err_p90_deg"])
          << "\n";
    }
    std::vector<double> e;
    for (const auto& im : r["images"]) e.push_back(im["focal_err"].get<double>());
    std::sort(e.begin(), e.end());
    std::ofstream cdf(d / "camera_focal_cdf.dat");
    cdf << "# focal_rel_error share_of_images\n";
    for (size_t i = 0; i < e.size(); ++i) cdf << e[i] << " " << (i + 1.0) / e.size() << "\n";
  }
  const std::string sweep = (d / "camera_sweep.dat").string();
  std::ofstream gp(d / "camera.gp");
  gp << "set terminal png size 800,560\nset grid\nset key top right\n"
        "set logscale x\n"
        "set output '" << (d / "camera_sweep_focal.png").string() << "'\n"
        "set title 'Camera stage on NYU-VP: focal lengths within 10% vs time (labels: the knob value)'\n"
        "set xlabel 'seconds per image'\nset ylabel 'share of images with |f/f_{true} - 1| <= 0.1'\n"
        "plot for [i=0:*] '" << sweep << "' index i using 2:4 with linespoints pt 7 title columnhead(1), "
        "'" << sweep << "' using 2:4:1 with labels offset 1,1 notitle\n"
        "set output '" << (d / "camera_sweep_axes.png").string() << "'\n"
        "set title 'Camera stage on NYU-VP: 90th-percentile axis error vs time (labels: the knob value)'\n"
        "set ylabel '90th percentile of the axis error (deg)'\n"
        "plot for [i=0:*] '" << sweep << "' index i using 2:6 with linespoints pt 7 title columnhead(1), "
        "'" << sweep << "' using 2:6:1 with labels offset 1,1 notitle\n"
        "unset logscale x\nset xrange [0:0.5]\nset yrange [0:1]\n"
        "set output '" << (d / "camera_focal_cdf.png").string() << "'\n"
        "set title 'Camera stage on NYU-VP: share of images within a focal error'\n"
        "set xlabel '|f/f_{true} - 1|'\nset ylabel 'share of images'\n"
        "plot '" << (d / "camera_focal_cdf.dat").string() << "' using 1:2 with lines lw 2 title 'estimate\\_camera'\n";
  gp.close();
  const std::string cmd = "gnuplot '" + (d / "camera.gp").string() + "' 2>'" + (d / "gnuplot.log").string() + "'";
  if (std::system(cmd.c_str()) != 0) throw std::runtime_error("gnuplot failed on " + (d / "camera.gp").string());
}

void add_bench_camera_options(CLI::App& cmd, CameraBenchArgs& a) {
  cmd.add_option("--nyu", a.options.nyu_dir, "NYU-VP folder: lsd_lines_NNNN.csv and vps_NNNN.csv")->required();
  cmd.add_option("--size", a.size, "Image size WxH of the dataset");
  cmd.add_option("--intrinsics", a.intrinsics, "True FX,FY,CX,CY (default: NYU's Kinect)");
  cmd.add_option("--prior-focal", a.options.prior_focal_px, "Focal prior in pixels given to the stage (0: its default)")
      ->check(CLI::NonNegativeNumber);
  cmd.add_flag("--fixed-focal", a.options.fixed_focal, "Use the focal prior as the focal length (rotation only)");
  cmd.add_flag("--centre-principal-point", a.options.centre_principal_point,
                "Keep the principal point at the image centre (do not estimate it)");
  cmd.add_option("--max-images", a.options.max_images, "Use only the first N images (0: all)");
  cmd.add_option("--sweep-images", a.options.sweep_images, "Images per sweep point, evenly spaced (0: no sweep)");
  cmd.add_option("--plot", a.options.plot_dir, "Write PNG plots (gnuplot) to this folder");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_camera_command(CameraBenchArgs a) {
  char x = 0;
  std::istringstream size(a.size);
  if (!(size >> a.options.width >> x >> a.options.height) || x != 'x' || a.options.width <= 0 || a.options.height <= 0)
    throw std::invalid_argument("--size expects WxH");
  if (!a.intrinsics.empty()) {
    std::istringstream in(a.intrinsics);
    char c1 = 0, c2 = 0, c3 = 0;
    TrueIntrinsics& t = a.options.truth;
    if (!(in >> t.fx >> c1 >> t.fy >> c2 >> t.cx >> c3 >> t.cy) || c1 != ',' || c2 != ',' || c3 != ',' || !(t.fx > 0) ||
        !(t.fy > 0))
      throw std::invalid_argument("--intrinsics expects FX,FY,CX,CY with positive focal lengths");
  }
  if (a.options.sweep_images < 0 || a.options.max_images < 0)
    throw std::invalid_argument("--max-images and --sweep-images must be >= 0");
  a.options.quiet = a.json_out;
  return report_bench_result(run_camera_bench(a.options),
                             a.json_out, a.options.plot_dir, plot_camera_bench, format_camera_bench);
}

}  // namespace propcam::firmware
