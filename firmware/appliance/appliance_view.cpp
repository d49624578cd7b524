// The screen of each state, filled in from the state machine's model and what
// the workers published (appliance.h's build_view).
#include <cmath>
#include <cstdio>

#include "appliance/appliance.h"
#include "appliance/appliance_shared.h"

namespace propcam::firmware {
using namespace appliance;
using ui_fb::Button;
using ui_fb::ButtonHint;
using ui_fb::ScreenKind;

namespace {

ButtonHint hint(Button button, std::string label, bool long_press = false) {
  ButtonHint h;
  h.button = button;
  h.label = std::move(label);
  h.long_press = long_press;
  return h;
}

constexpr Tier kTiers[] = {Tier::Draft, Tier::Good, Tier::Final};

// What the workers published, copied under the lock once per frame.
struct Published {
  std::shared_ptr<const Analysis> analysis;
  std::shared_ptr<const RenderSnapshot> render;
  cv::Mat still;
  double affected_share = 0, rate_pixel_samples = 0;
  cv::Mat preview;  // empty unless it shows the prop and spot the screen wants
};

void fill_carousel(ui_fb::ScreenView& view, const std::vector<PropEntry>& props, int prop_index) {
  view.kind = ScreenKind::Carousel;
  view.title = "Choose a prop";
  for (const PropEntry& p : props) {
    ui_fb::PropCard card;
    card.name = p.name;
    card.material = p.material;
    card.thumbnail = p.thumbnail;
    card.from_usb = p.from_usb;
    view.props.push_back(card);
  }
  view.selected_prop = prop_index;
  view.hints = {hint(Button::Prev, "prop"), hint(Button::Next, "prop"), hint(Button::Ok, "choose"),
                hint(Button::Back, "new photo")};
}

void fill_tier_pick(ui_fb::ScreenView& view, const cv::Mat& photo, const Published& pub, Tier selected) {
  view.kind = ScreenKind::TierPick;
  view.title = "Render quality";
  const double pixels = photo.empty() ? 0.0 : static_cast<double>(photo.total()) * pub.affected_share;
  for (Tier t : kTiers) {
    const TierSpec spec = tier_spec(t);
    ui_fb::TierChoice c;
    c.name = to_string(t);
    c.samples_per_pixel = spec.max_samples_per_pixel;
    // An upper bound: tiles stop early at the tier's target error.
    c.predicted_seconds =
        pub.rate_pixel_samples > 0 ? pixels * spec.max_samples_per_pixel / pub.rate_pixel_samples : -1;
    view.tiers.push_back(c);
    if (t == selected) view.selected_tier = static_cast<int>(view.tiers.size()) - 1;
  }
  view.hints = {hint(Button::Prev, "quality"), hint(Button::Next, "quality"), hint(Button::Ok, "render"),
                hint(Button::Back, "move")};
}

void fill_rendering(ui_fb::ScreenView& view, const RenderSnapshot* render, double render_fraction) {
  view.kind = ScreenKind::Rendering;
  if (render) {
    for (const auto& t : render->tiles) {
      ui_fb::TileView tv;
      tv.rect = t.rect;
      tv.affected = t.affected;
      tv.done = t.done;
      tv.relative_error = t.relative_error;
      tv.samples = t.samples;
      view.tiles.push_back(tv);
    }
    view.converged_fraction = render->converged_fraction;
    view.elapsed_seconds = render->elapsed_seconds;
    view.predicted_seconds_to_good = render->seconds_to_good;
    view.predicted_seconds_to_done = render->seconds_to_done;
    view.samples_per_pixel = render->samples_per_pixel;
    view.skipped_tiles = render->skipped_tiles;
    view.skipped_effects = render->skipped_effects;
  }
  view.hints = {hint(Button::Back, "cancel")};
  if (render_fraction >= kMinUsableFraction) {
    view.hints.push_back(hint(Button::Ok, "stop, keep"));
    view.hints.push_back(hint(Button::Ok, "export", true));
  }
}

void fill_sliders(ui_fb::ScreenView& view, const Model& model, const RenderSnapshot* render) {
  const double distance = render ? render->prop_distance_m : 2.0;
  for (int i = 0; i < kRelightParamCount; ++i) {
    const auto param = static_cast<RelightParam>(i);
    ui_fb::SliderView s;
    s.name = to_string(param);
    s.value = model.relight_values[static_cast<size_t>(i)];
    s.min = -kRelightMaxSteps;
    s.max = kRelightMaxSteps;
    s.value_text = describe_step(param, s.value, distance);
    view.sliders.push_back(s);
  }
  view.selected_slider = static_cast<int>(model.relight);
}

}  // namespace

// The placement screen: the spots, the prop's footprint on the chosen one
// (its mesh loaded on first use) and where that is.
void Appliance::fill_placement(ui_fb::ScreenView& view, const Analysis* analysis, const cv::Mat& preview,
                               const std::string& prop_name) const {
  const Model& model = machine_.model();
  view.kind = ScreenKind::Placement;
  view.title = "Place the " + prop_name;
  if (!preview.empty()) view.image = preview;
  for (const Spot& s : spots_) view.spots.push_back(s.pixel);
  if (!spots_.empty() && analysis) {
    const size_t index = static_cast<size_t>(spot_index_) % spots_.size();
    const Spot& spot = spots_[index];
    view.selected_spot = static_cast<int>(index);
    const size_t p = static_cast<size_t>(model.prop_index);
    if (p < props_.size()) {
      if (!prop_meshes_[p]) prop_meshes_[p] = load_prop(props_[p].source);
      view.footprint = footprint_outline(analysis->scene, spot, *prop_meshes_[p], props_[p].natural_height_m);
    }
    char text[96];
    std::snprintf(text, sizeof text, "on the %s, %.1f m away", spot.surface.c_str(), spot.distance_m);
    view.placement_text = text;
  }
  view.hints = {hint(Button::Prev, "move"), hint(Button::Next, "move"), hint(Button::Ok, "place here"),
                hint(Button::Back, "prop")};
}

ui_fb::ScreenView Appliance::build_view() const {
  const Model& model = machine_.model();
  ui_fb::ScreenView view;
  Published pub;
  const std::string wanted_preview = preview_key();
  {
    std::lock_guard lock(shared_->mutex);
    pub.analysis = shared_->analysis;
    pub.render = shared_->render;
    pub.still = shared_->still.rgb8;
    view.status = shared_->usb_message;
    view.stages = shared_->stages;
    if (model.state == State::Analysing) view.elapsed_seconds = seconds_since(shared_->analysis_start);
    if (model.state == State::Exporting) view.elapsed_seconds = seconds_since(shared_->export_start);
    view.export_text = shared_->export_text;
    view.export_succeeded = shared_->export_ok;
    pub.affected_share = shared_->affected_share;
    if (shared_->preview_key == wanted_preview) pub.preview = shared_->preview;
    pub.rate_pixel_samples = throughput_->pixel_samples_per_second();
  }
  const cv::Mat photo = pub.analysis ? pub.analysis->photo_rgb8 : pub.still;
  const RenderSnapshot* render = pub.render.get();
  const cv::Mat render_image = render && !render->display.empty() ? render->display : photo;
  const std::string prop_name =
      model.prop_index < static_cast<int>(props_.size()) ? props_[static_cast<size_t>(model.prop_index)].name : "";

  switch (model.state) {
    case State::Viewfinder: {
      view.kind = ScreenKind::Viewfinder;
      view.title = "PropCam";
      const ViewfinderFrame frame = camera_->latest();
      view.image = frame.rgb8;
      view.image_caption = frame.problem;
      shown_frame_ = frame.number;
      view.hints = {hint(Button::Shoot, "shoot")};
      break;
    }
    case State::Captured:
      view.kind = ScreenKind::Captured;
      view.title = "Capturing";
      view.image = pub.still.empty() ? camera_->latest().rgb8 : pub.still;
      view.hints = {hint(Button::Back, "cancel")};
      break;
    case State::Analysing:
      view.kind = ScreenKind::Analysing;
      view.title = "Analysing the scene";
      view.image = photo;
      view.hints = {hint(Button::Back, "cancel")};
      break;
    case State::Placing:
      view.image = photo;
      if (model.placing_step == PlacingStep::Prop) fill_carousel(view, props_, model.prop_index);
      if (model.placing_step == PlacingStep::Spot) fill_placement(view, pub.analysis.get(), pub.preview, prop_name);
      if (model.placing_step == PlacingStep::Tier) fill_tier_pick(view, photo, pub, model.tier);
      break;
    case State::Rendering:
      view.title = "Rendering the " + prop_name + " (" + to_string(model.tier) + ")";
      view.image = render_image;
      fill_rendering(view, render, model.render_fraction);
      break;
    case State::Adjusting:
    case State::Exporting:
      view.kind = model.state == State::Adjusting ? ScreenKind::Adjusting : ScreenKind::Exporting;
      view.title = model.state == State::Adjusting ? "Adjust the " + prop_name : "Exporting";
      view.image = adjusted_.empty() ? render_image : adjusted_;
      fill_sliders(view, model, render);
      if (model.state == State::Adjusting) {
        if (model.last_export && !view.export_text.empty()) view.image_caption = view.export_text;
        view.hints = {hint(Button::Prev, "less"), hint(Button::Next, "more"), hint(Button::Ok, "next setting"),
                      hint(Button::Ok, "export", true), hint(Button::Back, "re-render")};
      }
      break;
    case State::Fault:
      view.kind = ScreenKind::Fault;
      view.title = "Something went wrong";
      view.fault_message = model.fault_message;
      view.hints = {hint(Button::Ok, "continue")};
      break;
  }
  return view;
}

}  // namespace propcam::firmware
