#pragma once

// The appliance's state machine: pure (no threads, no IO, no clocks). The
// firmware feeds it button inputs and worker results and carries out the
// actions it returns; screens draw from the Model. Every event is checked
// against the graph below: an event a state does not accept is Rejected with a
// reason and leaves the model unchanged (libcamera's camera state machine does
// the same), so a stray button or a late worker result can never corrupt it.
//
// Worker jobs are numbered: every Start* action carries a fresh job id and
// every worker result names the job it belongs to. A result whose job is not
// the active one (a render cancelled with BACK that finishes anyway) is
// Rejected as stale.
//
// Captured is the moment after SHOOT: the viewfinder freezes while the still
// is read out (StartCapture in flight); analysis starts when it arrives.
//
// Placing has three steps, one per thing five buttons must choose:
// Prop (NEXT/PREV cycle props), Spot (NEXT/PREV move the cursor between the
// support-surface positions the firmware snaps to), Tier (NEXT/PREV cycle
// draft/good/final). OK advances a step, BACK goes one step back.
//
// | state        | event                       | next state          | actions                              |
// |--------------|-----------------------------|---------------------|--------------------------------------|
// | Viewfinder   | Shoot                       | Captured            | StartCapture{job}                    |
// | Captured     | CaptureDone{job}            | Analysing           | StartAnalysis{job'}                  |
// | Captured     | CaptureFailed{job}          | Fault               | ShowFault{msg}                       |
// | Captured     | Back                        | Viewfinder          | CancelCapture                        |
// | Captured     | Cancelled{job}              | Viewfinder          | -                                    |
// | Analysing    | AnalysisDone{job}           | Placing/Prop        | -                                    |
// | Analysing    | AnalysisFailed{job}         | Fault               | ShowFault{msg}                       |
// | Analysing    | Back                        | Viewfinder          | CancelAnalysis                       |
// | Analysing    | Cancelled{job}              | Viewfinder          | -                                    |
// | Placing/Prop | Next / Prev                 | Placing/Prop        | SelectNextProp / SelectPrevProp      |
// | Placing/Prop | Ok                          | Placing/Spot        | -                                    |
// | Placing/Prop | Back                        | Viewfinder          | DiscardShot                          |
// | Placing/Spot | Next / Prev                 | Placing/Spot        | MoveCursor{+1 / -1}                  |
// | Placing/Spot | Ok                          | Placing/Tier        | -                                    |
// | Placing/Spot | Back                        | Placing/Prop        | -                                    |
// | Placing/Tier | Next / Prev                 | Placing/Tier        | SelectTier{tier} (cycles)            |
// | Placing/Tier | Ok                          | Rendering           | StartRender{job, tier, prop}         |
// | Placing/Tier | Back                        | Placing/Spot        | -                                    |
// | Rendering    | RenderProgress{job, f}      | Rendering           | - (fraction = f, f in [0, 1])        |
// | Rendering    | RenderConverged{job}        | Adjusting           | -                                    |
// | Rendering    | RenderFailed{job}           | Fault               | ShowFault{msg}                       |
// | Rendering    | Ok      (f >= kMinUsable)   | Adjusting           | FinishRender (keep the composite)    |
// | Rendering    | OkLong  (f >= kMinUsable)   | Exporting           | FinishRender, StartExport{job'}      |
// | Rendering    | Back                        | Placing/Tier        | CancelRender                         |
// | Rendering    | Cancelled{job}              | Placing/Tier        | -                                    |
// | Adjusting    | Next / Prev (not at bound)  | Adjusting           | AdjustRelight{which, +1/-1, value}   |
// | Adjusting    | Ok                          | Adjusting           | - (cycles the relight selection)     |
// | Adjusting    | OkLong                      | Exporting           | StartExport{job}                     |
// | Adjusting    | Back                        | Placing/Tier        | -                                    |
// | Exporting    | ExportDone{job, result}     | Adjusting           | - (last_export = result)             |
// | Exporting    | ExportFailed{job}           | Fault               | ShowFault{msg}                       |
// | Exporting    | Cancelled{job}              | Adjusting           | -                                    |
// | Fault        | FaultCleared / Ok / Back    | Viewfinder          | -                                    |
// | any but Fault| Failure{msg}                | Fault               | Cancel<active job>, ShowFault{msg}   |
// | any          | PropsChanged{count >= 1}    | same                | - (prop index clamped to the list)   |
//
// Everything else is Rejected, among them: SHOOT outside the viewfinder (an
// accidental press never loses work), any button while exporting (the export
// is atomic and short; a stuck one ends as ExportFailed or Cancelled), NEXT/PREV
// beyond a relight bound, and every worker result outside its state or for a
// job that is not the active one.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace propcam::appliance {

enum class State { Viewfinder, Captured, Analysing, Placing, Rendering, Adjusting, Exporting, Fault };
inline constexpr std::array kAllStates{State::Viewfinder, State::Captured, State::Analysing,
                                       State::Placing,    State::Rendering, State::Adjusting,
                                       State::Exporting,  State::Fault};

enum class PlacingStep { Prop, Spot, Tier };
enum class Tier { Draft, Good, Final };
enum class RelightParam { SceneLight, PropLight, Focus, Aperture };
inline constexpr int kRelightParamCount = 4;

// The five buttons, OK's long press being the sixth input.
enum class Input { Shoot, Next, Prev, Ok, Back, OkLong };
inline constexpr std::array kAllInputs{Input::Shoot, Input::Next, Input::Prev,
                                       Input::Ok,    Input::Back, Input::OkLong};

