// Placement: the photo with the candidate spots, the selected one under a
// crosshair, and the prop's footprint.
#include "screen_kinds.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace propcam::ui_fb::detail {
namespace {

constexpr double kSpotRadiusEm = 0.22;
constexpr double kCursorArmEm = 1.1;
constexpr double kFootprintLineEm = 0.15;

// A white dot with a half-pixel dark rim, visible on light and dark photos.
void draw_spot(cv::Mat& pixels, const cv::Point2d& at, int radius) {
  constexpr int kRim = static_cast<int>(kSubpixelScale) / 2;
  cv::circle(pixels, subpixel(at), radius * static_cast<int>(kSubpixelScale) + kRim,
             cv::Scalar(0, 0, 0), cv::FILLED, cv::LINE_AA, kSubpixelBits);
  cv::circle(pixels, subpixel(at), radius * static_cast<int>(kSubpixelScale),
             to_scalar(colours::kSpot), cv::FILLED, cv::LINE_AA, kSubpixelBits);
}

// A crosshair with a gap in the middle, so the spot under it stays visible.
void draw_cursor(cv::Mat& pixels, const cv::Point2d& at, int arm, int gap, int thickness) {
  const cv::Scalar colour = to_scalar(colours::kCursor);
  const cv::Point2d directions[] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  for (const cv::Point2d& d : directions) {
    cv::line(pixels, subpixel(at + d * gap), subpixel(at + d * arm), colour, thickness, cv::LINE_AA,
             kSubpixelBits);
  }
  cv::circle(pixels, subpixel(at), gap * static_cast<int>(kSubpixelScale), colour, thickness,
             cv::LINE_AA, kSubpixelBits);
}

void draw_footprint(cv::Mat& pixels, const ImageMapping& mapping,
                    const std::vector<cv::Point2d>& footprint, int thickness) {
  std::vector<cv::Point> polygon;
  for (const cv::Point2d& p : footprint) {
    if (finite_point(p)) polygon.push_back(subpixel(mapping.local_point(p)));
  }
  if (polygon.size() < 2) return;
  cv::polylines(pixels, polygon, true, to_scalar(colours::kFootprint), thickness, cv::LINE_AA,
                kSubpixelBits);
}

}  // namespace

void draw_placement(const ScreenContext& c) {
  const Rect image = draw_picture(c.canvas, c.picture, c.view.image, "no photo", c.m);
  const Rect visible = intersect(image, c.canvas.bounds());
  if (!visible.empty() && visible == image) {
    // Marks are drawn into the picture's own pixels, so none can leave it.
    cv::Mat pixels = c.canvas.pixels()(to_cv(image));
    const ImageMapping mapping(image, size_of(c.view.image));
    const double em = c.m.body_px;
    draw_footprint(pixels, mapping, c.view.footprint,
                   std::max(1, static_cast<int>(std::lround(kFootprintLineEm * em))));
    const int radius = std::max(2, static_cast<int>(std::lround(kSpotRadiusEm * em)));
    for (const cv::Point2d& spot : c.view.spots) {
      if (finite_point(spot)) draw_spot(pixels, mapping.local_point(spot), radius);
    }
    if (valid_index(c.view.selected_spot, c.view.spots.size())) {
      const cv::Point2d& spot = c.view.spots[static_cast<std::size_t>(c.view.selected_spot)];
      if (finite_point(spot)) {
        draw_cursor(pixels, mapping.local_point(spot),
                    static_cast<int>(kCursorArmEm * em), 2 * radius, std::max(1, radius / 2));
      }
    }
  }
  const Rect frame = image.empty() ? c.picture : image;
  draw_caption(c.canvas, frame, c.view.placement_text, Edge::Bottom, c.m);
  draw_caption(c.canvas, frame, c.view.image_caption,
               c.view.placement_text.empty() ? Edge::Bottom : Edge::Top, c.m);
}

}  // namespace propcam::ui_fb::detail
