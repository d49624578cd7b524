#include "propcam/capture/image_file.h"

#include <OpenImageIO/imageio.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <unistd.h>

namespace propcam::capture {
namespace {

// Decoding 8-bit values is the hot path: one table instead of a pow per channel.
const std::array<float, 256>& srgb8_decode_table() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = srgb_to_linear(static_cast<float>(i) / 255.f);
    return t;
  }();
  return table;
}

bool is_float_format(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".exr" || ext == ".hdr" || ext == ".tif" || ext == ".tiff" || ext == ".pfm";
}

cv::Mat to_three_channels(const cv::Mat& image) {
  if (image.channels() == 3) return image;
  std::vector<cv::Mat> planes;
  cv::split(image, planes);
  if (image.channels() == 1 || image.channels() == 2) return cv::Mat();  // caller expands grey
  cv::Mat rgb;
  cv::merge(std::vector<cv::Mat>{planes[0], planes[1], planes[2]}, rgb);
  return rgb;
}

}  // namespace

float srgb_to_linear(float v) {
  if (!(v > 0.f)) return 0.f;  // also maps NaN to 0
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

double srgb_to_linear_precise(double v) {
  if (!(v > 0.0)) return 0.0;
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

float linear_to_srgb(float v) {
  if (!(v > 0.f)) return 0.f;
  return v <= 0.0031308f ? v * 12.92f : 1.055f * std::pow(v, 1.f / 2.4f) - 0.055f;
}

cv::Mat srgb8_to_linear(const cv::Mat& srgb8) {
  CV_Assert(srgb8.type() == CV_8UC3);
  const auto& table = srgb8_decode_table();
  cv::Mat out(srgb8.size(), CV_32FC3);
  for (int y = 0; y < srgb8.rows; ++y) {
    const uint8_t* in = srgb8.ptr<uint8_t>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < srgb8.cols * 3; ++x) o[x] = table[in[x]];
  }
  return out;
}

cv::Mat linear_to_srgb8(const cv::Mat& linear) {
  CV_Assert(linear.depth() == CV_32F);
  cv::Mat out(linear.size(), CV_8UC(linear.channels()));
  const int n = linear.cols * linear.channels();
  for (int y = 0; y < linear.rows; ++y) {
    const float* in = linear.ptr<float>(y);
    uint8_t* o = out.ptr<uint8_t>(y);
    for (int x = 0; x < n; ++x)
      o[x] = static_cast<uint8_t>(std::lround(std::clamp(linear_to_srgb(in[x]), 0.f, 1.f) * 255.f));
  }
  return out;
}

namespace {

// Diagonal of the 35 mm frame (36 x 24 mm) that equivalent focal lengths refer to.
constexpr double kFullFrameDiagonalMm = 43.2666;
// A focal length outside 0.1..10 image diagonals (a 157 to 6 degree diagonal
// field of view) is a bad tag, not a lens.
constexpr double kMinFocalOfDiagonal = 0.1, kMaxFocalOfDiagonal = 10.0;
// Exif FocalPlaneResolutionUnit: 2 inch, 3 cm, 4 mm, 5 um (in mm).
double resolution_unit_mm(int unit) {
  switch (unit) {
    case 2: return 25.4;
    case 3: return 10.0;
    case 4: return 1.0;
    case 5: return 1e-3;
    default: return 0.0;
  }
}

double number_attribute(const OIIO::ImageSpec& spec, const char* name) {
  const OIIO::ParamValue* p = spec.find_attribute(name);
  if (!p) return 0.0;
  const double v = p->get_float();
  return std::isfinite(v) ? v : 0.0;
}

}  // namespace

namespace {

// Applies f to every channel value of a float image (any channel count).
template <typename Fn>
cv::Mat map_values(const cv::Mat& image, Fn f) {
  CV_Assert(image.depth() == CV_32F);
  cv::Mat out(image.size(), image.type());
  const int n = image.cols * image.channels();
  for (int y = 0; y < image.rows; ++y) {
    const float* in = image.ptr<float>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < n; ++x) o[x] = f(in[x]);
  }
  return out;
}

void check_gamma(double gamma) {
  if (!(gamma > 0) || !std::isfinite(gamma)) throw std::invalid_argument("camera response exponent must be positive and finite");
}

}  // namespace

