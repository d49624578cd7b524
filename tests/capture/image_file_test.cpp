#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "propcam/capture/image_file.h"

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;

std::string temp(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / "propcam_image_file_test";
  fs::create_directories(dir);
  return (dir / name).string();
}

// A grey 640x480 JPEG carrying the given EXIF attributes.
template <typename Fn>
std::string jpeg_with(const std::string& name, Fn add_attributes) {
  const std::string path = temp(name);
  OIIO::ImageSpec spec(640, 480, 3, OIIO::TypeDesc::UINT8);
  add_attributes(spec);
  std::vector<uint8_t> pixels(640 * 480 * 3, 128);
  auto out = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT8, pixels.data()) && out->close());
  return path;
}

TEST(ImageFile, SrgbRoundTripsAndLinearisesMidGrey) {
  for (int v = 0; v < 256; ++v)
    EXPECT_EQ(std::lround(linear_to_srgb(srgb_to_linear(v / 255.f)) * 255.f), v);
  const cv::Mat photo = load_photo_linear(jpeg_with("grey.jpg", [](OIIO::ImageSpec&) {}));
  ASSERT_EQ(photo.type(), CV_32FC3);
  EXPECT_NEAR(photo.at<cv::Vec3f>(240, 320)[1], srgb_to_linear(128 / 255.f), 2e-3);
}

TEST(ImageFile, ExifEquivalentFocalLengthGivesPixels) {
  // 28 mm equivalent: f = 28 / 43.27 mm of diagonal x 800 px of diagonal.
  const ExifLens lens = read_exif_focal(jpeg_with("f35.jpg", [](OIIO::ImageSpec& s) {
    s.attribute("Exif:FocalLengthIn35mmFilm", 28);
  }));
  EXPECT_NEAR(lens.focal_px, 28.0 * 800.0 / 43.2666, 0.01);
  EXPECT_EQ(lens.source, "Exif:FocalLengthIn35mmFilm");
}

TEST(ImageFile, ExifFocalPlaneResolutionScaledToTheStoredSize) {
  // 4 mm lens, 500 px per mm on a sensor read out 1280 px wide, stored at 640.
  const ExifLens lens = read_exif_focal(jpeg_with("fplane.jpg", [](OIIO::ImageSpec& s) {
    s.attribute("Exif:FocalLength", 4.0f);
    s.attribute("Exif:FocalPlaneXResolution", 500.0f);
    s.attribute("Exif:FocalPlaneResolutionUnit", 4);
    s.attribute("Exif:PixelXDimension", 1280);
  }));
  EXPECT_NEAR(lens.focal_px, 4.0 * 500.0 * 640.0 / 1280.0, 0.5);
}

TEST(ImageFile, MissingOrImplausibleExifFocalIsIgnored) {
  EXPECT_EQ(read_exif_focal(jpeg_with("none.jpg", [](OIIO::ImageSpec&) {})).focal_px, 0.0);
  // 1 mm equivalent: a 180-degree lens; a bad tag, not trusted.
  EXPECT_EQ(read_exif_focal(jpeg_with("absurd.jpg", [](OIIO::ImageSpec& s) {
              s.attribute("Exif:FocalLengthIn35mmFilm", 1);
            })).focal_px,
            0.0);
  EXPECT_THROW(read_exif_focal(temp("does_not_exist.jpg")), std::runtime_error);
}

}  // namespace
}  // namespace propcam::capture

