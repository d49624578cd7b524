#include "propcam/inference/scene_class_knn.h"

#include <algorithm>
#include <numeric>
#include <stdexcept>

namespace propcam::inference {

KnnSceneClass classify_indoor_knn(const cv::Mat& photo_linear, const DepthDatabase& db, int k) {
  if (db.size() == 0) throw std::invalid_argument("k-NN scene class: empty database");
  if (k < 1) throw std::invalid_argument("k-NN scene class: k must be at least 1");
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3)
    throw std::invalid_argument("k-NN scene class: photo must be a non-empty CV_32FC3 image");
  const std::vector<float> query = appearance_descriptor(photo_linear);
  std::vector<double> distance(db.size());
  for (size_t i = 0; i < db.size(); ++i) {
    const std::vector<float>& d = db.at(i).descriptor;
    if (d.size() != query.size()) throw std::invalid_argument("k-NN scene class: database descriptor length differs");
    double sum = 0;
    for (size_t j = 0; j < d.size(); ++j) sum += (double(d[j]) - query[j]) * (double(d[j]) - query[j]);
    distance[i] = sum;
  }
  std::vector<size_t> order(db.size());
  std::iota(order.begin(), order.end(), size_t{0});
  const int used = static_cast<int>(std::min<size_t>(static_cast<size_t>(k), db.size()));
  std::partial_sort(order.begin(), order.begin() + used, order.end(), [&](size_t a, size_t b) {
    return distance[a] < distance[b] || (distance[a] == distance[b] && a < b);
  });
  int indoor_votes = 0;
  for (int i = 0; i < used; ++i) indoor_votes += db.at(order[i]).indoor ? 1 : 0;
  KnnSceneClass out;
  out.k = used;
  out.indoor_share = static_cast<double>(indoor_votes) / used;
  // An even k can tie: indoor then wins, the class that asks nothing of the sky.
  out.indoor = 2 * indoor_votes >= used;
  return out;
}

}  // namespace propcam::inference