cv::Mat srgb_linear_to_response_linear(const cv::Mat& srgb_linear, double gamma) {
  check_gamma(gamma);
  const float g = static_cast<float>(gamma);
  // Values above 1 (HDR input) keep the power law beyond the encoding's range.
  return map_values(srgb_linear, [g](float v) { return std::pow(linear_to_srgb(std::max(v, 0.f)), g); });
}

cv::Mat response_linear_to_srgb_linear(const cv::Mat& response_linear, double gamma) {
  check_gamma(gamma);
  const float inv = static_cast<float>(1.0 / gamma);
  return map_values(response_linear, [inv](float v) { return srgb_to_linear(std::pow(std::max(v, 0.f), inv)); });
}

ExifLens read_exif_focal(const std::string& path) {
  auto input = OIIO::ImageInput::open(path);
  if (!input) throw std::runtime_error("cannot open image '" + path + "': " + OIIO::geterror());
  const OIIO::ImageSpec spec = input->spec();
  input->close();
  const double diagonal_px = std::hypot(spec.width, spec.height);
  const auto plausible = [&](double f) {
    return f >= kMinFocalOfDiagonal * diagonal_px && f <= kMaxFocalOfDiagonal * diagonal_px;
  };
  ExifLens lens;
  const double f35 = number_attribute(spec, "Exif:FocalLengthIn35mmFilm");
  if (f35 > 0 && plausible(f35 * diagonal_px / kFullFrameDiagonalMm)) {
    lens.focal_px = f35 * diagonal_px / kFullFrameDiagonalMm;
    lens.source = "Exif:FocalLengthIn35mmFilm";
    return lens;
  }
  const double f_mm = number_attribute(spec, "Exif:FocalLength");
  const double x_res = number_attribute(spec, "Exif:FocalPlaneXResolution");
  const double unit_mm = resolution_unit_mm(static_cast<int>(number_attribute(spec, "Exif:FocalPlaneResolutionUnit")));
  if (f_mm > 0 && x_res > 0 && unit_mm > 0) {
    double f_px = f_mm * x_res / unit_mm;  // pixels of the sensor's full readout
    const double original_width = number_attribute(spec, "Exif:PixelXDimension");
    if (original_width > 0) f_px *= spec.width / original_width;
    if (plausible(f_px)) {
      lens.focal_px = f_px;
      lens.source = "Exif:FocalLength and Exif:FocalPlaneXResolution";
    }
  }
  return lens;
}

namespace {

// The largest image read_image_float reads, its pixels as float: a 12-MP
// photo is ~150 MiB, an 8k x 4k RGB panorama ~400 MiB. A corrupt header can
// claim any size and the pixels are allocated before they are read, so
// larger claims are refused.
constexpr std::size_t kMaxImageFloatBytes = std::size_t{512} << 20;

void check_image_size(const std::string& path, int width, int height, int channels) {
  if (channels > CV_CN_MAX)
    throw std::runtime_error("image '" + path + "' has " + std::to_string(channels) + " channels (at most " +
                             std::to_string(CV_CN_MAX) + ")");
  const std::size_t bytes = std::size_t(width) * std::size_t(height) * std::size_t(channels) * sizeof(float);
  if (bytes > kMaxImageFloatBytes)
    throw std::runtime_error("image '" + path + "' is too large: " + std::to_string(width) + "x" +
                             std::to_string(height) + "x" + std::to_string(channels) + " (at most " +
                             std::to_string(kMaxImageFloatBytes >> 20) + " MiB as float)");
}

// A missing file or a folder, said plainly (OpenImageIO's message for a
// folder is its first format's, e.g. "Not a PNG file").
void check_is_a_file(const std::string& path) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (status.type() == std::filesystem::file_type::not_found)
    throw std::runtime_error("image '" + path + "' does not exist");
  if (status.type() == std::filesystem::file_type::directory)
    throw std::runtime_error("'" + path + "' is a folder, not an image file");
}

