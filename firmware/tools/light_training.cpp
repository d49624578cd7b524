#include "tools/light_training.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "tools/cache_key.h"
#include "common/progress.h"
#include "propcam/capture/image_file.h"
#include "worlds/real_views.h"
#include "worlds/world_metrics.h"
#include "worlds/world_scenes.h"

namespace propcam::firmware {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// A panorama's views (kept for evaluation) and their labelled superpixels.
struct Panorama {
  std::string name;
  std::vector<inference::LabelledView> views;
  inference::LabelledFeatures features;  // of all its views, computed once
};

std::vector<Panorama> load_views(const LightTrainingSpec& spec, Progress& progress) {
  std::vector<Panorama> out;
  for (const auto& name : spec.panoramas) {
    progress.stage("light classifier: views of " + name);
    const cv::Mat latlong = capture::read_image_float(panorama_entry_file(name));
    cv::Mat rgb;
    std::vector<cv::Mat> ch;
    cv::split(latlong, ch);
    if (ch.size() < 3) throw std::runtime_error("panorama '" + name + "' has fewer than three channels");
    cv::merge(std::vector<cv::Mat>{ch[0], ch[1], ch[2]}, rgb);
    Panorama p{name, inference::panorama_views(rgb, spec.views_per_turn, spec.pitches_deg, spec.horizontal_fov_deg,
                                               spec.width, spec.height), {}};
    p.features = inference::labelled_features(p.views, spec.classifier);
    out.push_back(std::move(p));
  }
  return out;
}

// A Blender scene's photo with its true emitters.
struct BlenderScene {
  std::string name;
  int fold = 0;
  inference::LabelledView view;
};

std::vector<BlenderScene> load_blender_scenes(const LightTrainingSpec& spec, Progress& progress) {
  std::vector<BlenderScene> out;
  if (spec.blender_world.empty()) return out;
  progress.stage("light classifier: photos of the Blender world's tune split");
  // Never the held split: it is the one reported, never learnt from.
  for (const WorldScene& w : load_blender_world(spec.blender_world, "tune")) {
    if (w.emitters.empty()) continue;
    out.push_back({w.name, blender_light_fold(w.name, spec.blender_folds), {w.photo_linear, w.emitters}});
  }
  return out;
}

std::vector<LightTrainingGroup> groups_of(const std::vector<BlenderScene>& scenes, const LightTrainingSpec& spec) {
  std::vector<LightTrainingGroup> out;
  for (const auto& s : scenes) out.push_back({s.name, s.fold, inference::labelled_features({s.view}, spec.classifier)});
  return out;
}

struct Counts {
  double tp = 0, fp = 0, fn = 0, ms = 0;
  int views = 0;
  EmitterCounts emitters;
  bool objects = false;  // emitters counted (Blender scenes)
  void add(const Counts& o) {
    tp += o.tp, fp += o.fp, fn += o.fn, ms += o.ms, views += o.views;
    emitters += o.emitters;
    objects |= o.objects;
  }
  json summary() const {
    const double precision = tp + fp > 0 ? tp / (tp + fp) : 1.0, recall = tp + fn > 0 ? tp / (tp + fn) : 1.0;
    json s = {{"precision", precision},
              {"recall", recall},
              {"f1", precision + recall > 0 ? 2 * precision * recall / (precision + recall) : 0.0},
              {"ms_per_view", views ? ms / views : 0.0},
              {"source_pixels", tp + fn}};
    if (objects)
      s["emitters"] = {{"truth", emitters.truth}, {"found", emitters.found}, {"detected", emitters.detected},
                       {"right", emitters.right}};
    return s;
  }
};

void count(const cv::Mat& predicted, const cv::Mat& truth, Counts& c, bool objects) {
  c.tp += cv::countNonZero(predicted & truth);
  c.fp += cv::countNonZero(predicted & ~truth);
  c.fn += cv::countNonZero(~predicted & truth);
  if (!objects) return;
  c.emitters += count_emitters(truth, predicted);
  c.objects = true;
}

double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

// The classifier, the threshold and both (what the lighting stage uses: the
// bright pixels of source superpixels) on held-out views.
struct HeldOutCounts {
  Counts classifier, threshold, both;
  void add(const HeldOutCounts& o) { classifier.add(o.classifier), threshold.add(o.threshold), both.add(o.both); }
  json summary() const {
    return {{"classifier", classifier.summary()}, {"threshold", threshold.summary()}, {"both", both.summary()}};
  }
};

HeldOutCounts score_views(const inference::LightClassifier& model, const std::vector<const inference::LabelledView*>& views,
                          const LightTrainingSpec& spec, bool objects) {
  HeldOutCounts c;
  for (const auto* v : views) {
    auto t = std::chrono::steady_clock::now();
    const cv::Mat by_classifier = model.source_mask(v->photo_linear, spec.classifier);
    c.classifier.ms += ms_since(t);
    count(by_classifier, v->source_mask, c.classifier, objects);
    ++c.classifier.views;
    t = std::chrono::steady_clock::now();
    const cv::Mat by_threshold = inference::threshold_source_mask(v->photo_linear);
    c.threshold.ms += ms_since(t);
    count(by_threshold, v->source_mask, c.threshold, objects);
    ++c.threshold.views;
    count(by_classifier & by_threshold, v->source_mask, c.both, objects);
    c.both.ms = c.classifier.ms + c.threshold.ms;
    ++c.both.views;
  }
  return c;
}

json spec_key(const LightTrainingSpec& spec) {
  json panoramas = json::array();
  for (const auto& p : spec.panoramas) panoramas.push_back({p, file_stamp(panorama_entry_file(p))});
  return {{"panoramas", panoramas}, {"views_per_turn", spec.views_per_turn}, {"pitches_deg", spec.pitches_deg},
          {"fov_deg", spec.horizontal_fov_deg}, {"size", {spec.width, spec.height}},
          {"negative_stride", spec.negative_stride}, {"trees", spec.trees}, {"depth", spec.depth},
          {"work_width", spec.classifier.work_width}, {"superpixel_px", spec.classifier.superpixel_px},
          {"blender_world", spec.blender_world.empty() ? std::string()
                                                       : fs::absolute(spec.blender_world).lexically_normal().string()},
          {"blender_world_json",
           spec.blender_world.empty() ? std::string() : file_stamp((fs::path(spec.blender_world) / "world.json").string())},
          {"blender_folds", spec.blender_folds}, {"blender_copies", spec.blender_copies}};
}

}  // namespace

