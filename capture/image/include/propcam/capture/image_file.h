// Image files in and out, through OpenImageIO. Inside PropCam images are
// cv::Mat in RGB channel order; 8-bit sRGB only at the edges, linear float
// (CV_32FC3 / CV_32FC1) everywhere else.
#pragma once

#include <opencv2/core.hpp>
#include <filesystem>
#include <memory>
#include <string>

namespace propcam::capture {

// The exact sRGB transfer functions (IEC 61966-2-1).
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);
// The decoding in double, for tables built once (ui_fb's 8-bit encoder):
// the same curve, without float's rounding of its thresholds.
double srgb_to_linear_precise(double encoded);

// CV_8UC3 sRGB -> CV_32FC3 linear, and back (clamped, rounded).
cv::Mat srgb8_to_linear(const cv::Mat& srgb8);
cv::Mat linear_to_srgb8(const cv::Mat& linear);

// The camera response: a photo decoded with the sRGB curve (as
// load_photo_linear does) re-linearised as if the camera wrote
// encoded = linear^(1/gamma) (inference fits gamma with the light
// intensities), and back. A pixel taken there and back is unchanged
// (up to float rounding), so untouched photo pixels stay as they were.
cv::Mat srgb_linear_to_response_linear(const cv::Mat& srgb_linear, double gamma);
cv::Mat response_linear_to_srgb_linear(const cv::Mat& response_linear, double gamma);

// Reads a photo as linear RGB CV_32FC3. 8/16-bit files are taken as sRGB-encoded;
// float files (EXR, HDR) as linear. Grey is expanded to RGB, alpha dropped.
// Throws std::runtime_error naming the file on failure.
cv::Mat load_photo_linear(const std::string& path);

// The lens's focal length in pixels at the file's resolution, from its EXIF
// metadata: the 35-mm-equivalent focal length (scaled by the diagonals, as
// the equivalence is defined), else the focal length in mm times the focal
// plane resolution (scaled to the stored size when the original size is
// recorded). `source` names the tags used; focal_px is 0 when the file has
// no usable tags (implausible values are ignored, not trusted).
struct ExifLens {
  double focal_px = 0;
  std::string source;
};
ExifLens read_exif_focal(const std::string& path);

// Reads any image as stored (float channels, no transfer function applied).
cv::Mat read_image_float(const std::string& path);

// Writes atomically (temporary name in the same folder, then rename).
// Float formats (.exr) store the Mat as float; others store 8-bit, and a float
// Mat is then encoded from linear to sRGB first.
void write_image(const std::string& path, const cv::Mat& image);

// A photo a band of rows at a time, for images too large to hold whole:
// each band is exactly what load_photo_linear gives for those rows. Bands are
// read top to bottom. Errors as load_photo_linear's (a file cut short is
// found at the band that reaches the cut, or at the last).
class PhotoRowReader {
 public:
  explicit PhotoRowReader(const std::string& path);
  ~PhotoRowReader();
  PhotoRowReader(const PhotoRowReader&) = delete;
  PhotoRowReader& operator=(const PhotoRowReader&) = delete;
  cv::Size size() const { return size_; }
  cv::Mat read(int first_row, int rows);  // CV_32FC3 linear RGB

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  cv::Size size_;
};

// The pixel size a photo file declares (its header only). Throws as
// load_photo_linear does for a missing file, a folder or an unreadable one.
cv::Size photo_file_size(const std::string& path);

// The photo reduced to `size` (no larger than the file's) by area averaging,
// read a band of rows at a time: memory for the reduced photo and one band,
// whatever the file's size. Equal to cv::resize(load_photo_linear(path),
// size, INTER_AREA) up to float rounding.
cv::Mat load_photo_reduced(const std::string& path, cv::Size size);

// write_image a band of rows at a time: linear CV_32FC3 rows in, stored as
// write_image would store the whole image. Nothing appears at `path` until
// finish(); destroyed unfinished, it leaves nothing behind.
class ImageRowWriter {
 public:
  ImageRowWriter(const std::string& path, cv::Size size);
  ~ImageRowWriter();
  ImageRowWriter(const ImageRowWriter&) = delete;
  ImageRowWriter& operator=(const ImageRowWriter&) = delete;
  void write(const cv::Mat& linear_rows);  // the next rows, top to bottom
  void finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace propcam::capture
