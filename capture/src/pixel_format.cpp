#include "propcam/capture/pixel_format.h"

#include <array>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

// jpeglib.h needs FILE and size_t declared first.
#include <jerror.h>
#include <jpeglib.h>

#include "propcam/capture/image_file.h"

namespace propcam::capture {
namespace {

// ---------------------------------------------------------------------------
// Y'CbCr coefficients (ITU-R BT.601 / BT.709) and the two quantisation ranges.

struct LumaWeights {
  double kr, kb;
  double kg() const { return 1.0 - kr - kb; }
};

LumaWeights weights(YcbcrEncoding encoding) {
  return encoding == YcbcrEncoding::Bt709 ? LumaWeights{0.2126, 0.0722} : LumaWeights{0.299, 0.114};
}

// Limited range: Y' 16..235 (219 steps), Cb/Cr 16..240 around 128 (224 steps).
// Full range: both span 255 steps (Cb/Cr around 128), as V4L2 and JFIF define it.
struct Quantisation {
  double y_offset, y_steps, c_steps;
};

Quantisation quantisation(QuantisationRange range) {
  return range == QuantisationRange::Full ? Quantisation{0, 255, 255} : Quantisation{16, 219, 224};
}

// Per-byte lookup tables in 12.20 fixed point: each RGB channel is a sum of
// two or three table entries. The rounding bias (half) sits in the luma table;
// 20 fractional bits keep the result equal to the exactly rounded value
// except within ~1e-5 of a tie.
constexpr int kShift = 20;

struct YuvTables {
  std::array<std::int32_t, 256> y, r_v, g_u, g_v, b_u;
};

YuvTables make_tables(YcbcrEncoding encoding, QuantisationRange range) {
  const LumaWeights w = weights(encoding);
  const Quantisation q = quantisation(range);
  const double one = static_cast<double>(1 << kShift);
  const double ys = 255.0 / q.y_steps, cs = 255.0 / q.c_steps;
  YuvTables t{};
  for (int i = 0; i < 256; ++i) {
    const double c = (i - 128) * cs;
    t.y[i] = static_cast<std::int32_t>(std::lround((i - q.y_offset) * ys * one + one / 2));
    t.r_v[i] = static_cast<std::int32_t>(std::lround(2 * (1 - w.kr) * c * one));
    t.g_u[i] = static_cast<std::int32_t>(std::lround(-2 * w.kb * (1 - w.kb) / w.kg() * c * one));
    t.g_v[i] = static_cast<std::int32_t>(std::lround(-2 * w.kr * (1 - w.kr) / w.kg() * c * one));
    t.b_u[i] = static_cast<std::int32_t>(std::lround(2 * (1 - w.kb) * c * one));
  }
  return t;
}

const YuvTables& tables(YcbcrEncoding encoding, QuantisationRange range) {
  static const std::array<YuvTables, 4> all{
      make_tables(YcbcrEncoding::Bt601, QuantisationRange::Limited),
      make_tables(YcbcrEncoding::Bt601, QuantisationRange::Full),
      make_tables(YcbcrEncoding::Bt709, QuantisationRange::Limited),
      make_tables(YcbcrEncoding::Bt709, QuantisationRange::Full)};
  const int index = (encoding == YcbcrEncoding::Bt709 ? 2 : 0) + (range == QuantisationRange::Full ? 1 : 0);
  return all[index];
}

inline std::uint8_t clamp8(std::int32_t fixed) {
  const std::int32_t v = fixed >> kShift;  // arithmetic shift: floor (C++20)
  return static_cast<std::uint8_t>(v < 0 ? 0 : (v > 255 ? 255 : v));
}

// One pixel from its luma and the chroma terms it shares with its neighbours.
inline void put_rgb(std::uint8_t* out, std::int32_t y, std::int32_t r_c, std::int32_t g_c, std::int32_t b_c) {
  out[0] = clamp8(y + r_c);
  out[1] = clamp8(y + g_c);
  out[2] = clamp8(y + b_c);
}

// YUYV and UYVY: 4 bytes per pixel pair; the template fixes the byte order.
template <int Y0, int U, int Y1, int V>
void packed422_to_rgb(const std::uint8_t* src, int stride, const YuvTables& t, cv::Mat& out) {
  const int pairs = out.cols / 2;
  for (int row = 0; row < out.rows; ++row) {
    const std::uint8_t* s = src + static_cast<std::ptrdiff_t>(row) * stride;
    std::uint8_t* d = out.ptr<std::uint8_t>(row);
    for (int p = 0; p < pairs; ++p, s += 4, d += 6) {
      const std::int32_t r_c = t.r_v[s[V]], g_c = t.g_u[s[U]] + t.g_v[s[V]], b_c = t.b_u[s[U]];
      put_rgb(d, t.y[s[Y0]], r_c, g_c, b_c);
      put_rgb(d + 3, t.y[s[Y1]], r_c, g_c, b_c);
    }
  }
}

void nv12_to_rgb(const std::uint8_t* src, int stride, const YuvTables& t, cv::Mat& out) {
  const std::uint8_t* chroma = src + static_cast<std::ptrdiff_t>(stride) * out.rows;
  const int pairs = out.cols / 2;
  for (int row = 0; row < out.rows; ++row) {
    const std::uint8_t* s = src + static_cast<std::ptrdiff_t>(row) * stride;
    const std::uint8_t* c = chroma + static_cast<std::ptrdiff_t>(row / 2) * stride;
    std::uint8_t* d = out.ptr<std::uint8_t>(row);
    for (int p = 0; p < pairs; ++p, s += 2, c += 2, d += 6) {
      const std::int32_t r_c = t.r_v[c[1]], g_c = t.g_u[c[0]] + t.g_v[c[1]], b_c = t.b_u[c[0]];
      put_rgb(d, t.y[s[0]], r_c, g_c, b_c);
      put_rgb(d + 3, t.y[s[1]], r_c, g_c, b_c);
    }
  }
}

void grey_to_rgb(const std::uint8_t* src, int stride, QuantisationRange range, cv::Mat& out) {
  std::array<std::uint8_t, 256> lut{};
  const YuvTables& t = tables(YcbcrEncoding::Bt601, range);  // luma scaling only
  for (int i = 0; i < 256; ++i) lut[i] = clamp8(t.y[i]);
  for (int row = 0; row < out.rows; ++row) {
    const std::uint8_t* s = src + static_cast<std::ptrdiff_t>(row) * stride;
    std::uint8_t* d = out.ptr<std::uint8_t>(row);
    for (int x = 0; x < out.cols; ++x, d += 3) d[0] = d[1] = d[2] = lut[s[x]];
  }
}

void rgb24_to_rgb(const std::uint8_t* src, int stride, bool swap, cv::Mat& out) {
  const std::size_t row_bytes = static_cast<std::size_t>(out.cols) * 3;
  for (int row = 0; row < out.rows; ++row) {
    const std::uint8_t* s = src + static_cast<std::ptrdiff_t>(row) * stride;
    std::uint8_t* d = out.ptr<std::uint8_t>(row);
    if (!swap) {
      std::memcpy(d, s, row_bytes);
      continue;
    }
    for (std::size_t x = 0; x < row_bytes; x += 3) {
      d[x] = s[x + 2];
      d[x + 1] = s[x + 1];
      d[x + 2] = s[x];
    }
  }
}

// ---------------------------------------------------------------------------
// libjpeg-turbo. Its default error handler calls exit(); ours longjmps back
// to the decode or encode call, which turns the message into an exception
// outside the C frames. Warnings that mean the data is corrupt or truncated
// (where libjpeg would otherwise hand back a grey-filled image) are errors.

struct JpegError {
  jpeg_error_mgr mgr;  // first, so libjpeg's pointer is also ours
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void jpeg_fail(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegError*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}

void jpeg_message(j_common_ptr cinfo, int level) {
  if (level >= 0) return;  // trace output
  switch (cinfo->err->msg_code) {
    case JWRN_EXTRANEOUS_DATA:  // stray bytes between markers: common from webcams, harmless
    case JWRN_JFIF_MAJOR:
    case JWRN_ADOBE_XFORM:
    case JWRN_BOGUS_ICC: return;
    default: jpeg_fail(cinfo);
  }
}

void install(JpegError& err) {
  jpeg_std_error(&err.mgr);
  err.mgr.error_exit = jpeg_fail;
  err.mgr.emit_message = jpeg_message;
  err.message[0] = '\0';
}

// Decodes into `out`, already allocated at the size the frame format says.
// Only objects created before setjmp live across it. Returns false with the
// reason in `message`.
bool decode_jpeg(const std::uint8_t* data, std::size_t size, cv::Mat& out, std::vector<JSAMPROW>& rows,
                 char* message) {
  jpeg_decompress_struct cinfo;
  JpegError err;
  install(err);
  cinfo.err = &err.mgr;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    std::snprintf(message, JMSG_LENGTH_MAX, "%s", err.message);
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  if (cinfo.image_width != static_cast<JDIMENSION>(out.cols) ||
      cinfo.image_height != static_cast<JDIMENSION>(out.rows)) {
    std::snprintf(message, JMSG_LENGTH_MAX, "the JPEG is %ux%u, the frame format says %dx%d", cinfo.image_width,
                  cinfo.image_height, out.cols, out.rows);
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  cinfo.out_color_space = JCS_RGB;  // also expands greyscale JPEGs
  jpeg_start_decompress(&cinfo);
  while (cinfo.output_scanline < cinfo.output_height)
    jpeg_read_scanlines(&cinfo, rows.data() + cinfo.output_scanline, cinfo.output_height - cinfo.output_scanline);
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return true;
}

// A destination writing into a vector that doubles when full. An exception
// must not cross libjpeg's C frames: a failed allocation becomes a libjpeg
// error (a longjmp) instead.
struct VectorDestination {
  jpeg_destination_mgr mgr;  // first, as above
  std::vector<std::uint8_t>* out;
};

void destination_init(j_compress_ptr cinfo) {
  auto* dest = reinterpret_cast<VectorDestination*>(cinfo->dest);
  dest->mgr.next_output_byte = dest->out->data();
  dest->mgr.free_in_buffer = dest->out->size();
}

boolean destination_full(j_compress_ptr cinfo) {
  auto* dest = reinterpret_cast<VectorDestination*>(cinfo->dest);
  const std::size_t used = dest->out->size();  // libjpeg calls this only when all of it is used
  bool grown = false;
  try {
    dest->out->resize(2 * used);
    grown = true;
  } catch (...) {
  }
  if (!grown) ERREXIT(cinfo, JERR_OUT_OF_MEMORY);
  dest->mgr.next_output_byte = dest->out->data() + used;
  dest->mgr.free_in_buffer = dest->out->size() - used;
  return TRUE;
}

void destination_term(j_compress_ptr) {}

bool encode_jpeg(const cv::Mat& rgb, int quality, std::vector<std::uint8_t>& out, std::size_t& used,
                 std::vector<JSAMPROW>& rows, char* message) {
  jpeg_compress_struct cinfo;
  JpegError err;
  VectorDestination dest{{nullptr, 0, destination_init, destination_full, destination_term}, &out};
  install(err);
  cinfo.err = &err.mgr;
  if (setjmp(err.jump)) {
    jpeg_destroy_compress(&cinfo);
    std::snprintf(message, JMSG_LENGTH_MAX, "%s", err.message);
    return false;
  }
  jpeg_create_compress(&cinfo);
  cinfo.dest = &dest.mgr;
  cinfo.image_width = static_cast<JDIMENSION>(rgb.cols);
  cinfo.image_height = static_cast<JDIMENSION>(rgb.rows);
  cinfo.input_components = 3;
  cinfo.in_color_space = JCS_RGB;
  jpeg_set_defaults(&cinfo);  // 4:2:0 chroma, as webcams send
  jpeg_set_quality(&cinfo, quality, TRUE);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height)
    jpeg_write_scanlines(&cinfo, rows.data() + cinfo.next_scanline, cinfo.image_height - cinfo.next_scanline);
  jpeg_finish_compress(&cinfo);
  used = out.size() - dest.mgr.free_in_buffer;
  jpeg_destroy_compress(&cinfo);
  return true;
}

// ---------------------------------------------------------------------------

int effective_stride(const FrameFormat& f) {
  return f.stride ? f.stride : minimum_stride(f.pixel_format, f.width);
}

// For messages about a format validate_frame_format accepted.
std::string describe(const FrameFormat& f) {
  std::string s = to_string(f.pixel_format) + " " + std::to_string(f.width) + "x" + std::to_string(f.height);
  if (f.pixel_format != PixelFormat::MJPEG) s += " (stride " + std::to_string(effective_stride(f)) + ")";
  return s;
}

// The frame's bytes, checked against its format (throws saying what is wrong).
std::span<const std::uint8_t> checked_bytes(const Frame& frame) {
  const FrameFormat& f = frame.format;
  validate_frame_format(f);
  if (!frame.buffer) throw std::runtime_error(describe(f) + " frame: no buffer");
  const std::size_t have = frame.buffer->bytes().size();
  if (frame.bytes_used > have)
    throw std::runtime_error(describe(f) + " frame: bytes_used " + std::to_string(frame.bytes_used) +
                             " exceeds its buffer of " + std::to_string(have) + " bytes");
  const std::size_t need = frame_bytes(f);
  if (f.pixel_format == PixelFormat::MJPEG) {
    if (frame.bytes_used == 0) throw std::runtime_error(describe(f) + " frame: empty JPEG");
    if (frame.bytes_used > need)
      throw std::runtime_error(describe(f) + " frame: " + std::to_string(frame.bytes_used) +
                               " bytes, more than a JPEG of that size can need (" + std::to_string(need) + ")");
  } else if (frame.bytes_used < need) {
    throw std::runtime_error(describe(f) + " frame: needs " + std::to_string(need) + " bytes, has " +
                             std::to_string(frame.bytes_used));
  }
  return frame.data();
}

cv::Mat mjpeg_to_rgb(std::span<const std::uint8_t> bytes, const FrameFormat& f) {
  cv::Mat out(f.height, f.width, CV_8UC3);
  std::vector<JSAMPROW> rows(static_cast<std::size_t>(f.height));
  for (int r = 0; r < f.height; ++r) rows[r] = out.ptr<std::uint8_t>(r);
  char message[JMSG_LENGTH_MAX] = {};
  if (!decode_jpeg(bytes.data(), bytes.size(), out, rows, message))
    throw std::runtime_error(describe(f) + " frame: cannot decode the JPEG (" + std::string(message) + ")");
  return out;
}

// ---------------------------------------------------------------------------
// RGB -> Y'CbCr, for rgb8_to_frame (tests, synthetic scenes): double math,
// chroma averaged over the pixels that share a sample before quantising.

struct Encoder {
  LumaWeights w;
  Quantisation q;