void throw_if_damaged(OIIO::ImageInput& input, const std::string& path) {
  // libjpeg reads a cut-off JPEG to the end, fills the rest grey and only
  // warns ("Premature end of JPEG file"): OpenImageIO keeps that as an error
  // while reporting success.
  if (input.has_error())
    throw std::runtime_error("image '" + path + "' is damaged or cut short (" + input.geterror() +
                             "); copy the file again or take the photo again");
}

// An image file opened, with pixels; `what` ("image", "photo") names it in
// the errors.
std::unique_ptr<OIIO::ImageInput> open_image(const std::string& path, const char* what) {
  check_is_a_file(path);
  auto input = OIIO::ImageInput::open(path);
  if (!input) throw std::runtime_error(std::string("cannot open ") + what + " '" + path + "': " + OIIO::geterror());
  const OIIO::ImageSpec& spec = input->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
    throw std::runtime_error("image '" + path + "' has no pixels");
  return input;
}

bool stored_as_linear(const OIIO::ImageSpec& spec, const std::string& path) {
  return spec.format.is_floating_point() || is_float_format(path);
}

// The whole image as stored (float channels); `stored_linear` (if given)
// says whether the file holds linear values.
cv::Mat read_stored(const std::string& path, const char* what, bool* stored_linear) {
  const auto input = open_image(path, what);
  const OIIO::ImageSpec& spec = input->spec();
  check_image_size(path, spec.width, spec.height, spec.nchannels);
  if (stored_linear) *stored_linear = stored_as_linear(spec, path);
  cv::Mat image(spec.height, spec.width, CV_32FC(spec.nchannels));
  if (!input->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.data))
    throw std::runtime_error("cannot read image '" + path + "': " + input->geterror());
  throw_if_damaged(*input, path);
  input->close();
  return image;
}

}  // namespace

cv::Mat read_image_float(const std::string& path) { return read_stored(path, "image", nullptr); }

namespace {

// Rows as stored (any channel count, float) -> linear RGB CV_32FC3.
cv::Mat stored_rows_to_linear(const cv::Mat& raw, bool stored_linear) {
  cv::Mat rgb;
  if (raw.channels() <= 2) {
    cv::Mat grey;
    cv::extractChannel(raw, grey, 0);
    cv::merge(std::vector<cv::Mat>{grey, grey, grey}, rgb);
  } else {
    rgb = to_three_channels(raw);
  }
  if (!stored_linear) {
    for (int y = 0; y < rgb.rows; ++y) {
      float* p = rgb.ptr<float>(y);
      for (int x = 0; x < rgb.cols * 3; ++x) p[x] = srgb_to_linear(p[x]);
    }
  }
  // Non-finite or negative texels (lossy EXR) would poison every later stage.
  cv::patchNaNs(rgb, 0.0);
  cv::max(rgb, 0.0, rgb);
  cv::min(rgb, std::numeric_limits<float>::max(), rgb);  // +inf -> largest finite
  return rgb;
}

// Same folder (so rename is atomic), same extension (so the writer picks the format).
std::filesystem::path temp_path_beside(const std::string& path) {
  const std::filesystem::path final_path(path);
  std::string temp_name = final_path.stem().string();
  temp_name.insert(0, 1, '.');
  temp_name += ".tmp" + std::to_string(::getpid()) + final_path.extension().string();
  return final_path.parent_path() / temp_name;
}

}  // namespace

cv::Mat load_photo_linear(const std::string& path) {
  bool stored_linear = false;
  const cv::Mat raw = read_stored(path, "photo", &stored_linear);
  return stored_rows_to_linear(raw, stored_linear);
}

struct PhotoRowReader::Impl {
  std::string path;
  std::unique_ptr<OIIO::ImageInput> input;
  int channels = 0;
  bool stored_linear = false;
  int next_row = 0;
};

