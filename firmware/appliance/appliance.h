// The appliance: buttons in, screen out, and the pipeline in between. One UI
// thread runs the loop (button events and worker results into the state
// machine, its actions out to the camera and the job runner, the screen
// redrawn from the model); the camera and the jobs have their own threads.
#pragma once

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "appliance/appliance_camera.h"
#include "appliance/appliance_jobs.h"
#include "appliance/appliance_shot.h"
#include "appliance/appliance_state.h"
#include "common/board_config.h"
#include "propcam/ui_fb/buttons.h"
#include "propcam/ui_fb/console.h"
#include "propcam/ui_fb/display.h"
#include "propcam/ui_fb/screens.h"
#include "storage/storage_export.h"

namespace propcam::firmware {

struct ApplianceShared;

inline double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

struct ApplianceOptions {
  BoardConfig board;
  std::filesystem::path script;         // replaces the board's button script (script boards)
  std::filesystem::path snapshots_dir;  // a PNG of the screen after every state change, and at the end
  std::filesystem::path usb_dir;        // the stick (boards whose storage.usb is "runtime")
  std::filesystem::path spool_dir;      // (storage.spool_dir "runtime": default <data_dir>/spool)
  std::filesystem::path data_dir;       // (storage.data_dir "runtime": default a folder under $TMPDIR)
  std::string daemon_socket;            // take frames from propcamd instead of opening the camera
  int render_threads = 0;               // 0: all cores
  // Script boards end when the script has played (and its last await passed).
  bool exit_at_script_end = true;
};

// What one run did, for the CLI's summary and the tests.
struct ApplianceRunSummary {
  int state_changes = 0;
  std::vector<std::filesystem::path> snapshots;
  std::vector<std::filesystem::path> exported;  // files written to the stick
  int spooled = 0;
  std::string final_state;
  std::vector<std::string> props;  // the carousel at the end (presets, then the stick's)
  int rejected_inputs = 0;
  // From each accepted button event (debounced) to the screen that shows its
  // effect presented, milliseconds.
  std::vector<double> input_to_screen_ms;
};

// A scripted session cannot go on (the appliance faulted while the script
// waited for another state); the run ends with this error.
struct ScriptAborted : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Appliance {
 public:
  // Opens the display, the buttons, the camera and the storage; throws
  // std::runtime_error saying which one cannot be used.
  explicit Appliance(ApplianceOptions options);
  ~Appliance();
  Appliance(const Appliance&) = delete;
  Appliance& operator=(const Appliance&) = delete;

  // Runs until the script ends (script boards) or `stop` is raised (SIGTERM).
  ApplianceRunSummary run(const std::atomic<bool>& stop);

 private:
  using Shared = ApplianceShared;  // what the worker threads publish for the screen

  void handle_button(const ui_fb::ButtonEvent& event);
  void handle(const appliance::Event& event);
  void perform(const appliance::Action& action);
  void start_analysis(appliance::JobId job);
  void start_render(appliance::JobId job, int prop_index);
  void start_export(appliance::JobId job);
  void request_preview();
  std::string preview_key() const;  // the prop and spot the placement screen shows
  void on_state_changed();
  void refresh_adjusted();
  void poll_usb();
  ui_fb::ScreenView build_view() const;
  void fill_placement(ui_fb::ScreenView& view, const Analysis* analysis, const cv::Mat& preview,
                      const std::string& prop_name) const;
  void draw_and_present();
  void take_snapshot(const std::string& label);

  ApplianceOptions options_;
  // The VT under a device display, in graphics mode while the UI is up.
  std::unique_ptr<ui_fb::ConsoleTakeover> console_;
  std::unique_ptr<ui_fb::Display> display_;
  std::unique_ptr<ui_fb::ButtonInput> buttons_;
  ui_fb::ScriptButtonInput* script_ = nullptr;  // buttons_ when it is a script
  std::vector<PropEntry> props_;
  mutable std::vector<std::optional<render::Mesh>> prop_meshes_;  // loaded on first use, for footprints
  appliance::ApplianceStateMachine machine_;
  EventQueue events_;
  std::shared_ptr<Shared> shared_;
  std::unique_ptr<ThroughputModel> throughput_;
  std::unique_ptr<Exporter> exporter_;
  std::unique_ptr<ApplianceCamera> camera_;
  std::unique_ptr<JobRunner> jobs_;  // last: destroyed first, while what it uses still exists

  // UI-thread state.
  std::vector<Spot> spots_;
  int spot_index_ = 0;
  appliance::JobId render_job_ = 0;
  // Ids of the jobs the state machine never sees (preview, stick poll), far
  // above the machine's own so the two never meet.
  appliance::JobId next_internal_job_ = appliance::JobId{1} << 62;
  std::shared_ptr<std::atomic<bool>> keep_render_;  // FinishRender: the stopped render is kept
  cv::Mat adjusted_;        // CV_32FC3 linear sRGB: the composite as shown in Adjusting/Exporting
  std::shared_ptr<const RenderSnapshot> adjusted_from_;
  std::array<int, appliance::kRelightParamCount> adjusted_steps_{};
  bool ok_held_long_ = false;
  std::int64_t input_pending_since_ns_ = 0;  // an accepted input not yet on screen
  std::filesystem::path props_usb_root_;       // the stick whose props are listed
  std::filesystem::path thumbnail_dir_;
  bool dirty_ = true;
  mutable std::uint64_t shown_frame_ = 0;
  std::int64_t last_present_ns_ = 0;
  std::int64_t last_usb_poll_ns_ = 0;
  std::string usb_status_;
  appliance::State shown_state_ = appliance::State::Viewfinder;
  appliance::PlacingStep shown_step_ = appliance::PlacingStep::Prop;
  ApplianceRunSummary summary_;
  std::unique_ptr<ui_fb::Canvas> canvas_;
};

// The board's display as configured (file displays write into `snapshot_dir`
// when given, else the board's path, else, for "runtime", `data_dir`).
std::unique_ptr<ui_fb::Display> open_display(const DisplayConfig& config, const std::filesystem::path& snapshot_dir,
                                             const std::filesystem::path& data_dir);
// The board's buttons; `script` replaces a script board's file.
std::unique_ptr<ui_fb::ButtonInput> open_buttons(const ButtonsConfig& config, const std::filesystem::path& script);

}  // namespace propcam::firmware
