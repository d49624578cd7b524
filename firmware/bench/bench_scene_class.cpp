#include "bench/bench_scene_class.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>

#include "propcam/capture/image_file.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/inference/scene_class_knn.h"
#include "propcam/inference/scene_classifier.h"
#include "propcam/inference/sky.h"
#include "propcam/render/panorama.h"
#include "worlds/real_views.h"
#include "tools/scene_reference_builder.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

constexpr const char* kOpenCvExamples = "/usr/share/doc/opencv-doc/examples/data";
// Leave-one-panorama-out views: 8 yaws x 2 pitches at a 60-degree lens.
constexpr int kLopoViewsPerTurn = 8;
constexpr double kLopoPitches[] = {-5.0, 5.0};
constexpr double kLopoFovDeg = 60.0;
// The views of the README's "Real photographs" table.
constexpr int kTableWidth = 480, kTableHeight = 360;
constexpr double kTableFovDeg = 60.0;
// The hotel room's window with sheer curtains (interior.exr, centred at this yaw).
constexpr double kInteriorWindowYawDeg = 315.0;

enum Set { kRooms, kStreets, kPanoIndoor, kPanoOutdoor, kTableViews, kRealPhotos, kSetCount };
constexpr const char* kSetNames[kSetCount] = {"rooms", "streets", "pano in", "pano out", "table", "photos"};

struct Tally {
  int correct = 0, total = 0;
  double seconds = 0;
  void add(bool ok, double s) {
    correct += ok;
    ++total;
    seconds += s;
  }
};

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

struct Case {
  cv::Mat photo;
  render::PinholeCamera camera;
  bool indoor = true;
  int exclude_group = -2;  // the photo's own panorama
};

// Every classifier's verdict on one photo, with its time.
struct Verdicts {
  std::vector<bool> indoor;
  std::vector<double> seconds;
  double knn_share = 0, sky_fraction = 0;
};

class Bench {
 public:
  Bench(const SceneClassBenchArgs& args, const inference::SceneReferenceSet& refs) : args_(args), all_(refs) {
    for (size_t i = 0; i < refs.size(); ++i)
      if (refs.at(i).group == inference::kRenderedGroup) renders_.add(refs.at(i));
    names_ = {"k-NN, renders (1st cut)", "k-NN, renders + real", "sky rule", "SVM, renders + real"};
    for (const char* learnt : {"k-NN", "SVM"})
      for (double t : args.sky_fractions) {
        char name[64];
        std::snprintf(name, sizeof name, "sky >= %.0f%%, else %s", 100 * t, learnt);
        names_.push_back(name);
      }
  }
  const std::vector<std::string>& names() const { return names_; }

  Verdicts judge(const Case& c) const {
    Verdicts v;
    auto t0 = std::chrono::steady_clock::now();
    const std::vector<float> desc = inference::appearance_descriptor(c.photo);
    const double t_desc = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    const auto knn_renders = inference::classify_indoor_knn(desc, renders_, {args_.k, -2, false});  // the first cut
    const double t_renders = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    const auto knn = inference::classify_indoor_knn(desc, all_, {args_.k, c.exclude_group, !args_.unbalanced});
    const double t_all = seconds_since(t0);
    inference::StageReport report;
    inference::SkyEstimate sky;
    t0 = std::chrono::steady_clock::now();
    const bool sky_indoor = inference::classify_indoor(c.photo, c.camera, report, &sky);
    const double t_sky = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    const bool svm_indoor = classifier_without(c.exclude_group).indoor_score(desc) >= 0;
    const double t_svm = seconds_since(t0);
    v.indoor = {knn_renders.indoor, knn.indoor, sky_indoor, svm_indoor};
    v.seconds = {t_desc + t_renders, t_desc + t_all, t_sky, t_desc + t_svm};
    for (const auto& [learnt_indoor, t_learnt] : {std::pair{knn.indoor, t_all}, std::pair{svm_indoor, t_svm}})
      for (double t : args_.sky_fractions) {
        const bool sky_decides = !sky_indoor && sky.fraction >= t;
        v.indoor.push_back(sky_decides ? false : learnt_indoor);
        v.seconds.push_back(t_sky + (sky_decides ? 0 : t_desc + t_learnt));
      }
    v.knn_share = knn.indoor_share;
    v.sky_fraction = sky.fraction;
    return v;
  }