PhotoRowReader::PhotoRowReader(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->input = open_image(path, "photo");
  const OIIO::ImageSpec& spec = impl_->input->spec();
  if (spec.nchannels > CV_CN_MAX)
    throw std::runtime_error("image '" + path + "' has " + std::to_string(spec.nchannels) + " channels");
  impl_->channels = spec.nchannels;
  impl_->stored_linear = stored_as_linear(spec, path);
  size_ = {spec.width, spec.height};
}

PhotoRowReader::~PhotoRowReader() = default;

cv::Mat PhotoRowReader::read(int first_row, int rows) {
  if (first_row != impl_->next_row || rows <= 0 || first_row + rows > size_.height)
    throw std::invalid_argument("PhotoRowReader: rows are read top to bottom, within the image");
  cv::Mat raw(rows, size_.width, CV_32FC(impl_->channels));
  const int y0 = impl_->input->spec().y + first_row;
  if (!impl_->input->read_scanlines(0, 0, y0, y0 + rows, 0, 0, impl_->channels, OIIO::TypeDesc::FLOAT, raw.data))
    throw std::runtime_error("cannot read image '" + impl_->path + "': " + impl_->input->geterror());
  throw_if_damaged(*impl_->input, impl_->path);
  impl_->next_row = first_row + rows;
  return stored_rows_to_linear(raw, impl_->stored_linear);
}

cv::Size photo_file_size(const std::string& path) {
  const auto input = open_image(path, "photo");
  return {input->spec().width, input->spec().height};
}

cv::Mat load_photo_reduced(const std::string& path, cv::Size size) {
  constexpr int kBandRows = 64;
  PhotoRowReader reader(path);
  const cv::Size full = reader.size();
  if (size.width <= 0 || size.height <= 0 || size.width > full.width || size.height > full.height)
    throw std::invalid_argument("load_photo_reduced: the size must lie within the photo's");
  // Separable area averaging: each band is reduced across by cv::resize
  // (INTER_AREA), then every input row adds to the output rows its unit
  // interval overlaps, weighted by the overlap. An input row spans at most
  // two output rows, and output rows complete in order: two rows of sums
  // suffice (a 4096x4096 texture's whole sum would be 400 MB).
  cv::Mat out(size, CV_32FC3);
  cv::Mat sum(2, size.width, CV_64FC3, cv::Scalar::all(0));  // output row j in sum.row(j % 2)
  int next_unwritten = 0;
  const auto write_rows_before = [&](int end) {
    for (; next_unwritten < std::min(end, size.height); ++next_unwritten) {
      cv::Mat row = sum.row(next_unwritten % 2);
      row.convertTo(out.row(next_unwritten), CV_32FC3);
      row.setTo(cv::Scalar::all(0));
    }
  };
  const double rows_per_output = static_cast<double>(full.height) / size.height;
  cv::Mat across, across64;
  for (int y = 0; y < full.height; y += kBandRows) {
    const int rows = std::min(kBandRows, full.height - y);
    cv::resize(reader.read(y, rows), across, cv::Size(size.width, rows), 0, 0, cv::INTER_AREA);
    across.convertTo(across64, CV_64FC3);
    for (int r = 0; r < rows; ++r) {
      const double top = (y + r) / rows_per_output, bottom = (y + r + 1) / rows_per_output;  // in output rows
      write_rows_before(static_cast<int>(top));
      for (int j = static_cast<int>(top); j < size.height && j < bottom; ++j) {
        const double overlap = std::min(bottom, j + 1.0) - std::max(top, static_cast<double>(j));
        cv::Mat row = sum.row(j % 2);
        if (overlap > 0) cv::scaleAdd(across64.row(r), overlap, row, row);
      }
    }
  }
  write_rows_before(size.height);
  return out;
}

struct ImageRowWriter::Impl {
  std::string path;
  std::filesystem::path temp;
  std::unique_ptr<OIIO::ImageOutput> output;
  bool float_file = false;
  cv::Size size;
  int next_row = 0;
  bool finished = false;
};

