#include "propcam/inference/scene_classifier.h"
#include "propcam/inference/data_dir.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <opencv2/ml.hpp>
#include <stdexcept>

#include "atomic_file.h"

namespace propcam::inference {
namespace {

constexpr int kFormatVersion = 1;
// A descriptor entry that never varies in training is scaled by 1, not 1/0.
constexpr double kMinStd = 1e-6;
// libsvm stops when the KKT violation falls below this; the iteration bound
// keeps a degenerate set from running on.
constexpr double kSvmEpsilon = 1e-3;
constexpr int kSvmMaxIterations = 100000;

void check_length(size_t n) {
  if (n != static_cast<size_t>(kAppearanceDescriptorLength))
    throw std::invalid_argument("scene classifier: descriptor length " + std::to_string(n) + ", expected " +
                                std::to_string(kAppearanceDescriptorLength));
}

}  // namespace

SceneClassifier::SceneClassifier() = default;
SceneClassifier::~SceneClassifier() = default;
SceneClassifier::SceneClassifier(SceneClassifier&&) noexcept = default;
SceneClassifier& SceneClassifier::operator=(SceneClassifier&&) noexcept = default;

SceneClassifier SceneClassifier::train(const SceneReferenceSet& refs, int exclude_group,
                                       const SceneClassifierOptions& options) {
  if (!(options.c > 0) || !std::isfinite(options.c)) throw std::invalid_argument("scene classifier: C must be positive");
  const int length = kAppearanceDescriptorLength;
  std::vector<size_t> used;
  int indoor = 0;
  for (size_t i = 0; i < refs.size(); ++i)
    if (refs.at(i).group != exclude_group) {
      used.push_back(i);
      indoor += refs.at(i).indoor ? 1 : 0;
    }
  const int n = static_cast<int>(used.size());
  if (indoor == 0 || indoor == n) throw std::invalid_argument("scene classifier: training needs indoor and outdoor references");

  // Standardise each entry (in double: 2k references of small values).
  SceneClassifier c;
  c.mean_.assign(length, 0.f);
  c.inv_std_.assign(length, 1.f);
  std::vector<double> sum(length, 0.0), sum_sq(length, 0.0);
  for (size_t i : used)
    for (int j = 0; j < length; ++j) {
      const double v = refs.at(i).descriptor[j];
      sum[j] += v;
      sum_sq[j] += v * v;
    }
  for (int j = 0; j < length; ++j) {
    const double mean = sum[j] / n;
    const double sd = std::sqrt(std::max(0.0, sum_sq[j] / n - mean * mean));
    c.mean_[j] = static_cast<float>(mean);
    c.inv_std_[j] = static_cast<float>(sd > kMinStd ? 1.0 / sd : 1.0);
  }
  cv::Mat samples(n, length, CV_32F), labels(n, 1, CV_32S);
  double all_sum = 0, all_sq = 0;
  for (int r = 0; r < n; ++r) {
    const SceneReference& ref = refs.at(used[r]);
    float* row = samples.ptr<float>(r);
    for (int j = 0; j < length; ++j) {
      row[j] = (ref.descriptor[j] - c.mean_[j]) * c.inv_std_[j];
      all_sum += row[j];
      all_sq += static_cast<double>(row[j]) * row[j];
    }
    labels.at<int>(r) = ref.indoor ? 1 : 0;
  }
  const double count = static_cast<double>(n) * length;
  const double variance = std::max(kMinStd, all_sq / count - (all_sum / count) * (all_sum / count));

  c.svm_ = cv::ml::SVM::create();
  c.svm_->setType(cv::ml::SVM::C_SVC);
  c.svm_->setKernel(cv::ml::SVM::RBF);
  c.svm_->setC(options.c);
  c.svm_->setGamma(1.0 / (length * variance));
  // Classes weigh equally: C of class k is scaled by n / (2 n_k).
  c.svm_->setClassWeights(cv::Mat(cv::Matx12d(n / (2.0 * (n - indoor)), n / (2.0 * indoor))));
  c.svm_->setTermCriteria({cv::TermCriteria::MAX_ITER + cv::TermCriteria::EPS, kSvmMaxIterations, kSvmEpsilon});
  c.svm_->train(cv::ml::TrainData::create(samples, cv::ml::ROW_SAMPLE, labels));
  // Orient the raw output so positive means indoor: a reference of each
  // class is checked, since OpenCV's sign depends on the label order.
  for (int r = 0; r < n; ++r) {
    const float label = c.svm_->predict(samples.row(r));
    const float raw = c.svm_->predict(samples.row(r), cv::noArray(), cv::ml::StatModel::RAW_OUTPUT);
    if (raw != 0) {
      c.sign_ = ((label > 0.5f) == (raw > 0)) ? 1.0 : -1.0;
      break;
    }
  }
  return c;
}

SceneClassifier SceneClassifier::load(const std::string& path) {
  if (!std::filesystem::exists(path)) throw std::runtime_error("scene classifier '" + path + "' does not exist");
  SceneClassifier c;
  try {
    cv::FileStorage fs(path, cv::FileStorage::READ);
    if (!fs.isOpened()) throw std::runtime_error("cannot be opened");
    if (static_cast<int>(fs["version"]) != kFormatVersion) throw std::runtime_error("has another format version");
    cv::Mat mean, inv_std;
    fs["mean"] >> mean;
    fs["inv_std"] >> inv_std;
    if (mean.total() != static_cast<size_t>(kAppearanceDescriptorLength) || inv_std.total() != mean.total() ||
        mean.type() != CV_32F || inv_std.type() != CV_32F)
      throw std::runtime_error("has no standardisation for " + std::to_string(kAppearanceDescriptorLength) + " entries");
    c.mean_.assign(mean.begin<float>(), mean.end<float>());
    c.inv_std_.assign(inv_std.begin<float>(), inv_std.end<float>());
    for (size_t j = 0; j < c.mean_.size(); ++j)
      if (!std::isfinite(c.mean_[j]) || !std::isfinite(c.inv_std_[j])) throw std::runtime_error("has a non-finite scale");
    c.sign_ = static_cast<double>(fs["sign"]) < 0 ? -1.0 : 1.0;
    c.svm_ = cv::ml::SVM::create();
    c.svm_->read(fs["svm"]);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("scene classifier '" + path + "' is not a model: " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("scene classifier '" + path + "' " + e.what());
  }
  if (!c.svm_->isTrained() || c.svm_->getVarCount() != kAppearanceDescriptorLength)
    throw std::runtime_error("scene classifier '" + path + "' is not a trained SVM over " +
                             std::to_string(kAppearanceDescriptorLength) + " entries");
  return c;
}

void SceneClassifier::save(const std::string& path) const {
  if (!svm_) throw std::runtime_error("scene classifier: nothing to save");
  write_atomically(path, [&](const std::string& tmp) {
    // The temporary name keeps the .gz that tells OpenCV to compress.
    cv::FileStorage fs(tmp, cv::FileStorage::WRITE);
    fs << "version" << kFormatVersion;
    fs << "mean" << cv::Mat(mean_, true);
    fs << "inv_std" << cv::Mat(inv_std_, true);
    fs << "sign" << sign_;
    fs << "svm" << "{";
    svm_->write(fs);
    fs << "}";
  });
}

double SceneClassifier::indoor_score(const std::vector<float>& descriptor) const {
  check_length(descriptor.size());
  if (!svm_) throw std::logic_error("scene classifier: not trained");
  cv::Mat row(1, kAppearanceDescriptorLength, CV_32F);
  for (int j = 0; j < kAppearanceDescriptorLength; ++j) {
    if (!std::isfinite(descriptor[j])) throw std::invalid_argument("scene classifier: non-finite descriptor");
    row.at<float>(j) = (descriptor[j] - mean_[j]) * inv_std_[j];
  }
  const double raw = svm_->predict(row, cv::noArray(), cv::ml::StatModel::RAW_OUTPUT);
  return sign_ * raw;
}

std::string default_scene_classifier_path() {
  if (const char* env = std::getenv("PROPCAM_SCENE_CLASSIFIER"); env && *env) return env;
  // Shipped beside the references it was trained on.
  return data_file("inference/scene_classifier.yml.gz").string();
}

}  // namespace propcam::inference
