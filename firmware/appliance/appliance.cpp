#include "appliance/appliance.h"
#include "appliance/appliance_shared.h"

#include <systemd/sd-daemon.h>

#include <chrono>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>
#include <thread>

#include "propcam/capture/image_file.h"
#include "propcam/inference/infer.h"

namespace propcam::firmware {
namespace fs = std::filesystem;
using namespace appliance;

namespace {

// The UI loop waits at most this long for a button, then looks at the workers.
constexpr std::chrono::milliseconds kLoopPoll{10};
// A Repeat older than this when the loop gets to it is dropped: the user let
// go long ago and would see the cursor run on.
constexpr std::int64_t kStaleRepeatNs = 150'000'000;
// Viewfinder refresh: a device display as often as frames come; a file
// display (a PNG per present) a few times a second.
constexpr std::int64_t kDeviceFrameIntervalNs = 33'000'000;
constexpr std::int64_t kFileFrameIntervalNs = 250'000'000;
constexpr std::int64_t kUsbPollIntervalNs = 2'000'000'000;
// The first snapshot waits this long for the camera's first frame.
constexpr std::int64_t kFirstFrameWaitNs = 3'000'000'000;
constexpr int kMaxSpots = 12;
constexpr int kThumbnailSize = 128;
// The worker runs below the UI thread's priority.
constexpr int kWorkerNiceness = 5;

std::int64_t now_ns() { return ui_fb::monotonic_now_ns(); }

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

fs::path resolve_location(const StorageLocation& location, const fs::path& runtime, const fs::path& fallback,
                          const char* what) {
  if (!runtime.empty()) return runtime;
  if (location.kind == StorageLocation::Kind::Path) return location.path;
  if (!fallback.empty()) return fallback;
  throw std::invalid_argument(std::string("the board's ") + what + " is given at run time: pass it on the command line");
}

}  // namespace


// ------------------------------------------------------------------ devices

std::unique_ptr<ui_fb::Display> open_display(const DisplayConfig& config, const fs::path& snapshot_dir,
                                             const fs::path& data_dir) {
  switch (config.backend) {
    case DisplayBackend::File: {
      ui_fb::FileDisplayOptions o;
      o.size = {config.width, config.height};
      const fs::path folder = !snapshot_dir.empty() ? snapshot_dir : !config.device.empty() ? config.device : data_dir;
      o.snapshot_path = folder / "screen.png";
      return std::make_unique<ui_fb::FileDisplay>(o);
    }
    case DisplayBackend::Fbdev:
      return std::make_unique<ui_fb::FbdevDisplay>(config.device);
    case DisplayBackend::Drm: {
      ui_fb::DrmDisplayOptions o;
      o.card = config.device;
      return std::make_unique<ui_fb::DrmDisplay>(o);
    }
  }
  throw std::invalid_argument("unknown display backend");
}

std::unique_ptr<ui_fb::ButtonInput> open_buttons(const ButtonsConfig& config, const fs::path& script) {
  ui_fb::DebounceOptions debounce;
  debounce.debounce_ns = std::int64_t{config.debounce_ms} * 1'000'000;
  debounce.long_press_ns = std::int64_t{config.long_press_ms} * 1'000'000;
  switch (config.backend) {
    case ButtonBackend::Script: {
      const fs::path file = script.empty() ? config.script : script;
      return std::make_unique<ui_fb::ScriptButtonInput>(ui_fb::ButtonScript::load(file), debounce);
    }
    case ButtonBackend::Gpiod: {
      ui_fb::GpiodButtonOptions o;
      o.chip = config.gpio_chip;
      o.lines = config.gpio_lines;
      o.debounce = debounce;
      return std::make_unique<ui_fb::GpiodButtonInput>(o);
    }
    case ButtonBackend::Evdev: {
      ui_fb::EvdevButtonOptions o;
      o.keys.clear();
      for (const auto& [button, key] : config.evdev_keys) o.keys[key] = button;
      o.debounce = debounce;
      o.grab = true;  // the keys are the appliance's, not the console's
      const fs::path device = config.evdev_device.empty()
                                  ? ui_fb::EvdevButtonInput::find_device(config.evdev_device_name)
                                  : config.evdev_device;
      return std::make_unique<ui_fb::EvdevButtonInput>(device, o);
    }
  }
  throw std::invalid_argument("unknown button backend");
}

// ------------------------------------------------------------------ set-up

Appliance::Appliance(ApplianceOptions options)
    : options_(std::move(options)), machine_(1), shared_(std::make_shared<Shared>()) {
  const BoardConfig& board = options_.board;
  const fs::path data_dir = resolve_location(board.storage.data_dir, options_.data_dir,
                                             fs::temp_directory_path() / "propcam", "data folder");
  const fs::path spool_dir = resolve_location(board.storage.spool_dir, options_.spool_dir, data_dir / "spool",
                                              "spool folder");
  fs::create_directories(data_dir);
  if (!options_.snapshots_dir.empty()) fs::create_directories(options_.snapshots_dir);
  display_ = open_display(board.display, options_.snapshots_dir, data_dir);
  if (board.display.backend != DisplayBackend::File) {
    console_ = std::make_unique<ui_fb::ConsoleTakeover>();
    spdlog::info("appliance: console {}", console_->taken() ? "in graphics mode (" + console_->description() + ")"
                                                             : console_->description());
  }
  canvas_ = std::make_unique<ui_fb::Canvas>(display_->size());
  std::optional<fs::path> usb_runtime;
  if (!options_.usb_dir.empty()) usb_runtime = options_.usb_dir;
  exporter_ = std::make_unique<Exporter>(spool_dir, UsbTarget::from_config(board.storage.usb, usb_runtime));
  throughput_ = std::make_unique<ThroughputModel>(data_dir / "throughput.json");

  thumbnail_dir_ = data_dir / "thumbnails";
  const UsbStatus usb = exporter_->usb_status();
  props_usb_root_ = usb.usable() ? usb.root : fs::path();
  props_ = list_props(thumbnail_dir_, props_usb_root_, kThumbnailSize);
  prop_meshes_.resize(props_.size());
  machine_ = ApplianceStateMachine(static_cast<int>(props_.size()));

  ApplianceCameraOptions camera;
  // Through propcamd the daemon's camera is used (it was started with the board's).
  camera.camera_id = options_.daemon_socket.empty() ? board.camera.id : std::string();
  camera.daemon_socket = options_.daemon_socket;
  const auto format = capture::pixel_format_from_string(board.camera.viewfinder_format);
  if (!format) throw std::invalid_argument("the board's viewfinder format " + board.camera.viewfinder_format + " is unknown");
  camera.viewfinder.pixel_format = *format;
  camera.viewfinder.width = board.camera.viewfinder_size.width;
  camera.viewfinder.height = board.camera.viewfinder_size.height;
  camera.viewfinder.fps = board.camera.viewfinder_fps;
  if (board.camera.still_size.width > 0) {
    capture::StreamConfig still = camera.viewfinder;
    still.width = board.camera.still_size.width;
    still.height = board.camera.still_size.height;
    camera.still = still;
  }
  std::shared_ptr<Shared> shared = shared_;
  camera_ = std::make_unique<ApplianceCamera>(camera, [this, shared](StillResult still) {
    const JobId job = still.request;
    const bool ok = still.error.empty();
    std::string error = still.error;
    {
      std::lock_guard lock(shared->mutex);
      shared->still = std::move(still);
      shared->changed = true;
    }
    if (ok) events_.push(CaptureDone{job});
    else events_.push(CaptureFailed{job, error});
  });
  jobs_ = std::make_unique<JobRunner>(kWorkerNiceness);
  // Last: a script's clock starts here, after the slow set-up (thumbnails).
  buttons_ = open_buttons(board.buttons, options_.script);
  script_ = dynamic_cast<ui_fb::ScriptButtonInput*>(buttons_.get());
  spdlog::info("appliance: board {}, display {}, buttons {}, camera {}, {} props", board.name, display_->name(),
               buttons_->name(), camera_->name(), props_.size());
}

Appliance::~Appliance() { jobs_.reset(); }

// ------------------------------------------------------------------ the loop

ApplianceRunSummary Appliance::run(const std::atomic<bool>& stop) {
  sd_notify(0, "READY=1\nSTATUS=viewfinder");
  std::uint64_t watchdog_usec = 0;
  const bool watchdog = sd_watchdog_enabled(0, &watchdog_usec) > 0 && watchdog_usec > 0;
  std::int64_t last_watchdog_ns = now_ns();
  // The first screen: the viewfinder once the camera's first frame is in
  // (or it is clearly not coming).
  const std::int64_t start_ns = now_ns();
  while (!stop && camera_->latest().number == 0 && now_ns() - start_ns < kFirstFrameWaitNs)
    std::this_thread::sleep_for(kLoopPoll);
  draw_and_present();
  take_snapshot(lower(to_string(machine_.state())));
  if (script_) script_->notify_state(lower(to_string(machine_.state())));
  poll_usb();

  while (!stop) {
    std::optional<ui_fb::ButtonEvent> button;
    try {
      button = buttons_->next_event(kLoopPoll);
    } catch (const ui_fb::ButtonScriptError& e) {
      spdlog::error("button script: {}", e.what());
      take_snapshot("script-error");
      throw;
    }
    if (button) handle_button(*button);
    while (auto event = events_.pop()) handle(*event);
    std::optional<std::vector<PropEntry>> new_props;
    {
      std::lock_guard lock(shared_->mutex);
      if (shared_->changed) dirty_ = true;
      shared_->changed = false;
      new_props.swap(shared_->new_props);
      if (new_props) props_usb_root_ = shared_->new_props_root;
    }
    if (new_props && !new_props->empty()) {
      props_ = std::move(*new_props);
      prop_meshes_.assign(props_.size(), std::nullopt);
      handle(PropsChanged{static_cast<int>(props_.size())});
    }
    const std::int64_t now = now_ns();
    if (now - last_usb_poll_ns_ >= kUsbPollIntervalNs) poll_usb();
    const bool file_display = dynamic_cast<ui_fb::FileDisplay*>(display_.get()) != nullptr;
    const std::int64_t frame_interval = file_display ? kFileFrameIntervalNs : kDeviceFrameIntervalNs;
    const bool live = machine_.state() == State::Viewfinder;
    const bool new_frame = live && camera_->latest().number != shown_frame_;
    if (dirty_ || (new_frame && now - last_present_ns_ >= frame_interval)) draw_and_present();
    if (watchdog && now - last_watchdog_ns >= static_cast<std::int64_t>(watchdog_usec) * 1000 / 2) {
      sd_notify(0, "WATCHDOG=1");
      last_watchdog_ns = now;
    }
    if (script_ && options_.exit_at_script_end && script_->end_of_script()) break;
  }
  sd_notify(0, "STOPPING=1");
  draw_and_present();
  take_snapshot("end");
  summary_.final_state = lower(to_string(machine_.state()));
  summary_.props.clear();
  for (const PropEntry& p : props_) summary_.props.push_back(p.name);
  {
    std::lock_guard lock(shared_->mutex);
    summary_.exported = shared_->exported;
    summary_.spooled = shared_->spooled;
  }
  return summary_;
}

void Appliance::handle_button(const ui_fb::ButtonEvent& event) {
  using Kind = ui_fb::ButtonEvent::Kind;
  std::optional<Input> input;
  switch (event.kind) {
    case Kind::Press:
      if (event.button == ui_fb::Button::Ok) ok_held_long_ = false;  // OK acts on release: it may become long
      else if (event.button == ui_fb::Button::Shoot) input = Input::Shoot;
      else if (event.button == ui_fb::Button::Next) input = Input::Next;
      else if (event.button == ui_fb::Button::Prev) input = Input::Prev;
      else if (event.button == ui_fb::Button::Back) input = Input::Back;
      break;
    case Kind::LongPress:
      if (event.button == ui_fb::Button::Ok) {
        ok_held_long_ = true;
        input = Input::OkLong;
      }
      break;
    case Kind::Release:
      if (event.button == ui_fb::Button::Ok && !ok_held_long_) input = Input::Ok;
      break;
    case Kind::Repeat:
      if (now_ns() - event.time_ns > kStaleRepeatNs) break;
      if (event.button == ui_fb::Button::Next) input = Input::Next;
      if (event.button == ui_fb::Button::Prev) input = Input::Prev;
      break;
  }
  if (!input) return;
  const int rejected = summary_.rejected_inputs;
  // Set before handling: a state change presents its screen at once.
  if (input_pending_since_ns_ == 0) input_pending_since_ns_ = event.time_ns;
  handle(*input);
  if (summary_.rejected_inputs != rejected) input_pending_since_ns_ = 0;  // nothing to show
}

void Appliance::handle(const Event& event) {
  try {
    const Outcome outcome = machine_.handle(event);
    if (!outcome.accepted()) {
      if (std::holds_alternative<Input>(event)) ++summary_.rejected_inputs;
      spdlog::debug("rejected {}: {}", describe(event), outcome.rejection);
      return;
    }
    spdlog::debug("{} -> {}", describe(event), to_string(machine_.state()));
    if (std::holds_alternative<AnalysisDone>(event)) {
      std::lock_guard lock(shared_->mutex);
      spots_ = shared_->spots;
      spot_index_ = 0;
    }
    for (const Action& action : outcome.actions) perform(action);
    dirty_ = true;
    if (machine_.state() != shown_state_ ||
        (machine_.state() == State::Placing && machine_.model().placing_step != shown_step_))
      on_state_changed();
  } catch (const ScriptAborted&) {
    throw;
  } catch (const std::exception& e) {
    spdlog::error("{}: {}", describe(event), e.what());
    if (machine_.state() != State::Fault) handle(Failure{e.what()});
  }
}

void Appliance::on_state_changed() {
  shown_state_ = machine_.state();
  shown_step_ = machine_.model().placing_step;
  ++summary_.state_changes;
  std::string label = lower(to_string(shown_state_));
  if (shown_state_ == State::Placing) label += std::string("-") + lower(to_string(shown_step_));
  sd_notify(0, ("STATUS=" + label).c_str());
  if (shown_state_ == State::Adjusting || shown_state_ == State::Exporting) refresh_adjusted();
  if (shown_state_ == State::Placing && shown_step_ == PlacingStep::Spot) request_preview();
  draw_and_present();
  take_snapshot(label);
  // Last, so a script waiting for this state sees its screen drawn first.
  if (script_) script_->notify_state(lower(to_string(shown_state_)));
  // A script waiting for something else will not get it: end the run now
  // with the reason rather than at the await's timeout.
  if (script_ && shown_state_ == State::Fault) {
    const std::optional<std::string> awaited = script_->awaiting();
    if (awaited && lower(*awaited) != "fault")
      throw ScriptAborted("button script: waiting for " + *awaited + " but the appliance faulted: " +
                          machine_.model().fault_message);
  }
}

void Appliance::perform(const Action& action) {
  if (const auto* a = std::get_if<StartCapture>(&action)) {
    camera_->request_still(a->job);
  } else if (std::holds_alternative<CancelCapture>(action)) {
    camera_->cancel_still();
  } else if (std::holds_alternative<DiscardShot>(action)) {
    std::lock_guard lock(shared_->mutex);
    shared_->analysis.reset();
    shared_->render.reset();
    spots_.clear();
  } else if (const auto* a = std::get_if<StartAnalysis>(&action)) {
    start_analysis(a->job);
  } else if (std::holds_alternative<CancelAnalysis>(action)) {
    jobs_->cancel(machine_.model().last_job);
  } else if (const auto* a = std::get_if<MoveCursor>(&action)) {
    const int n = static_cast<int>(spots_.size());
    if (n > 0) spot_index_ = ((spot_index_ + a->delta) % n + n) % n;
    request_preview();
  } else if (const auto* a = std::get_if<StartRender>(&action)) {
    start_render(a->job, a->prop_index);
  } else if (std::holds_alternative<FinishRender>(action)) {
    if (keep_render_) *keep_render_ = true;
    jobs_->cancel(render_job_);
  } else if (std::holds_alternative<CancelRender>(action)) {
    jobs_->cancel(render_job_);
  } else if (std::holds_alternative<AdjustRelight>(action)) {
    refresh_adjusted();
  } else if (const auto* a = std::get_if<StartExport>(&action)) {
    start_export(a->job);
  }
  // SelectNextProp/SelectPrevProp/SelectTier/CancelExport/ShowFault: the model
  // holds the choice and the screen shows it; an export is short and atomic,
  // so it is never cut off halfway.
}

// ------------------------------------------------------------------ jobs

void Appliance::start_analysis(JobId job) {
  StillResult still;
  {
    std::lock_guard lock(shared_->mutex);
    still = shared_->still;
    shared_->stages.clear();
    for (const char* name : inference::kInferenceStages) {
      ui_fb::StageLine line;
      line.name = name;
      shared_->stages.push_back(line);
    }
    shared_->analysis.reset();
    shared_->analysis_start = std::chrono::steady_clock::now();
  }
  const double height = options_.board.camera_mount_height_m;
  const long working_pixels = options_.board.budgets.working_pixels;
  const render::Vignetting vignetting = options_.board.camera.vignetting;
  std::shared_ptr<Shared> shared = shared_;
  jobs_->run(job, [this, shared, job, still, height, working_pixels, vignetting](const std::atomic<bool>& cancel) {
    auto stage_start = std::chrono::steady_clock::now();
    auto on_stage = [&](const std::string& name) {
      if (cancel) throw JobCancelled();
      std::lock_guard lock(shared->mutex);
      for (auto& line : shared->stages)
        if (line.status == ui_fb::StageLine::Status::Running) {
          line.status = ui_fb::StageLine::Status::Done;
          line.seconds = seconds_since(stage_start);
        }
      auto it = std::find_if(shared->stages.begin(), shared->stages.end(),
                             [&](const ui_fb::StageLine& l) { return l.name == name; });
      if (it == shared->stages.end()) {
        ui_fb::StageLine line;
        line.name = name;
        it = shared->stages.insert(shared->stages.end(), line);
      }
      it->status = ui_fb::StageLine::Status::Running;
      shared->changed = true;
      stage_start = std::chrono::steady_clock::now();
    };
    try {
      auto analysis = std::make_shared<Analysis>(
          analyse_still(still.linear, still.rgb8, height, working_pixels, on_stage, vignetting));
      std::vector<Spot> spots = find_spots(analysis->scene, kMaxSpots);
      std::vector<ui_fb::StageLine> lines;
      for (const auto& r : analysis->scene.reports) {
        ui_fb::StageLine line;
        line.name = r.stage;
        line.status = r.usable ? ui_fb::StageLine::Status::Done : ui_fb::StageLine::Status::Skipped;
        line.seconds = r.seconds;
        line.detail = r.why;
        lines.push_back(line);
      }
      {
        std::lock_guard lock(shared->mutex);
        shared->stages = lines;
        shared->changed = true;
      }
      if (cancel) return;
      if (spots.empty()) {
        events_.push(AnalysisFailed{job, "no floor or table to stand a prop on was found in this photo: shoot again"});
        return;
      }
      {
        std::lock_guard lock(shared->mutex);
        shared->analysis = analysis;
        shared->spots = std::move(spots);
      }
      events_.push(AnalysisDone{job});
    } catch (const JobCancelled&) {
      // The user went back; the machine expects nothing.
    } catch (const std::exception& e) {
      events_.push(AnalysisFailed{job, std::string("analysis failed: ") + e.what()});
    }
  });
}

void Appliance::start_render(JobId job, int prop_index) {
  std::shared_ptr<const Analysis> analysis;
  {
    std::lock_guard lock(shared_->mutex);
    analysis = shared_->analysis;
    shared_->render.reset();
  }
  if (!analysis || spots_.empty()) throw std::logic_error("render without an analysed photo");
  const Spot spot = spots_[static_cast<size_t>(spot_index_) % spots_.size()];
  const PropEntry prop = props_.at(static_cast<size_t>(prop_index));
  const TierSpec tier = tier_spec(machine_.model().tier);
  auto keep = std::make_shared<std::atomic<bool>>(false);
  keep_render_ = keep;
  render_job_ = job;
  const int threads = options_.render_threads;
  const double time_budget = options_.board.budgets.render_seconds;
  std::shared_ptr<Shared> shared = shared_;
  jobs_->run(job, [this, shared, job, analysis, spot, prop, tier, keep, threads,
                   time_budget](const std::atomic<bool>& cancel) {
    std::unique_ptr<CompositeRender> render;
    try {
      render = std::make_unique<CompositeRender>(analysis, prop, spot, tier, threads, time_budget);
      while (!render->finished() && !cancel) {
        render->run_pass(&cancel);
        if (cancel) break;
        auto snapshot = render->snapshot(false);
        const double fraction = std::clamp(snapshot->converged_fraction, 0.0, 1.0);
        {
          std::lock_guard lock(shared->mutex);
          shared->render = snapshot;
          shared->changed = true;
        }
        if (!render->finished()) events_.push(RenderProgress{job, fraction});
      }
      if (cancel && !*keep) return;  // cancelled: nothing to keep
      auto final_snapshot = render->snapshot(true);
      {
        std::lock_guard lock(shared->mutex);
        shared->render = final_snapshot;
        shared->changed = true;
        const int all = static_cast<int>(final_snapshot->tiles.size());
        if (all > 0) shared->affected_share = 1.0 - static_cast<double>(final_snapshot->skipped_tiles) / all;
        throughput_->record(render->pixel_samples(), render->seconds());
      }
      if (!cancel) events_.push(RenderConverged{job});
    } catch (const std::exception& e) {
      events_.push(RenderFailed{job, std::string("render failed: ") + e.what()});
    }
  });
}

void Appliance::start_export(JobId job) {
  std::shared_ptr<const Analysis> analysis;
  {
    std::lock_guard lock(shared_->mutex);
    analysis = shared_->analysis;
    shared_->export_text = "saving the composite";
    shared_->export_ok.reset();
    shared_->export_start = std::chrono::steady_clock::now();
  }
  const auto steps = machine_.model().relight_values;
  const Model model = machine_.model();
  const std::string prop_name = props_.at(static_cast<size_t>(model.prop_index)).name;
  const Spot spot = spots_.empty() ? Spot{} : spots_[static_cast<size_t>(spot_index_) % spots_.size()];
  std::shared_ptr<Shared> shared = shared_;
  // Queued behind the render job, so a render stopped with a long OK has
  // published its final snapshot by the time this runs.
  jobs_->run(job, [this, shared, job, analysis, steps, model, prop_name, spot](const std::atomic<bool>&) {
    try {
      std::shared_ptr<const RenderSnapshot> render;
      {
        std::lock_guard lock(shared->mutex);
        render = shared->render;
      }
      if (!analysis || !render) throw std::logic_error("export without a composite");
      const Adjustment adjustment = adjustment_from_steps(steps, render->prop_distance_m);
      ExportItem item;
      item.composite_srgb8 = capture::linear_to_srgb8(exported_composite(*analysis, *render, adjustment));
      item.prop_name = prop_name;
      item.metadata = {{"prop", prop_name},
                       {"base_pixel", {render->base_pixel.x, render->base_pixel.y}},
                       {"surface", spot.surface},
                       {"tier", to_string(model.tier)},
                       {"samples_per_pixel", render->samples_per_pixel},
                       {"stopped_by_time_budget", render->stopped_by_time_budget},
                       {"working_size", {analysis->photo_linear.cols, analysis->photo_linear.rows}},
                       {"render_seconds", render->elapsed_seconds},
                       {"converged_fraction", render->converged_fraction},
                       {"scene_light_ev", adjustment.scene_ev},
                       {"prop_light_ev", adjustment.prop_ev},
                       {"aperture_m", adjustment.aperture_m},
                       {"focus_m", adjustment.focus_m},
                       {"camera_height_m", analysis->scene.camera_height_m},
                       {"indoor", analysis->scene.indoor}};
      const ExportOutcome outcome = exporter_->export_composite(item);
      const int waiting = static_cast<int>(exporter_->spool().size());
      {
        std::lock_guard lock(shared->mutex);
        shared->export_text = outcome.message;
        shared->export_ok = outcome.kind != ExportOutcome::Kind::Failed;
        shared->spool_waiting = waiting;
        if (outcome.kind == ExportOutcome::Kind::Written)
          shared->exported.insert(shared->exported.end(), outcome.files.begin(), outcome.files.end());
        if (outcome.kind == ExportOutcome::Kind::Spooled) ++shared->spooled;
        shared->changed = true;
      }
      if (outcome.kind == ExportOutcome::Kind::Failed) events_.push(ExportFailed{job, outcome.message});
      else
        events_.push(ExportDone{job, outcome.kind == ExportOutcome::Kind::Written ? ExportResult::Written
                                                                                   : ExportResult::Spooled});
    } catch (const std::exception& e) {
      events_.push(ExportFailed{job, std::string("export failed: ") + e.what()});
    }
  });
}

std::string Appliance::preview_key() const {
  return std::to_string(machine_.model().last_job) + "/" + std::to_string(machine_.model().prop_index) + "/" +
         std::to_string(spot_index_);
}

void Appliance::request_preview() {
  if (spots_.empty() || props_.empty()) return;
  std::shared_ptr<const Analysis> analysis;
  {
    std::lock_guard lock(shared_->mutex);
    analysis = shared_->analysis;
    shared_->preview_wanted = preview_key();
    shared_->preview_spot = spots_[static_cast<size_t>(spot_index_) % spots_.size()];
    shared_->preview_prop = props_.at(static_cast<size_t>(machine_.model().prop_index) % props_.size());
  }
  if (!analysis) return;
  std::shared_ptr<Shared> shared = shared_;
  jobs_->run(next_internal_job_++, [shared, analysis](const std::atomic<bool>&) {
    std::string key;
    Spot spot;
    PropEntry prop;
    std::shared_ptr<PlacementPreview> world;
    {
      std::lock_guard lock(shared->mutex);
      if (shared->preview_wanted == shared->preview_key) return;  // drawn already (requests coalesce)
      key = shared->preview_wanted;
      spot = shared->preview_spot;
      prop = shared->preview_prop;
      world = shared->preview_world;
    }
    try {
      if (!world || world->prop_source() != prop.source || world->analysis() != analysis.get())
        world = std::make_shared<PlacementPreview>(analysis, prop, spot);
      cv::Mat image = world->render(spot);
      std::lock_guard lock(shared->mutex);
      shared->preview_world = world;
      shared->preview = image;
      shared->preview_key = key;
      shared->changed = true;
    } catch (const std::exception& e) {
      spdlog::warn("placement preview: {}", e.what());
    }
  });
}

void Appliance::poll_usb() {
  last_usb_poll_ns_ = now_ns();
  int waiting = 0;
  {
    std::lock_guard lock(shared_->mutex);
    waiting = shared_->spool_waiting;
  }
  // The stick is looked at and the spool flushed on the worker: the
  // Exporter is used from one thread only, and a slow stick never stalls the UI.
  if (!jobs_->idle()) return;
  std::shared_ptr<Shared> shared = shared_;
  const fs::path listed_root = props_usb_root_;
  const fs::path thumbnails = thumbnail_dir_;
  jobs_->run(next_internal_job_++, [this, shared, waiting, listed_root, thumbnails](const std::atomic<bool>&) {
    const UsbStatus usb = exporter_->usb_status();
    // A stick came or went: its props/ folder joins or leaves the carousel.
    const fs::path root = usb.usable() ? usb.root : fs::path();
    if (root != listed_root) {
      auto props = list_props(thumbnails, root, kThumbnailSize);
      std::lock_guard lock(shared->mutex);
      shared->new_props = std::move(props);
      shared->new_props_root = root;
    }
    int left = static_cast<int>(exporter_->spool().size());
    std::vector<fs::path> moved;
    if (usb.usable() && left > 0) {
      const FlushReport report = exporter_->flush_spool();
      spdlog::info("spool: {}", report.message);
      left = report.waiting;
      moved = report.files;
    }
    std::lock_guard lock(shared->mutex);
    const std::string status = left > 0 ? usb.message + " · " + std::to_string(left) + " waiting" : usb.message;
    if (status != shared->usb_message || left != waiting) shared->changed = true;
    shared->usb_message = status;
    shared->spool_waiting = left;
    shared->exported.insert(shared->exported.end(), moved.begin(), moved.end());
  });
}

// ------------------------------------------------------------------ screen

void Appliance::refresh_adjusted() {
  std::shared_ptr<const Analysis> analysis;
  std::shared_ptr<const RenderSnapshot> render;
  {
    std::lock_guard lock(shared_->mutex);
    analysis = shared_->analysis;
    render = shared_->render;
  }
  if (!analysis || !render) {
    adjusted_.release();
    adjusted_from_.reset();
    return;
  }
  const auto steps = machine_.model().relight_values;
  if (render == adjusted_from_ && steps == adjusted_steps_ && !adjusted_.empty()) return;
  adjusted_ = adjusted_composite(*analysis, *render, adjustment_from_steps(steps, render->prop_distance_m));
  adjusted_from_ = render;
  adjusted_steps_ = steps;
}

void Appliance::draw_and_present() {
  const State state = machine_.state();
  if (state == State::Adjusting || state == State::Exporting) refresh_adjusted();
  ui_fb::draw_screen(*canvas_, build_view());
  display_->present(*canvas_);
  last_present_ns_ = now_ns();
  dirty_ = false;
  if (input_pending_since_ns_ != 0) {
    summary_.input_to_screen_ms.push_back(1e-6 * static_cast<double>(last_present_ns_ - input_pending_since_ns_));
    spdlog::debug("button to screen {:.1f} ms ({})", summary_.input_to_screen_ms.back(), to_string(machine_.state()));
    input_pending_since_ns_ = 0;
  }
}

void Appliance::take_snapshot(const std::string& label) {
  if (options_.snapshots_dir.empty()) return;
  char name[96];
  std::snprintf(name, sizeof name, "%03zu-%s.png", summary_.snapshots.size() + 1, label.c_str());
  const fs::path path = options_.snapshots_dir / name;
  const fs::path tmp = options_.snapshots_dir / (std::string(".") + name + ".tmp.png");
  std::error_code ec;
  // A file display has just written what the screen shows: copy it.
  if (auto* file = dynamic_cast<ui_fb::FileDisplay*>(display_.get()); file && !file->last_snapshot().empty()) {
    fs::copy_file(file->last_snapshot(), tmp, fs::copy_options::overwrite_existing, ec);
  } else {
    cv::Mat bgr;
    cv::cvtColor(canvas_->pixels(), bgr, cv::COLOR_RGB2BGR);
    if (!cv::imwrite(tmp.string(), bgr)) ec = std::make_error_code(std::errc::io_error);
  }
  if (!ec) fs::rename(tmp, path, ec);
  if (ec) {
    spdlog::warn("snapshot {}: {}", path.string(), ec.message());
    return;
  }
  summary_.snapshots.push_back(path);
}

}  // namespace propcam::firmware
