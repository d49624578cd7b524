// Helpers shared by the screens tests: solid-colour images and pixel counting,
// so every check compares exact colours.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>

#include <opencv2/core.hpp>

#include "propcam/ui_fb/screens.h"

namespace propcam::ui_fb::testing_helpers {

inline cv::Mat solid_image(int width, int height, Rgb colour) {
  return cv::Mat(height, width, CV_8UC3, cv::Scalar(colour.r, colour.g, colour.b));
}

// Pixels of `rect` (clipped to the canvas) that satisfy `predicate`.
inline int count_pixels(const Canvas& canvas, const Rect& rect,
                        const std::function<bool(Rgb)>& predicate) {
  const Rect visible = intersect(rect, canvas.bounds());
  int count = 0;
  for (int y = visible.y; y < visible.bottom(); ++y) {
    for (int x = visible.x; x < visible.right(); ++x) {
      if (predicate(canvas.pixel(x, y))) ++count;
    }
  }
  return count;
}

inline int count_colour(const Canvas& canvas, const Rect& rect, Rgb colour) {
  return count_pixels(canvas, rect, [colour](Rgb p) { return p == colour; });
}

inline int area_of(const Rect& rect) { return rect.empty() ? 0 : rect.width * rect.height; }

// The bounding box of the pixels of `rect` that have `colour`; empty if none.
inline Rect bounding_box_of(const Canvas& canvas, const Rect& rect, Rgb colour) {
  const Rect visible = intersect(rect, canvas.bounds());
  int left = visible.right(), top = visible.bottom(), right = visible.x, bottom = visible.y;
  for (int y = visible.y; y < visible.bottom(); ++y) {
    for (int x = visible.x; x < visible.right(); ++x) {
      if (canvas.pixel(x, y) == colour) {
        left = std::min(left, x);
        top = std::min(top, y);
        right = std::max(right, x + 1);
        bottom = std::max(bottom, y + 1);
      }
    }
  }
  if (right <= left || bottom <= top) return {};
  return {left, top, right - left, bottom - top};
}

// Maps an image pixel edge to the screen the way draw_screen does.
inline int screen_edge(int area_origin, int area_extent, int image_extent, double image_edge) {
  return area_origin + static_cast<int>(std::lround(image_edge * area_extent / image_extent));
}

}  // namespace propcam::ui_fb::testing_helpers
