#include "appliance/appliance_state.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <type_traits>

namespace propcam::appliance {
namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

Outcome accept(Model next, std::vector<Action> actions = {}) {
  return Outcome{std::move(next), std::move(actions), {}};
}

Outcome reject(const Model& model, std::string reason) {
  return Outcome{model, {}, std::move(reason)};
}

int wrap(int value, int count) { return ((value % count) + count) % count; }

Tier cycle_tier(Tier tier, int delta) {
  return static_cast<Tier>(wrap(static_cast<int>(tier) + delta, 3));
}

RelightParam next_param(RelightParam param) {
  return static_cast<RelightParam>(wrap(static_cast<int>(param) + 1, kRelightParamCount));
}

// Hands out a fresh job id and makes it the active one.
JobId start_job(Model& m) {
  m.active_job = ++m.last_job;
  return m.active_job;
}

Model enter(Model m, State state) {
  m.state = state;
  m.active_job = 0;
  return m;
}

Model enter_placing(Model m, PlacingStep step) {
  m = enter(std::move(m), State::Placing);
  m.placing_step = step;
  return m;
}

Model enter_viewfinder(Model m) {
  m = enter(std::move(m), State::Viewfinder);
  m.fault_message.clear();
  return m;
}

std::string fault_text(const char* what, const std::string& reason) {
  return reason.empty() ? std::string(what) : std::string(what) + ": " + reason;
}

Outcome to_fault(const Model& m, std::string message, std::vector<Action> actions = {}) {
  Model next = enter(m, State::Fault);
  next.fault_message = std::move(message);
  actions.push_back(ShowFault{next.fault_message});
  return accept(std::move(next), std::move(actions));
}

// A worker result is for the active job of the one state that expects it.
std::string check_result(const Model& m, State expected, JobId job, const char* what) {
  if (m.state != expected)
    return std::string(what) + " is not expected in " + to_string(m.state);
  if (job == 0 || job != m.active_job)
    return std::string("stale ") + what + " for job " + std::to_string(job) + " (active job " +
           std::to_string(m.active_job) + ")";
  return {};
}

// --- buttons, one function per state -------------------------------------

Outcome viewfinder_input(const Model& m, Input in) {
  if (in != Input::Shoot) return reject(m, std::string(to_string(in)) + " does nothing in the viewfinder; SHOOT takes a photo");
  Model next = enter(m, State::Captured);
  const JobId job = start_job(next);
  return accept(std::move(next), {StartCapture{job}});
}

Outcome captured_input(const Model& m, Input in) {
  if (in == Input::Back) return accept(enter_viewfinder(m), {CancelCapture{}});
  return reject(m, std::string(to_string(in)) + " is not allowed while the photo is being taken");
}

Outcome analysing_input(const Model& m, Input in) {
  if (in == Input::Back) return accept(enter_viewfinder(m), {CancelAnalysis{}});
  return reject(m, std::string(to_string(in)) + " is not allowed while analysing; BACK cancels");
}

Outcome placing_prop_input(const Model& m, Input in) {
  Model next = m;
  switch (in) {
    case Input::Next:
      next.prop_index = wrap(m.prop_index + 1, m.prop_count);
      return accept(std::move(next), {SelectNextProp{next.prop_index}});
    case Input::Prev:
      next.prop_index = wrap(m.prop_index - 1, m.prop_count);
      return accept(std::move(next), {SelectPrevProp{next.prop_index}});
    case Input::Ok: next.placing_step = PlacingStep::Spot; return accept(std::move(next));
    case Input::Back: return accept(enter_viewfinder(m), {DiscardShot{}});
    default: return reject(m, std::string(to_string(in)) + " is not allowed while choosing a prop");
  }
}

Outcome placing_spot_input(const Model& m, Input in) {
  Model next = m;
  switch (in) {
    case Input::Next: return accept(std::move(next), {MoveCursor{+1}});
    case Input::Prev: return accept(std::move(next), {MoveCursor{-1}});
    case Input::Ok: next.placing_step = PlacingStep::Tier; return accept(std::move(next));
    case Input::Back: next.placing_step = PlacingStep::Prop; return accept(std::move(next));
    default: return reject(m, std::string(to_string(in)) + " is not allowed while placing the prop");
  }
}

Outcome placing_tier_input(const Model& m, Input in) {
  Model next = m;
  switch (in) {
    case Input::Next:
    case Input::Prev:
      next.tier = cycle_tier(m.tier, in == Input::Next ? 1 : -1);
      return accept(std::move(next), {SelectTier{next.tier}});
    case Input::Ok: {
      next = enter(m, State::Rendering);
      next.render_fraction = 0.0;
      next.relight_values = {};
      next.last_export.reset();
      const JobId job = start_job(next);
      return accept(std::move(next), {StartRender{job, next.tier, next.prop_index}});
    }
    case Input::Back: next.placing_step = PlacingStep::Spot; return accept(std::move(next));
    default: return reject(m, std::string(to_string(in)) + " is not allowed while choosing the quality");
  }
}

Outcome placing_input(const Model& m, Input in) {
  switch (m.placing_step) {
    case PlacingStep::Prop: return placing_prop_input(m, in);
    case PlacingStep::Spot: return placing_spot_input(m, in);
    case PlacingStep::Tier: return placing_tier_input(m, in);
  }
  return reject(m, "unknown placing step");
}

Outcome start_export(Model next, std::vector<Action> actions) {
  next = enter(std::move(next), State::Exporting);
  const JobId job = start_job(next);
  actions.push_back(StartExport{job});
  return accept(std::move(next), std::move(actions));
}

Outcome rendering_input(const Model& m, Input in) {
  const bool usable = m.render_fraction >= kMinUsableFraction;
  switch (in) {
    case Input::Back: return accept(enter_placing(m, PlacingStep::Tier), {CancelRender{}});
    case Input::Ok:
      if (!usable) return reject(m, "the render is not far enough along to stop; BACK cancels it");
      return accept(enter(m, State::Adjusting), {FinishRender{}});
    case Input::OkLong:
      if (!usable) return reject(m, "the render is not far enough along to export");
      return start_export(m, {FinishRender{}});
    default: return reject(m, std::string(to_string(in)) + " is not allowed while rendering");
  }
}

Outcome adjust(const Model& m, int delta) {
  const auto which = static_cast<std::size_t>(m.relight);
  const int value = m.relight_values[which] + delta;
  if (value < -kRelightMaxSteps || value > kRelightMaxSteps)
    return reject(m, std::string(to_string(m.relight)) + " is already at its " +
                         (delta > 0 ? "maximum" : "minimum"));
  Model next = m;
  next.relight_values[which] = value;
  next.last_export.reset();  // the composite changed since it was exported
  return accept(std::move(next), {AdjustRelight{m.relight, delta, value}});
}

Outcome adjusting_input(const Model& m, Input in) {
  switch (in) {
    case Input::Next: return adjust(m, +1);
    case Input::Prev: return adjust(m, -1);
    case Input::Ok: {
      Model next = m;
      next.relight = next_param(m.relight);
      return accept(std::move(next));
    }
    case Input::OkLong: return start_export(m, {});
    case Input::Back: return accept(enter_placing(m, PlacingStep::Tier));
    default: return reject(m, std::string(to_string(in)) + " is not allowed while adjusting");
  }
}

Outcome fault_input(const Model& m, Input in) {
  if (in == Input::Ok || in == Input::Back) return accept(enter_viewfinder(m));
  return reject(m, std::string(to_string(in)) + " is not allowed on the fault screen; OK or BACK returns");
}

Outcome on_input(const Model& m, Input in) {
  switch (m.state) {
    case State::Viewfinder: return viewfinder_input(m, in);
    case State::Captured: return captured_input(m, in);
    case State::Analysing: return analysing_input(m, in);
    case State::Placing: return placing_input(m, in);
    case State::Rendering: return rendering_input(m, in);
    case State::Adjusting: return adjusting_input(m, in);
    case State::Exporting: return reject(m, std::string(to_string(in)) + " is not allowed while exporting");
    case State::Fault: return fault_input(m, in);
  }
  return reject(m, "unknown state");
}

// --- worker results and firmware events -------------------------------------

Outcome on_cancelled(const Model& m, const Cancelled& e) {
  if (e.job == 0 || e.job != m.active_job)
    return reject(m, "stale Cancelled for job " + std::to_string(e.job) + " (active job " +
                         std::to_string(m.active_job) + ")");
  switch (m.state) {
    case State::Captured:
    case State::Analysing: return accept(enter_viewfinder(m));
    case State::Rendering: return accept(enter_placing(m, PlacingStep::Tier));
    case State::Exporting: return accept(enter(m, State::Adjusting));
    default: return reject(m, std::string("Cancelled is not expected in ") + to_string(m.state));
  }
}

// The cancel action for the job in flight, if any.
std::vector<Action> cancel_active(const Model& m) {
  if (m.active_job == 0) return {};
  switch (m.state) {
    case State::Captured: return {CancelCapture{}};
    case State::Analysing: return {CancelAnalysis{}};
    case State::Rendering: return {CancelRender{}};
    case State::Exporting: return {CancelExport{}};
    default: return {};
  }
}

Outcome on_failure(const Model& m, const Failure& e) {
  if (m.state == State::Fault) return reject(m, "already showing a fault");
  return to_fault(m, fault_text("failure", e.message), cancel_active(m));
}

Outcome on_props_changed(const Model& m, const PropsChanged& e) {
  if (e.count < 1) return reject(m, "the prop list cannot be empty (count " + std::to_string(e.count) + ")");
  Model next = m;
  next.prop_count = e.count;
  if (next.prop_index >= e.count) next.prop_index = e.count - 1;
  return accept(std::move(next));
}

Outcome on_progress(const Model& m, const RenderProgress& e) {
  if (auto why = check_result(m, State::Rendering, e.job, "RenderProgress"); !why.empty())
    return reject(m, why);
  if (!std::isfinite(e.fraction) || e.fraction < 0.0 || e.fraction > 1.0)
    return reject(m, "render progress out of [0, 1]: " + std::to_string(e.fraction));
  Model next = m;
  next.render_fraction = e.fraction;
  return accept(std::move(next));
}

Outcome on_event(const Model& m, const Event& event) {
  return std::visit(
      Overloaded{
          [&](Input in) { return on_input(m, in); },
          [&](const CaptureDone& e) {
            if (auto why = check_result(m, State::Captured, e.job, "CaptureDone"); !why.empty())
              return reject(m, why);
            Model next = enter(m, State::Analysing);
            const JobId job = start_job(next);
            return accept(std::move(next), {StartAnalysis{job}});
          },
          [&](const CaptureFailed& e) {
            if (auto why = check_result(m, State::Captured, e.job, "CaptureFailed"); !why.empty())
              return reject(m, why);
            return to_fault(m, fault_text("capture failed", e.reason));
          },
          [&](const AnalysisDone& e) {
            if (auto why = check_result(m, State::Analysing, e.job, "AnalysisDone"); !why.empty())
              return reject(m, why);
            return accept(enter_placing(m, PlacingStep::Prop));
          },
          [&](const AnalysisFailed& e) {
            if (auto why = check_result(m, State::Analysing, e.job, "AnalysisFailed"); !why.empty())
              return reject(m, why);
            return to_fault(m, fault_text("analysis failed", e.reason));
          },
          [&](const RenderProgress& e) { return on_progress(m, e); },
          [&](const RenderConverged& e) {
            if (auto why = check_result(m, State::Rendering, e.job, "RenderConverged"); !why.empty())
              return reject(m, why);
            Model next = enter(m, State::Adjusting);
            next.render_fraction = 1.0;
            return accept(std::move(next));
          },
          [&](const RenderFailed& e) {
            if (auto why = check_result(m, State::Rendering, e.job, "RenderFailed"); !why.empty())
              return reject(m, why);
            return to_fault(m, fault_text("render failed", e.reason));
          },
          [&](const ExportDone& e) {
            if (auto why = check_result(m, State::Exporting, e.job, "ExportDone"); !why.empty())
              return reject(m, why);
            Model next = enter(m, State::Adjusting);
            next.last_export = e.result;
            return accept(std::move(next));
          },
          [&](const ExportFailed& e) {
            if (auto why = check_result(m, State::Exporting, e.job, "ExportFailed"); !why.empty())
              return reject(m, why);
            return to_fault(m, fault_text("export failed", e.reason));
          },
          [&](const Cancelled& e) { return on_cancelled(m, e); },
          [&](const FaultCleared&) {
            if (m.state != State::Fault) return reject(m, "no fault to clear");
            return accept(enter_viewfinder(m));
          },
          [&](const Failure& e) { return on_failure(m, e); },
          [&](const PropsChanged& e) { return on_props_changed(m, e); },
      },
      event);
}

bool has_job(State state) {
  return state == State::Captured || state == State::Analysing || state == State::Rendering ||
         state == State::Exporting;
}

template <class E>
int enum_index(E e) { return static_cast<int>(e); }

}  // namespace