std::string panorama_entry_file(const std::string& entry) {
  const bool is_file = entry.find('/') != std::string::npos || entry.find('.') != std::string::npos;
  return is_file ? entry : panorama_path(entry);
}

int blender_light_fold(const std::string& scene_name, int folds) {
  const auto at = scene_name.find_last_of('_');
  int seed = 0;
  try {
    seed = std::stoi(scene_name.substr(at == std::string::npos ? 0 : at + 1));
  } catch (const std::exception&) {
    seed = static_cast<int>(std::hash<std::string>{}(scene_name) % 100000);
  }
  return std::abs(seed) % std::max(1, folds);
}

std::vector<LightTrainingGroup> blender_light_groups(const LightTrainingSpec& spec) {
  Progress progress(spec.quiet);
  return groups_of(load_blender_scenes(spec, progress), spec);
}

inference::LabelledFeatures light_training_set(const std::vector<const inference::LabelledFeatures*>& groups,
                                                int negative_stride) {
  inference::LabelledFeatures all;
  std::vector<int> labels;
  int negatives = 0;
  for (const inference::LabelledFeatures* f : groups) {
    for (int r = 0; r < f->features.rows; ++r) {
      const int label = f->labels.at<int>(r);
      if (label == 0 && negatives++ % std::max(1, negative_stride) != 0) continue;
      all.features.push_back(f->features.row(r));
      labels.push_back(label);
    }
  }
  all.labels = cv::Mat(labels, true).reshape(1, static_cast<int>(labels.size()));
  return all;
}

