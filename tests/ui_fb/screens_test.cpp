#include "propcam/ui_fb/screens.h"

#include <cmath>
#include <set>
#include <utility>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "screen_test_helpers.h"

namespace propcam::ui_fb {
namespace {

using namespace testing_helpers;
namespace colours = screen_colours;

constexpr Rgb kPhoto{90, 140, 60};  // a colour no widget uses
constexpr Rgb kRedThumb{200, 30, 30};
constexpr Rgb kGreenThumb{30, 200, 30};
constexpr Rgb kBlueThumb{30, 30, 200};

constexpr ScreenKind kAllKinds[] = {
    ScreenKind::Viewfinder, ScreenKind::Captured,  ScreenKind::Analysing, ScreenKind::Carousel,
    ScreenKind::Placement,  ScreenKind::TierPick,  ScreenKind::Rendering, ScreenKind::Adjusting,
    ScreenKind::Exporting,  ScreenKind::Fault};

std::vector<ButtonHint> typical_hints() {
  return {{Button::Prev, "prop", false},
          {Button::Next, "prop", false},
          {Button::Ok, "place", false},
          {Button::Ok, "export", true}};
}

// A view of `kind` with every field filled, for the determinism check.
ScreenView full_view(ScreenKind kind) {
  ScreenView view;
  view.kind = kind;
  view.title = to_string(kind);
  view.status = "USB 3.1 GB free";
  view.hints = typical_hints();
  view.image = solid_image(320, 240, kPhoto);
  view.image_caption = "camera lost: reconnecting";
  view.stages = {{"pose", StageLine::Status::Done, 0.42, "f=3.2 mm"},
                 {"lights", StageLine::Status::Running, 1.5, "3 lights"},
                 {"materials", StageLine::Status::Pending, 0.0, ""}};
  view.elapsed_seconds = 3.25;
  view.props = {{"vase", "glossy", solid_image(32, 32, kRedThumb), true}};
  view.spots = {{100, 200}, {200, 210}};
  view.selected_spot = 1;
  view.footprint = {{180, 200}, {220, 200}, {220, 220}, {180, 220}};
  view.placement_text = "on the floor, 2.3 m away";
  view.tiers = {{"draft", 12, 16}, {"good", 95, 128}};
  view.tiles = {{cv::Rect(0, 0, 160, 120), true, false, 0.1, 16}};
  view.converged_fraction = 0.4;
  view.predicted_seconds_to_good = 4;
  view.predicted_seconds_to_done = 20;
  view.samples_per_pixel = 64;
  view.skipped_tiles = 3;
  view.skipped_effects = {"no caustics"};
  view.sliders = {{"scene light", 3, -10, 10, "+1.5 EV"}};
  view.export_text = "writing composite.png";
  view.fault_message = "the camera stopped answering";
  return view;
}

Canvas draw(const ScreenView& view, Size size = {640, 480}) {
  Canvas canvas(size);
  draw_screen(canvas, view);
  return canvas;
}

TEST(ScreensLayout, BarsAndMainAreaTileTheCanvas) {
  for (Size size : {Size{320, 240}, Size{640, 480}, Size{800, 480}, Size{1280, 800}}) {
    const ScreenLayout layout = screen_layout(size);
    EXPECT_EQ(layout.title_bar.y, 0);
    EXPECT_EQ(layout.main.y, layout.title_bar.bottom());
    EXPECT_EQ(layout.hint_bar.y, layout.main.bottom());
    EXPECT_EQ(layout.hint_bar.bottom(), size.height);
    for (const Rect& r : {layout.title_bar, layout.main, layout.hint_bar}) {
      EXPECT_EQ(r.x, 0);
      EXPECT_EQ(r.width, size.width);
    }
    // The bars hold a readable line but leave most of the screen to the picture.
    EXPECT_GE(layout.title_bar.height, 16);
    EXPECT_GE(layout.hint_bar.height, 16);
    EXPECT_GT(layout.main.height, size.height * 2 / 3);
  }
  EXPECT_GT(screen_layout({1280, 800}).title_bar.height,
            screen_layout({320, 240}).title_bar.height);
}

TEST(ScreensLayout, TinyCanvasesKeepHalfForTheMainArea) {
  for (Size size : {Size{1, 1}, Size{40, 10}, Size{10, 40}}) {
    const ScreenLayout layout = screen_layout(size);
    EXPECT_GE(layout.main.height, size.height / 2);
    EXPECT_EQ(layout.hint_bar.bottom(), size.height);
  }
}

TEST(ScreensImageArea, FitsCentredWithTheAspectKept) {
  EXPECT_EQ(image_area({0, 0, 400, 200}, {640, 480}), (Rect{66, 0, 267, 200}));
  EXPECT_EQ(image_area({10, 20, 300, 300}, {200, 100}), (Rect{10, 95, 300, 150}));
  EXPECT_TRUE(image_area({0, 0, 400, 200}, {0, 0}).empty());
  EXPECT_TRUE(image_area({0, 0, 0, 200}, {10, 10}).empty());
}

TEST(ScreensKinds, NamesAreDistinct) {
  std::set<std::string> names;
  for (ScreenKind kind : kAllKinds) names.insert(to_string(kind));
  EXPECT_EQ(names.size(), std::size(kAllKinds));
  EXPECT_STREQ(to_string(ScreenKind::TierPick), "tier-pick");
}

TEST(ScreensViewfinder, ImageAreaHoldsExactlyTheFrame) {
  ScreenView view;
  view.kind = ScreenKind::Viewfinder;
  view.image = solid_image(640, 360, kPhoto);  // 16:9 in a 4:3 canvas: bars above and below
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  EXPECT_EQ(area, image_area(screen_layout(canvas.size()).main, {640, 360}));
  EXPECT_EQ(count_colour(canvas, area, kPhoto), area_of(area));
  EXPECT_EQ(count_colour(canvas, canvas.bounds(), kPhoto), area_of(area))
      << "frame drawn elsewhere";
}

TEST(ScreensViewfinder, CaptionIsDrawnOverTheBottomEdge) {
  ScreenView view;
  view.image = solid_image(640, 480, kPhoto);
  view.image_caption = "camera lost: reconnecting";
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  const Rect bottom{area.x, area.bottom() - area.height / 8, area.width, area.height / 8};
  const Rect top{area.x, area.y, area.width, area.height / 8};
  EXPECT_EQ(count_colour(canvas, top, kPhoto), area_of(top));
  EXPECT_LT(count_colour(canvas, bottom, kPhoto), area_of(bottom) / 2);
  EXPECT_GT(count_colour(canvas, bottom, colours::kText), 0);
}

TEST(ScreensViewfinder, EmptyImageDrawsAPlaceholderWithText) {
  ScreenView view;
  const Canvas canvas = draw(view);
  const Rect main = screen_layout(canvas.size()).main;
  EXPECT_TRUE(screen_image_area(canvas.size(), view).empty());
  EXPECT_EQ(canvas.pixel(main.x + 1, main.y + 1), colours::kPlaceholder);
  EXPECT_GT(count_pixels(canvas, main, [](Rgb p) { return p.r > 120; }), 50) << "no text";
}

TEST(ScreensFrame, TitleStatusAndHintsAreDrawn) {
  ScreenView view;
  view.title = "Viewfinder";
  view.status = "USB 3.1 GB free";
  view.hints = typical_hints();
  const Canvas canvas = draw(view);
  const ScreenLayout layout = screen_layout(canvas.size());
  const Rect bar = layout.title_bar;
  const auto ink = [](Rgb p) { return p.r > 120 && p.g > 120; };
  EXPECT_GT(count_pixels(canvas, {bar.x, bar.y, bar.width / 3, bar.height}, ink), 30);
  EXPECT_GT(count_pixels(canvas, {bar.right() - bar.width / 3, bar.y, bar.width / 3, bar.height},
                         ink), 30);
  // Keys in the accent colour, labels in text colour.
  EXPECT_GT(count_colour(canvas, layout.hint_bar, colours::kAccent), 30);
  EXPECT_GT(count_colour(canvas, layout.hint_bar, colours::kText), 30);

  view.hints.clear();
  const Canvas without = draw(view);
  EXPECT_EQ(count_colour(without, layout.hint_bar, colours::kBar), area_of(layout.hint_bar));
}

TEST(ScreensFrame, HintsTooWideForTheBarStayInsideIt) {
  ScreenView view;
  for (int i = 0; i < 8; ++i) view.hints.push_back({Button::Ok, "a rather long label", i % 2 == 0});
  const Canvas canvas = draw(view, {320, 240});
  const ScreenLayout layout = screen_layout(canvas.size());
  EXPECT_GT(count_colour(canvas, layout.hint_bar, colours::kAccent), 10);
  // The main area is the placeholder, untouched by the hints.
  const Rect main_bottom{0, layout.main.bottom() - 3, layout.main.width, 3};
  EXPECT_EQ(count_colour(canvas, main_bottom, colours::kPlaceholder), area_of(main_bottom));
}

TEST(ScreensCaptured, FrozenFrameGetsAWhiteFlashBorder) {
  ScreenView view;
  view.kind = ScreenKind::Captured;
  view.image = solid_image(640, 480, kPhoto);
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  EXPECT_EQ(canvas.pixel(area.x, area.y + area.height / 2), colours::kFlash);
  EXPECT_EQ(canvas.pixel(area.right() - 1, area.y + area.height / 2), colours::kFlash);
  EXPECT_EQ(canvas.pixel(area.x + area.width / 2, area.y), colours::kFlash);
  EXPECT_EQ(canvas.pixel(area.x + area.width / 2, area.y + area.height / 3), kPhoto);
}

TEST(ScreensAnalysing, PhotoIsDimmedAndStagesShowTheirStatus) {
  ScreenView view;
  view.kind = ScreenKind::Analysing;
  view.image = solid_image(640, 480, kPhoto);
  view.stages = {{"pose", StageLine::Status::Done, 0.42, ""},
                 {"depth", StageLine::Status::Failed, 1.0, "model missing"}};
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  const Rgb corner = canvas.pixel(area.x + 1, area.y + 1);
  EXPECT_LT(corner.g, kPhoto.g);
  EXPECT_GT(corner.g, 0);
  EXPECT_EQ(count_colour(canvas, area, kPhoto), 0);
  EXPECT_GT(count_colour(canvas, area, colours::kGood), 5) << "✔ of the done stage";
  EXPECT_GT(count_colour(canvas, area, colours::kFault), 5) << "✖ of the failed stage";
}

ScreenView carousel_view(bool selected_from_usb) {
  ScreenView view;
  view.kind = ScreenKind::Carousel;
  view.props = {{"cube", "metal", solid_image(48, 48, kRedThumb), false},
                {"vase", "glossy", solid_image(48, 48, kGreenThumb), selected_from_usb},
                {"lamp", "emissive", solid_image(48, 48, kBlueThumb), false}};
  view.selected_prop = 1;
  return view;
}

TEST(ScreensCarousel, SelectedThumbnailIsLargeWithNeighboursOnBothSides) {
  const Canvas canvas = draw(carousel_view(false));
  const Rect main = screen_layout(canvas.size()).main;
  const int centre_x = main.x + main.width / 2;
  EXPECT_EQ(canvas.pixel(centre_x, main.y + main.height / 2), kGreenThumb);
  const Rect large = bounding_box_of(canvas, main, kGreenThumb);
  const Rect left = bounding_box_of(canvas, main, kRedThumb);
  const Rect right = bounding_box_of(canvas, main, kBlueThumb);
  ASSERT_FALSE(large.empty());
  ASSERT_FALSE(left.empty());
  ASSERT_FALSE(right.empty());
  EXPECT_GT(large.width, main.width / 3);
  EXPECT_LT(left.width, large.width);
  EXPECT_LE(left.right(), large.x);     // PREV's prop to the left
  EXPECT_GE(right.x, large.right());    // NEXT's prop to the right
  EXPECT_EQ(count_colour(canvas, main, kGreenThumb), area_of(large));  // solid, unobstructed
  EXPECT_EQ(count_colour(canvas, main, colours::kUsbBadge), 0);
}

TEST(ScreensCarousel, UsbPropsGetABadge) {
  const Canvas canvas = draw(carousel_view(true));
  const Rect main = screen_layout(canvas.size()).main;
  const Rect badge = bounding_box_of(canvas, main, colours::kUsbBadge);
  const Rect large = bounding_box_of(canvas, main, kGreenThumb);
  ASSERT_FALSE(badge.empty());
  EXPECT_EQ(intersect(badge, large), badge) << "the badge sits on the selected thumbnail";
}

TEST(ScreensCarousel, IndexIsShown) {
  ScreenView view = carousel_view(false);
  const Canvas one = draw(view);
  view.props.push_back({"extra", "glossy", solid_image(4, 4, kBlueThumb), false});
  const Canvas two = draw(view);  // "2 / 3" becomes "2 / 4"
  const Rect main = screen_layout(one.size()).main;
  const Rect top_right{main.right() - main.width / 4, main.y, main.width / 4, main.height / 12};
  EXPECT_GT(count_pixels(one, top_right, [](Rgb p) { return p.r > 100; }), 10);
  int differing = 0;
  for (int y = top_right.y; y < top_right.bottom(); ++y) {
    for (int x = top_right.x; x < top_right.right(); ++x) {
      differing += !(one.pixel(x, y) == two.pixel(x, y));
    }
  }
  EXPECT_GT(differing, 0);
}

TEST(ScreensPlacement, CursorSpotsAndFootprintAreDrawnOnThePhoto) {
  ScreenView view;
  view.kind = ScreenKind::Placement;
  view.image = solid_image(640, 480, kPhoto);
  view.spots = {{100, 400}, {500, 400}};
  view.selected_spot = 1;
  view.footprint = {{450, 380}, {550, 380}, {550, 420}, {450, 420}};
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  const Rect cursor = bounding_box_of(canvas, area, colours::kCursor);
  ASSERT_FALSE(cursor.empty());
  const int spot_x = screen_edge(area.x, area.width, 640, 500.5);
  const int spot_y = screen_edge(area.y, area.height, 480, 400.5);
  EXPECT_NEAR(cursor.x + cursor.width / 2.0, spot_x, 2.0);
  EXPECT_NEAR(cursor.y + cursor.height / 2.0, spot_y, 2.0);
  const Rect footprint = bounding_box_of(canvas, area, colours::kFootprint);
  EXPECT_NEAR(footprint.x, screen_edge(area.x, area.width, 640, 450.5), 2.0);
  EXPECT_NEAR(footprint.right(), screen_edge(area.x, area.width, 640, 550.5), 2.0);
  // The other spot is a white dot near its place, away from the cursor.
  const Rect left_half{area.x, area.y, area.width / 2, area.height};
  EXPECT_GT(count_colour(canvas, left_half, colours::kSpot), 3);
  EXPECT_EQ(count_colour(canvas, left_half, colours::kCursor), 0);

  view.selected_spot = -1;
  EXPECT_EQ(count_colour(draw(view), area, colours::kCursor), 0);
}

TEST(ScreensPlacement, TextIsShownOverThePhoto) {
  ScreenView view;
  view.kind = ScreenKind::Placement;
  view.image = solid_image(640, 480, kPhoto);
  const Rect area = screen_image_area({640, 480}, view);
  EXPECT_EQ(count_colour(draw(view), area, kPhoto), area_of(area));
  view.placement_text = "on the floor, 2.3 m away";
  EXPECT_GT(count_colour(draw(view), area, colours::kText), 20);
}

// The rows (y) holding highlight-coloured pixels.
Rect highlight_band(const Canvas& canvas) {
  return bounding_box_of(canvas, screen_layout(canvas.size()).main, colours::kHighlight);
}

TEST(ScreensTierPick, SelectedTierRowIsHighlighted) {
  ScreenView view;
  view.kind = ScreenKind::TierPick;
  view.image = solid_image(640, 480, kPhoto);
  view.tiers = {{"draft", 12, 16}, {"good", 95, 128}, {"final", -1, 1024}};
  view.selected_tier = 0;
  const Rect first = highlight_band(draw(view));
  view.selected_tier = 2;
  const Rect last = highlight_band(draw(view));
  ASSERT_FALSE(first.empty());
  ASSERT_FALSE(last.empty());
  EXPECT_EQ(first.height, last.height);
  EXPECT_GE(last.y, first.bottom()) << "one row, moving down with the selection";
  EXPECT_LT(first.height, screen_layout({640, 480}).main.height / 4);
  view.selected_tier = 7;
  EXPECT_TRUE(highlight_band(draw(view)).empty());
}

TEST(ScreensTierPick, UnknownTimeIsSaidSo) {
  ScreenView view;
  view.kind = ScreenKind::TierPick;
  view.tiers = {{"final", 0, 1024}};
  const Canvas unknown = draw(view);
  view.tiers[0].predicted_seconds = 12;
  const Canvas known = draw(view);
  const Rect main = screen_layout(known.size()).main;
  // "time unknown" is wider than "~12 s".
  const auto ink = [](Rgb p) { return p.r > 150 && p.g > 150 && p.b > 150; };
  EXPECT_GT(count_pixels(unknown, main, ink), count_pixels(known, main, ink));
}

// A 320x240 composite in 40x40 tiles.
ScreenView rendering_view() {
  ScreenView view;
  view.kind = ScreenKind::Rendering;
  view.image = solid_image(320, 240, kPhoto);
  for (int y = 0; y < 240; y += 40) {
    for (int x = 0; x < 320; x += 40) {
      TileView tile;
      tile.rect = cv::Rect(x, y, 40, 40);
      tile.affected = x >= 160;            // the right half can see the prop
      tile.done = x >= 160 && y >= 160;    // its bottom rows have converged
      tile.relative_error = y < 80 ? 0.5 : 0.005;
      view.tiles.push_back(tile);
    }
  }
  view.converged_fraction = 0.5;
  return view;
}

Rect tile_on_screen(const Rect& area, const cv::Rect& tile) {
  const int left = screen_edge(area.x, area.width, 320, tile.x);
  const int top = screen_edge(area.y, area.height, 240, tile.y);
  return {left, top, screen_edge(area.x, area.width, 320, tile.x + tile.width) - left,
          screen_edge(area.y, area.height, 240, tile.y + tile.height) - top};
}

TEST(ScreensRendering, CulledTilesShowThePhotoAndUnfinishedTilesTheirError) {
  const ScreenView view = rendering_view();
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  ASSERT_FALSE(area.empty());
  EXPECT_LT(area.bottom(), screen_layout(canvas.size()).main.bottom()) << "room for progress";
  for (const TileView& tile : view.tiles) {
    const Rect screen = tile_on_screen(area, tile.rect);
    const int photo = count_colour(canvas, screen, kPhoto);
    if (!tile.affected || tile.done) {
      EXPECT_EQ(photo, area_of(screen)) << "tile at " << tile.rect.x << "," << tile.rect.y;
    } else {
      const Rgb outline = tile_error_colour(tile.relative_error);
      EXPECT_EQ(canvas.pixel(screen.x, screen.y + screen.height / 2), outline);
      EXPECT_EQ(canvas.pixel(screen.x + screen.width / 2, screen.bottom() - 1), outline);
      EXPECT_EQ(canvas.pixel(screen.x + screen.width / 2, screen.y + screen.height / 2), kPhoto);
    }
  }
}

TEST(ScreensRendering, ProgressBarShowsTheConvergedFraction) {
  ScreenView view = rendering_view();
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  const Rect main = screen_layout(canvas.size()).main;
  const Rect strip{main.x, area.bottom(), main.width, main.bottom() - area.bottom()};
  int best_row = -1, best = 0;
  for (int y = strip.y; y < strip.bottom(); ++y) {
    const int accent = count_colour(canvas, {strip.x, y, strip.width, 1}, colours::kAccent);
    if (accent > best) best = accent, best_row = y;
  }
  ASSERT_GE(best_row, 0);
  const int track = count_colour(canvas, {strip.x, best_row, strip.width, 1}, colours::kTrack);
  EXPECT_NEAR(static_cast<double>(best) / (best + track), 0.5, 0.01);
}

TEST(ScreensRendering, FiguresAppearOnlyWhenKnown) {
  ScreenView view = rendering_view();
  const Canvas bare = draw(view);
  view.elapsed_seconds = 12.5;
  view.predicted_seconds_to_good = 4;
  view.predicted_seconds_to_done = 20;
  view.samples_per_pixel = 256;
  view.skipped_tiles = 24;
  view.skipped_effects = {"no caustics"};
  const Canvas full = draw(view);
  const Rect area = screen_image_area(full.size(), view);
  const Rect main = screen_layout(full.size()).main;
  const Rect strip{main.x, area.bottom(), main.width, main.bottom() - area.bottom()};
  const auto ink = [](Rgb p) { return p.r > 120 && p.g > 120 && p.b > 120; };
  EXPECT_GT(count_pixels(full, strip, ink), count_pixels(bare, strip, ink) + 100);
}

TEST(ScreensRendering, TileErrorColourGoesFromGreenToRed) {
  const Rgb low = tile_error_colour(kTileErrorLow / 2);
  const Rgb high = tile_error_colour(kTileErrorHigh * 2);
  EXPECT_GT(low.g, low.r);
  EXPECT_GT(high.r, high.g);
  EXPECT_EQ(tile_error_colour(std::nan("")), high);
  EXPECT_EQ(tile_error_colour(-1.0), low);
  const Rgb middle = tile_error_colour(std::sqrt(kTileErrorLow * kTileErrorHigh));
  EXPECT_GT(middle.r, 200);
  EXPECT_GT(middle.g, 150);
}

TEST(ScreensAdjusting, SelectedSliderIsHighlightedBelowThePicture) {
  ScreenView view;
  view.kind = ScreenKind::Adjusting;
  view.image = solid_image(640, 480, kPhoto);
  view.sliders = {{"scene light", 3, -10, 10, "+1.5 EV"}, {"aperture", 5, 0, 10, "f/2.8"}};
  view.selected_slider = 1;
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  EXPECT_EQ(count_colour(canvas, area, kPhoto), area_of(area));
  const Rect band = highlight_band(canvas);
  ASSERT_FALSE(band.empty());
  EXPECT_GE(band.y, area.bottom());
  view.selected_slider = 0;
  EXPECT_LT(highlight_band(draw(view)).y, band.y);
}

TEST(ScreensExporting, ShowsProgressThenTheResult) {
  ScreenView view;
  view.kind = ScreenKind::Exporting;
  view.image = solid_image(640, 480, kPhoto);
  view.export_text = "writing composite.png";
  const Rect main = screen_layout({640, 480}).main;
  const Canvas running = draw(view);
  view.elapsed_seconds = 0.5;
  EXPECT_NE(cv::norm(running.pixels(), draw(view).pixels(), cv::NORM_INF), 0) << "spinner moves";
  view.export_succeeded = true;
  const Canvas done = draw(view);
  view.export_succeeded = false;
  const Canvas failed = draw(view);
  EXPECT_GT(count_colour(done, main, colours::kGood), 20);
  EXPECT_EQ(count_colour(done, main, colours::kFault), 0);
  EXPECT_GT(count_colour(failed, main, colours::kFault), 20);
  EXPECT_EQ(count_colour(running, main, colours::kGood), 0);
}

TEST(ScreensFault, MessageIsWrappedOverSeveralLinesInARedPanel) {
  ScreenView view;
  view.kind = ScreenKind::Fault;
  view.fault_message =
      "The camera stopped answering. Check the ribbon cable, then press OK to restart the camera.";
  view.hints = {{Button::Ok, "restart", false}};
  const Canvas canvas = draw(view, {320, 240});
  const ScreenLayout layout = screen_layout(canvas.size());
  EXPECT_GT(count_colour(canvas, layout.main, colours::kFault), 100);
  // Text rows: runs of rows holding text-coloured pixels.
  int runs = 0;
  bool in_run = false;
  for (int y = layout.main.y; y < layout.main.bottom(); ++y) {
    const bool ink = count_colour(canvas, {0, y, canvas.width(), 1}, colours::kText) > 0;
    if (ink && !in_run) ++runs;
    in_run = ink;
  }
  EXPECT_GE(runs, 3);
  EXPECT_GT(count_colour(canvas, layout.hint_bar, colours::kAccent), 5);
}

TEST(ScreensAll, EveryKindDrawsAnEmptyView) {
  for (ScreenKind kind : kAllKinds) {
    for (Size size : {Size{320, 240}, Size{640, 480}, Size{1280, 800}}) {
      ScreenView view;
      view.kind = kind;
      Canvas canvas(size);
      EXPECT_NO_THROW(draw_screen(canvas, view)) << to_string(kind);
    }
  }
}

TEST(ScreensAll, DrawingIsDeterministic) {
  for (ScreenKind kind : kAllKinds) {
    const ScreenView view = full_view(kind);
    Canvas first(640, 480);
    Canvas second(640, 480);
    second.fill({1, 2, 3});  // whatever was on screen before does not show through
    draw_screen(first, view);
    draw_screen(second, view);
    EXPECT_EQ(cv::norm(first.pixels(), second.pixels(), cv::NORM_INF), 0) << to_string(kind);
  }
}

TEST(ScreensAll, FloatImagesDrawLikeTheirEightBitTwins) {
  ScreenView view;
  view.image = cv::Mat(240, 320, CV_32FC3, cv::Scalar(1.0, 0.0, 1.0));  // linear magenta
  const Canvas canvas = draw(view);
  const Rect area = screen_image_area(canvas.size(), view);
  EXPECT_EQ(count_colour(canvas, area, Rgb{255, 0, 255}), area_of(area));
}

TEST(ScreensAll, BigShrinksAverageInsteadOfAliasing) {
  // One-pixel black and white columns: shrunk by more than 2x (even blocks, so
  // a box filter is exact) they must become an even grey, not stripes.
  cv::Mat stripes(960, 1280, CV_8UC3, cv::Scalar::all(0));
  for (int x = 0; x < stripes.cols; x += 2) stripes.col(x).setTo(cv::Scalar::all(255));
  cv::Mat linear;
  stripes.convertTo(linear, CV_32FC3, 1.0 / 255.0);
  // 8-bit frames average their codes; float renders average light (0.5 is sRGB 188).
  for (const auto& [image, grey] : {std::pair{stripes, 128}, std::pair{linear, 188}}) {
    ScreenView view;
    view.image = image;
    const Canvas canvas = draw(view);
    const Rect area = screen_image_area(canvas.size(), view);
    const auto near_grey = [level = grey](Rgb p) { return std::abs(p.r - level) <= 3; };
    EXPECT_EQ(count_pixels(canvas, area, near_grey), area_of(area)) << "grey " << grey;
  }
}

}  // namespace
}  // namespace propcam::ui_fb
