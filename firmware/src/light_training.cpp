#include "light_training.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "progress.h"
#include "propcam/capture/image_file.h"
#include "real_views.h"

namespace propcam::firmware {
namespace {

using nlohmann::json;

struct Panorama {
  std::string name;
  std::vector<inference::LabelledView> views;
  inference::LabelledFeatures features;  // of all its views, computed once
};

std::vector<Panorama> load_views(const LightTrainingSpec& spec, Progress& progress) {
  std::vector<Panorama> out;
  for (const auto& name : spec.panoramas) {
    progress.stage("light classifier: views of " + name);
    // A name is one of blender-data's panoramas; anything with a path or an
    // extension is a file (e.g. scripts/fetch_pmndrs_hdri.sh's).
    const bool is_file = name.find('/') != std::string::npos || name.find('.') != std::string::npos;
    const cv::Mat latlong = capture::read_image_float(is_file ? name : panorama_path(name));
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

// Every source superpixel and every negative_stride-th other one.
inference::LabelledFeatures training_set(const std::vector<const Panorama*>& panoramas, const LightTrainingSpec& spec) {
  inference::LabelledFeatures all;
  std::vector<int> labels;
  int negatives = 0;
  for (const Panorama* p : panoramas) {
    const inference::LabelledFeatures& f = p->features;
    for (int r = 0; r < f.features.rows; ++r) {
      const int label = f.labels.at<int>(r);
      if (label == 0 && negatives++ % std::max(1, spec.negative_stride) != 0) continue;
      all.features.push_back(f.features.row(r));
      labels.push_back(label);
    }
  }
  all.labels = cv::Mat(labels, true).reshape(1, static_cast<int>(labels.size()));
  return all;
}

struct Counts {
  double tp = 0, fp = 0, fn = 0, ms = 0;
  int views = 0;
  json summary() const {
    const double precision = tp + fp > 0 ? tp / (tp + fp) : 1.0, recall = tp + fn > 0 ? tp / (tp + fn) : 1.0;
    return {{"precision", precision},
            {"recall", recall},
            {"f1", precision + recall > 0 ? 2 * precision * recall / (precision + recall) : 0.0},
            {"ms_per_view", views ? ms / views : 0.0},
            {"source_pixels", tp + fn}};
  }
};

void count(const cv::Mat& predicted, const cv::Mat& truth, Counts& c) {
  c.tp += cv::countNonZero(predicted & truth);
  c.fp += cv::countNonZero(predicted & ~truth);
  c.fn += cv::countNonZero(~predicted & truth);
}

double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

std::vector<std::string> default_training_panoramas() {
  return {"city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"};
}

inference::LightClassifier train_light_classifier(const LightTrainingSpec& spec) {
  Progress progress(spec.quiet);
  const std::vector<Panorama> panoramas = load_views(spec, progress);
  std::vector<const Panorama*> all;
  for (const auto& p : panoramas) all.push_back(&p);
  progress.stage("light classifier: features");
  const inference::LabelledFeatures set = training_set(all, spec);
  progress.stage("light classifier: training on " + std::to_string(set.features.rows) + " superpixels");
  return inference::LightClassifier::train(set.features, set.labels, spec.trees, spec.depth);
}

json evaluate_light_classifier(const LightTrainingSpec& spec) {
  Progress progress(spec.quiet);
  const std::vector<Panorama> panoramas = load_views(spec, progress);
  json held_out = json::array();
  Counts classifier_total, threshold_total, both_total;
  for (size_t h = 0; h < panoramas.size(); ++h) {
    std::vector<const Panorama*> others;
    for (size_t i = 0; i < panoramas.size(); ++i)
      if (i != h) others.push_back(&panoramas[i]);
    progress.stage("light classifier: holding out " + panoramas[h].name);
    const inference::LabelledFeatures set = training_set(others, spec);
    const int positives = cv::countNonZero(set.labels);
    if (positives == 0 || positives == set.labels.rows) {
      held_out.push_back({{"panorama", panoramas[h].name}, {"skipped", "the other panoramas' views hold one class only"}});
      continue;
    }
    const inference::LightClassifier model = inference::LightClassifier::train(set.features, set.labels, spec.trees, spec.depth);
    Counts classifier, threshold, both;
    for (const auto& v : panoramas[h].views) {
      auto t = std::chrono::steady_clock::now();
      const cv::Mat by_classifier = model.source_mask(v.photo_linear, spec.classifier);
      classifier.ms += ms_since(t);
      count(by_classifier, v.source_mask, classifier);
      ++classifier.views;
      t = std::chrono::steady_clock::now();
      const cv::Mat by_threshold = inference::threshold_source_mask(v.photo_linear);
      threshold.ms += ms_since(t);
      count(by_threshold, v.source_mask, threshold);
      ++threshold.views;
      // What the lighting stage uses: bright pixels of source superpixels.
      count(by_classifier & by_threshold, v.source_mask, both);
      both.ms = classifier.ms + threshold.ms;
      ++both.views;
    }
    for (auto [total, part] : {std::pair{&classifier_total, &classifier}, std::pair{&threshold_total, &threshold},
                               std::pair{&both_total, &both}}) {
      total->tp += part->tp, total->fp += part->fp, total->fn += part->fn, total->ms += part->ms;
      total->views += part->views;
    }
    held_out.push_back({{"panorama", panoramas[h].name},
                        {"views", panoramas[h].views.size()},
                        {"training_superpixels", set.features.rows},
                        {"classifier", classifier.summary()},
                        {"threshold", threshold.summary()},
                        {"both", both.summary()}});
  }
  return {{"views_per_panorama", spec.views_per_turn * static_cast<int>(spec.pitches_deg.size())},
          {"size", {spec.width, spec.height}},
          {"held_out", held_out},
          {"all", {{"classifier", classifier_total.summary()}, {"threshold", threshold_total.summary()},
                   {"both", both_total.summary()}}}};
}

std::string format_light_evaluation(const json& r) {
  std::ostringstream out;
  char line[256];
  out << "Visible light sources, leave one panorama out (" << r["views_per_panorama"] << " views each, "
      << r["size"][0] << "x" << r["size"][1] << "): pixel precision / recall / F1, ms per view\n";
  std::snprintf(line, sizeof line, "  %-10s %8s   %-24s %-24s %-24s\n", "held out", "sources", "classifier", "threshold",
                "both (used)");
  out << line;
  const auto row = [&](const std::string& name, const json& c, const json& t, const json& u) {
    char a[64], b[64], d[64];
    std::snprintf(a, sizeof a, "%.2f / %.2f / %.2f  %5.1f", c["precision"].get<double>(), c["recall"].get<double>(),
                  c["f1"].get<double>(), c["ms_per_view"].get<double>());
    std::snprintf(b, sizeof b, "%.2f / %.2f / %.2f  %5.1f", t["precision"].get<double>(), t["recall"].get<double>(),
                  t["f1"].get<double>(), t["ms_per_view"].get<double>());
    std::snprintf(d, sizeof d, "%.2f / %.2f / %.2f  %5.1f", u["precision"].get<double>(), u["recall"].get<double>(),
                  u["f1"].get<double>(), u["ms_per_view"].get<double>());
    std::snprintf(line, sizeof line, "  %-10s %8.0f   %-24s %-24s %-24s\n", name.c_str(), c["source_pixels"].get<double>(),
                  a, b, d);
    out << line;
  };
  for (const auto& h : r["held_out"]) {
    if (h.contains("skipped")) {
      out << "  " << h["panorama"].get<std::string>() << ": skipped (" << h["skipped"].get<std::string>() << ")\n";
      continue;
    }
    row(h["panorama"], h["classifier"], h["threshold"], h["both"]);
  }
  row("all", r["all"]["classifier"], r["all"]["threshold"], r["all"]["both"]);
  return out.str();
}

namespace {

void add_spec_options(CLI::App* cmd, LightTrainingArgs& a) {
  cmd->add_option("--views-per-turn", a.spec.views_per_turn, "Views per full turn of each panorama")->check(CLI::PositiveNumber);
  cmd->add_option("--trees", a.spec.trees, "Trees in the forest")->check(CLI::PositiveNumber);
  cmd->add_option("--negative-stride", a.spec.negative_stride, "Keep every n-th non-source superpixel")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--superpixel-px", a.spec.classifier.superpixel_px, "SLIC region size at the 320-px working width")
      ->check(CLI::Range(4, 64));
  cmd->add_option("--panoramas", a.spec.panoramas,
                  "blender-data panorama names or EXR files (default: blender-data's eight)")->delimiter(',');
}

}  // namespace

CLI::App* add_train_light_classifier_command(CLI::App& app, LightTrainingArgs& a) {
  auto* cmd = app.add_subcommand("train-light-classifier",
                                 "Train the visible-light classifier on HDR panorama views (scripts/train_light_classifier.sh)");
  cmd->add_option("-o,--output", a.output, "Model file to write (.yml.gz)")->required();
  add_spec_options(cmd, a);
  return cmd;
}

int run_train_light_classifier_command(const LightTrainingArgs& a) {
  LightTrainingSpec spec = a.spec;
  if (spec.panoramas.empty()) spec.panoramas = default_training_panoramas();
  const inference::LightClassifier model = train_light_classifier(spec);
  model.save(a.output);
  std::cerr << "wrote " << a.output << "\n";
  return 0;
}

CLI::App* add_bench_lights_command(CLI::App& bench, LightTrainingArgs& a) {
  auto* cmd = bench.add_subcommand("lights", "The visible-light classifier against thresholding, leave one panorama out");
  add_spec_options(cmd, a);
  cmd->add_flag("--json", a.json_out, "Machine-readable output");
  return cmd;
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