std::vector<std::string> default_training_panoramas() {
  return {"city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"};
}

inference::LightClassifier train_light_classifier_on(const std::vector<const inference::LabelledFeatures*>& panoramas,
                                                     const std::vector<LightTrainingGroup>& blender,
                                                     const LightTrainingSpec& spec, int skip_fold, int* rows) {
  std::vector<const inference::LabelledFeatures*> groups = panoramas;
  for (int copy = 0; copy < std::max(1, spec.blender_copies); ++copy)
    for (const auto& g : blender)
      if (g.fold != skip_fold) groups.push_back(&g.features);
  const inference::LabelledFeatures set = light_training_set(groups, spec.negative_stride);
  if (rows) *rows = set.features.rows;
  return inference::LightClassifier::train(set.features, set.labels, spec.trees, spec.depth);
}

namespace {

// Trains on the panoramas (but the one at `skip_panorama`, if any) and the
// Blender groups (but those of `skip_fold`, if any), in that order.
inference::LightClassifier train_on(const std::vector<Panorama>& panoramas, const std::vector<LightTrainingGroup>& blender,
                                    const LightTrainingSpec& spec, int skip_panorama, int skip_fold, int* rows = nullptr) {
  std::vector<const inference::LabelledFeatures*> kept;
  for (size_t i = 0; i < panoramas.size(); ++i)
    if (static_cast<int>(i) != skip_panorama) kept.push_back(&panoramas[i].features);
  return train_light_classifier_on(kept, blender, spec, skip_fold, rows);
}

}  // namespace

inference::LightClassifier train_light_classifier(const LightTrainingSpec& spec) {
  Progress progress(spec.quiet);
  const std::vector<Panorama> panoramas = load_views(spec, progress);
  const std::vector<LightTrainingGroup> blender = groups_of(load_blender_scenes(spec, progress), spec);
  progress.stage("light classifier: training");
  return train_on(panoramas, blender, spec, -1, -1);
}

std::vector<std::string> blender_fold_light_classifiers(const LightTrainingSpec& spec, const std::string& cache_dir) {
  const fs::path dir = fs::path(cache_dir) / "blender_light_folds";
  std::vector<std::string> paths;
  std::vector<int> missing;
  const json spec_part = spec_key(spec);
  const auto key_of = [&](int fold) {
    json key = spec_part;
    key["fold_left_out"] = fold;
    return key;
  };
  const auto key_path = [&](int fold) { return dir / ("light_classifier_fold" + std::to_string(fold) + ".json"); };
  for (int fold = 0; fold < spec.blender_folds; ++fold) {
    const fs::path model = dir / ("light_classifier_fold" + std::to_string(fold) + ".yml.gz");
    if (!key_matches(key_path(fold), key_of(fold)) || !fs::exists(model)) missing.push_back(fold);
    paths.push_back(model.string());
  }
  if (missing.empty()) return paths;
  Progress progress(spec.quiet);
  const std::vector<Panorama> panoramas = load_views(spec, progress);
  const std::vector<LightTrainingGroup> blender = groups_of(load_blender_scenes(spec, progress), spec);
  fs::create_directories(dir);
  for (int fold : missing) {
    progress.stage("light classifier: training without the Blender fold " + std::to_string(fold));
    train_on(panoramas, blender, spec, -1, fold).save(paths[fold]);
    write_key(key_path(fold), key_of(fold));
  }
  return paths;
}

std::string cached_light_classifier(const LightTrainingSpec& spec, const std::string& cache_dir, const std::string& name) {
  const fs::path dir = fs::path(cache_dir) / "light_classifiers";
  const fs::path model = dir / (name + ".yml.gz"), key_path = dir / (name + ".json");
  const json key = spec_key(spec);
  if (key_matches(key_path, key) && fs::exists(model)) return model.string();
  const inference::LightClassifier c = train_light_classifier(spec);
  fs::create_directories(dir);
  c.save(model.string());
  write_key(key_path, key);
  return model.string();
}