Model initial_model(int prop_count) {
  if (prop_count < 1)
    throw std::invalid_argument("the appliance needs at least one prop, got " + std::to_string(prop_count));
  Model m;
  m.prop_count = prop_count;
  return m;
}

Outcome step(const Model& model, const Event& event) { return on_event(model, event); }

std::string check_invariants(const Model& m) {
  if (enum_index(m.state) < 0 || enum_index(m.state) > enum_index(State::Fault)) return "unknown state";
  if (enum_index(m.placing_step) < 0 || enum_index(m.placing_step) > 2) return "unknown placing step";
  if (enum_index(m.tier) < 0 || enum_index(m.tier) > 2) return "unknown tier";
  if (enum_index(m.relight) < 0 || enum_index(m.relight) >= kRelightParamCount) return "unknown relight parameter";
  if (m.prop_count < 1) return "empty prop list";
  if (m.prop_index < 0 || m.prop_index >= m.prop_count) return "prop index out of range";
  for (int v : m.relight_values)
    if (v < -kRelightMaxSteps || v > kRelightMaxSteps) return "relight value out of range";
  if (!std::isfinite(m.render_fraction) || m.render_fraction < 0.0 || m.render_fraction > 1.0)
    return "render fraction out of [0, 1]";
  if (has_job(m.state) != (m.active_job != 0)) return "active job does not match the state";
  if (m.active_job > m.last_job) return "active job id was never handed out";
  if ((m.state == State::Fault) == m.fault_message.empty()) return "fault message does not match the state";
  return {};
}

