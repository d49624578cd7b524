#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <set>

#include "appliance/appliance_state.h"

namespace propcam::appliance {
namespace {

constexpr int kProps = 5;

// Where a test starts: a state, and the placing step when it is Placing.
struct Spot {
  State state;
  PlacingStep step = PlacingStep::Prop;
  bool operator<(const Spot& o) const {
    return std::pair(state, step) < std::pair(o.state, o.step);
  }
};

std::string name(const Spot& s) {
  std::string n = to_string(s.state);
  if (s.state == State::Placing) n += std::string("/") + to_string(s.step);
  return n;
}

// Applies an event that must be accepted and returns its actions.
std::vector<Action> must(ApplianceStateMachine& sm, const Event& e) {
  const Outcome out = sm.handle(e);
  EXPECT_TRUE(out.accepted()) << describe(e) << " in " << to_string(sm.state()) << ": " << out.rejection;
  EXPECT_EQ(check_invariants(sm.model()), "") << "after " << describe(e);
  return out.actions;
}

// Drives a fresh machine along the happy path to the given spot.
ApplianceStateMachine reach(const Spot& target) {
  ApplianceStateMachine sm(kProps);
  auto at = [&] {
    return sm.state() == target.state &&
           (target.state != State::Placing || sm.model().placing_step == target.step);
  };
  if (target.state == State::Fault) {
    must(sm, Failure{"test fault"});
    return sm;
  }
  const std::vector<std::function<Event()>> path{
      [] { return Event{Input::Shoot}; },
      [&] { return Event{CaptureDone{sm.model().active_job}}; },
      [&] { return Event{AnalysisDone{sm.model().active_job}}; },
      [] { return Event{Input::Ok}; },  // prop -> spot
      [] { return Event{Input::Ok}; },  // spot -> tier
      [] { return Event{Input::Ok}; },  // tier -> rendering
      [&] { return Event{RenderConverged{sm.model().active_job}}; },
      [] { return Event{Input::OkLong}; },  // adjusting -> exporting
  };
  for (const auto& next : path) {
    if (at()) return sm;
    must(sm, next());
  }
  EXPECT_TRUE(at()) << "could not reach " << name(target);
  return sm;
}

const std::vector<Spot> kAllSpots{
    {State::Viewfinder}, {State::Captured},  {State::Analysing},
    {State::Placing, PlacingStep::Prop},     {State::Placing, PlacingStep::Spot},
    {State::Placing, PlacingStep::Tier},     {State::Rendering},
    {State::Adjusting},  {State::Exporting}, {State::Fault}};

TEST(ApplianceState, StartsInTheViewfinder) {
  ApplianceStateMachine sm(3);
  EXPECT_EQ(sm.state(), State::Viewfinder);
  EXPECT_EQ(sm.model().prop_index, 0);
  EXPECT_EQ(sm.model().prop_count, 3);
  EXPECT_EQ(sm.model().active_job, 0u);
  EXPECT_EQ(check_invariants(sm.model()), "");
  EXPECT_THROW(ApplianceStateMachine(0), std::invalid_argument);
  EXPECT_THROW(initial_model(-2), std::invalid_argument);
}

// Shoot -> analyse -> cycle props -> place -> pick tier -> render -> converge
// -> relight -> export -> back, checking every action on the way.
TEST(ApplianceState, ScriptedHappyPath) {
  ApplianceStateMachine sm(kProps);
  using V = std::vector<Action>;

  EXPECT_EQ(must(sm, Input::Shoot), (V{StartCapture{1}}));
  EXPECT_EQ(sm.state(), State::Captured);
  EXPECT_EQ(must(sm, CaptureDone{1}), (V{StartAnalysis{2}}));
  EXPECT_EQ(sm.state(), State::Analysing);
  EXPECT_EQ(must(sm, AnalysisDone{2}), V{});
  EXPECT_EQ(sm.state(), State::Placing);
  EXPECT_EQ(sm.model().placing_step, PlacingStep::Prop);

  // Props wrap both ways.
  EXPECT_EQ(must(sm, Input::Next), (V{SelectNextProp{1}}));
  EXPECT_EQ(must(sm, Input::Next), (V{SelectNextProp{2}}));
  EXPECT_EQ(must(sm, Input::Prev), (V{SelectPrevProp{1}}));
  EXPECT_EQ(must(sm, Input::Prev), (V{SelectPrevProp{0}}));
  EXPECT_EQ(must(sm, Input::Prev), (V{SelectPrevProp{kProps - 1}}));
  EXPECT_EQ(must(sm, Input::Next), (V{SelectNextProp{0}}));
  EXPECT_EQ(must(sm, Input::Next), (V{SelectNextProp{1}}));
  EXPECT_EQ(sm.model().prop_index, 1);

  EXPECT_EQ(must(sm, Input::Ok), V{});
  EXPECT_EQ(sm.model().placing_step, PlacingStep::Spot);
  EXPECT_EQ(must(sm, Input::Next), (V{MoveCursor{+1}}));
  EXPECT_EQ(must(sm, Input::Prev), (V{MoveCursor{-1}}));
  EXPECT_EQ(must(sm, Input::Next), (V{MoveCursor{+1}}));

  EXPECT_EQ(must(sm, Input::Ok), V{});
  EXPECT_EQ(sm.model().placing_step, PlacingStep::Tier);
  EXPECT_EQ(sm.model().tier, Tier::Good);
  EXPECT_EQ(must(sm, Input::Next), (V{SelectTier{Tier::Final}}));
  EXPECT_EQ(must(sm, Input::Next), (V{SelectTier{Tier::Draft}}));
  EXPECT_EQ(must(sm, Input::Prev), (V{SelectTier{Tier::Final}}));

  EXPECT_EQ(must(sm, Input::Ok), (V{StartRender{3, Tier::Final, 1}}));
  EXPECT_EQ(sm.state(), State::Rendering);
  EXPECT_EQ(must(sm, RenderProgress{3, 0.25}), V{});
  EXPECT_DOUBLE_EQ(sm.model().render_fraction, 0.25);
  EXPECT_EQ(must(sm, RenderProgress{3, 0.75}), V{});
  EXPECT_EQ(must(sm, RenderConverged{3}), V{});
  EXPECT_EQ(sm.state(), State::Adjusting);
  EXPECT_DOUBLE_EQ(sm.model().render_fraction, 1.0);

  // Relight: scene light +2, prop light -1, focus +1, aperture untouched.
  EXPECT_EQ(sm.model().relight, RelightParam::SceneLight);
  EXPECT_EQ(must(sm, Input::Next), (V{AdjustRelight{RelightParam::SceneLight, +1, 1}}));
  EXPECT_EQ(must(sm, Input::Next), (V{AdjustRelight{RelightParam::SceneLight, +1, 2}}));
  must(sm, Input::Ok);
  EXPECT_EQ(sm.model().relight, RelightParam::PropLight);
  EXPECT_EQ(must(sm, Input::Prev), (V{AdjustRelight{RelightParam::PropLight, -1, -1}}));
  must(sm, Input::Ok);
  EXPECT_EQ(must(sm, Input::Next), (V{AdjustRelight{RelightParam::Focus, +1, 1}}));
  must(sm, Input::Ok);
  EXPECT_EQ(sm.model().relight, RelightParam::Aperture);
  must(sm, Input::Ok);
  EXPECT_EQ(sm.model().relight, RelightParam::SceneLight);
  EXPECT_EQ(sm.model().relight_values, (std::array<int, 4>{2, -1, 1, 0}));

  EXPECT_EQ(must(sm, Input::OkLong), (V{StartExport{4}}));
  EXPECT_EQ(sm.state(), State::Exporting);
  EXPECT_EQ(must(sm, ExportDone{4, ExportResult::Spooled}), V{});
  EXPECT_EQ(sm.state(), State::Adjusting);
  EXPECT_EQ(sm.model().last_export, ExportResult::Spooled);
  EXPECT_EQ(sm.model().relight_values, (std::array<int, 4>{2, -1, 1, 0}));

  // Back out all the way to the viewfinder.
  EXPECT_EQ(must(sm, Input::Back), V{});
  EXPECT_EQ(sm.state(), State::Placing);
  EXPECT_EQ(sm.model().placing_step, PlacingStep::Tier);
  must(sm, Input::Back);
  EXPECT_EQ(sm.model().placing_step, PlacingStep::Spot);
  must(sm, Input::Back);
  EXPECT_EQ(sm.model().placing_step, PlacingStep::Prop);
  EXPECT_EQ(must(sm, Input::Back), (V{DiscardShot{}}));
  EXPECT_EQ(sm.state(), State::Viewfinder);
  EXPECT_EQ(sm.model().active_job, 0u);
  EXPECT_EQ(sm.model().prop_index, 1);  // the selection survives the next shot
}

TEST(ApplianceState, BackTransitions) {
  struct Case {
    Spot from;
    Spot to;
    std::vector<Action> actions;
  };
  const std::vector<Case> cases{
      {{State::Captured}, {State::Viewfinder}, {CancelCapture{}}},
      {{State::Analysing}, {State::Viewfinder}, {CancelAnalysis{}}},
      {{State::Placing, PlacingStep::Prop}, {State::Viewfinder}, {DiscardShot{}}},
      {{State::Placing, PlacingStep::Spot}, {State::Placing, PlacingStep::Prop}, {}},
      {{State::Placing, PlacingStep::Tier}, {State::Placing, PlacingStep::Spot}, {}},
      {{State::Rendering}, {State::Placing, PlacingStep::Tier}, {CancelRender{}}},
      {{State::Adjusting}, {State::Placing, PlacingStep::Tier}, {}},
      {{State::Fault}, {State::Viewfinder}, {}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(name(c.from));
    ApplianceStateMachine sm = reach(c.from);
    EXPECT_EQ(must(sm, Input::Back), c.actions);
    EXPECT_EQ(sm.state(), c.to.state);
    if (c.to.state == State::Placing) {
      EXPECT_EQ(sm.model().placing_step, c.to.step);
    }
    EXPECT_EQ(sm.model().active_job, 0u);
  }
}

// The buttons each spot accepts (Rendering at fraction 0, relight values 0);
// everything else must be rejected with a reason and no change.
const std::map<Spot, std::set<Input>> kAllowedButtons{
    {{State::Viewfinder}, {Input::Shoot}},
    {{State::Captured}, {Input::Back}},
    {{State::Analysing}, {Input::Back}},
    {{State::Placing, PlacingStep::Prop}, {Input::Next, Input::Prev, Input::Ok, Input::Back}},
    {{State::Placing, PlacingStep::Spot}, {Input::Next, Input::Prev, Input::Ok, Input::Back}},
    {{State::Placing, PlacingStep::Tier}, {Input::Next, Input::Prev, Input::Ok, Input::Back}},
    {{State::Rendering}, {Input::Back}},
    {{State::Adjusting}, {Input::Next, Input::Prev, Input::Ok, Input::Back, Input::OkLong}},
    {{State::Exporting}, {}},
    {{State::Fault}, {Input::Ok, Input::Back}},
};

TEST(ApplianceState, EveryForbiddenButtonIsRejectedAndChangesNothing) {
  int forbidden = 0;
  for (const Spot& spot : kAllSpots) {
    for (Input in : kAllInputs) {
      ApplianceStateMachine sm = reach(spot);
      const Model before = sm.model();
      const Outcome out = sm.handle(in);
      const bool allowed = kAllowedButtons.at(spot).count(in) > 0;
      EXPECT_EQ(out.accepted(), allowed) << to_string(in) << " in " << name(spot) << ": " << out.rejection;
      if (allowed) continue;
      ++forbidden;
      EXPECT_FALSE(out.rejection.empty());
      EXPECT_TRUE(out.actions.empty());
      EXPECT_EQ(out.model, before);
      EXPECT_EQ(sm.model(), before) << to_string(in) << " in " << name(spot);
    }
  }
  EXPECT_EQ(forbidden, 37);  // 60 pairs, 23 allowed
}

// Worker results and firmware events, each for the job in flight (so only the
// state rejects them), except the ones that carry no job.
std::vector<std::pair<std::string, Event>> results_for(JobId job) {
  return {
      {"CaptureDone", CaptureDone{job}},
      {"CaptureFailed", CaptureFailed{job, "x"}},
      {"AnalysisDone", AnalysisDone{job}},
      {"AnalysisFailed", AnalysisFailed{job, "x"}},
      {"RenderProgress", RenderProgress{job, 0.5}},
      {"RenderConverged", RenderConverged{job}},
      {"RenderFailed", RenderFailed{job, "x"}},
      {"ExportDone", ExportDone{job, ExportResult::Written}},
      {"ExportFailed", ExportFailed{job, "x"}},
      {"Cancelled", Cancelled{job}},
      {"FaultCleared", FaultCleared{}},
      {"Failure", Failure{"x"}},
      {"PropsChanged", PropsChanged{kProps}},
  };
}

const std::map<State, std::set<std::string>> kAllowedResults{
    {State::Viewfinder, {"Failure", "PropsChanged"}},
    {State::Captured, {"CaptureDone", "CaptureFailed", "Cancelled", "Failure", "PropsChanged"}},
    {State::Analysing, {"AnalysisDone", "AnalysisFailed", "Cancelled", "Failure", "PropsChanged"}},
    {State::Placing, {"Failure", "PropsChanged"}},
    {State::Rendering,
     {"RenderProgress", "RenderConverged", "RenderFailed", "Cancelled", "Failure", "PropsChanged"}},
    {State::Adjusting, {"Failure", "PropsChanged"}},
    {State::Exporting, {"ExportDone", "ExportFailed", "Cancelled", "Failure", "PropsChanged"}},
    {State::Fault, {"FaultCleared", "PropsChanged"}},
};

TEST(ApplianceState, EveryMisplacedResultIsRejectedAndChangesNothing) {
  for (const Spot& spot : kAllSpots) {
    ApplianceStateMachine probe = reach(spot);
    for (const auto& [label, event] : results_for(probe.model().active_job)) {
      ApplianceStateMachine sm = reach(spot);
      const Model before = sm.model();
      const Outcome out = sm.handle(event);
      const bool allowed = kAllowedResults.at(spot.state).count(label) > 0;
      EXPECT_EQ(out.accepted(), allowed) << label << " in " << name(spot) << ": " << out.rejection;
      if (allowed) continue;
      EXPECT_FALSE(out.rejection.empty());
      EXPECT_TRUE(out.actions.empty());
      EXPECT_EQ(sm.model(), before) << label << " in " << name(spot);
    }
  }
}

TEST(ApplianceState, StaleResultsAreRejected) {
  ApplianceStateMachine sm = reach({State::Rendering});
  const JobId old_job = sm.model().active_job;
  must(sm, Input::Back);  // cancel the render...
  must(sm, Input::Ok);    // ...and start another
  const JobId new_job = sm.model().active_job;
  ASSERT_NE(old_job, new_job);
  const Model before = sm.model();
  for (const Event& late : {Event{RenderConverged{old_job}}, Event{RenderProgress{old_job, 0.9}},
                            Event{RenderFailed{old_job, "late"}}, Event{Cancelled{old_job}},
                            Event{RenderConverged{0}}, Event{RenderConverged{new_job + 1}}}) {
    const Outcome out = sm.handle(late);
    EXPECT_FALSE(out.accepted()) << describe(late);
    EXPECT_NE(out.rejection.find("stale"), std::string::npos) << out.rejection;
    EXPECT_EQ(sm.model(), before);
  }
  must(sm, RenderConverged{new_job});
  EXPECT_EQ(sm.state(), State::Adjusting);
}

TEST(ApplianceState, RenderProgressMustBeAFraction) {
  ApplianceStateMachine sm = reach({State::Rendering});
  const JobId job = sm.model().active_job;
  for (double bad : {-0.1, 1.5, std::nan(""), std::numeric_limits<double>::infinity()}) {
    const Model before = sm.model();
    EXPECT_FALSE(sm.handle(RenderProgress{job, bad}).accepted()) << bad;
    EXPECT_EQ(sm.model(), before);
  }
  must(sm, RenderProgress{job, 0.0});
  must(sm, RenderProgress{job, 1.0});
}

TEST(ApplianceState, StoppingARenderEarlyNeedsAUsableComposite) {
  ApplianceStateMachine sm = reach({State::Rendering});
  const JobId job = sm.model().active_job;
  must(sm, RenderProgress{job, kMinUsableFraction - 0.01});
  EXPECT_FALSE(sm.handle(Input::Ok).accepted());
  EXPECT_FALSE(sm.handle(Input::OkLong).accepted());
  must(sm, RenderProgress{job, kMinUsableFraction});

  ApplianceStateMachine stop = sm;
  EXPECT_EQ(must(stop, Input::Ok), (std::vector<Action>{FinishRender{}}));
  EXPECT_EQ(stop.state(), State::Adjusting);

  EXPECT_EQ(must(sm, Input::OkLong), (std::vector<Action>{FinishRender{}, StartExport{job + 1}}));
  EXPECT_EQ(sm.state(), State::Exporting);
  must(sm, ExportDone{job + 1, ExportResult::Written});
  EXPECT_EQ(sm.state(), State::Adjusting);
  EXPECT_EQ(sm.model().last_export, ExportResult::Written);
}

TEST(ApplianceState, RelightValuesStopAtTheirBounds) {
  ApplianceStateMachine sm = reach({State::Adjusting});
  for (int i = 0; i < kRelightMaxSteps; ++i) must(sm, Input::Next);
  const Model top = sm.model();
  const Outcome out = sm.handle(Input::Next);
  EXPECT_FALSE(out.accepted());
  EXPECT_NE(out.rejection.find("maximum"), std::string::npos) << out.rejection;
  EXPECT_EQ(sm.model(), top);
  for (int i = 0; i < 2 * kRelightMaxSteps; ++i) must(sm, Input::Prev);
  EXPECT_FALSE(sm.handle(Input::Prev).accepted());
  EXPECT_EQ(sm.model().relight_values[0], -kRelightMaxSteps);
}

TEST(ApplianceState, ANewRenderResetsRelightAndExport) {
  ApplianceStateMachine sm = reach({State::Adjusting});
  must(sm, Input::Next);
  must(sm, Input::OkLong);
  must(sm, ExportDone{sm.model().active_job, ExportResult::Written});
  ASSERT_TRUE(sm.model().last_export.has_value());
  must(sm, Input::Next);  // changing the composite forgets the export
  EXPECT_FALSE(sm.model().last_export.has_value());
  must(sm, Input::Back);
  must(sm, Input::Ok);
  EXPECT_EQ(sm.state(), State::Rendering);
  EXPECT_EQ(sm.model().relight_values, (std::array<int, 4>{}));
  EXPECT_EQ(sm.model().render_fraction, 0.0);
}

TEST(ApplianceState, FailuresLeadToFaultAndRecover) {
  struct Case {
    Spot from;
    std::function<Event(JobId)> failure;
    std::string message;
  };
  const std::vector<Case> cases{
      {{State::Captured}, [](JobId j) { return CaptureFailed{j, "device lost"}; }, "capture failed: device lost"},
      {{State::Analysing}, [](JobId j) { return AnalysisFailed{j, "no floor"}; }, "analysis failed: no floor"},
      {{State::Rendering}, [](JobId j) { return RenderFailed{j, "NaN tile"}; }, "render failed: NaN tile"},
      {{State::Exporting}, [](JobId j) { return ExportFailed{j, "stick full"}; }, "export failed: stick full"},
      {{State::Rendering}, [](JobId j) { return RenderFailed{j, ""}; }, "render failed"},
  };
  int recovery = 0;
  for (const Case& c : cases) {
    for (const Event& clear : {Event{FaultCleared{}}, Event{Input::Ok}, Event{Input::Back}}) {
      SCOPED_TRACE(name(c.from) + " then " + describe(clear));
      ApplianceStateMachine sm = reach(c.from);
      EXPECT_EQ(must(sm, c.failure(sm.model().active_job)), (std::vector<Action>{ShowFault{c.message}}));
      EXPECT_EQ(sm.state(), State::Fault);
      EXPECT_EQ(sm.model().fault_message, c.message);
      EXPECT_EQ(sm.model().active_job, 0u);
      EXPECT_FALSE(sm.handle(Failure{"again"}).accepted());
      must(sm, clear);
      EXPECT_EQ(sm.state(), State::Viewfinder);
      EXPECT_EQ(sm.model().fault_message, "");
      ++recovery;
      // And the appliance works again.
      must(sm, Input::Shoot);
      EXPECT_EQ(sm.state(), State::Captured);
    }
  }
  EXPECT_EQ(recovery, 15);
}

TEST(ApplianceState, AFailureCancelsTheJobInFlight) {
  const std::vector<std::pair<Spot, std::vector<Action>>> cases{
      {{State::Viewfinder}, {}},
      {{State::Captured}, {CancelCapture{}}},
      {{State::Analysing}, {CancelAnalysis{}}},
      {{State::Placing, PlacingStep::Spot}, {}},
      {{State::Rendering}, {CancelRender{}}},
      {{State::Adjusting}, {}},
      {{State::Exporting}, {CancelExport{}}},
  };
  for (auto [spot, cancels] : cases) {
    SCOPED_TRACE(name(spot));
    ApplianceStateMachine sm = reach(spot);
    cancels.push_back(ShowFault{"failure: out of memory"});
    EXPECT_EQ(must(sm, Failure{"out of memory"}), cancels);
    EXPECT_EQ(sm.state(), State::Fault);
  }
}

TEST(ApplianceState, WorkerCancellationActsLikeBackWithoutACancelAction) {
  const std::vector<std::pair<Spot, Spot>> cases{
      {{State::Captured}, {State::Viewfinder}},
      {{State::Analysing}, {State::Viewfinder}},
      {{State::Rendering}, {State::Placing, PlacingStep::Tier}},
      {{State::Exporting}, {State::Adjusting}},
  };
  for (const auto& [from, to] : cases) {
    SCOPED_TRACE(name(from));
    ApplianceStateMachine sm = reach(from);
    EXPECT_EQ(must(sm, Cancelled{sm.model().active_job}), std::vector<Action>{});
    EXPECT_EQ(sm.state(), to.state);
    if (to.state == State::Placing) {
      EXPECT_EQ(sm.model().placing_step, to.step);
    }
  }
}

TEST(ApplianceState, PropsChangedClampsTheSelection) {
  ApplianceStateMachine sm = reach({State::Placing, PlacingStep::Prop});
  for (int i = 0; i < 4; ++i) must(sm, Input::Next);
  EXPECT_EQ(sm.model().prop_index, 4);
  must(sm, PropsChanged{3});
  EXPECT_EQ(sm.model().prop_index, 2);
  must(sm, Input::Next);
  EXPECT_EQ(sm.model().prop_index, 0);
  must(sm, PropsChanged{9});
  EXPECT_EQ(sm.model().prop_index, 0);
  EXPECT_FALSE(sm.handle(PropsChanged{0}).accepted());
  EXPECT_EQ(sm.model().prop_count, 9);
}

Event random_event(std::mt19937_64& rng, const Model& m) {
  // Mostly buttons; results mostly for the active job, sometimes stale.
  std::uniform_int_distribution<int> kind(0, 19);
  const int k = kind(rng);
  if (k < 8) return kAllInputs[std::uniform_int_distribution<std::size_t>(0, kAllInputs.size() - 1)(rng)];
  const JobId job = std::bernoulli_distribution(0.8)(rng) ? m.active_job
                                                          : std::uniform_int_distribution<JobId>(0, m.last_job + 1)(rng);
  switch (k) {
    case 8: return CaptureDone{job};
    case 9: return std::bernoulli_distribution(0.2)(rng) ? Event{CaptureFailed{job, "r"}} : Event{AnalysisDone{job}};
    case 10: return AnalysisFailed{job, std::bernoulli_distribution(0.5)(rng) ? "r" : ""};
    case 11: return RenderProgress{job, std::uniform_real_distribution<double>(-0.2, 1.2)(rng)};
    case 12: return RenderConverged{job};
    case 13: return RenderFailed{job, "r"};
    case 14: return ExportDone{job, std::bernoulli_distribution(0.5)(rng) ? ExportResult::Written : ExportResult::Spooled};
    case 15: return ExportFailed{job, "r"};
    case 16: return Cancelled{job};
    case 17: return FaultCleared{};
    case 18: return std::bernoulli_distribution(0.1)(rng) ? Event{Failure{"boom"}} : Event{RenderProgress{job, 0.6}};
    default: return PropsChanged{std::uniform_int_distribution<int>(-1, 12)(rng)};
  }
}

struct RunSummary {
  std::vector<Model> trace;
  std::set<State> visited;
  int accepted = 0;
};

RunSummary random_run(std::uint64_t seed, int steps) {
  std::mt19937_64 rng(seed);
  ApplianceStateMachine sm(kProps);
  RunSummary run;
  for (int i = 0; i < steps; ++i) {
    const Model before = sm.model();
    const Event e = random_event(rng, before);
    const Outcome out = sm.handle(e);
    if (out.accepted()) {
      ++run.accepted;
    } else {
      EXPECT_EQ(sm.model(), before) << "step " << i << ": " << describe(e);
      EXPECT_TRUE(out.actions.empty());
    }
    const std::string bad = check_invariants(sm.model());
    if (!bad.empty()) {
      ADD_FAILURE() << "step " << i << " (" << describe(e) << " in " << to_string(before.state) << "): " << bad;
      break;
    }
    run.visited.insert(sm.state());
    if (i % 1000 == 0) run.trace.push_back(sm.model());
  }
  return run;
}

TEST(ApplianceState, RandomInputsKeepTheInvariants) {
  const RunSummary run = random_run(20261201, 100000);
  EXPECT_EQ(run.visited.size(), kAllStates.size()) << "the random walk should reach every state";
  EXPECT_GT(run.accepted, 10000);
}

TEST(ApplianceState, IsDeterministic) {
  const RunSummary a = random_run(7, 20000);
  const RunSummary b = random_run(7, 20000);
  EXPECT_EQ(a.trace, b.trace);
  EXPECT_EQ(a.accepted, b.accepted);
  // step() is a function of its arguments: same model and event, same outcome.
  const Model m = reach({State::Adjusting}).model();
  const Outcome x = step(m, Input::Next);
  const Outcome y = step(m, Input::Next);
  EXPECT_EQ(x.model, y.model);
  EXPECT_EQ(x.actions, y.actions);
}

TEST(ApplianceState, NamesForLogsAndScreens) {
  EXPECT_STREQ(to_string(State::Analysing), "Analysing");
  EXPECT_STREQ(to_string(Input::OkLong), "OK (long)");
  EXPECT_STREQ(to_string(Tier::Final), "final");
  EXPECT_STREQ(to_string(RelightParam::Aperture), "aperture");
  EXPECT_EQ(describe(Event{RenderProgress{3, 0.25}}), "RenderProgress{job 3, 0.25}");
  EXPECT_EQ(describe(Action{StartRender{3, Tier::Good, 2}}), "StartRender{job 3, good, prop 2}");
}

}  // namespace
}  // namespace propcam::appliance
