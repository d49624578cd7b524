// Photos larger than the working size: inference and rendering run on the
// photo reduced to a pixel budget, and the composite is delivered at the
// photo's full size by carrying the prop's change up to it.
//
// Outside the prop the change is a ratio (a shadow darkens the photo's own
// texture, a bounce brightens it), so the full-size photo keeps its detail;
// the prop's own colour is rebuilt from the working composite and blended by
// its coverage, traced at the full size around the prop (or upsampled). Both
// are interpolated bilinearly, row by row, into the full-size image in place:
// no full-size temporaries.
#pragma once

#include <opencv2/core.hpp>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/job_budget.h"
#include "propcam/render/camera.h"
#include "propcam/render/scene.h"

namespace propcam::firmware {

// The largest photo taken: a 200-megapixel phone sensor's. Reading one costs
// a band of rows in memory, but its decoding time grows with it.
inline constexpr long kMaxPhotoPixels = 200'000'000L;

// Throws std::invalid_argument naming the photo, its size and the limit
// when it has more than kMaxPhotoPixels.
void check_photo_pixels(const std::string& path, cv::Size size);

// The size a photo of `full` pixels is worked at: itself when it fits
// `max_pixels`, else the same aspect ratio reduced to fit (each side >= 1).
cv::Size working_size(cv::Size full, long max_pixels);

// `photo` reduced to `size` by area averaging (a copy when the size is its own).
cv::Mat reduce_to(const cv::Mat& photo, cv::Size size);

// The prop's silhouette at the full size: its coverage from camera rays at
// that size (CV_32F) over `region`, the full-size pixels around where the
// working render saw it.
struct SharpCoverage {
  cv::Rect region;
  cv::Mat coverage;
  int rays_per_side = 0;
  double seconds = 0.0;  // to trace it
  bool empty() const { return coverage.empty(); }
};

// Rays per side of a full-size pixel for its prop coverage (9 levels of
// edge), fewer over a larger region so that it costs at most about 36 M rays
// and 64 MB; a region over kMaxSharpCoveragePixels is not traced (the
// upsampled working coverage is used).
inline constexpr int kSharpCoverageRaysPerSide = 3;
inline constexpr long kMaxSharpCoveragePixels = 16'000'000L;
inline constexpr long long kMaxSharpCoverageRays = 36'000'000LL;
int sharp_coverage_rays_per_side(long region_pixels);  // 0: not traced

// `world` holds the placed prop, `working_camera` renders the working size.
// The coverage is softened by the photo's blur, `blur_sigma_working_px` in
// working pixels (scaled to the full size).
SharpCoverage full_size_prop_coverage(const render::Scene& world, const render::PinholeCamera& working_camera,
                                      const cv::Mat& working_coverage, cv::Size full_size,
                                      double blur_sigma_working_px);

// Carries a working composite up to the full size, a band of rows at a
// time. `working_photo` is the full photo reduced (CV_32FC3, the same linear
// space as the full rows), `working_composite` its composite, `coverage`
// (CV_32F) the share of each working pixel the prop covers. Where the
// composite equals the photo, the full rows are left exactly as they are.
class FullSizeDelivery {
 public:
  FullSizeDelivery(const cv::Mat& working_photo, const cv::Mat& working_composite, const cv::Mat& coverage,
                   cv::Size full_size);
  // Inside its region the prop is blended by this coverage instead of the
  // upsampled working one: its edges as sharp as the full size allows.
  void use_sharp_coverage(SharpCoverage sharp);
  // Rows [first_row, first_row + rows.rows) of the full photo (CV_32FC3), in place.
  void apply(cv::Mat& rows, int first_row) const;

 private:
  struct Taps {  // bilinear: the two source indices and the second's weight
    int lo, hi;
    float t;
  };
  cv::Size full_size_;
  cv::Mat untouched_, ratio_, colour_, coverage_;
  SharpCoverage sharp_;
  std::vector<Taps> xs_, ys_;
};

// A reduction of `full` to `working` keeps the view: the aspect ratios agree
// to within a pixel of rounding.
bool same_view_reduced(cv::Size full, cv::Size working);

// The working copy of a photo file. The full-size pixels are never held
// whole: the file is reduced while it is read, and the composite reads it
// again at the end (a 12 MP photo is 144 MB as float).
struct WorkingPhoto {
  std::string path;
  cv::Size full_size;
  cv::Mat working;     // linear sRGB, reduced (the photo itself when it fits)
  std::uintmax_t file_bytes = 0;
  std::filesystem::file_time_type file_time;
  bool reduced() const { return working.size() != full_size; }
  double scale() const { return static_cast<double>(working.cols) / full_size.width; }  // working width / full width
};

// Reads `path` reduced to `forced` when given (a scene folder's size), else
// to fit `budget` pixels. Throws std::invalid_argument for a photo above
// kMaxPhotoPixels or smaller than `forced`, and what load_photo_linear throws.
WorkingPhoto load_working_photo(const std::string& path, long budget, cv::Size forced = {});

// The composite at the photo's own size, a band of rows at a time: the file
// read again (checked unchanged since load_working_photo), each band taken
// to the response-linear space of `gamma`, the working composite's change
// carried onto it, and written atomically to `out_path`.
void write_full_size_composite(const WorkingPhoto& photo, const std::string& out_path,
                               const FullSizeDelivery& delivery, double gamma);

// The whole full photo at once (tests, small photos).
void deliver_at_full_size(cv::Mat& full_photo, const cv::Mat& working_photo, const cv::Mat& working_composite,
                          const cv::Mat& coverage);

}  // namespace propcam::firmware