json evaluate_light_classifier(const LightTrainingSpec& spec) {
  Progress progress(spec.quiet);
  const std::vector<Panorama> panoramas = load_views(spec, progress);
  const std::vector<BlenderScene> scenes = load_blender_scenes(spec, progress);
  const std::vector<LightTrainingGroup> blender = groups_of(scenes, spec);
  json held_out = json::array();
  HeldOutCounts panorama_total, blender_total;
  const auto skipped_if_one_class = [&](int skip_panorama, int skip_fold) -> bool {
    int positives = 0, rows = 0;
    for (size_t i = 0; i < panoramas.size(); ++i)
      if (static_cast<int>(i) != skip_panorama)
        positives += cv::countNonZero(panoramas[i].features.labels), rows += panoramas[i].features.labels.rows;
    for (const auto& g : blender)
      if (g.fold != skip_fold) positives += cv::countNonZero(g.features.labels), rows += g.features.labels.rows;
    return positives == 0 || positives == rows;
  };
  for (size_t h = 0; h < (spec.hold_out == "blender" ? 0 : panoramas.size()); ++h) {
    progress.stage("light classifier: holding out " + panoramas[h].name);
    if (skipped_if_one_class(static_cast<int>(h), -1)) {
      held_out.push_back({{"panorama", panoramas[h].name}, {"skipped", "the other panoramas' views hold one class only"}});
      continue;
    }
    int rows = 0;
    const inference::LightClassifier model = train_on(panoramas, blender, spec, static_cast<int>(h), -1, &rows);
    std::vector<const inference::LabelledView*> views;
    for (const auto& v : panoramas[h].views) views.push_back(&v);
    const HeldOutCounts c = score_views(model, views, spec, false);
    panorama_total.add(c);
    json row = c.summary();
    row["panorama"] = panoramas[h].name;
    row["views"] = views.size();
    row["training_superpixels"] = rows;
    held_out.push_back(row);
  }
  for (int fold = 0; fold < (blender.empty() || spec.hold_out == "panoramas" ? 0 : spec.blender_folds); ++fold) {
    std::vector<const inference::LabelledView*> views;
    for (const auto& s : scenes)
      if (s.fold == fold) views.push_back(&s.view);
    if (views.empty()) continue;
    const std::string name = "blender fold " + std::to_string(fold);
    progress.stage("light classifier: holding out " + name);
    if (skipped_if_one_class(-1, fold)) {
      held_out.push_back({{"panorama", name}, {"skipped", "the other groups hold one class only"}});
      continue;
    }
    int rows = 0;
    const inference::LightClassifier model = train_on(panoramas, blender, spec, -1, fold, &rows);
    const HeldOutCounts c = score_views(model, views, spec, true);
    blender_total.add(c);
    json row = c.summary();
    row["panorama"] = name;
    row["views"] = views.size();
    row["training_superpixels"] = rows;
    held_out.push_back(row);
  }
  json r = {{"views_per_panorama", spec.views_per_turn * static_cast<int>(spec.pitches_deg.size())},
            {"size", {spec.width, spec.height}},
            {"held_out", held_out}};
  if (spec.hold_out != "blender") r["all"] = panorama_total.summary();
  if (!blender.empty() && spec.hold_out != "panoramas") r["blender"] = blender_total.summary();
  return r;
}