Outcome ApplianceStateMachine::handle(const Event& event) {
  Outcome out = step(model_, event);
  if (out.accepted()) model_ = out.model;
  return out;
}

const char* to_string(State state) {
  switch (state) {
    case State::Viewfinder: return "Viewfinder";
    case State::Captured: return "Captured";
    case State::Analysing: return "Analysing";
    case State::Placing: return "Placing";
    case State::Rendering: return "Rendering";
    case State::Adjusting: return "Adjusting";
    case State::Exporting: return "Exporting";
    case State::Fault: return "Fault";
  }
  return "?";
}

const char* to_string(PlacingStep step) {
  switch (step) {
    case PlacingStep::Prop: return "prop";
    case PlacingStep::Spot: return "spot";
    case PlacingStep::Tier: return "tier";
  }
  return "?";
}

const char* to_string(Tier tier) {
  switch (tier) {
    case Tier::Draft: return "draft";
    case Tier::Good: return "good";
    case Tier::Final: return "final";
  }
  return "?";
}

const char* to_string(RelightParam param) {
  switch (param) {
    case RelightParam::SceneLight: return "scene light";
    case RelightParam::PropLight: return "prop light";
    case RelightParam::Focus: return "focus";
    case RelightParam::Aperture: return "aperture";
  }
  return "?";
}

