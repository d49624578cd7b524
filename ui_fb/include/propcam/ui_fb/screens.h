// The appliance's screens, drawn from a view model. ui_fb knows nothing of
// cameras, scenes or the state machine: the firmware fills a ScreenView (what
// the user should see right now) and draw_screen paints it. Every screen has
// the same frame: a title bar on top, the main area, and a hint bar at the
// bottom naming what each button does here.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "propcam/ui_fb/buttons.h"
#include "propcam/ui_fb/canvas.h"

namespace propcam::ui_fb {

enum class ScreenKind {
  Viewfinder,  // live camera frames
  Captured,    // the frozen frame while the still is read out
  Analysing,   // the photo dimmed, each inference stage with its progress and time
  Carousel,    // prop thumbnails, the selected one large
  Placement,   // the photo, a cursor on a support surface, the prop's footprint and a preview
  TierPick,    // draft / good / final, each with its predicted time
  Rendering,   // the progressive composite, each tile's convergence, elapsed and predicted time
  Adjusting,   // the composite with relight / depth-of-field sliders
  Exporting,   // the composite with the export's progress or result
  Fault,       // what went wrong and how to go on
};

// One button's meaning on this screen, drawn in the hint bar ("OK  place").
struct ButtonHint {
  Button button = Button::Ok;
  std::string label;
  bool long_press = false;  // drawn as "hold OK"
};

struct StageLine {
  enum class Status { Pending, Running, Done, Failed, Skipped };
  std::string name;
  Status status = Status::Pending;
  double seconds = 0.0;   // spent so far (Running) or in all (Done)
  std::string detail;     // short, e.g. "3 lights" or the failure
};

struct PropCard {
  std::string name;
  std::string material;   // "glossy", "metal", ...
  cv::Mat thumbnail;      // CV_8UC3 RGB or CV_32FC3 linear; may be empty (a placeholder is drawn)
  bool from_usb = false;  // listed from the stick's props/ folder
};

struct TierChoice {
  std::string name;                // "draft"
  double predicted_seconds = 0.0;  // from this device's measured throughput; <= 0: unknown
  int samples_per_pixel = 0;
};

// A render tile in image pixel coordinates.
struct TileView {
  cv::Rect rect;
  bool affected = true;          // false: the prop cannot reach it, never traced
  bool done = false;
  double relative_error = 0.0;   // standard error / brightness
  int samples = 0;
};

struct SliderView {
  std::string name;        // "scene light"
  int value = 0;           // in [min, max]
  int min = -10, max = 10;
  std::string value_text;  // "+1.5 EV", "f/2.8", "2.4 m"
};

struct ScreenView {
  ScreenKind kind = ScreenKind::Viewfinder;
  std::string title;   // top bar, left
  std::string status;  // top bar, right: "USB 3.1 GB free", "no stick: 2 spooled", ...
  std::vector<ButtonHint> hints;

  // The picture of the main area: the viewfinder frame, the photo or the
  // composite (CV_8UC3 RGB or CV_32FC3 linear). Drawn fitted to the main area,
  // aspect kept; image_area() says where.
  cv::Mat image;
  std::string image_caption;  // drawn over the image's bottom edge, e.g. "camera lost: reconnecting"

  // Analysing
  std::vector<StageLine> stages;
  double elapsed_seconds = 0.0;  // also Rendering and Exporting

  // Carousel
  std::vector<PropCard> props;
  int selected_prop = 0;

  // Placement (image pixel coordinates)
  std::vector<cv::Point2d> spots;      // the snapped positions NEXT/PREV move between
  int selected_spot = -1;
  std::vector<cv::Point2d> footprint;  // the prop's base outline at the cursor (a closed polygon)
  std::string placement_text;          // "on the floor, 2.3 m away"

  // TierPick
  std::vector<TierChoice> tiers;
  int selected_tier = 0;

  // Rendering
  std::vector<TileView> tiles;
  double converged_fraction = 0.0;            // of affected tiles, in [0, 1]
  double predicted_seconds_to_good = -1.0;    // < 0: unknown
  double predicted_seconds_to_done = -1.0;    // < 0: unknown
  int samples_per_pixel = 0;                  // of the most sampled tile
  int skipped_tiles = 0;                      // tiles the prop cannot affect
  std::vector<std::string> skipped_effects;   // "no caustics", "no glossy" (transport the plan skipped)

  // Adjusting
  std::vector<SliderView> sliders;
  int selected_slider = 0;

  // Exporting
  std::string export_text;              // "writing composite.png", "saved to USB: ...", "no stick: kept in spool"
  std::optional<bool> export_succeeded; // nullopt while running

  // Fault
  std::string fault_message;
};

// Layout of a canvas: the title bar, the main area and the hint bar.
struct ScreenLayout {
  Rect title_bar;
  Rect main;
  Rect hint_bar;
};
ScreenLayout screen_layout(Size canvas);

// Where draw_screen puts an image of `image` size inside `area` (fitted,
// centred, aspect kept), so callers can map image pixels to screen pixels.
Rect image_area(const Rect& area, Size image);

// Where draw_screen puts view.image on a canvas of this size (in canvas pixels):
// image_area() of the screen's picture region, which is the main area except
// on Rendering (a progress strip below) and Adjusting (the sliders below).
// Empty when the image is empty or of a type that cannot be drawn.
Rect screen_image_area(Size canvas, const ScreenView& view);

// The outline colour of an unfinished tile on the Rendering screen: green at or
// below kTileErrorLow, through yellow, to red at or above kTileErrorHigh (log
// scale in between). NaN (no estimate yet) counts as high.
inline constexpr double kTileErrorLow = 0.01;
inline constexpr double kTileErrorHigh = 0.25;
Rgb tile_error_colour(double relative_error);

// The colours draw_screen paints with, so tests and tools can find things on screen.
namespace screen_colours {
inline constexpr Rgb kBackground{18, 20, 24};
inline constexpr Rgb kBar{34, 38, 46};         // title and hint bars
inline constexpr Rgb kText{236, 238, 240};
inline constexpr Rgb kDimText{150, 156, 166};
inline constexpr Rgb kAccent{64, 156, 255};    // keys in the hint bar, progress, selection border
inline constexpr Rgb kHighlight{30, 96, 190};  // the selected row (tier, slider)
inline constexpr Rgb kTrack{70, 76, 88};       // empty part of progress bars and sliders
inline constexpr Rgb kPlaceholder{44, 46, 52}; // where an image is missing
inline constexpr Rgb kFlash{255, 255, 255};    // the Captured screen's border
inline constexpr Rgb kFault{224, 52, 52};
inline constexpr Rgb kFaultPanel{52, 20, 22};
inline constexpr Rgb kGood{72, 200, 96};
inline constexpr Rgb kUsbBadge{240, 150, 30};
inline constexpr Rgb kFootprint{255, 214, 0};
inline constexpr Rgb kCursor{255, 60, 170};
inline constexpr Rgb kSpot{255, 255, 255};
}  // namespace screen_colours

// Paints the whole canvas. Never throws for view contents (empty images,
// out-of-range indices, NaN times and huge strings are drawn as something
// sensible); throws std::runtime_error only if the font is missing.
void draw_screen(Canvas& canvas, const ScreenView& view);

const char* to_string(ScreenKind kind);

}  // namespace propcam::ui_fb