std::string format_light_evaluation(const json& r) {
  std::ostringstream out;
  char line[256];
  out << "Visible light sources held out: each panorama (" << r["views_per_panorama"] << " views each, "
      << r["size"][0] << "x" << r["size"][1]
      << "), then the Blender world's tune photos in folds: pixel precision / recall / F1, ms per view\n";
  std::snprintf(line, sizeof line, "  %-14s %8s   %-24s %-24s %-24s %s\n", "held out", "sources", "classifier", "threshold",
                "both (used)", "emitters found/true, right/detected (both)");
  out << line;
  const auto row = [&](const std::string& name, const json& h) {
    const auto cell = [](const json& c) {
      char a[64];
      std::snprintf(a, sizeof a, "%.2f / %.2f / %.2f  %5.1f", c["precision"].get<double>(), c["recall"].get<double>(),
                    c["f1"].get<double>(), c["ms_per_view"].get<double>());
      return std::string(a);
    };
    std::string objects;
    if (h["both"].contains("emitters")) {
      const json& e = h["both"]["emitters"];
      objects = std::to_string(e["found"].get<int>()) + "/" + std::to_string(e["truth"].get<int>()) + ", " +
                std::to_string(e["right"].get<int>()) + "/" + std::to_string(e["detected"].get<int>());
    }
    std::snprintf(line, sizeof line, "  %-14s %8.0f   %-24s %-24s %-24s %s\n", name.c_str(),
                  h["classifier"]["source_pixels"].get<double>(), cell(h["classifier"]).c_str(),
                  cell(h["threshold"]).c_str(), cell(h["both"]).c_str(), objects.c_str());
    out << line;
  };
  for (const auto& h : r["held_out"]) {
    if (h.contains("skipped")) {
      out << "  " << h["panorama"].get<std::string>() << ": skipped (" << h["skipped"].get<std::string>() << ")\n";
      continue;
    }
    row(h["panorama"], h);
  }
  if (r.contains("all")) row("all panoramas", r["all"]);
  if (r.contains("blender")) row("all Blender", r["blender"]);
  return out.str();
}

namespace {

void add_spec_options(CLI::App& cmd, LightTrainingArgs& a) {
  cmd.add_option("--views-per-turn", a.spec.views_per_turn, "Views per full turn of each panorama")->check(CLI::PositiveNumber);
  cmd.add_option("--trees", a.spec.trees, "Trees in the forest")->check(CLI::PositiveNumber);
  cmd.add_option("--negative-stride", a.spec.negative_stride, "Keep every n-th non-source superpixel")
      ->check(CLI::PositiveNumber);
  cmd.add_option("--superpixel-px", a.spec.classifier.superpixel_px, "SLIC region size at the 320-px working width")
      ->check(CLI::Range(4, 64));
  cmd.add_option("--panoramas", a.spec.panoramas,
                  "blender-data panorama names or EXR files (default: blender-data's eight)")->delimiter(',');
  cmd.add_option("--blender-world", a.spec.blender_world,
                  "A Blender world (scripts/make_blender_world.sh) whose tune photos, with their true emitters, to add");
  cmd.add_option("--blender-folds", a.spec.blender_folds, "Folds the Blender scenes are held out in (bench lights)")
      ->check(CLI::Range(2, 64));
  cmd.add_option("--blender-copies", a.spec.blender_copies, "Times each Blender photo's superpixels join the training set")
      ->check(CLI::Range(1, 100));
}

}  // namespace

void add_train_light_classifier_options(CLI::App& cmd, LightTrainingArgs& a) {
  cmd.add_option("-o,--output", a.output, "Model file to write (.yml.gz)")->required();
  add_spec_options(cmd, a);
}

int run_train_light_classifier_command(const LightTrainingArgs& a) {
  LightTrainingSpec spec = a.spec;
  if (spec.panoramas.empty()) spec.panoramas = default_training_panoramas();
  const inference::LightClassifier model = train_light_classifier(spec);
  model.save(a.output);
  std::cerr << "wrote " << a.output << "\n";
  return 0;
}

void add_bench_lights_options(CLI::App& cmd, LightTrainingArgs& a) {
  add_spec_options(cmd, a);
  cmd.add_option("--hold-out", a.spec.hold_out, "What is held out in turn: all, panoramas or blender (its folds)")
      ->check(CLI::IsMember({"all", "panoramas", "blender"}));
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_bench_lights_command(LightTrainingArgs a) {
  if (a.spec.panoramas.empty()) a.spec.panoramas = default_training_panoramas();
  a.spec.quiet = a.json_out;
  const json r = evaluate_light_classifier(a.spec);
  if (a.json_out) std::cout << r.dump(2) << std::endl;
  else std::cout << format_light_evaluation(r);
  return 0;
}

}  // namespace propcam::firmware