const char* to_string(Input input) {
  switch (input) {
    case Input::Shoot: return "SHOOT";
    case Input::Next: return "NEXT";
    case Input::Prev: return "PREV";
    case Input::Ok: return "OK";
    case Input::Back: return "BACK";
    case Input::OkLong: return "OK (long)";
  }
  return "?";
}

const char* to_string(ExportResult result) {
  return result == ExportResult::Written ? "written" : "spooled";
}

std::string describe(const Event& event) {
  std::ostringstream os;
  std::visit(Overloaded{
                 [&](Input in) { os << to_string(in); },
                 [&](const CaptureDone& e) { os << "CaptureDone{job " << e.job << "}"; },
                 [&](const CaptureFailed& e) { os << "CaptureFailed{job " << e.job << ", " << e.reason << "}"; },
                 [&](const AnalysisDone& e) { os << "AnalysisDone{job " << e.job << "}"; },
                 [&](const AnalysisFailed& e) { os << "AnalysisFailed{job " << e.job << ", " << e.reason << "}"; },
                 [&](const RenderProgress& e) { os << "RenderProgress{job " << e.job << ", " << e.fraction << "}"; },
                 [&](const RenderConverged& e) { os << "RenderConverged{job " << e.job << "}"; },
                 [&](const RenderFailed& e) { os << "RenderFailed{job " << e.job << ", " << e.reason << "}"; },
                 [&](const ExportDone& e) { os << "ExportDone{job " << e.job << ", " << to_string(e.result) << "}"; },
                 [&](const ExportFailed& e) { os << "ExportFailed{job " << e.job << ", " << e.reason << "}"; },
                 [&](const Cancelled& e) { os << "Cancelled{job " << e.job << "}"; },
                 [&](const FaultCleared&) { os << "FaultCleared"; },
                 [&](const Failure& e) { os << "Failure{" << e.message << "}"; },
                 [&](const PropsChanged& e) { os << "PropsChanged{" << e.count << "}"; },
             },
             event);
  return os.str();
}