  std::uint8_t quantise(double v) const { return static_cast<std::uint8_t>(std::clamp(std::floor(v + 0.5), 0.0, 255.0)); }
  double luma(const std::uint8_t* rgb) const {  // E'Y in 0..1
    return (w.kr * rgb[0] + w.kg() * rgb[1] + w.kb * rgb[2]) / 255.0;
  }
  double pb(const std::uint8_t* rgb) const { return (rgb[2] / 255.0 - luma(rgb)) / (2 * (1 - w.kb)); }
  double pr(const std::uint8_t* rgb) const { return (rgb[0] / 255.0 - luma(rgb)) / (2 * (1 - w.kr)); }
  std::uint8_t y(const std::uint8_t* rgb) const { return quantise(q.y_offset + q.y_steps * luma(rgb)); }
  std::uint8_t c(double p) const { return quantise(128 + q.c_steps * p); }
};

Encoder encoder(const FrameFormat& f) { return Encoder{weights(f.encoding), quantisation(f.range)}; }

void rgb_to_packed422(const cv::Mat& rgb, const FrameFormat& f, int stride, std::uint8_t* dst) {
  const Encoder e = encoder(f);
  const bool yuyv = f.pixel_format == PixelFormat::YUYV;
  for (int row = 0; row < rgb.rows; ++row) {
    const std::uint8_t* s = rgb.ptr<std::uint8_t>(row);
    std::uint8_t* d = dst + static_cast<std::ptrdiff_t>(row) * stride;
    for (int x = 0; x < rgb.cols; x += 2, s += 6, d += 4) {
      const std::uint8_t u = e.c((e.pb(s) + e.pb(s + 3)) / 2), v = e.c((e.pr(s) + e.pr(s + 3)) / 2);
      const std::uint8_t bytes[4] = {e.y(s), u, e.y(s + 3), v};  // Y0 U Y1 V
      const std::uint8_t swapped[4] = {u, bytes[0], v, bytes[2]};  // U Y0 V Y1
      std::memcpy(d, yuyv ? bytes : swapped, 4);
    }
  }
}

void rgb_to_nv12(const cv::Mat& rgb, const FrameFormat& f, int stride, std::uint8_t* dst) {
  const Encoder e = encoder(f);
  std::uint8_t* chroma = dst + static_cast<std::ptrdiff_t>(stride) * rgb.rows;
  for (int row = 0; row < rgb.rows; ++row) {
    const std::uint8_t* s = rgb.ptr<std::uint8_t>(row);
    std::uint8_t* d = dst + static_cast<std::ptrdiff_t>(row) * stride;
    for (int x = 0; x < rgb.cols; ++x) d[x] = e.y(s + 3 * x);
  }
  for (int row = 0; row < rgb.rows; row += 2) {
    const std::uint8_t* top = rgb.ptr<std::uint8_t>(row);
    const std::uint8_t* bottom = rgb.ptr<std::uint8_t>(row + 1);
    std::uint8_t* c = chroma + static_cast<std::ptrdiff_t>(row / 2) * stride;
    for (int x = 0; x < rgb.cols; x += 2) {
      const std::uint8_t* px[4] = {top + 3 * x, top + 3 * x + 3, bottom + 3 * x, bottom + 3 * x + 3};
      double pb = 0, pr = 0;
      for (const std::uint8_t* p : px) pb += e.pb(p), pr += e.pr(p);
      c[x] = e.c(pb / 4);
      c[x + 1] = e.c(pr / 4);
    }
  }
}

void rgb_to_grey(const cv::Mat& rgb, const FrameFormat& f, int stride, std::uint8_t* dst) {
  const Encoder e = encoder(f);
  for (int row = 0; row < rgb.rows; ++row) {
    const std::uint8_t* s = rgb.ptr<std::uint8_t>(row);
    std::uint8_t* d = dst + static_cast<std::ptrdiff_t>(row) * stride;
    for (int x = 0; x < rgb.cols; ++x) d[x] = e.y(s + 3 * x);
  }
}

void rgb_to_rgb24(const cv::Mat& rgb, bool swap, int stride, std::uint8_t* dst) {
  for (int row = 0; row < rgb.rows; ++row) {
    const std::uint8_t* s = rgb.ptr<std::uint8_t>(row);
    std::uint8_t* d = dst + static_cast<std::ptrdiff_t>(row) * stride;
    for (int x = 0; x < rgb.cols * 3; x += 3) {
      d[x] = s[swap ? x + 2 : x];
      d[x + 1] = s[x + 1];
      d[x + 2] = s[swap ? x : x + 2];
    }
  }
}

std::vector<std::uint8_t> rgb_to_mjpeg(const cv::Mat& rgb, const FrameFormat& f, int quality) {
  if (quality < 1 || quality > 100)
    throw std::runtime_error("rgb8_to_frame: JPEG quality " + std::to_string(quality) + " outside 1..100");
  // Half a byte per pixel is typical at high quality; the buffer grows if not.
  std::vector<std::uint8_t> out(static_cast<std::size_t>(f.width) * f.height / 2 + 16384);
  std::vector<JSAMPROW> rows(static_cast<std::size_t>(rgb.rows));
  for (int r = 0; r < rgb.rows; ++r) rows[r] = const_cast<std::uint8_t*>(rgb.ptr<std::uint8_t>(r));
  std::size_t used = 0;
  char message[JMSG_LENGTH_MAX] = {};
  if (!encode_jpeg(rgb, quality, out, used, rows, message))
    throw std::runtime_error("rgb8_to_frame: cannot encode the JPEG (" + std::string(message) + ")");
  out.resize(used);
  return out;
}

}  // namespace

cv::Mat frame_to_rgb8(const Frame& frame) {
  const std::span<const std::uint8_t> bytes = checked_bytes(frame);
  const FrameFormat& f = frame.format;
  if (f.pixel_format == PixelFormat::MJPEG) return mjpeg_to_rgb(bytes, f);
  cv::Mat out(f.height, f.width, CV_8UC3);
  const int stride = effective_stride(f);
  const std::uint8_t* src = bytes.data();
  switch (f.pixel_format) {
    case PixelFormat::RGB24: rgb24_to_rgb(src, stride, false, out); break;
    case PixelFormat::BGR24: rgb24_to_rgb(src, stride, true, out); break;
    case PixelFormat::YUYV: packed422_to_rgb<0, 1, 2, 3>(src, stride, tables(f.encoding, f.range), out); break;
    case PixelFormat::UYVY: packed422_to_rgb<1, 0, 3, 2>(src, stride, tables(f.encoding, f.range), out); break;
    case PixelFormat::NV12: nv12_to_rgb(src, stride, tables(f.encoding, f.range), out); break;
    case PixelFormat::GREY: grey_to_rgb(src, stride, f.range, out); break;
    case PixelFormat::MJPEG: break;  // handled above
  }
  return out;
}

cv::Mat frame_to_linear(const Frame& frame) { return srgb8_to_linear(frame_to_rgb8(frame)); }

Frame rgb8_to_frame(const cv::Mat& rgb8, const FrameFormat& format, int jpeg_quality) {
  validate_frame_format(format);
  if (rgb8.type() != CV_8UC3)
    throw std::runtime_error("rgb8_to_frame: the image must be CV_8UC3, it is type " + std::to_string(rgb8.type()));
  if (rgb8.cols != format.width || rgb8.rows != format.height)
    throw std::runtime_error("rgb8_to_frame: the image is " + std::to_string(rgb8.cols) + "x" +
                             std::to_string(rgb8.rows) + ", the format " + describe(format));
  Frame frame;
  frame.format = format;
  std::vector<std::uint8_t> bytes;
  if (format.pixel_format == PixelFormat::MJPEG) {
    frame.format.stride = 0;
    bytes = rgb_to_mjpeg(rgb8, format, jpeg_quality);
  } else {
    frame.format.stride = effective_stride(format);
    bytes.assign(frame_bytes(frame.format), 0);  // padding bytes are zero
    const int stride = frame.format.stride;
    switch (format.pixel_format) {
      case PixelFormat::RGB24: rgb_to_rgb24(rgb8, false, stride, bytes.data()); break;
      case PixelFormat::BGR24: rgb_to_rgb24(rgb8, true, stride, bytes.data()); break;
      case PixelFormat::YUYV:
      case PixelFormat::UYVY: rgb_to_packed422(rgb8, format, stride, bytes.data()); break;
      case PixelFormat::NV12: rgb_to_nv12(rgb8, format, stride, bytes.data()); break;
      case PixelFormat::GREY: rgb_to_grey(rgb8, format, stride, bytes.data()); break;
      case PixelFormat::MJPEG: break;
    }
  }
  frame.bytes_used = bytes.size();
  frame.buffer = std::make_shared<VectorFrameBuffer>(std::move(bytes));
  return frame;
}

}  // namespace propcam::capture