 private:
  // Trained once per left-out panorama (a few seconds each).
  const inference::SceneClassifier& classifier_without(int group) const {
    auto& slot = classifiers_[group];
    if (!slot) slot = std::make_unique<inference::SceneClassifier>(inference::SceneClassifier::train(all_, group));
    return *slot;
  }

  const SceneClassBenchArgs& args_;
  const inference::SceneReferenceSet& all_;
  inference::SceneReferenceSet renders_;
  std::vector<std::string> names_;
  mutable std::map<int, std::unique_ptr<inference::SceneClassifier>> classifiers_;
};

using Tallies = std::vector<Tally>;  // one per classifier

void add(Tallies& t, const Verdicts& v, bool truth) {
  t.resize(v.indoor.size());
  for (size_t i = 0; i < v.indoor.size(); ++i) t[i].add(v.indoor[i] == truth, v.seconds[i]);
}

struct TableRow {
  std::string label, panorama;
  std::vector<double> yaws;
  std::vector<double> pitches;
};

std::vector<TableRow> table_rows() {
  const std::vector<double> sixths = {0, 60, 120, 180, 240, 300}, thirds = {0, 120, 240};
  return {{"interior, yaw 0-300/60, pitch +5", "interior", sixths, {5}},
          {"interior window, pitch -20/0/+10", "interior", {kInteriorWindowYawDeg}, {-20, 0, 10}},
          {"studio, yaw 0-300/60", "studio", sixths, {0}},
          {"sunrise, yaw 0/120/240", "sunrise", thirds, {0}},
          {"sunset, yaw 0/120/240", "sunset", thirds, {0}},
          {"city, yaw 0/120/240", "city", thirds, {0}},
          {"forest, yaw 0/120/240", "forest", thirds, {0}},
          {"courtyard, yaw 0/120/240", "courtyard", thirds, {0}}};
}

void print_counts(const char* label, const Tallies& t, int width = 34) {
  std::printf("%-*s", width, label);
  for (const auto& x : t) std::printf(" %3d/%-3d", x.correct, x.total);
  std::printf("\n");
}

void print_header(const Bench& bench, const char* first, int width = 34) {
  std::printf("\n%-*s", width, first);
  for (size_t i = 0; i < bench.names().size(); ++i) std::printf("  [%zu]   ", i);
  std::printf("\n");
}

}  // namespace

void add_bench_scene_class_options(CLI::App& cmd, SceneClassBenchArgs& args) {
  cmd.add_option("--rooms", args.rooms, "Held-out rooms")->check(CLI::NonNegativeNumber);
  cmd.add_option("--streets", args.streets, "Held-out streets")->check(CLI::NonNegativeNumber);
  cmd.add_option("--first-seed", args.first_seed, "First generator seed (keep clear of the database's 1001..)");
  cmd.add_option("--spp", args.spp, "Samples per pixel")->check(CLI::PositiveNumber);
  cmd.add_option("--k", args.k, "Neighbours")->check(CLI::PositiveNumber);
  cmd.add_option("--refs", args.refs, "Reference set (default: the committed one)");
  cmd.add_option("--sky-fractions", args.sky_fractions, "Combined classifier: sky share from which the sky rule decides")
      ->delimiter(',');
  cmd.add_flag("--unbalanced", args.unbalanced, "Plain majority vote (default: votes weighted by 1 / class size)");
  cmd.add_flag("--verbose", args.verbose, "One line per panorama view and photo");
}

