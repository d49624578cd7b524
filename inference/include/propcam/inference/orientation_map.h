// Orientation map of the geometry stage (Lee, Hebert & Kanade, "Geometric
// reasoning for single image structure recovery", CVPR 2009): which of the
// three Manhattan orientations each pixel's surface has, from line sweeps.
// Karsch et al. 2014 (section 4) use it as the sparse orientation prior of the
// depth solve (E_o). Method, simplifications and measurements:
// docs/orientation_map.md.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "propcam/inference/camera.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

// Surface orientation = which world axis the surface NORMAL is parallel to.
// World frame: the Manhattan frame of the camera stage, Y up (floor/ceiling have kNormalY).
enum class SurfaceOrientation : uint8_t { kUnknown = 0, kNormalX = 1, kNormalY = 2, kNormalZ = 3 };

struct OrientationMapOptions {
  int width = 160;  // output width; height keeps the photo's aspect ratio (rounded, >= 1)
  // Longest sweep, as a fraction of the image diagonal: Lee et al. sweep until
  // blocked; on the synthetic rooms a bound keeps an unblocked edge (a lone
  // tile line) from painting across a whole wall it does not belong to.
  double max_sweep_fraction = 0.5;
  // A blocker must reach this far (fraction of the diagonal) into the sweep to
  // stop it: segments meeting at a corner overshoot each other by a pixel or
  // two, and that must not stop the sweep at its start.
  double block_margin_fraction = 0.006;
  // The swept band is narrowed by this fraction of the segment at each end,
  // so a blocker that only touches an endpoint (an L junction) does not count.
  double end_inset_fraction = 0.05;
  // Segments shorter than this (fraction of the diagonal) are not swept: their
  // direction is too uncertain to carry a surface (they still block).
  double min_sweep_length_fraction = 0.02;
  // A segment is not swept toward a vanishing point seen within this angle of
  // its own direction (degrees): the plane of the two directions is then seen
  // nearly edge-on and the sweep only slides the segment along itself into a
  // long sliver (on the synthetic rooms such slivers ran up the back wall).
  double min_sweep_angle_deg = 20.0;
  // Lines of the class swept toward (j) also stop a sweep when they lie wholly
  // ahead of it (crossing ones never do: a tiled floor is a grid). Without
  // this, a floor line sweeps up a wall whose base edge was not detected.
  bool block_by_lines_ahead = true;
};

struct OrientationMap {
  cv::Mat labels;      // CV_8U, values SurfaceOrientation, at options.width x round(width*h/w)
  // stage "orientation_map"; details: coverage (fraction labelled), per-label
  // fractions, ceiling_fraction / floor_fraction (kNormalY above / below the
  // horizon), lines used, seconds
  StageReport report;
};

// lines in full-resolution pixels, line_labels from CameraEstimate::line_labels
// (0,1,2 = world X,Y,Z direction of the LINE; -1 outlier), camera = the
// estimated camera at full resolution. Each line of class i is swept toward
// (and away from) the vanishing point of each other class j until a line of
// the third class k blocks it; a pixel gets orientation k where sweeps of
// i-lines toward j and of j-lines toward i both cover it, and no other
// orientation does. Deterministic; non-finite segments and labels outside
// -1..2 are ignored. Throws std::invalid_argument when lines and labels differ
// in size, options.width < 1, or the camera has a non-positive size or
// non-finite / non-positive intrinsics or a non-finite rotation.
OrientationMap estimate_orientation_map(const std::vector<LineSegment>& lines, const std::vector<int>& line_labels,
                                        const render::PinholeCamera& camera, const OrientationMapOptions& options = {});

// Debug colours: CV_8UC3 in PropCam's RGB channel order (write it with
// capture::write_image to a .png): X red, Y green, Z blue, unknown black.
// Throws std::invalid_argument unless labels is CV_8U.
cv::Mat orientation_map_to_color(const cv::Mat& labels);

}  // namespace propcam::inference