ImageRowWriter::ImageRowWriter(const std::string& path, cv::Size size) : impl_(std::make_unique<Impl>()) {
  if (size.width <= 0 || size.height <= 0) throw std::runtime_error("refusing to write an empty image to '" + path + "'");
  impl_->path = path;
  impl_->size = size;
  impl_->float_file = is_float_format(path);
  impl_->temp = temp_path_beside(path);
  impl_->output = OIIO::ImageOutput::create(path);
  if (!impl_->output) throw std::runtime_error("no image writer for '" + path + "': " + OIIO::geterror());
  OIIO::ImageSpec spec(size.width, size.height, 3, impl_->float_file ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
  if (impl_->float_file) spec.attribute("compression", "zip");
  if (!impl_->output->open(impl_->temp.string(), spec))
    throw std::runtime_error("cannot create '" + impl_->temp.string() + "': " + impl_->output->geterror());
}

ImageRowWriter::~ImageRowWriter() {
  if (impl_->finished) return;
  impl_->output->close();
  std::error_code ec;
  std::filesystem::remove(impl_->temp, ec);
}

void ImageRowWriter::write(const cv::Mat& linear_rows) {
  if (linear_rows.type() != CV_32FC3 || linear_rows.cols != impl_->size.width ||
      impl_->next_row + linear_rows.rows > impl_->size.height)
    throw std::invalid_argument("ImageRowWriter: CV_32FC3 rows of the image's width, within its height");
  cv::Mat data = impl_->float_file ? linear_rows : linear_to_srgb8(linear_rows);
  if (!data.isContinuous()) data = data.clone();
  const OIIO::TypeDesc type = impl_->float_file ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  if (!impl_->output->write_scanlines(impl_->next_row, impl_->next_row + data.rows, 0, type, data.data))
    throw std::runtime_error("cannot write '" + impl_->path + "': " + impl_->output->geterror());
  impl_->next_row += data.rows;
}

void ImageRowWriter::finish() {
  if (impl_->next_row != impl_->size.height)
    throw std::logic_error("ImageRowWriter: finished with " + std::to_string(impl_->next_row) + " of " +
                           std::to_string(impl_->size.height) + " rows written");
  if (!impl_->output->close()) throw std::runtime_error("cannot write '" + impl_->path + "': " + impl_->output->geterror());
  std::filesystem::rename(impl_->temp, impl_->path);
  impl_->finished = true;
}

void write_image(const std::string& path, const cv::Mat& image) {
  if (image.empty()) throw std::runtime_error("refusing to write an empty image to '" + path + "'");
  const bool float_file = is_float_format(path);
  cv::Mat data;
  OIIO::TypeDesc type;
  if (float_file) {
    image.convertTo(data, CV_32F);
    type = OIIO::TypeDesc::FLOAT;
  } else if (image.depth() == CV_8U) {
    data = image;
    type = OIIO::TypeDesc::UINT8;
  } else {
    cv::Mat as_float;
    image.convertTo(as_float, CV_32F);
    data = linear_to_srgb8(as_float);
    type = OIIO::TypeDesc::UINT8;
  }
  if (!data.isContinuous()) data = data.clone();

  const std::filesystem::path final_path(path);
  const std::filesystem::path temp_path = temp_path_beside(path);
  auto output = OIIO::ImageOutput::create(path);
  if (!output) throw std::runtime_error("no image writer for '" + path + "': " + OIIO::geterror());
  OIIO::ImageSpec spec(data.cols, data.rows, data.channels(), type);
  if (float_file) spec.attribute("compression", "zip");
  if (!output->open(temp_path.string(), spec))
    throw std::runtime_error("cannot create '" + temp_path.string() + "': " + output->geterror());
  const bool ok = output->write_image(type, data.data);
  output->close();
  if (!ok) {
    std::filesystem::remove(temp_path);
    throw std::runtime_error("cannot write '" + path + "': " + output->geterror());
  }
  std::filesystem::rename(temp_path, final_path);
}

}  // namespace propcam::capture
