// What the appliance's worker threads (camera, jobs) publish for the UI
// thread, under one mutex. Private to appliance*.cpp.
#pragma once

#include <chrono>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "appliance/appliance_camera.h"
#include "appliance/appliance_shot.h"
#include "propcam/ui_fb/screens.h"

namespace propcam::firmware {

// Before the first render, this share of the image is taken as what the prop affects.
inline constexpr double kDefaultAffectedShare = 0.5;

struct ApplianceShared {
  std::mutex mutex;
  StillResult still;
  std::shared_ptr<const Analysis> analysis;
  std::vector<Spot> spots;
  std::vector<ui_fb::StageLine> stages;
  std::chrono::steady_clock::time_point analysis_start;
  std::shared_ptr<const RenderSnapshot> render;
  double affected_share = kDefaultAffectedShare;
  std::string export_text;
  std::optional<bool> export_ok;
  std::chrono::steady_clock::time_point export_start;
  std::vector<std::filesystem::path> exported;
  int spooled = 0;
  int spool_waiting = 0;
  std::string usb_message = "USB: looking";
  std::optional<std::vector<PropEntry>> new_props;  // the stick's props changed
  std::filesystem::path new_props_root;
  // The placement preview: what is asked for (latest wins), what is drawn,
  // and its world, which only the worker touches.
  std::string preview_wanted, preview_key;
  Spot preview_spot;
  PropEntry preview_prop;
  cv::Mat preview;
  std::shared_ptr<PlacementPreview> preview_world;
  bool changed = false;
};

}  // namespace propcam::firmware