namespace propcam::capture {
namespace {

TEST(ImageFile, CameraResponseRoundTripsAndMatchesAPowerLaw) {
  cv::Mat photo(1, 5, CV_32FC3);
  const float values[5] = {0.f, 0.002f, 0.18f, 0.7f, 1.5f};
  for (int i = 0; i < 5; ++i) photo.at<cv::Vec3f>(0, i) = {values[i], values[i], values[i]};
  for (double gamma : {1.8, 2.2, 2.6}) {
    const cv::Mat response = srgb_linear_to_response_linear(photo, gamma);
    const cv::Mat back = response_linear_to_srgb_linear(response, gamma);
    for (int i = 0; i < 5; ++i) {
      EXPECT_NEAR(back.at<cv::Vec3f>(0, i)[0], values[i], 1e-5f * (1 + values[i])) << gamma;
      // The camera wrote sRGB-encoded value e; under this response, e^gamma.
      EXPECT_NEAR(response.at<cv::Vec3f>(0, i)[1], std::pow(linear_to_srgb(values[i]), gamma), 1e-6);
    }
  }
  EXPECT_THROW(srgb_linear_to_response_linear(photo, 0.0), std::invalid_argument);
  EXPECT_THROW(response_linear_to_srgb_linear(photo, std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::capture

namespace propcam::capture {
namespace {

// A textured 8-bit image (every pixel different), to catch a band in the wrong place.
cv::Mat pattern8(int width, int height, int channels) {
  cv::Mat m(height, width, CV_8UC(channels));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < channels; ++c) m.ptr<uint8_t>(y)[x * channels + c] = static_cast<uint8_t>(x * 7 + y * 13 + c * 50);
  return m;
}

void write_raw(const std::string& path, const cv::Mat& m) {
  OIIO::ImageSpec spec(m.cols, m.rows, m.channels(), m.depth() == CV_8U ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT);
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec));
  ASSERT_TRUE(out->write_image(spec.format, m.data) && out->close());
}

cv::Mat read_in_bands(const std::string& path, int band) {
  PhotoRowReader reader(path);
  cv::Mat whole(reader.size(), CV_32FC3);
  for (int y = 0; y < reader.size().height; y += band) {
    const int rows = std::min(band, reader.size().height - y);
    reader.read(y, rows).copyTo(whole.rowRange(y, y + rows));
  }
  return whole;
}

bool identical(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

TEST(PhotoRowReader, BandsAreWhatTheWholePhotoReadGives) {
  const std::string rgb = temp("bands_rgb.png"), grey = temp("bands_grey.png"), hdr = temp("bands.exr");
  write_raw(rgb, pattern8(37, 29, 3));
  write_raw(grey, pattern8(37, 29, 1));
  cv::Mat linear;
  pattern8(37, 29, 3).convertTo(linear, CV_32FC3, 1.0 / 64);
  write_raw(hdr, linear);
  for (const std::string& path : {rgb, grey, hdr})
    for (int band : {1, 8, 29}) EXPECT_TRUE(identical(read_in_bands(path, band), load_photo_linear(path))) << path << " " << band;
  PhotoRowReader reader(rgb);
  reader.read(0, 8);
  EXPECT_THROW(reader.read(4, 4), std::invalid_argument);  // top to bottom only
}

TEST(PhotoRowReader, AJpegCutShortIsAnError) {
  const std::string whole = temp("rows_whole.jpg"), half = temp("rows_half.jpg");
  write_raw(whole, pattern8(256, 192, 3));
  std::ifstream in(whole, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(half, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  EXPECT_THROW(read_in_bands(half, 64), std::runtime_error);
  EXPECT_NO_THROW(read_in_bands(whole, 64));
}

TEST(ImageRowWriter, BandsWriteWhatWriteImageWrites) {
  cv::Mat linear;
  pattern8(41, 23, 3).convertTo(linear, CV_32FC3, 1.0 / 255);
  for (const std::string ext : {".png", ".exr"}) {
    const std::string whole = temp("whole_write" + ext), banded = temp("banded_write" + ext);
    write_image(whole, linear);
    {
      ImageRowWriter writer(banded, linear.size());
      for (int y = 0; y < linear.rows; y += 10) writer.write(linear.rowRange(y, std::min(y + 10, linear.rows)));
      writer.finish();
    }
    EXPECT_TRUE(identical(read_image_float(banded), read_image_float(whole))) << ext;
  }
}

TEST(ImageRowWriter, AnUnfinishedWriterLeavesNothing) {
  const fs::path dir = fs::path(temp("unfinished_dir"));
  fs::remove_all(dir);
  fs::create_directories(dir);
  {
    ImageRowWriter writer((dir / "out.png").string(), cv::Size(8, 8));
    writer.write(cv::Mat(4, 8, CV_32FC3, cv::Scalar::all(0.5)));
    EXPECT_THROW(writer.finish(), std::logic_error);  // 4 of 8 rows
  }
  EXPECT_TRUE(fs::is_empty(dir));
}

}  // namespace
}  // namespace propcam::capture

namespace propcam::capture {
namespace {

TEST(LoadPhotoReduced, IsAreaAveragingOfTheWholePhoto) {
  const std::string path = temp("reduce_me.png");
  cv::Mat pattern(301, 403, CV_8UC3);
  cv::randu(pattern, 0, 255);
  write_image(path, pattern);
  EXPECT_EQ(photo_file_size(path), cv::Size(403, 301));
  const cv::Mat whole = load_photo_linear(path);
  for (const cv::Size size : {cv::Size(100, 75), cv::Size(403, 301), cv::Size(37, 11), cv::Size(1, 1)}) {
    cv::Mat expected;
    cv::resize(whole, expected, size, 0, 0, cv::INTER_AREA);
    EXPECT_LT(cv::norm(load_photo_reduced(path, size), expected, cv::NORM_INF), 1e-5) << size;
  }
  EXPECT_THROW(load_photo_reduced(path, {404, 301}), std::invalid_argument);
  EXPECT_THROW(photo_file_size(temp("no_such_photo.png")), std::runtime_error);
}

}  // namespace
}  // namespace propcam::capture
