#include "tools/ibl_training.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numeric>
#include <random>
#include <sstream>

#include "common/progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/render/panorama.h"

namespace propcam::firmware {
namespace {

using nlohmann::json;
using inference::IblSimilarity;

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// The paper's views: azimuth stratified over the turn, elevation and field
// of view drawn uniformly (seeded per entry, so one entry's views do not
// depend on the others).
std::vector<render::ViewSpec> view_specs(int entry, const IblTrainingSpec& spec) {
  std::mt19937_64 rng(spec.seed * 1000003ull + static_cast<uint64_t>(entry));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<render::ViewSpec> out;
  for (int i = 0; i < spec.views_per_entry; ++i) {
    render::ViewSpec v;
    v.width = spec.width;
    v.height = spec.height;
    v.yaw_deg = 360.0 * (i + unit(rng)) / spec.views_per_entry;
    v.pitch_deg = spec.max_abs_pitch_deg * (2 * unit(rng) - 1);
    v.horizontal_fov_deg = spec.min_fov_deg + (spec.max_fov_deg - spec.min_fov_deg) * unit(rng);
    out.push_back(v);
  }
  return out;
}

// A view exposed as a camera would, through an 8-bit file's quantisation.
cv::Mat exposed_view(const cv::Mat& latlong, const render::ViewSpec& spec) {
  cv::Mat linear = render::rectilinear_view(latlong, render::view_camera(spec));
  render::auto_expose(linear);
  return capture::srgb8_to_linear(capture::linear_to_srgb8(linear));
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

// Pairs (better, worse) for each query: random candidate pairs of the
// query's kind, ordered by their IBL distance to the query.
void collect_pairs(const IblTrainingSet& set, int held_out, const IblTrainingSpec& spec,
                   std::vector<IblSimilarity>& differences, std::vector<double>& margins) {
  const auto& views = set.ranker.views;
  const auto& entries = set.ranker.entries;
  std::mt19937_64 rng(spec.seed);
  for (size_t q = 0; q < views.size(); ++q) {
    const int qe = views[q].entry;
    if (qe == held_out) continue;
    std::vector<int> candidates;
    for (size_t j = 0; j < views.size(); ++j) {
      const int je = views[j].entry;
      if (je != qe && je != held_out && entries[je].kind == entries[qe].kind) candidates.push_back(static_cast<int>(j));
    }
    if (candidates.size() < 2) continue;
    std::stable_sort(candidates.begin(), candidates.end(),
                     [&](int a, int b) { return set.distance(q, a) < set.distance(q, b); });
    const size_t nearest = spec.better_from_nearest > 0
                               ? std::min(candidates.size(), static_cast<size_t>(spec.better_from_nearest))
                               : candidates.size();
    std::uniform_int_distribution<size_t> pick(0, candidates.size() - 1), pick_near(0, nearest - 1);
    for (int p = 0; p < spec.pairs_per_query; ++p) {
      int j = candidates[pick_near(rng)], k = candidates[pick(rng)];
      if (set.distance(q, j) > set.distance(q, k)) std::swap(j, k);
      const double margin = set.distance(q, k) - set.distance(q, j);
      if (!(margin > 0)) continue;
      differences.push_back(set.similarity[q][j] - set.similarity[q][k]);
      margins.push_back(margin);
    }
  }
}

// Per query view of `entry`: the ranked candidates' distances.
struct QueryScore {
  double top1 = 0, best_of_top3 = 0, oracle = 0, mean = 0, light_error_deg = -1;
};

QueryScore score_query(const IblTrainingSet& set, int q, const IblSimilarity& w) {
  const auto& views = set.ranker.views;
  const auto& entries = set.ranker.entries;
  const int qe = views[q].entry;
  // Best view per candidate entry, as IblRanker::rank does.
  std::vector<std::pair<double, int>> best(entries.size(), {-std::numeric_limits<double>::infinity(), -1});
  QueryScore s;
  s.oracle = std::numeric_limits<double>::infinity();
  int n = 0;
  for (size_t j = 0; j < views.size(); ++j) {
    const int je = views[j].entry;
    if (je == qe || entries[je].kind != entries[qe].kind) continue;
    const double score = w.dot(set.similarity[q][j]);
    if (score > best[je].first) best[je] = {score, static_cast<int>(j)};
    s.oracle = std::min(s.oracle, set.distance(q, j));
    s.mean += set.distance(q, j);
    ++n;
  }
  std::vector<std::pair<double, int>> ranked;
  for (const auto& b : best)
    if (b.second >= 0) ranked.push_back(b);
  if (ranked.empty()) return {};
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  s.mean /= n;
  s.top1 = set.distance(q, ranked[0].second);
  s.best_of_top3 = s.top1;
  for (size_t r = 1; r < std::min<size_t>(3, ranked.size()); ++r)
    s.best_of_top3 = std::min(s.best_of_top3, set.distance(q, ranked[r].second));
  // The brightest light of each, seen from its view's heading.
  const auto& top = views[ranked[0].second];
  if (!entries[qe].lights.empty() && !entries[top.entry].lights.empty())
    s.light_error_deg = angle_deg(views[q].heading.transpose() * entries[qe].lights[0].direction,
                                  top.heading.transpose() * entries[top.entry].lights[0].direction);
  return s;
}

struct Summary {
  double top1 = 0, top3 = 0, oracle = 0, mean = 0, light = 0;
  int queries = 0, lit = 0;
  void add(const QueryScore& s) {
    top1 += s.top1, top3 += s.best_of_top3, oracle += s.oracle, mean += s.mean;
    ++queries;
    if (s.light_error_deg >= 0) light += s.light_error_deg, ++lit;
  }
  json to_json() const {
    const double n = std::max(1, queries);
    return {{"top1_distance", top1 / n}, {"best_of_top3_distance", top3 / n}, {"oracle_distance", oracle / n},
            {"random_distance", mean / n}, {"light_direction_error_deg", lit ? light / lit : -1.0}, {"queries", queries}};
  }
};

// The photo's features as inference computes them: lines, camera, scene
// class and orientation map (infer_geometry without the depth solve) and the
// light classifier's mask.
inference::IblFeatureInputs ibl_feature_inputs(const cv::Mat& photo_linear, const inference::InferenceOptions& options,
                                               const inference::LightClassifier* classifier) {
  inference::InferenceOptions o = options;
  o.geometry.solve = false;  // the features need lines, camera, sky and orientation, not dense depth
  const inference::GeometryEstimate g = inference::infer_geometry(photo_linear, o);
  inference::IblFeatureInputs in;
  in.photo_linear = photo_linear;
  in.camera = g.pinhole;
  in.orientation = g.orientation;
  in.sky_mask = g.sky.mask;
  if (classifier) in.light_mask = classifier->source_mask(photo_linear, options.lighting.classifier);
  return in;
}

}  // namespace

IblTrainingSet build_ibl_training_set(const IblTrainingSpec& spec) {
  // The classifier inference uses (estimate_lighting's default).
  return build_ibl_training_set_with(spec, inference::InferenceOptions{},
                                     inference::LightClassifier::load(inference::default_light_classifier_path()));
}

IblTrainingSet build_ibl_training_set_with(const IblTrainingSpec& spec, const inference::InferenceOptions& options,
                                           const inference::LightClassifier& classifier,
                                           const std::set<std::string>& drop_entries) {
  const auto start = std::chrono::steady_clock::now();
  Progress progress(spec.quiet);
  progress.stage("IBL ranker: building the library at width " + std::to_string(spec.library.width));
  const inference::IblLibrary library = inference::build_ibl_library(spec.library);
  IblTrainingSet set;
  for (size_t e = 0; e < library.entries.size(); ++e) {
    const auto& entry = library.entries[e];
    if (drop_entries.count(entry.name)) continue;
    progress.stage("IBL ranker: views of " + entry.name);
    inference::IblRankerEntry re;
    re.name = entry.name;
    re.kind = entry.kind;
    re.lights = entry.lights;
    re.sh = inference::project_radiance_sh(entry.latlong);
    const int index = static_cast<int>(set.ranker.entries.size());
    set.ranker.entries.push_back(std::move(re));
    // Seeded by the index in the whole library: dropping an entry leaves the others' views as they were.
    for (const auto& v : view_specs(static_cast<int>(e), spec)) {
      inference::IblRankerView rv;
      rv.entry = index;
      rv.yaw_deg = v.yaw_deg;
      rv.pitch_deg = v.pitch_deg;
      rv.fov_deg = v.horizontal_fov_deg;
      rv.heading = inference::heading_frame(render::view_camera(v).R_world_from_cam);
      rv.features = inference::ibl_view_features(ibl_feature_inputs(exposed_view(entry.latlong, v), options, &classifier));
      set.ranker.views.push_back(std::move(rv));
    }
  }
  progress.stage("IBL ranker: similarities and distances");
  const auto& views = set.ranker.views;
  const size_t n = views.size();
  set.similarity.assign(n, std::vector<IblSimilarity>(n, IblSimilarity::Zero()));
  set.distance = Eigen::MatrixXd::Zero(n, n);
  for (size_t q = 0; q < n; ++q)
    for (size_t j = 0; j < n; ++j) {
      set.similarity[q][j] = inference::ibl_similarity(views[q].features, views[j].features);
      set.distance(q, j) = inference::ibl_render_distance(set.ranker.entries[views[q].entry].sh, views[q].heading,
                                                          set.ranker.entries[views[j].entry].sh, views[j].heading);
    }
  set.seconds = seconds_since(start);
  return set;
}

inference::SvmRankResult train_ibl_weights(const IblTrainingSet& set, int held_out, const IblTrainingSpec& spec) {
  std::vector<IblSimilarity> differences;
  std::vector<double> margins;
  collect_pairs(set, held_out, spec, differences, margins);
  return inference::train_svm_rank(differences, margins, spec.svm);
}

json evaluate_ibl_ranking(const IblTrainingSet& set, const IblTrainingSpec& spec) {
  Progress progress(spec.quiet);
  const auto& views = set.ranker.views;
  const auto& entries = set.ranker.entries;
  // Rankers compared: the trained one (left out per panorama), all seven
  // similarities summed, and each one alone.
  std::vector<std::string> names = {"trained (1-slack SVM-rank)", "equal weights"};
  for (int f = 0; f < inference::kIblSimilarityCount; ++f) names.push_back(std::string(inference::ibl_similarity_name(f)) + " alone");
  std::vector<std::array<Summary, 2>> totals(names.size());  // [ranker][indoor, outdoor]
  json per_entry = json::array();
  double train_seconds = 0, rank_ms = 0;
  int ranked_queries = 0, iterations = 0, converged = 0;
  for (size_t e = 0; e < entries.size(); ++e) {
    progress.stage("IBL ranker: holding out " + entries[e].name);
    const auto t = std::chrono::steady_clock::now();
    const inference::SvmRankResult trained = train_ibl_weights(set, static_cast<int>(e), spec);
    train_seconds += seconds_since(t);
    iterations += trained.iterations;
    converged += trained.converged;
    std::vector<IblSimilarity> rankers = {trained.w, IblSimilarity::Ones()};
    for (int f = 0; f < inference::kIblSimilarityCount; ++f) rankers.push_back(IblSimilarity::Unit(f));
    Summary held_trained;
    for (size_t q = 0; q < views.size(); ++q) {
      if (views[q].entry != static_cast<int>(e)) continue;
      for (size_t r = 0; r < rankers.size(); ++r) {
        const auto tq = std::chrono::steady_clock::now();
        const QueryScore s = score_query(set, static_cast<int>(q), rankers[r]);
        if (r == 0) rank_ms += 1e3 * seconds_since(tq), ++ranked_queries, held_trained.add(s);
        totals[r][entries[e].kind == inference::SceneKind::Indoor ? 0 : 1].add(s);
      }
    }
    per_entry.push_back({{"entry", entries[e].name}, {"kind", inference::to_string(entries[e].kind)},
                         {"trained", held_trained.to_json()}});
  }
  json rows = json::array();
  for (size_t r = 0; r < names.size(); ++r)
    rows.push_back({{"ranker", names[r]}, {"indoor", totals[r][0].to_json()}, {"outdoor", totals[r][1].to_json()}});
  const inference::SvmRankResult all = train_ibl_weights(set, -1, spec);
  json weights = json::object();
  for (int f = 0; f < inference::kIblSimilarityCount; ++f) weights[inference::ibl_similarity_name(f)] = all.w[f];
  return {{"entries", entries.size()}, {"views", views.size()}, {"C", spec.svm.C},
          {"rankers", rows}, {"per_entry", per_entry}, {"weights_all", weights},
          {"training_set_seconds", set.seconds}, {"train_seconds_per_fold", train_seconds / std::max<size_t>(1, entries.size())},
          {"cutting_plane_iterations_per_fold", static_cast<double>(iterations) / std::max<size_t>(1, entries.size())},
          {"folds_converged", converged}, {"rank_ms_per_query", ranked_queries ? rank_ms / ranked_queries : 0.0}};
}

std::string format_ibl_evaluation(const json& r) {
  std::ostringstream out;
  char line[320];
  out << "IBL ranking, leave one panorama out (" << r["entries"] << " panoramas, " << r["views"]
      << " views, C = " << r["C"] << "): mean view-frame IBL distance of the top-1 and best of top-3 panoramas,\n"
      << "the oracle (best candidate) and a random candidate; brightest-light direction error of the top-1\n";
  std::snprintf(line, sizeof line, "  %-28s | %-40s | %-40s\n", "ranker", "indoor: top1 / top3 / oracle / random / light",
                "outdoor: top1 / top3 / oracle / random / light");
  out << line;
  const auto cell = [](const json& s) {
    char c[96];
    std::snprintf(c, sizeof c, "%.3f / %.3f / %.3f / %.3f / %5.1f", s["top1_distance"].get<double>(),
                  s["best_of_top3_distance"].get<double>(), s["oracle_distance"].get<double>(),
                  s["random_distance"].get<double>(), s["light_direction_error_deg"].get<double>());
    return std::string(c);
  };
  for (const auto& row : r["rankers"]) {
    std::snprintf(line, sizeof line, "  %-28s | %-40s | %-40s\n", row["ranker"].get<std::string>().c_str(),
                  cell(row["indoor"]).c_str(), cell(row["outdoor"]).c_str());
    out << line;
  }
  out << "  weights trained on all: " << r["weights_all"].dump() << "\n";
  std::snprintf(line, sizeof line,
                "  training set %.1f s; per fold %.2f s, %.1f cutting planes, %d/%zu converged; ranking %.2f ms per photo\n",
                r["training_set_seconds"].get<double>(), r["train_seconds_per_fold"].get<double>(),
                r["cutting_plane_iterations_per_fold"].get<double>(), r["folds_converged"].get<int>(),
                r["per_entry"].size(), r["rank_ms_per_query"].get<double>());
  out << line;
  return out.str();
}

namespace {

void add_spec_options(CLI::App& cmd, IblTrainingArgs& a) {
  cmd.add_option("--views", a.spec.views_per_entry, "Rectilinear views per panorama")->check(CLI::PositiveNumber);
  cmd.add_option("--library-width", a.spec.library.width, "Panorama width the views are cut from")
      ->check(CLI::Range(64, 4096));
  cmd.add_option("--skies", a.spec.library.procedural_skies, "Procedural skies")->check(CLI::NonNegativeNumber);
  cmd.add_option("--rooms", a.spec.library.procedural_rooms, "Procedural rooms")->check(CLI::NonNegativeNumber);
  cmd.add_option("--blender-dir", a.spec.library.blender_dir, "blender-data world panoramas (skipped if absent)");
  cmd.add_option_function<std::vector<std::string>>(
         "--panoramas",
         [&a](const std::vector<std::string>& specs) {
           for (const auto& s : specs) a.spec.library.extra_panoramas.push_back(inference::parse_extra_panorama(s));
         },
         "Further EXR panoramas as PATH=indoor|outdoor (e.g. scripts/fetch_pmndrs_hdri.sh's)")
      ->delimiter(',');
  cmd.add_option("--pairs", a.spec.pairs_per_query, "Training pairs per query view")->check(CLI::PositiveNumber);
  cmd.add_option("--C", a.spec.svm.C, "SVM-rank's slack weight")->check(CLI::PositiveNumber);
  cmd.add_option("--better-from-nearest", a.spec.better_from_nearest,
                  "The better view of a training pair is among the query's N nearest (0: any)")->check(CLI::NonNegativeNumber);
  cmd.add_option("--seed", a.spec.seed, "View sampling and pair seed");
}

}  // namespace

void add_train_ibl_ranker_options(CLI::App& cmd, IblTrainingArgs& a) {
  cmd.add_option("-o,--output", a.output, "Model file to write (.yml.gz)")->required();
  add_spec_options(cmd, a);
}

int run_train_ibl_ranker_command(const IblTrainingArgs& a) {
  IblTrainingSet set = build_ibl_training_set(a.spec);
  const inference::SvmRankResult r = train_ibl_weights(set, -1, a.spec);
  if (!r.converged) std::cerr << "warning: SVM-rank stopped after " << r.iterations << " cutting planes without converging\n";
  set.ranker.weights = r.w;
  set.ranker.save(a.output);
  std::cerr << "wrote " << a.output << " (" << set.ranker.entries.size() << " panoramas, " << set.ranker.views.size()
            << " views, weights " << r.w.transpose() << ")\n";
  return 0;
}

void add_bench_ibl_ranking_options(CLI::App& cmd, IblTrainingArgs& a) {
  add_spec_options(cmd, a);
  cmd.add_option("--C-values", a.C_values, "A grid of C values (one training set)")->delimiter(',');
  cmd.add_option("--nearest-values", a.nearest_values, "A grid of --better-from-nearest values")->delimiter(',');
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_ibl_ranking_command(const IblTrainingArgs& a) {
  IblTrainingSpec spec = a.spec;
  spec.quiet = a.json_out;
  const IblTrainingSet set = build_ibl_training_set(spec);
  if (a.C_values.empty() && a.nearest_values.empty()) {
    const json r = evaluate_ibl_ranking(set, spec);
    if (a.json_out) std::cout << r.dump(2) << std::endl;
    else std::cout << format_ibl_evaluation(r);
    return 0;
  }
  // The grid: the trained ranker's row per setting.
  json grid = json::array();
  for (double C : a.C_values.empty() ? std::vector<double>{spec.svm.C} : a.C_values)
    for (int nearest : a.nearest_values.empty() ? std::vector<int>{spec.better_from_nearest} : a.nearest_values) {
      IblTrainingSpec s = spec;
      s.svm.C = C;
      s.better_from_nearest = nearest;
      s.quiet = true;
      const json r = evaluate_ibl_ranking(set, s);
      grid.push_back({{"C", C}, {"better_from_nearest", nearest}, {"trained", r["rankers"][0]},
                      {"equal_weights", r["rankers"][1]}, {"weights_all", r["weights_all"]}});
      if (!a.json_out) {
        const json& t = r["rankers"][0];
        std::printf("C %8.2f nearest %3d | indoor top1 %.3f top3 %.3f light %5.1f | outdoor top1 %.3f top3 %.3f light %5.1f\n", C,
                    nearest, t["indoor"]["top1_distance"].get<double>(), t["indoor"]["best_of_top3_distance"].get<double>(),
                    t["indoor"]["light_direction_error_deg"].get<double>(), t["outdoor"]["top1_distance"].get<double>(),
                    t["outdoor"]["best_of_top3_distance"].get<double>(), t["outdoor"]["light_direction_error_deg"].get<double>());
        std::fflush(stdout);
      }
    }
  if (a.json_out) std::cout << grid.dump(2) << std::endl;
  return 0;
}

void add_build_ibl_library_options(CLI::App& cmd, IblLibraryArgs& a) {
  inference::IblLibraryOptions& o = a.options;
  cmd.add_option("-o,--output", a.output, "Library folder to write (library.json + EXR panoramas)")->required();
  cmd.add_option("--width", o.width, "Stored panorama width (height is half)")->check(CLI::Range(8, 4096));
  cmd.add_option("--blender-dir", o.blender_dir, "blender-data world panoramas (skipped if absent)");
  cmd.add_option("--skies", o.procedural_skies, "Procedural skies")->check(CLI::NonNegativeNumber);
  cmd.add_option("--rooms", o.procedural_rooms, "Procedural rooms")->check(CLI::NonNegativeNumber);
  cmd.add_option_function<std::vector<std::string>>(
         "--panoramas",
         [&o](const std::vector<std::string>& specs) {
           for (const auto& s : specs) o.extra_panoramas.push_back(inference::parse_extra_panorama(s));
         },
         "Further EXR panoramas as PATH=indoor|outdoor")
      ->delimiter(',');
}

int run_build_ibl_library_command(const IblLibraryArgs& a) {
  const auto start = std::chrono::steady_clock::now();
  const inference::IblLibrary library = inference::build_ibl_library(a.options);
  inference::save_ibl_library(library, a.output);
  size_t lights = 0, indoor = 0;
  for (const auto& e : library.entries) {
    lights += e.lights.size();
    indoor += e.kind == inference::SceneKind::Indoor;
  }
  std::fprintf(stderr, "wrote %zu panoramas (%zu indoor, %zu outdoor, %zu light regions) to %s in %.2f s\n",
               library.entries.size(), indoor, library.entries.size() - indoor, lights, a.output.c_str(),
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}

}  // namespace propcam::firmware
