// Photos larger than the working size: inference and rendering run on the
// photo reduced to a pixel budget, and the composite is delivered at the
// photo's full size by carrying the prop's change up to it.
//
// Outside the prop the change is a ratio (a shadow darkens the photo's own
// texture, a bounce brightens it), so the full-size photo keeps its detail;
// the prop's own colour is rebuilt from the working composite and blended by
// its upsampled coverage. Both are interpolated bilinearly, row by row, into
// the full-size image in place: no full-size temporaries.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace propcam::firmware {

// About 0.8 megapixels (1024x768): inference's figures and its ≤ 3 s are
// measured at this size, and a 12 MP photo's working copy costs 9 MB.
inline constexpr long kDefaultWorkingPixels = 1024L * 768L;

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

// Carries a working composite up to the full size, a band of rows at a
// time. `working_photo` is the full photo reduced (CV_32FC3, the same linear
// space as the full rows), `working_composite` its composite, `coverage`
// (CV_32F) the share of each working pixel the prop covers. Where the
// composite equals the photo, the full rows are left exactly as they are.
class FullSizeDelivery {
 public:
  FullSizeDelivery(const cv::Mat& working_photo, const cv::Mat& working_composite, const cv::Mat& coverage,
                   cv::Size full_size);
  // Rows [first_row, first_row + rows.rows) of the full photo (CV_32FC3), in place.
  void apply(cv::Mat& rows, int first_row) const;

 private:
  struct Taps {  // bilinear: the two source indices and the second's weight
    int lo, hi;
    float t;
  };
  cv::Size full_size_;
  cv::Mat untouched_, ratio_, colour_, coverage_;
  std::vector<Taps> xs_, ys_;
};

// The whole full photo at once (tests, small photos).
void deliver_at_full_size(cv::Mat& full_photo, const cv::Mat& working_photo, const cv::Mat& working_composite,
                          const cv::Mat& coverage);

}  // namespace propcam::firmware