// Relight values are steps in [-kRelightMaxSteps, kRelightMaxSteps]; the
// firmware maps a step to exposure stops, focus distance or f-number.
inline constexpr int kRelightMaxSteps = 10;
// A render this far along (share of tiles at the tier's target) is worth
// keeping when the user stops it early.
inline constexpr double kMinUsableFraction = 0.5;

using JobId = std::uint64_t;  // 0 = no job

// Worker results. Reasons are short human text; the fault screen shows them.
struct CaptureDone { JobId job = 0; };
struct CaptureFailed { JobId job = 0; std::string reason; };
struct AnalysisDone { JobId job = 0; };
struct AnalysisFailed { JobId job = 0; std::string reason; };
struct RenderProgress { JobId job = 0; double fraction = 0.0; };
struct RenderConverged { JobId job = 0; };
struct RenderFailed { JobId job = 0; std::string reason; };
enum class ExportResult { Written, Spooled };  // spooled: no stick, kept for later
struct ExportDone { JobId job = 0; ExportResult result = ExportResult::Written; };
struct ExportFailed { JobId job = 0; std::string reason; };
struct Cancelled { JobId job = 0; };  // the worker gave up on its own (timeout, device gone)
// Firmware-side events.
struct FaultCleared {};
struct Failure { std::string message; };  // an exception the firmware caught
struct PropsChanged { int count = 1; };   // a USB stick's props came or went

using Event = std::variant<Input, CaptureDone, CaptureFailed, AnalysisDone, AnalysisFailed,
                           RenderProgress, RenderConverged, RenderFailed, ExportDone, ExportFailed,
                           Cancelled, FaultCleared, Failure, PropsChanged>;

// Actions for the firmware to carry out, in order.
struct StartCapture { JobId job = 0; bool operator==(const StartCapture&) const = default; };
struct CancelCapture { bool operator==(const CancelCapture&) const = default; };
struct DiscardShot { bool operator==(const DiscardShot&) const = default; };
struct StartAnalysis { JobId job = 0; bool operator==(const StartAnalysis&) const = default; };
struct CancelAnalysis { bool operator==(const CancelAnalysis&) const = default; };
struct SelectNextProp { int index = 0; bool operator==(const SelectNextProp&) const = default; };
struct SelectPrevProp { int index = 0; bool operator==(const SelectPrevProp&) const = default; };
struct MoveCursor { int delta = 0; bool operator==(const MoveCursor&) const = default; };
struct SelectTier { Tier tier = Tier::Draft; bool operator==(const SelectTier&) const = default; };
struct StartRender {
  JobId job = 0;
  Tier tier = Tier::Draft;
  int prop_index = 0;
  bool operator==(const StartRender&) const = default;
};
struct FinishRender { bool operator==(const FinishRender&) const = default; };
struct CancelRender { bool operator==(const CancelRender&) const = default; };
struct AdjustRelight {
  RelightParam which = RelightParam::SceneLight;
  int delta = 0;
  int value = 0;  // the value after the change
  bool operator==(const AdjustRelight&) const = default;
};
struct StartExport { JobId job = 0; bool operator==(const StartExport&) const = default; };
struct CancelExport { bool operator==(const CancelExport&) const = default; };
struct ShowFault { std::string message; bool operator==(const ShowFault&) const = default; };

using Action = std::variant<StartCapture, CancelCapture, DiscardShot, StartAnalysis, CancelAnalysis,
                            SelectNextProp, SelectPrevProp, MoveCursor, SelectTier, StartRender,
                            FinishRender, CancelRender, AdjustRelight, StartExport, CancelExport,
                            ShowFault>;

// Everything the screens need, and all the machine remembers.
struct Model {
  State state = State::Viewfinder;
  PlacingStep placing_step = PlacingStep::Prop;  // meaningful in Placing
  int prop_count = 1;
  int prop_index = 0;
  Tier tier = Tier::Good;
  RelightParam relight = RelightParam::SceneLight;
  std::array<int, kRelightParamCount> relight_values{};  // reset by every new render
  double render_fraction = 0.0;                          // of the current render
  std::optional<ExportResult> last_export;               // of the current composite
  std::string fault_message;                             // meaningful in Fault
  JobId active_job = 0;                                  // the worker job in flight, 0 = none
  JobId last_job = 0;                                    // the last id handed out
  bool operator==(const Model&) const = default;
};

struct Outcome {
  Model model;                  // equal to the old model when rejected
  std::vector<Action> actions;  // empty when rejected
  std::string rejection;        // why the event was not allowed; empty when accepted
  bool accepted() const { return rejection.empty(); }
};

// The initial model: viewfinder, prop 0 of prop_count (>= 1, else throws
// std::invalid_argument).
Model initial_model(int prop_count);

// The transition function. Total: any model satisfying check_invariants and
// any event give an Outcome; the result satisfies check_invariants again.
Outcome step(const Model& model, const Event& event);

// Empty when the model is consistent, else what is wrong (prop index out of
// range, a job in flight in a state that has none, a non-finite fraction...).
std::string check_invariants(const Model& model);

// Holds the current model; the firmware's one instance.
class ApplianceStateMachine {
 public:
  explicit ApplianceStateMachine(int prop_count) : model_(initial_model(prop_count)) {}
  // Applies the event when accepted; the model stays as it was otherwise.
  Outcome handle(const Event& event);
  const Model& model() const { return model_; }
  State state() const { return model_.state; }

 private:
  Model model_;
};

const char* to_string(State state);
const char* to_string(PlacingStep step);
const char* to_string(Tier tier);
const char* to_string(RelightParam param);
const char* to_string(Input input);
const char* to_string(ExportResult result);
std::string describe(const Event& event);    // e.g. "Ok", "RenderProgress{job 3, 0.25}"
std::string describe(const Action& action);  // e.g. "StartRender{job 3, good, prop 2}"

}  // namespace propcam::appliance