std::string describe(const Action& action) {
  std::ostringstream os;
  std::visit(Overloaded{
                 [&](const StartCapture& a) { os << "StartCapture{job " << a.job << "}"; },
                 [&](const CancelCapture&) { os << "CancelCapture"; },
                 [&](const DiscardShot&) { os << "DiscardShot"; },
                 [&](const StartAnalysis& a) { os << "StartAnalysis{job " << a.job << "}"; },
                 [&](const CancelAnalysis&) { os << "CancelAnalysis"; },
                 [&](const SelectNextProp& a) { os << "SelectNextProp{" << a.index << "}"; },
                 [&](const SelectPrevProp& a) { os << "SelectPrevProp{" << a.index << "}"; },
                 [&](const MoveCursor& a) { os << "MoveCursor{" << a.delta << "}"; },
                 [&](const SelectTier& a) { os << "SelectTier{" << to_string(a.tier) << "}"; },
                 [&](const StartRender& a) {
                   os << "StartRender{job " << a.job << ", " << to_string(a.tier) << ", prop " << a.prop_index << "}";
                 },
                 [&](const FinishRender&) { os << "FinishRender"; },
                 [&](const CancelRender&) { os << "CancelRender"; },
                 [&](const AdjustRelight& a) {
                   os << "AdjustRelight{" << to_string(a.which) << ", " << a.delta << ", " << a.value << "}";
                 },
                 [&](const StartExport& a) { os << "StartExport{job " << a.job << "}"; },
                 [&](const CancelExport&) { os << "CancelExport"; },
                 [&](const ShowFault& a) { os << "ShowFault{" << a.message << "}"; },
             },
             action);
  return os.str();
}

}  // namespace propcam::appliance