int run_bench_scene_class_command(const SceneClassBenchArgs& args) {
  const inference::SceneReferenceSet refs =
      inference::SceneReferenceSet::load(args.refs.empty() ? inference::default_scene_reference_path() : args.refs);
  const Bench bench(args, refs);
  std::vector<Tallies> sets(kSetCount);
  render::RenderSettings settings;
  settings.samples_per_pixel = args.spp;
  for (int i = 0; i < args.rooms + args.streets; ++i) {
    const bool street = i >= args.rooms;
    const uint64_t seed = args.first_seed + static_cast<uint64_t>(street ? i - args.rooms : i);
    const SyntheticShot shot = street ? shoot_synthetic_street({args.width, args.height, seed, 0.0, 1.5}, settings)
                                      : shoot_synthetic_room({args.width, args.height, seed, 0.0, 1.5}, settings);
    add(sets[street ? kStreets : kRooms], bench.judge({shot.photo_linear, shot.truth.camera(), shot.truth.indoor}),
        shot.truth.indoor);
  }

  // Leave-one-panorama-out: each panorama's views against references without it.
  std::map<std::string, Tallies> per_panorama;
  for (const auto& p : blender_panoramas()) {
    const std::string path = panorama_path(p.name);
    if (!std::filesystem::exists(path)) continue;
    const cv::Mat latlong = load_panorama_rgb(path);
    const int group = refs.find_group(p.name);
    int n = 0;
    for (double pitch : kLopoPitches) {
      const auto views = inference::panorama_views(latlong, kLopoViewsPerTurn, {pitch}, kLopoFovDeg, args.width, args.height);
      for (size_t v = 0; v < views.size(); ++v, ++n) {
        const double yaw = 360.0 * static_cast<double>(v) / kLopoViewsPerTurn;
        const Case c{views[v].photo_linear, render::view_camera(render::view_spec(yaw, pitch, kLopoFovDeg, args.width, args.height)),
                     p.indoor, group};
        const Verdicts verdict = bench.judge(c);
        add(sets[p.indoor ? kPanoIndoor : kPanoOutdoor], verdict, p.indoor);
        add(per_panorama[p.name], verdict, p.indoor);
        if (args.verbose)
          std::printf("%-10s yaw %5.1f pitch %+3.0f  knn share %.2f  sky %.3f\n", p.name.c_str(), yaw, pitch,
                      verdict.knn_share, verdict.sky_fraction);
      }
    }
  }

  std::vector<std::pair<std::string, Tallies>> rows;
  for (const auto& row : table_rows()) {
    const std::string path = panorama_path(row.panorama);
    if (!std::filesystem::exists(path)) continue;
    const bool indoor = row.panorama == "interior" || row.panorama == "studio";
    Tallies t;
    for (double pitch : row.pitches)
      for (double yaw : row.yaws) {
        const RealView view = shoot_panorama_view(path, render::view_spec(yaw, pitch, kTableFovDeg, kTableWidth, kTableHeight));
        const Verdicts verdict = bench.judge({view.photo_linear, view.camera, indoor, refs.find_group(row.panorama)});
        add(t, verdict, indoor);
        add(sets[kTableViews], verdict, indoor);
      }
    rows.emplace_back(row.label, t);
  }

  std::vector<std::pair<std::string, Tallies>> photos;
  for (const char* file : {"building.jpg", "home.jpg"}) {  // both outdoor: a façade, a house in its garden
    const std::string path = std::string(kOpenCvExamples) + "/" + file;
    if (!std::filesystem::exists(path)) continue;
    const cv::Mat photo = capture::load_photo_linear(path);
    const Verdicts verdict = bench.judge({photo, render::view_camera(render::view_spec(0, 0, 60, photo.cols, photo.rows)), false});
    Tallies t;
    add(t, verdict, false);
    add(sets[kRealPhotos], verdict, false);
    photos.emplace_back(file, t);
    std::printf("%-14s truth outdoor  knn indoor share %.2f  sky fraction %.3f\n", file, verdict.knn_share,
                verdict.sky_fraction);
  }

  size_t rendered = 0;
  for (size_t i = 0; i < refs.size(); ++i) rendered += refs.at(i).group == inference::kRenderedGroup;
  std::printf("\nreferences: %zu (%zu rendered, %zu real views of %zu panoramas), k = %d\n", refs.size(), rendered,
              refs.size() - rendered, refs.groups().size(), args.k);
  std::printf("\n%-26s", "classifier");
  for (const char* s : kSetNames) std::printf(" %9s", s);
  std::printf(" %9s\n", "ms/photo");
  for (size_t c = 0; c < bench.names().size(); ++c) {
    std::printf("[%zu] %-22s", c, bench.names()[c].c_str());
    double seconds = 0;
    int total = 0;
    for (const auto& s : sets) {
      if (s.empty()) {
        std::printf(" %9s", "-");
        continue;
      }
      std::printf("   %3d/%-3d", s[c].correct, s[c].total);
      seconds += s[c].seconds;
      total += s[c].total;
    }
    std::printf(" %9.2f\n", total ? 1000 * seconds / total : 0.0);
  }
  print_header(bench, "panorama (leave-one-out views)");
  for (const auto& [name, t] : per_panorama) print_counts(name.c_str(), t);
  print_header(bench, "README table views (480x360, 60 deg)");
  for (const auto& [label, t] : rows) print_counts(label.c_str(), t);
  print_header(bench, "real photos");
  for (const auto& [label, t] : photos) print_counts(label.c_str(), t);
  return 0;
}

}  // namespace propcam::firmware
