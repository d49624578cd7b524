#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>

#include "propcam/inference/depth_transfer.h"
#include "propcam/render/path_tracer.h"
#include "room_truth.h"

namespace propcam::inference {
namespace {

// A small database of flat-shaded (albedo) generator rooms: cheap, exact depth.
struct Tiny {
  DepthDatabase db;
  std::vector<cv::Mat> photos;
  std::vector<render::PinholeCamera> cameras;
};

Tiny tiny_database() {
  Tiny t;
  for (uint64_t seed : {11, 12, 13, 14}) {
    const RoomTruth r = room_truth(seed, 96, 72);
    render::Scene scene;
    scene.add_mesh(r.room.room, render::Layer::Background);
    scene.commit();
    const cv::Mat photo = render::render_primary_buffers(scene, r.room.camera, false).albedo;
    DepthExample e;
    e.descriptor = appearance_descriptor(photo);
    cv::resize(r.depth, e.depth, cv::Size(48, 36), 0, 0, cv::INTER_NEAREST);
    e.depth /= r.room.camera.center_world.y();
    e.fx_over_width = r.room.camera.fx / r.room.camera.width;
    e.horizon = horizon_frame(r.room.camera.R_world_from_cam);
    t.db.add(e);
    t.photos.push_back(photo);
    t.cameras.push_back(r.room.camera);
  }
  return t;
}

TEST(AppearanceDescriptor, FixedLengthFiniteDeterministicAndUnit) {
  const RoomTruth r = room_truth(2, 96, 72);
  cv::Mat photo;
  cv::merge(std::vector<cv::Mat>{r.depth * 0.1, r.depth * 0.05, r.depth * 0.02}, photo);
  const auto a = appearance_descriptor(photo), b = appearance_descriptor(photo);
  ASSERT_EQ(a.size(), static_cast<size_t>(kAppearanceDescriptorLength));
  EXPECT_EQ(a, b);
  double n = 0;
  for (float v : a) {
    EXPECT_TRUE(std::isfinite(v));
    n += v * v;
  }
  EXPECT_NEAR(n, 1.0, 1e-4);
}

TEST(DepthTransfer, AnExampleFindsItselfAndItsOwnDepth) {
  const Tiny t = tiny_database();
  const render::PinholeCamera& cam = t.cameras[2];
  const TransferredDepth d = transfer_depth(t.photos[2], cam, cam.center_world.y(), true, t.db, cv::Size(48, 36), {3, true, true});
  ASSERT_EQ(d.indices.size(), 3u);
  EXPECT_EQ(d.indices[0], 2u);
  double sum = 0;
  for (double w : d.weights) sum += w;
  EXPECT_NEAR(sum, 1.0, 1e-9);
  EXPECT_GT(d.weights[0], d.weights[2]);
  for (const auto& c : d.candidates) {
    EXPECT_EQ(c.size(), cv::Size(48, 36));
    EXPECT_TRUE(cv::checkRange(c, true, nullptr, 1e-6, 1e5));
  }
  // The warp to its own camera is the identity: its own depth comes back.
  const cv::Mat own = t.db.at(2).depth * cam.center_world.y();
  cv::Mat rel;
  cv::absdiff(d.candidates[0], own, rel);
  cv::divide(rel, own, rel);
  EXPECT_LT(cv::mean(rel)[0], 0.02);
  EXPECT_EQ(d.report.stage, "depth_transfer");
}

TEST(DepthDatabase, SaveLoadRoundTripAndTheCommittedDatabase) {
  const Tiny t = tiny_database();
  const std::string path = ::testing::TempDir() + "/depth_db_roundtrip.bin";
  t.db.save(path);
  const DepthDatabase back = DepthDatabase::load(path);
  ASSERT_EQ(back.size(), t.db.size());
  EXPECT_EQ(back.at(1).descriptor, t.db.at(1).descriptor);
  cv::Mat rel;
  cv::absdiff(back.at(1).depth, t.db.at(1).depth, rel);
  cv::divide(rel, t.db.at(1).depth, rel);
  double worst = 0;
  cv::minMaxLoc(rel, nullptr, &worst);
  EXPECT_LT(worst, 1e-3);  // 16-bit log depth
  EXPECT_NEAR(back.at(1).horizon.horizon, t.db.at(1).horizon.horizon, 1e-12);
  const DepthDatabase shipped = DepthDatabase::load(default_depth_database_path());
  EXPECT_GE(shipped.size(), 100u);
}

}  // namespace
}  // namespace propcam::inference
