#include "propcam/render/mesh_io.h"

#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <tiny_obj_loader.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <new>
#include <optional>
#include <set>
#include <stdexcept>
#include <string_view>
#include <utility>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "propcam/capture/image_file.h"

namespace propcam::render {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector2f;
using Eigen::Vector3f;

[[noreturn]] void fail(const std::string& file, const std::string& what) {
  throw std::runtime_error("mesh file '" + file + "': " + what);
}

std::string trim(std::string text) {
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.pop_back();
  return text;
}

Vector3f clamp01(const Vector3f& v) { return v.cwiseMax(0.f).cwiseMin(1.f); }

// GGX alpha <-> Phong exponent, the usual Blinn-Phong/Beckmann correspondence.
float roughness_from_shininess(float ns) { return std::clamp(std::sqrt(2.f / (std::max(ns, 0.f) + 2.f)), 0.02f, 1.f); }
float shininess_from_roughness(float alpha) {
  const float a = std::clamp(alpha, 0.02f, 1.f);
  return 2.f / (a * a) - 2.f;
}

// 8-bit sRGB BGR (as cv::imread returns it) -> linear RGB CV_32FC3.
cv::Mat bgr8_srgb_to_linear_rgb(const cv::Mat& bgr) {
  std::array<float, 256> lut;
  for (int i = 0; i < 256; ++i) lut[i] = capture::srgb_to_linear(static_cast<float>(i) / 255.f);
  cv::Mat rgb(bgr.rows, bgr.cols, CV_32FC3);
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* src = bgr.ptr<cv::Vec3b>(y);
    auto* dst = rgb.ptr<cv::Vec3f>(y);
    for (int x = 0; x < bgr.cols; ++x) dst[x] = cv::Vec3f(lut[src[x][2]], lut[src[x][1]], lut[src[x][0]]);
  }
  return rgb;
}

cv::Mat linear_rgb_to_bgr8_srgb(const cv::Mat& rgb) {
  cv::Mat bgr(rgb.rows, rgb.cols, CV_8UC3);
  for (int y = 0; y < rgb.rows; ++y) {
    const auto* src = rgb.ptr<cv::Vec3f>(y);
    auto* dst = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < rgb.cols; ++x)
      for (int c = 0; c < 3; ++c)
        dst[x][2 - c] = static_cast<uchar>(std::lround(255.f * std::min(1.f, capture::linear_to_srgb(src[x][c]))));
  }
  return bgr;
}

// ---------------------------------------------------------------------------
// Loading

// Lines as tinyobjloader splits them (at \n, \r or \r\n; leading spaces and tabs skipped; a NUL ends a
// line's text), read in chunks so that no line, however long, is held whole. For each line with text,
// on_line(keyword, spaced, words): its first word (only the first kKeywordChars characters kept), whether a
// space or tab follows it, and the number of words after it (0 unless wants_text(keyword)). For the lines that
// wants_text, on_text(keyword, c) sees each character after that space or tab; the others are skipped through.
constexpr std::size_t kKeywordChars = 8;

template <typename WantsText, typename OnLine, typename OnText>
void scan_lines(std::istream& in, WantsText wants_text, OnLine on_line, OnText on_text) {
  std::vector<char> chunk(std::size_t{1} << 16);
  std::string keyword;
  bool spaced = false, in_word = false, skipping = false;
  std::uint64_t words = 0;
  const auto end_line = [&] {
    if (!keyword.empty()) on_line(std::string_view(keyword), spaced, words);
    keyword.clear();
    spaced = in_word = skipping = false;
    words = 0;
  };
  while (in.read(chunk.data(), static_cast<std::streamsize>(chunk.size())) || in.gcount() > 0) {
    const std::size_t count = static_cast<std::size_t>(in.gcount());
    for (std::size_t i = 0; i < count; ++i) {
      const char c = chunk[i];
      if (c == '\n' || c == '\r') {
        end_line();
      } else if (skipping) {  // to the end of the line: the next \n, or a \r before it
        const char* const from = chunk.data() + i;
        const char* end = static_cast<const char*>(std::memchr(from, '\n', count - i));
        if (const void* cr = std::memchr(from, '\r', (end ? end : chunk.data() + count) - from))
          end = static_cast<const char*>(cr);
        i = (end ? end - chunk.data() : count) - 1;
      } else if (c == '\0') {
        skipping = true;
      } else if (c == ' ' || c == '\t') {
        if (!spaced && !keyword.empty()) {
          spaced = true;
          skipping = !wants_text(std::string_view(keyword));
        }
        in_word = false;
        if (spaced && !skipping) on_text(std::string_view(keyword), c);
      } else if (!spaced) {
        if (keyword.size() < kKeywordChars) keyword += c;
      } else {  // the text of a line wants_text, in a loop of its own (faces are most of an OBJ)
        const std::string_view wanted(keyword);
        std::size_t j = i;
        for (; j < count && chunk[j] != '\n' && chunk[j] != '\r' && chunk[j] != '\0'; ++j) {
          on_text(wanted, chunk[j]);
          const bool space = chunk[j] == ' ' || chunk[j] == '\t';
          words += !space && !in_word;
          in_word = !space;
        }
        i = j - 1;  // the end of the line, or the NUL, is the outer loop's
      }
    }
  }
  end_line();
}

template <typename OnLine>
void scan_lines(std::istream& in, OnLine on_line) {
  scan_lines(in, [](std::string_view) { return false; }, on_line, [](std::string_view, char) {});
}

// tinyobjloader's ear clipping takes time quadratic in a polygon's corners (a 4000-gon takes 0.15 s).
// Larger polygons are split as a fan from their first corner before it sees them: right for convex
// polygons, which large ones nearly always are (discs, the caps of cylinders).
constexpr std::uint64_t kMaxEarClippedCorners = 64;

// The records of an OBJ that cost memory, counted before they are allocated, and what decides how it is read.
struct ObjCensus {
  std::uint64_t positions = 0, uvs = 0, normals = 0;
  std::uint64_t triangles = 0;        // after triangulation: corners - 2 per face
  std::uint64_t largest_polygon = 0;  // corners
  std::uint64_t quads = 0;
  // Lines only tinyobjloader's LoadObj reads as it does (StreamingObj tells why): a face of 5 to
  // kMaxEarClippedCorners corners (ear clipping); `l`, `p` or `vw` lines (LoadObj may refuse them); `usemtl` with
  // no space after it; a face whose texture coordinate or normal index could read as 0 (LoadObj refuses it, the
  // streaming reader cannot tell it from an absent one).
  bool needs_load_obj = false;
};

// Whether a face's index fields read as LoadObj reads them with none of texture coordinate or normal read as 0:
// each after a '/' starts with 1-9, or - and 1-9; '//' only after the position; at most two '/' a corner; at most 9
// digits in a row (no overflow to 0). A state machine over character classes, fed the text after the "f".
class FaceIndexCheck {
 public:
  void feed(char c) {
    const int kind = kClass[static_cast<unsigned char>(c)];
    state_ = kNext[state_][kind];
    digits_ = kind == kZero || kind == kDigit ? digits_ + 1 : 0;
    long_number_ = long_number_ || digits_ > 9;
  }
  // At the end of a face's line: whether LoadObj might read an index there as 0; then ready for the next line.
  bool doubtful_and_reset() {
    const bool doubtful = long_number_ || !(state_ == kInField0 || state_ == kInField1 || state_ == kInField2);
    state_ = kInField0;
    digits_ = 0;
    long_number_ = false;
    return doubtful;
  }

 private:
  enum Class : std::uint8_t { kOther, kZero, kDigit, kMinus, kSlash, kSpace };
  // In the position (or between corners), after the first '/', after it and '-', in the texture coordinate, after
  // the second '/', after it and '-', in the normal; refused.
  enum State : std::uint8_t { kInField0, kSlash1, kMinus1, kInField1, kSlash2, kMinus2, kInField2, kRefused };
  static constexpr std::array<std::uint8_t, 256> kClass = [] {
    std::array<std::uint8_t, 256> classes{};
    classes['0'] = kZero;
    for (char c = '1'; c <= '9'; ++c) classes[static_cast<unsigned char>(c)] = kDigit;
    classes['-'] = kMinus;
    classes['/'] = kSlash;
    classes[' '] = classes['\t'] = kSpace;
    return classes;
  }();
  static constexpr std::uint8_t kNext[8][6] = {
      // other      zero       1-9         -          /         space
      {kInField0, kInField0, kInField0, kInField0, kSlash1, kInField0},   // kInField0
      {kRefused, kRefused, kInField1, kMinus1, kSlash2, kRefused},        // kSlash1 ('//' after the position)
      {kRefused, kRefused, kInField1, kRefused, kRefused, kRefused},      // kMinus1
      {kInField1, kInField1, kInField1, kInField1, kSlash2, kInField0},   // kInField1
      {kRefused, kRefused, kInField2, kMinus2, kRefused, kRefused},       // kSlash2
      {kRefused, kRefused, kInField2, kRefused, kRefused, kRefused},      // kMinus2
      {kInField2, kInField2, kInField2, kInField2, kRefused, kInField0},  // kInField2
      {kRefused, kRefused, kRefused, kRefused, kRefused, kRefused},       // kRefused
  };
  int state_ = kInField0, digits_ = 0;  // not chars, which may alias anything: kept in registers
  bool long_number_ = false;
};

ObjCensus census_obj(std::istream& in) {
  ObjCensus census;
  FaceIndexCheck face_check;
  scan_lines(
      in, [](std::string_view keyword) { return keyword == "f"; },
      [&](std::string_view keyword, bool spaced, std::uint64_t words) {
        if (keyword.starts_with("usemtl") && (keyword.size() > 6 || !spaced)) census.needs_load_obj = true;
        if (spaced && (keyword == "l" || keyword == "p" || keyword == "vw")) census.needs_load_obj = true;
        if (!spaced) return;
        if (keyword == "v") {
          ++census.positions;
        } else if (keyword == "vt") {
          ++census.uvs;
        } else if (keyword == "vn") {
          ++census.normals;
        } else if (keyword == "f") {
          if (words >= 3) census.triangles += words - 2;
          census.largest_polygon = std::max(census.largest_polygon, words);
          census.quads += words == 4;
          if (words >= 5 && words <= kMaxEarClippedCorners) census.needs_load_obj = true;
          if (face_check.doubtful_and_reset()) census.needs_load_obj = true;
        }
      },
      [&](std::string_view, char c) { face_check.feed(c); });
  return census;
}

// An OBJ's text as it reads, but with every face of more than kMaxEarClippedCorners corners written as a fan of
// triangles; tinyobjloader reads through it, so only one line of the file is held at a time.
class FanSplittingBuf : public std::streambuf {
 public:
  explicit FanSplittingBuf(std::istream& source) : source_(*source.rdbuf()) {}

 protected:
  int_type underflow() override {
    if (gptr() == egptr()) {
      if (!next_line()) return traits_type::eof();
      setg(out_.data(), out_.data(), out_.data() + out_.size());
    }
    return traits_type::to_int_type(*gptr());
  }

 private:
  // The next line of the source (split at \n, \r or \r\n) into out_, as it is or as a fan.
  bool next_line() {
    line_.clear();
    out_.clear();
    int c = source_.sbumpc();
    if (c == traits_type::eof()) return false;
    for (; c != traits_type::eof() && c != '\n' && c != '\r'; c = source_.sbumpc()) line_ += static_cast<char>(c);
    if (c == '\r' && source_.sgetc() == '\n') source_.sbumpc();
    const std::string_view text(line_.c_str());  // up to a NUL, as tinyobjloader reads it
    const std::size_t start = text.find_first_not_of(" \t");
    corners_.clear();
    if (start != std::string_view::npos && text[start] == 'f' && start + 1 < text.size() &&
        (text[start + 1] == ' ' || text[start + 1] == '\t')) {
      for (std::size_t at = text.find_first_not_of(" \t", start + 1); at != std::string_view::npos;
           at = text.find_first_not_of(" \t", at)) {
        const std::size_t end = std::min(text.find_first_of(" \t", at), text.size());
        corners_.push_back(text.substr(at, end - at));
        at = end;
      }
    }
    if (corners_.size() <= kMaxEarClippedCorners) {
      out_.append(line_).push_back('\n');
      return true;
    }
    for (std::size_t k = 1; k + 1 < corners_.size(); ++k) {
      out_.append("f ").append(corners_[0]).append(" ").append(corners_[k]).append(" ");
      out_.append(corners_[k + 1]).push_back('\n');
    }
    return true;
  }

  std::streambuf& source_;
  std::string line_, out_;
  std::vector<std::string_view> corners_;
};

std::string count_over_limit(std::uint64_t count, const char* what, std::uint64_t limit) {
  return "too large: " + std::to_string(count) + " " + what + " (the limit is " + std::to_string(limit) + ")";
}

// Opens .mtl files next to the .obj and remembers which file each material
// came from, because texture paths are relative to their .mtl. Each file is
// read once however many `mtllib` lines name it, and the materials of all of
// them are counted against kMaxMeshMaterials before they are parsed.
class MtlFileReader : public tinyobj::MaterialReader {
 public:
  MtlFileReader(std::string obj_path, fs::path obj_folder)
      : obj_path_(std::move(obj_path)), obj_folder_(std::move(obj_folder)) {}

  bool operator()(const std::string& mtl_name, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* material_map, std::string* warn, std::string* err) override {
    std::string portable = mtl_name;
    std::replace(portable.begin(), portable.end(), '\\', '/');  // files written on Windows
    const fs::path mtl_path = obj_folder_ / portable;
    std::ifstream in(mtl_path, std::ios::binary);
    if (!in) {
      if (warn) *warn += "material file '" + mtl_path.string() + "' not found\n";
      return false;
    }
    std::error_code ec;
    const fs::path canonical = fs::weakly_canonical(mtl_path, ec);
    if (!read_.insert(ec ? mtl_path.lexically_normal() : canonical).second) return true;
    std::uint64_t count = 0;
    scan_lines(in, [&](std::string_view keyword, bool spaced, std::uint64_t) {
      count += spaced && keyword == "newmtl";
    });
    if (materials->size() + count > kMaxMeshMaterials)
      fail(obj_path_, count_over_limit(materials->size() + count, "materials", kMaxMeshMaterials) + " with '" +
                          mtl_path.string() + "'");
    in.clear();
    in.seekg(0);
    tinyobj::LoadMtl(material_map, materials, &in, warn, err);
    source_files_.resize(materials->size(), mtl_path);
    material_map_ = material_map;
    read_materials_.insert(read_materials_.end(), materials->begin() + read_materials_.size(), materials->end());
    return true;
  }

  fs::path mtl_folder(int material) const {
    return material < static_cast<int>(source_files_.size()) ? source_files_[material].parent_path() : obj_folder_;
  }

  // LoadObjWithCallback keeps the materials and their names to itself: the materials as read so far, and the
  // loader's map from name to index (null before the first .mtl; valid while the loader runs).
  std::vector<tinyobj::material_t>& read_materials() { return read_materials_; }
  const std::map<std::string, int>* material_map() const { return material_map_; }

 private:
  std::string obj_path_;
  fs::path obj_folder_;
  std::vector<fs::path> source_files_;  // per material index
  std::set<fs::path> read_;
  std::vector<tinyobj::material_t> read_materials_;
  const std::map<std::string, int>* material_map_ = nullptr;
};

// JPEG's signature, by which OpenCV picks its JPEG decoder: the one that can decode at 1/2, 1/4 or 1/8.
bool is_jpeg_file(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  unsigned char magic[3] = {};
  return in.read(reinterpret_cast<char*>(magic), sizeof magic) && magic[0] == 0xFF && magic[1] == 0xD8 &&
         magic[2] == 0xFF;
}

class TextureCache {
 public:
  explicit TextureCache(std::string obj_path) : obj_path_(std::move(obj_path)) {}

  std::shared_ptr<const cv::Mat> load(const std::string& name, const fs::path& mtl_folder,
                                      const std::string& material) {
    std::string portable = name;
    std::replace(portable.begin(), portable.end(), '\\', '/');
    const fs::path given(portable);
    // Exported files often carry the artist's absolute path; fall back to the bare file name.
    const fs::path candidates[] = {given.is_absolute() ? given : mtl_folder / given, mtl_folder / given.filename()};
    for (const auto& candidate : candidates) {
      std::error_code ec;
      if (!fs::is_regular_file(candidate, ec)) continue;
      const std::string key = candidate.lexically_normal().string();
      if (auto it = cache_.find(key); it != cache_.end()) return it->second;
      auto texture = std::make_shared<const cv::Mat>(read_bounded(key, material));
      cache_.emplace(key, texture);
      return texture;
    }
    fail(obj_path_, "texture '" + name + "' of material '" + material + "' not found (looked for '" +
                        candidates[0].string() + "')");
  }

 private:
  // The texture in linear RGB, its longer side reduced to kMaxTextureSide. Its size is read from the header
  // first, and pixels beyond kMaxTextureDecodePixels for the mesh are refused undecoded. A JPEG over the side
  // limit is decoded at 1/2, 1/4 or 1/8; another format is reduced while it is read, a band of rows at a time.
  cv::Mat read_bounded(const std::string& file, const std::string& material) {
    const std::string texture = "texture '" + file + "' of material '" + material + "'";
    std::uint64_t width = 0, height = 0;
    {
      const auto input = OIIO::ImageInput::open(file);
      if (!input) fail(obj_path_, "cannot read the size of " + texture + ": " + trim(OIIO::geterror()));
      width = static_cast<std::uint64_t>(std::max(input->spec().width, 0));
      height = static_cast<std::uint64_t>(std::max(input->spec().height, 0));
    }
    if (width == 0 || height == 0) fail(obj_path_, texture + " has no pixels");
    const auto pixels_at = [&](std::uint64_t scale) {
      return ((width + scale - 1) / scale) * ((height + scale - 1) / scale);  // libjpeg rounds up
    };
    const std::uint64_t budget = kMaxTextureDecodePixels - decoded_pixels_;
    const std::uint64_t long_side = std::max(width, height);
    if (long_side > static_cast<std::uint64_t>(kMaxTextureSide) && !is_jpeg_file(file))
      return read_reduced_while_read(file, texture, width, height, budget);
    std::uint64_t scale = 1;
    if (long_side > static_cast<std::uint64_t>(kMaxTextureSide) && is_jpeg_file(file)) {
      // The largest reduction that keeps the longer side at the limit or above; more only to fit the budget.
      while (scale < 8 && (long_side + 2 * scale - 1) / (2 * scale) >= static_cast<std::uint64_t>(kMaxTextureSide))
        scale *= 2;
      while (scale < 8 && pixels_at(scale) > budget) scale *= 2;
    }
    if (pixels_at(scale) > budget)
      fail(obj_path_, texture + " is too large: " + std::to_string(width) + "x" + std::to_string(height) +
                          " pixels to decode, and a mesh's textures may decode " +
                          std::to_string(kMaxTextureDecodePixels) + " in all (" + std::to_string(decoded_pixels_) +
                          " before it); textures are reduced to " + std::to_string(kMaxTextureSide) +
                          " on their longer side only once decoded");
    decoded_pixels_ += pixels_at(scale);
    const int flags = scale == 8   ? cv::IMREAD_REDUCED_COLOR_8
                      : scale == 4 ? cv::IMREAD_REDUCED_COLOR_4
                      : scale == 2 ? cv::IMREAD_REDUCED_COLOR_2
                                   : cv::IMREAD_COLOR;
    cv::Mat bgr = cv::imread(file, flags);
    if (bgr.empty()) fail(obj_path_, "cannot decode " + texture);
    const int decoded_side = std::max(bgr.cols, bgr.rows);
    if (decoded_side > kMaxTextureSide) {
      const double shrink = static_cast<double>(kMaxTextureSide) / decoded_side;
      const cv::Size size(std::clamp(static_cast<int>(std::lround(bgr.cols * shrink)), 1, kMaxTextureSide),
                          std::clamp(static_cast<int>(std::lround(bgr.rows * shrink)), 1, kMaxTextureSide));
      cv::Mat reduced;
      cv::resize(bgr, reduced, size, 0, 0, cv::INTER_AREA);  // averages sRGB values: 8 bits, not 32, per channel
      return bgr8_srgb_to_linear_rgb(reduced);
    }
    return bgr8_srgb_to_linear_rgb(bgr);
  }

  // Area-averaged to kMaxTextureSide on its longer side while it is read: memory for the result and one band.
  cv::Mat read_reduced_while_read(const std::string& file, const std::string& texture, std::uint64_t width,
                                  std::uint64_t height, std::uint64_t budget) {
    if (width * height > kMaxTextureFilePixels)
      fail(obj_path_, texture + " is too large: " + std::to_string(width) + "x" + std::to_string(height) +
                          " pixels (a texture file may hold " + std::to_string(kMaxTextureFilePixels) + ")");
    const double shrink = static_cast<double>(kMaxTextureSide) / static_cast<double>(std::max(width, height));
    const cv::Size size(std::clamp(static_cast<int>(std::lround(static_cast<double>(width) * shrink)), 1, kMaxTextureSide),
                        std::clamp(static_cast<int>(std::lround(static_cast<double>(height) * shrink)), 1, kMaxTextureSide));
    const auto pixels = static_cast<std::uint64_t>(size.area());
    if (pixels > budget)
      fail(obj_path_, texture + " is too large: reduced to " + std::to_string(size.width) + "x" +
                          std::to_string(size.height) + " it would hold " + std::to_string(pixels) +
                          " pixels, and a mesh's textures may decode " + std::to_string(kMaxTextureDecodePixels) +
                          " in all (" + std::to_string(decoded_pixels_) + " before it)");
    decoded_pixels_ += pixels;
    try {
      return capture::load_photo_reduced(file, size);
    } catch (const std::exception& e) {
      fail(obj_path_, "cannot decode " + texture + ": " + e.what());
    }
  }

  std::string obj_path_;
  std::map<std::string, std::shared_ptr<const cv::Mat>> cache_;
  std::uint64_t decoded_pixels_ = 0;
};

Material convert_material(const tinyobj::material_t& mtl, const fs::path& mtl_folder, TextureCache& textures) {
  const Vector3f kd = clamp01(Vector3f(mtl.diffuse[0], mtl.diffuse[1], mtl.diffuse[2]));
  const Vector3f ks = clamp01(Vector3f(mtl.specular[0], mtl.specular[1], mtl.specular[2]));
  const Vector3f ke = Vector3f(mtl.emission[0], mtl.emission[1], mtl.emission[2]).cwiseMax(0.f);
  Material m;
  m.name = mtl.name;
  m.roughness = roughness_from_shininess(mtl.shininess);
  m.albedo = kd;
  if (ke.maxCoeff() > 0.f) {
    m.type = Material::Type::Emissive;
    m.emission = ke;
  } else if (mtl.illum == 4 || mtl.illum == 6 || mtl.illum == 7) {
    // The MTL illumination models with refraction: glass, index Ni.
    m.type = Material::Type::Dielectric;
    m.ior = std::isfinite(mtl.ior) && mtl.ior > 0.f && std::abs(mtl.ior - 1.f) > 1e-3f ? mtl.ior : 1.5f;
  } else if (mtl.illum == 3 || (ks.maxCoeff() >= 0.5f && kd.maxCoeff() <= 0.1f)) {
    m.type = Material::Type::Metal;
    m.albedo = ks.maxCoeff() > 0.f ? ks : kd;  // illum 3 with black Ks: a black mirror is never meant
  } else if (ks.maxCoeff() > 0.f) {
    m.type = Material::Type::Glossy;
    m.specular = ks.maxCoeff();
  } else {
    m.type = Material::Type::Diffuse;
  }
  if (!mtl.diffuse_texname.empty()) {
    m.texture = textures.load(mtl.diffuse_texname, mtl_folder, mtl.name);
    // The texture multiplies albedo; a black Kd next to a map_Kd means "not set".
    if (m.type != Material::Type::Metal && m.albedo.isZero()) m.albedo = Vector3f::Ones();
  }
  return m;
}

Material default_material() {
  Material m;
  m.type = Material::Type::Diffuse;
  m.name = "default_grey";
  m.albedo = Vector3f::Constant(0.5f);
  return m;
}

// The loader's large temporary arrays ask the kernel for 2 MiB pages (transparent huge pages, where it gives them on
// request; advice it may ignore). Where first touches of memory are dear (a virtual machine: 12 to 23 us a 4 KiB
// page), they, not the parse, are most of a large mesh's loading time; one fault then maps 512 pages.
template <typename T>
struct BulkAllocator {
  using value_type = T;
  static constexpr std::size_t kHugePage = std::size_t{2} << 20;

  BulkAllocator() = default;
  template <typename U>
  BulkAllocator(const BulkAllocator<U>&) {}

  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHugePage) return std::allocator<T>().allocate(n);
    const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
    void* memory = std::aligned_alloc(kHugePage, rounded);
    if (!memory) throw std::bad_alloc();
    ::madvise(memory, rounded, MADV_HUGEPAGE);
    return static_cast<T*>(memory);
  }
  void deallocate(T* memory, std::size_t n) {
    if (n * sizeof(T) < kHugePage) {
      std::allocator<T>().deallocate(memory, n);
    } else {
      std::free(memory);
    }
  }
  friend bool operator==(const BulkAllocator&, const BulkAllocator&) { return true; }
};
template <typename T>
using BulkVector = std::vector<T, BulkAllocator<T>>;

struct ObjCorner {
  int position, uv, normal;  // OBJ indices, -1 when absent
};

// Key of an output vertex: the OBJ position and uv indices, and the OBJ normal index or, with the top bit set, the
// computed normal's index (computed normals are distinct in bits at each position, so equal bits share a vertex).
struct VertexKey {
  std::array<std::uint32_t, 3> words;
  bool operator==(const VertexKey&) const = default;
};
constexpr std::uint32_t kComputedNormal = 0x80000000u;

// Output vertices by key: open addressing with linear probing, at most half full (one cache miss a lookup,
// where std::unordered_map chases a bucket and a node). The hash is seeded per process, so no file can be
// made of keys that collide.
class VertexHashTable {
 public:
  // The vertex of `key`, or `next` (then stored for it) when it has none yet; and whether it was inserted.
  std::pair<int, bool> find_or_insert(const VertexKey& key, int next) {
    if (2 * (used_ + 1) > slots_.size()) grow();
    for (std::size_t i = hash(key) & (slots_.size() - 1);; i = (i + 1) & (slots_.size() - 1)) {
      Slot& slot = slots_[i];
      if (slot.vertex < 0) {
        slot = {key, next};
        ++used_;
        return {next, true};
      }
      if (slot.key == key) return {slot.vertex, false};
    }
  }

 private:
  struct Slot {
    VertexKey key{};
    int vertex = -1;
  };

  static std::uint64_t seed() {
    static const std::uint64_t value = static_cast<std::uint64_t>(
        std::chrono::steady_clock::now().time_since_epoch().count() ^ reinterpret_cast<std::uintptr_t>(&value));
    return value;
  }
  static std::uint64_t hash(const VertexKey& key) {
    std::uint64_t h = seed();
    for (const std::uint32_t w : key.words) {  // splitmix64's finaliser after each word
      h = (h ^ w) + 0x9e3779b97f4a7c15ull;
      h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
      h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
      h ^= h >> 31;
    }
    return h;
  }
  void grow() {
    BulkVector<Slot> old = std::exchange(slots_, BulkVector<Slot>(std::max<std::size_t>(64, 2 * slots_.size())));
    used_ = 0;
    for (const Slot& slot : old)
      if (slot.vertex >= 0) find_or_insert(slot.key, slot.vertex);
  }

  BulkVector<Slot> slots_;
  std::size_t used_ = 0;
};

// Output vertices by key. Most positions carry one vertex or a few, so the vertices at a position are chained from an
// array indexed by position: a lookup reads a few words near each other where a hash table takes a cache miss, and
// the memory grows with the positions and vertices, not with a table at most half full (touching new memory is what
// loading a large mesh mostly costs). A position whose chain would pass kMaxChain (a pole where each face has its own
// uv, or a file made to be slow) moves to a VertexHashTable, so no input costs more than linear time.
class VertexTable {
 public:
  explicit VertexTable(std::size_t positions) : first_(positions, kNone) {}

  // The vertex of `key`, or `next` (then stored for it) when it has none yet; and whether it was inserted. `next`
  // counts up from 0 with each insertion.
  std::pair<int, bool> find_or_insert(const VertexKey& key, int next) {
    int& first = first_[key.words[0]];
    if (first != kCrowded) {
      int length = 0;
      for (int v = first; v != kNone; v = chain_[v].next, ++length)
        if (chain_[v].uv == key.words[1] && chain_[v].normal == key.words[2]) return {v, false};
      if (length < kMaxChain) {
        chain_.push_back({key.words[1], key.words[2], first});
        first = next;
        return {next, true};
      }
      for (int v = first; v != kNone; v = chain_[v].next)
        crowded_.find_or_insert({{key.words[0], chain_[v].uv, chain_[v].normal}}, v);
      first = kCrowded;
    }
    const auto found = crowded_.find_or_insert(key, next);
    if (found.second) chain_.push_back({});  // keeps chain_ indexed by vertex
    return found;
  }

 private:
  static constexpr int kNone = -1, kCrowded = -2, kMaxChain = 16;
  struct Link {
    std::uint32_t uv = 0, normal = 0;
    int next = kNone;  // the next vertex at the same position
  };

  BulkVector<int> first_;    // per position: its latest vertex, kNone, or kCrowded
  BulkVector<Link> chain_;   // per vertex
  VertexHashTable crowded_;
};

// Smooth normals for corners the file gives none (faces more than 60 degrees apart keep separate normals).
constexpr float kCreaseCos = 0.5f;
// A corner's normal is the sum of the face normals (length 2 * area) around its position that lie within the
// crease angle of its own face, so corners whose faces point the same way (equal direction bits) share one
// sum, made once: work = directions x faces around the position. Past this many directions at one position
// (the apex of a fine cone) the directions are binned instead, so that no input costs more than linear time.
constexpr int kMaxExactCreaseDirections = 64;
constexpr int kCreaseBinsPerAxis = 8;  // octahedral bins, about 20 degrees wide
constexpr int kCreaseBins = kCreaseBinsPerAxis * kCreaseBinsPerAxis + 1;  // the last: degenerate faces

int crease_bin(const Vector3f& d) {
  const float l1 = std::abs(d.x()) + std::abs(d.y()) + std::abs(d.z());
  if (!(l1 > 0.f) || !std::isfinite(l1)) return kCreaseBins - 1;
  float u = d.x() / l1, v = d.y() / l1;
  if (d.z() < 0.f) {  // fold the lower hemisphere over the diagonals
    const float fu = (1.f - std::abs(v)) * (u < 0.f ? -1.f : 1.f), fv = (1.f - std::abs(u)) * (v < 0.f ? -1.f : 1.f);
    u = fu;
    v = fv;
  }
  const auto cell = [](float t) {
    return std::clamp(static_cast<int>((t * 0.5f + 0.5f) * kCreaseBinsPerAxis), 0, kCreaseBinsPerAxis - 1);
  };
  return cell(u) * kCreaseBinsPerAxis + cell(v);
}

struct SmoothNormals {
  BulkVector<int> of_corner;  // per corner (3 * triangle + k): index into `normals`, -1 where not needed
  std::vector<Vector3f> normals;  // distinct (in bits) at each position, so an index stands for the bits in a key
};

// The corners around each position, in triangle order, for the positions where some corner needs a normal:
// position p's are around[offsets[p]] to around[offsets[p + 1] - 1].
struct CornersAround {
  BulkVector<int> offsets, around;
};

CornersAround corners_around_positions(const BulkVector<std::array<ObjCorner, 3>>& corners, int position_count,
                                       const BulkVector<char>& needed) {
  const int corner_count = static_cast<int>(3 * corners.size());
  BulkVector<char> position_needed(position_count, 0);
  for (int c = 0; c < corner_count; ++c)
    if (needed[c]) position_needed[corners[c / 3][c % 3].position] = 1;
  CornersAround out{BulkVector<int>(position_count + 1, 0), {}};
  BulkVector<int>& offsets = out.offsets;
  for (int c = 0; c < corner_count; ++c) {
    const int p = corners[c / 3][c % 3].position;
    if (position_needed[p]) ++offsets[p + 1];
  }
  for (int p = 0; p < position_count; ++p) offsets[p + 1] += offsets[p];
  out.around.resize(offsets.back());
  BulkVector<int> fill(offsets.begin(), offsets.end() - 1);
  for (int c = 0; c < corner_count; ++c) {
    const int p = corners[c / 3][c % 3].position;
    if (position_needed[p]) out.around[fill[p]++] = c;
  }
  return out;
}

// `needed` per corner; `face_normal` per triangle (length 2 * area), `face_direction` its unit vector or zero.
SmoothNormals smooth_normals(const BulkVector<std::array<ObjCorner, 3>>& corners, int position_count,
                             const BulkVector<char>& needed, const BulkVector<Vector3f>& face_normal,
                             const BulkVector<Vector3f>& face_direction) {
  const int corner_count = static_cast<int>(3 * corners.size());
  const CornersAround corners_around = corners_around_positions(corners, position_count, needed);
  const BulkVector<int>& offsets = corners_around.offsets;
  const BulkVector<int>& around = corners_around.around;

  SmoothNormals out;
  out.of_corner.assign(corner_count, -1);
  const auto same_bits = [](const Vector3f& a, const Vector3f& b) {
    return std::memcmp(a.data(), b.data(), 3 * sizeof(float)) == 0;
  };
  // Index of the normal of a face pointing `direction` at the position whose normals start at `base`, from the
  // sum of the faces around it within the crease angle.
  const auto add_normal = [&](int base, const Vector3f& sum, const Vector3f& direction) {
    const float length = sum.norm();
    const Vector3f normal =
        length > 0.f ? Vector3f(sum / length) : direction.isZero() ? Vector3f(Vector3f::UnitY()) : direction;
    for (int i = base; i < static_cast<int>(out.normals.size()); ++i)
      if (same_bits(out.normals[i], normal)) return i;
    out.normals.push_back(normal);
    return static_cast<int>(out.normals.size()) - 1;
  };
  std::vector<int> normal_of_direction;
  std::vector<Vector3f> directions;
  std::vector<int> direction_of;
  std::array<Vector3f, kCreaseBins> bin_normal_sum, bin_direction;
  std::array<int, kCreaseBins> bin_index;
  for (int p = 0; p < position_count; ++p) {
    const int begin = offsets[p], end = offsets[p + 1];
    if (begin == end) continue;
    directions.clear();
    direction_of.clear();
    for (int k = begin; k < end; ++k) {
      const Vector3f& d = face_direction[around[k] / 3];
      int g = 0;
      while (g < static_cast<int>(directions.size()) && !same_bits(directions[g], d)) ++g;
      if (g == static_cast<int>(directions.size())) {
        if (g == kMaxExactCreaseDirections) break;
        directions.push_back(d);
      }
      direction_of.push_back(g);
    }
    const int base = static_cast<int>(out.normals.size());
    if (static_cast<int>(direction_of.size()) == end - begin) {
      normal_of_direction.clear();
      for (const Vector3f& d : directions) {
        Vector3f sum = Vector3f::Zero();
        for (int k = begin; k < end; ++k) {
          const int other = around[k] / 3;
          if (d.isZero() || d.dot(face_direction[other]) >= kCreaseCos) sum += face_normal[other];
        }
        normal_of_direction.push_back(add_normal(base, sum, d));
      }
      for (int k = begin; k < end; ++k) out.of_corner[around[k]] = normal_of_direction[direction_of[k - begin]];
      continue;
    }
    // Binned: each bin's faces share the normal made from the bins within the crease angle of their mean direction.
    bin_normal_sum.fill(Vector3f::Zero());
    bin_direction.fill(Vector3f::Zero());
    bin_index.fill(-1);
    for (int k = begin; k < end; ++k) {
      const int t = around[k] / 3, bin = crease_bin(face_direction[t]);
      bin_normal_sum[bin] += face_normal[t];
      if (bin != kCreaseBins - 1) bin_direction[bin] += face_direction[t];
      bin_index[bin] = 0;  // occupied
    }
    for (Vector3f& d : bin_direction) d = d.norm() > 0.f ? Vector3f(d.normalized()) : Vector3f(Vector3f::Zero());
    for (int bin = 0; bin < kCreaseBins; ++bin) {
      if (bin_index[bin] < 0) continue;
      const Vector3f& d = bin_direction[bin];
      Vector3f sum = Vector3f::Zero();
      for (int other = 0; other < kCreaseBins; ++other)
        if (bin_index[other] >= 0 && (d.isZero() || d.dot(bin_direction[other]) >= kCreaseCos))
          sum += bin_normal_sum[other];
      bin_index[bin] = add_normal(base, sum, d);
    }
    for (int k = begin; k < end; ++k) out.of_corner[around[k]] = bin_index[crease_bin(face_direction[around[k] / 3])];
  }
  return out;
}

// ---------------------------------------------------------------------------
// Reading an OBJ's records and faces

// An OBJ as the mesh is built from it: its records as tinyobjloader reads them (3, 2 and 3 floats a record), and its
// faces as triangles of corners in file order with their material (an index into `materials`, -1 for none). Corner
// indices are 0-based, relative ones resolved, not yet checked against the counts.
struct ObjContent {
  std::vector<float> positions, texcoords, normals;
  BulkVector<std::array<ObjCorner, 3>> corners;
  BulkVector<int> material_of;
  std::vector<tinyobj::material_t> materials;
};

// Thrown from read_obj_streaming's callbacks when the file turns out to need LoadObj after all.
struct NeedsLoadObj {};

// The OBJ through tinyobjloader's LoadObjWithCallback: records and corners go straight into arrays reserved from
// the census, where LoadObj keeps a vector per face (most of its 1.2 s and 150 MB a million faces) and copies its
// shapes once more. For a file without census.needs_load_obj it reads what LoadObj reads: the same numbers, indices
// resolved as LoadObj resolves them, faces of fewer than 3 corners dropped, quads split along the shorter diagonal
// (LoadObj's rule, with the positions read by its flush: the next group, object or change of material, or the end;
// a quad naming a position not read by then is dropped as LoadObj drops it), faces of more than
// kMaxEarClippedCorners split as a fan (as FanSplittingBuf does for LoadObj), `usemtl` names looked up as LoadObj
// looks them up. Throws NeedsLoadObj where LoadObj would refuse a face (a position index of 0).
class StreamingObj {
 public:
  StreamingObj(ObjContent& out, MtlFileReader& mtl_reader, std::uint64_t quads)
      : out_(out), mtl_reader_(mtl_reader) {
    quads_.reserve(quads);
  }

  tinyobj::callback_t callbacks() const {
    tinyobj::callback_t cb;
    cb.vertex_cb = [](void* self, float x, float y, float z, float) {
      static_cast<StreamingObj*>(self)->out_.positions.insert(static_cast<StreamingObj*>(self)->out_.positions.end(),
                                                              {x, y, z});
    };
    cb.texcoord_cb = [](void* self, float u, float v, float) {
      static_cast<StreamingObj*>(self)->out_.texcoords.insert(static_cast<StreamingObj*>(self)->out_.texcoords.end(),
                                                              {u, v});
    };
    cb.normal_cb = [](void* self, float x, float y, float z) {
      static_cast<StreamingObj*>(self)->out_.normals.insert(static_cast<StreamingObj*>(self)->out_.normals.end(),
                                                            {x, y, z});
    };
    cb.index_cb = [](void* self, tinyobj::index_t* indices, int count) {
      static_cast<StreamingObj*>(self)->face(indices, count);
    };
    cb.usemtl_cb = [](void* self, const char* name, int) { static_cast<StreamingObj*>(self)->usemtl(name); };
    cb.group_cb = [](void* self, const char**, int) { static_cast<StreamingObj*>(self)->flush(); };
    cb.object_cb = [](void* self, const char*) { static_cast<StreamingObj*>(self)->flush(); };
    return cb;
  }

  // After the parse: the quads split, those LoadObj drops dropped.
  void finish() {
    flush();
    if (split_quads()) remove_dropped_quads();
  }

 private:
  static constexpr int kDropped = -2;  // material_of of a dropped quad's two slots

  // LoadObj's fixIndex: 1-based, negative counts back from the records read so far; 0 (absent here) -> -1.
  static int resolved(int index, std::size_t count) {
    return index > 0 ? index - 1 : index < 0 ? static_cast<int>(count) + index : -1;
  }

  // Each quad split along its shorter diagonal as LoadObj splits it at its flush, or marked kDropped where it names
  // a position not read by then; whether any was dropped.
  bool split_quads() {
    auto& corners = out_.corners;
    bool dropped = false;
    std::size_t q = 0;
    for (const auto& [end, positions_read] : quad_flushes_) {
      const std::size_t position_count = positions_read;  // (clang 14 cannot capture a structured binding)
      for (; q < end; ++q) {
        const std::size_t slot = quads_[q];
        const ObjCorner c[4] = {corners[slot][0], corners[slot][1], corners[slot][2], corners[slot + 1][0]};
        if (std::any_of(c, c + 4, [&](const ObjCorner& k) {
              return k.position < 0 || static_cast<std::size_t>(k.position) >= position_count;
            })) {
          out_.material_of[slot] = out_.material_of[slot + 1] = kDropped;
          dropped = true;
          continue;
        }
        const float* p[4];
        for (int k = 0; k < 4; ++k) p[k] = &out_.positions[3 * static_cast<std::size_t>(c[k].position)];
        const float e02x = p[2][0] - p[0][0], e02y = p[2][1] - p[0][1], e02z = p[2][2] - p[0][2];
        const float e13x = p[3][0] - p[1][0], e13y = p[3][1] - p[1][1], e13z = p[3][2] - p[1][2];
        const float sqr02 = e02x * e02x + e02y * e02y + e02z * e02z;
        const float sqr13 = e13x * e13x + e13y * e13y + e13z * e13z;
        if (sqr02 < sqr13) {
          corners[slot] = {c[0], c[1], c[2]};
          corners[slot + 1] = {c[0], c[2], c[3]};
        } else {
          corners[slot] = {c[0], c[1], c[3]};
          corners[slot + 1] = {c[1], c[2], c[3]};
        }
      }
    }
    return dropped;
  }

  // The triangles left when the dropped quads' slots are taken out, in order.
  void remove_dropped_quads() {
    auto& corners = out_.corners;
    std::size_t kept = 0;
    for (std::size_t t = 0; t < corners.size(); ++t) {
      if (out_.material_of[t] == kDropped) continue;
      corners[kept] = corners[t];
      out_.material_of[kept++] = out_.material_of[t];
    }
    corners.resize(kept);
    out_.material_of.resize(kept);
  }

  void face(const tinyobj::index_t* indices, int count) {
    if (count < 3) return;  // LoadObj drops them
    if (count > 4 && count <= static_cast<int>(kMaxEarClippedCorners)) throw NeedsLoadObj{};  // ear clipping
    const std::size_t positions = out_.positions.size() / 3, uvs = out_.texcoords.size() / 2,
                      normals = out_.normals.size() / 3;
    const auto corner = [&](int k) {
      const tinyobj::index_t& i = indices[k];
      if (i.vertex_index == 0) throw NeedsLoadObj{};  // LoadObj refuses the line
      return ObjCorner{resolved(i.vertex_index, positions), std::max(resolved(i.texcoord_index, uvs), -1),
                       std::max(resolved(i.normal_index, normals), -1)};
    };
    const int material = material_ < static_cast<int>(mtl_reader_.read_materials().size()) ? material_ : -1;
    const ObjCorner first = corner(0);
    if (count == 4) {  // split in finish(), when the positions it names are read
      quads_.push_back(out_.corners.size());
      out_.corners.push_back({first, corner(1), corner(2)});
      out_.corners.push_back({corner(3), first, first});
      out_.material_of.insert(out_.material_of.end(), 2, material);
      return;
    }
    ObjCorner previous = corner(1);
    for (int k = 2; k < count; ++k) {
      const ObjCorner next = corner(k);
      out_.corners.push_back({first, previous, next});
      out_.material_of.push_back(material);
      previous = next;
    }
  }

  void usemtl(const char* rest_of_line) {
    // LoadObj's parseString: the first word.
    std::string_view name(rest_of_line);
    name.remove_prefix(std::min(name.find_first_not_of(" \t"), name.size()));
    name = name.substr(0, name.find_first_of(" \t\r"));
    int material = -1;
    if (const auto* map = mtl_reader_.material_map()) {
      const auto it = map->find(std::string(name));
      if (it != map->end()) material = it->second;
    }
    if (material == material_) return;
    flush();
    material_ = material;
  }

  // Where LoadObj would triangulate the faces read so far: the quads since the last flush see the positions read now.
  void flush() {
    if (quads_.size() == flushed_quads_) return;
    quad_flushes_.push_back({quads_.size(), out_.positions.size() / 3});
    flushed_quads_ = quads_.size();
  }

  ObjContent& out_;
  MtlFileReader& mtl_reader_;
  int material_ = -1;
  std::vector<std::size_t> quads_;                                // first of each quad's two slots
  std::vector<std::pair<std::size_t, std::size_t>> quad_flushes_;  // quads before it, positions read by then
  std::size_t flushed_quads_ = 0;
};

// The OBJ through LoadObjWithCallback, or nullopt where only LoadObj reads it as LoadObj does.
std::optional<ObjContent> read_obj_streaming(std::istream& in, const ObjCensus& census, MtlFileReader& mtl_reader) {
  if (census.needs_load_obj) return std::nullopt;
  ObjContent obj;
  obj.positions.reserve(3 * census.positions);
  obj.texcoords.reserve(2 * census.uvs);
  obj.normals.reserve(3 * census.normals);
  obj.corners.reserve(census.triangles);
  obj.material_of.reserve(census.triangles);
  StreamingObj reader(obj, mtl_reader, census.quads);
  std::string warnings, errors;
  try {
    tinyobj::LoadObjWithCallback(in, reader.callbacks(), &reader, &mtl_reader, &warnings, &errors);
  } catch (const NeedsLoadObj&) {
    return std::nullopt;
  }
  reader.finish();
  obj.materials = std::move(mtl_reader.read_materials());
  return obj;
}

// The OBJ through LoadObj (triangulating, ear clipping included), faces over kMaxEarClippedCorners split first.
ObjContent read_obj_with_load_obj(const std::string& path, std::istream& in, const ObjCensus& census,
                                  MtlFileReader& mtl_reader) {
  FanSplittingBuf fan_splitting(in);
  std::istream fanned(&fan_splitting);
  std::istream& text = census.largest_polygon > kMaxEarClippedCorners ? fanned : in;

  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  ObjContent obj;
  std::string warnings, errors;
  if (!tinyobj::LoadObj(&attrib, &shapes, &obj.materials, &warnings, &errors, &text, &mtl_reader,
                        /*triangulate=*/true, /*default_vcols_fallback=*/false))
    fail(path, "parse error: " + trim(errors));
  obj.positions.swap(attrib.vertices);
  obj.texcoords.swap(attrib.texcoords);
  obj.normals.swap(attrib.normals);
  attrib = {};

  // Triangles as OBJ corners (fan-split anything tinyobjloader left as a polygon).
  std::vector<ObjCorner> polygon;
  std::size_t triangle_total = 0;
  for (const auto& shape : shapes)
    for (const unsigned count : shape.mesh.num_face_vertices) triangle_total += count >= 3 ? count - 2 : 0;
  obj.corners.reserve(triangle_total);
  obj.material_of.reserve(triangle_total);
  for (const auto& shape : shapes) {
    size_t first = 0;
    for (size_t face = 0; face < shape.mesh.num_face_vertices.size(); ++face) {
      const int count = shape.mesh.num_face_vertices[face];
      const int material = face < shape.mesh.material_ids.size() ? shape.mesh.material_ids[face] : -1;
      polygon.clear();
      for (int k = 0; k < count; ++k) {
        const tinyobj::index_t& idx = shape.mesh.indices[first + k];
        polygon.push_back({idx.vertex_index, std::max(idx.texcoord_index, -1), std::max(idx.normal_index, -1)});
      }
      for (int k = 1; k + 1 < count; ++k) {
        obj.corners.push_back({polygon[0], polygon[k], polygon[k + 1]});
        obj.material_of.push_back(material < static_cast<int>(obj.materials.size()) ? material : -1);
      }
      first += count;
    }
  }
  return obj;
}

// ---------------------------------------------------------------------------
// Saving

std::string sanitized_name(const std::string& name) {
  std::string out;
  for (const char c : name)
    out += (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.') ? c : '_';
  return out;
}

void append_number(std::string& out, float value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);  // shortest exact round trip
  out.append(buffer, result.ptr);
}

void append_vector(std::string& out, const char* tag, const float* values, int count) {
  out += tag;
  for (int i = 0; i < count; ++i) {
    out += ' ';
    append_number(out, values[i]);
  }
  out += '\n';
}

void fsync_file(const fs::path& path, const std::string& file_for_errors) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0 || ::fsync(fd) != 0) {
    const std::string reason = std::strerror(errno);
    if (fd >= 0) ::close(fd);
    fail(file_for_errors, "cannot flush '" + path.string() + "': " + reason);
  }
  ::close(fd);
}

void write_text_file(const fs::path& path, const std::string& text, const std::string& file_for_errors) {
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out) fail(file_for_errors, "cannot create '" + path.string() + "': " + std::strerror(errno));
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.close();
    if (!out) fail(file_for_errors, "cannot write '" + path.string() + "'");
  }
  fsync_file(path, file_for_errors);  // data on disk before the rename makes it visible
}

// Temporary files that are renamed into place together, or removed.
class StagedFiles {
 public:
  explicit StagedFiles(std::string file_for_errors) : file_for_errors_(std::move(file_for_errors)) {}
  StagedFiles(const StagedFiles&) = delete;
  StagedFiles& operator=(const StagedFiles&) = delete;
  ~StagedFiles() {
    std::error_code ignored;
    for (const auto& [temp, final_path] : staged_) fs::remove(temp, ignored);
  }

  // Temporary name in the destination folder (rename stays atomic), keeping the
  // extension so encoders that go by it still work.
  fs::path stage(const fs::path& final_path) {
    static std::atomic<unsigned> counter{0};
    fs::path temp = final_path;
    temp.replace_filename(final_path.stem().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                          std::to_string(counter++) + final_path.extension().string());
    staged_.emplace_back(temp, final_path);
    return temp;
  }

  // Renames in staging order, so stage the file that names the others last.
  void commit() {
    for (auto& [temp, final_path] : staged_) {
      std::error_code ec;
      fs::rename(temp, final_path, ec);
      if (ec)
        fail(file_for_errors_,
             "cannot rename '" + temp.string() + "' to '" + final_path.string() + "': " + ec.message());
      temp.clear();
    }
  }

 private:
  std::string file_for_errors_;
  std::vector<std::pair<fs::path, fs::path>> staged_;
};

// ---------------------------------------------------------------------------
// Loading: the steps of load_mesh_file

// The file opened for reading, after the checks that need no parse.
std::ifstream open_obj(const std::string& path) {
  const fs::path file(path);
  std::error_code ec;
  if (!fs::exists(file, ec)) fail(path, "no such file");
  if (!fs::is_regular_file(file, ec)) fail(path, "not a regular file");
  std::string extension = file.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension != ".obj") fail(path, "unsupported format '" + extension + "' (expected .obj)");
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(path, std::string("cannot open: ") + std::strerror(errno));
  return in;
}

// The budget, from the census: refused before anything is parsed.
void check_census(const std::string& path, const ObjCensus& census) {
  if (census.triangles > kMaxMeshTriangles)
    fail(path, count_over_limit(census.triangles, "triangles", kMaxMeshTriangles));
  for (const auto& [count, what] : {std::pair{census.positions, "vertex positions ('v' lines)"},
                                    std::pair{census.uvs, "texture coordinates ('vt' lines)"},
                                    std::pair{census.normals, "normals ('vn' lines)"}})
    if (count > kMaxMeshVertices) fail(path, count_over_limit(count, what, kMaxMeshVertices));
}

// The OBJ streamed where that reads what LoadObj reads, else through LoadObj;
// `mtl_reader` is left as the one that read its materials.
ObjContent read_obj(const std::string& path, std::istream& in, const ObjCensus& census,
                    std::optional<MtlFileReader>& mtl_reader) {
  const fs::path folder = fs::path(path).parent_path();
  in.clear();
  in.seekg(0);
  mtl_reader.emplace(path, folder);
  std::optional<ObjContent> read = read_obj_streaming(in, census, *mtl_reader);
  if (read) return std::move(*read);
  in.clear();
  in.seekg(0);
  mtl_reader.emplace(path, folder);
  return read_obj_with_load_obj(path, in, census, *mtl_reader);
}

// Every record finite, every corner naming one, and some face.
void check_obj(const std::string& path, const ObjContent& obj) {
  const auto all_finite = [](const std::vector<float>& values) {
    return std::all_of(values.begin(), values.end(), [](float v) { return std::isfinite(v); });
  };
  if (!all_finite(obj.positions)) fail(path, "non-finite vertex position");
  if (!all_finite(obj.normals)) fail(path, "non-finite vertex normal");
  if (!all_finite(obj.texcoords)) fail(path, "non-finite texture coordinate");
  const int position_count = static_cast<int>(obj.positions.size() / 3);
  const int normal_count = static_cast<int>(obj.normals.size() / 3);
  const int uv_count = static_cast<int>(obj.texcoords.size() / 2);
  for (const auto& triangle : obj.corners) {
    for (const ObjCorner& corner : triangle) {
      if (corner.position < 0 || corner.position >= position_count)
        fail(path, "face refers to vertex " + std::to_string(corner.position + 1) + " but the file has " +
                       std::to_string(position_count));
      if (corner.normal >= normal_count)
        fail(path, "face refers to normal " + std::to_string(corner.normal + 1) + " but the file has " +
                       std::to_string(normal_count));
      if (corner.uv >= uv_count)
        fail(path, "face refers to texture coordinate " + std::to_string(corner.uv + 1) + " but the file has " +
                       std::to_string(uv_count));
    }
  }
  if (obj.corners.empty()) fail(path, "no triangles (the file has no faces)");
}

Vector3f obj_position(const ObjContent& obj, int i) {
  return Vector3f(obj.positions[3 * i], obj.positions[3 * i + 1], obj.positions[3 * i + 2]);
}

// Unit normal from the file, or zero when the corner has none (or a zero one).
Vector3f file_normal(const ObjContent& obj, int i) {
  if (i < 0) return Vector3f(Vector3f::Zero());
  const Vector3f n(obj.normals[3 * i], obj.normals[3 * i + 1], obj.normals[3 * i + 2]);
  return n.norm() > 1e-12f ? Vector3f(n.normalized()) : Vector3f(Vector3f::Zero());
}

// Per corner (3 * triangle + k): whether its normal is computed, and the computed ones.
struct CornerNormals {
  BulkVector<char> needs_computed;
  SmoothNormals computed;
};

// Which corners need a computed normal; then the face normals (length = 2 * area) for them, only if any do
// (freed on return, before the mesh's memory is taken).
CornerNormals corner_normals(const ObjContent& obj) {
  const BulkVector<std::array<ObjCorner, 3>>& corners = obj.corners;
  const int triangle_count = static_cast<int>(corners.size());
  CornerNormals out{BulkVector<char>(3 * static_cast<std::size_t>(triangle_count)), {}};
  bool needs_computed_normals = false;
  for (int t = 0; t < triangle_count; ++t) {
    for (int k = 0; k < 3; ++k) {
      out.needs_computed[3 * t + k] = file_normal(obj, corners[t][k].normal).isZero();
      needs_computed_normals = needs_computed_normals || out.needs_computed[3 * t + k];
    }
  }
  if (!needs_computed_normals) return out;
  BulkVector<Vector3f> face_normal(triangle_count), face_direction(triangle_count);
  for (int t = 0; t < triangle_count; ++t) {
    const auto& c = corners[t];
    const Vector3f p0 = obj_position(obj, c[0].position);
    face_normal[t] = (obj_position(obj, c[1].position) - p0).cross(obj_position(obj, c[2].position) - p0);
    const float length = face_normal[t].norm();
    face_direction[t] = length > 0.f ? Vector3f(face_normal[t] / length) : Vector3f::Zero();
  }
  out.computed = smooth_normals(corners, static_cast<int>(obj.positions.size() / 3), out.needs_computed, face_normal,
                                face_direction);
  return out;
}

// The mesh's triangles as vertex numbers, a vertex per distinct position, uv and normal; the attribute arrays
// reserved for them (taken once, at their size).
void number_vertices(const std::string& path, const ObjContent& obj, const CornerNormals& normals, bool has_uvs,
                    Mesh& mesh) {
  const auto normal_code = [&](std::size_t corner_index, const ObjCorner& corner) {
    return normals.needs_computed[corner_index]
               ? kComputedNormal | static_cast<std::uint32_t>(normals.computed.of_corner[corner_index])
               : static_cast<std::uint32_t>(corner.normal);
  };
  const int triangle_count = static_cast<int>(obj.corners.size());
  VertexTable vertex_of(obj.positions.size() / 3);
  int vertex_count = 0;
  mesh.triangles.resize(triangle_count);
  for (int t = 0; t < triangle_count; ++t) {
    for (int k = 0; k < 3; ++k) {
      const ObjCorner& corner = obj.corners[t][k];
      const VertexKey key{{static_cast<std::uint32_t>(corner.position), static_cast<std::uint32_t>(corner.uv),
                           normal_code(3 * t + k, corner)}};
      const auto [vertex, inserted] = vertex_of.find_or_insert(key, vertex_count);
      if (inserted && static_cast<std::uint64_t>(vertex_count++) >= kMaxMeshVertices)
        fail(path, "too large: more than " + std::to_string(kMaxMeshVertices) +
                       " vertices (the limit; a vertex is a distinct position, texture coordinate and normal)");
      mesh.triangles[t][k] = vertex;
    }
  }
  mesh.positions.reserve(vertex_count);
  mesh.normals.reserve(vertex_count);
  if (has_uvs) mesh.uvs.reserve(vertex_count);
}

// Each vertex's position, normal and uv, from the first corner that names it.
void fill_vertices(const ObjContent& obj, const CornerNormals& normals, bool has_uvs, Mesh& mesh) {
  const int triangle_count = static_cast<int>(obj.corners.size());
  for (int t = 0; t < triangle_count; ++t) {
    for (int k = 0; k < 3; ++k) {
      if (mesh.triangles[t][k] != static_cast<int>(mesh.positions.size())) continue;  // not its first corner
      const ObjCorner& corner = obj.corners[t][k];
      mesh.positions.push_back(obj_position(obj, corner.position));
      mesh.normals.push_back(normals.needs_computed[3 * t + k]
                                 ? normals.computed.normals[normals.computed.of_corner[3 * t + k]]
                                 : file_normal(obj, corner.normal));
      if (has_uvs)
        mesh.uvs.push_back(corner.uv >= 0 ? Vector2f(obj.texcoords[2 * corner.uv],
                                                     1.f - obj.texcoords[2 * corner.uv + 1])  // v up -> v down
                                          : Vector2f::Zero());
    }
  }
}

// Only the materials the faces use, in MTL order; the default one last.
void add_used_materials(const std::string& path, const ObjContent& obj, const MtlFileReader& mtl_reader, Mesh& mesh) {
  std::set<int> used(obj.material_of.begin(), obj.material_of.end());
  std::map<int, int> mesh_material_of;
  TextureCache textures(path);
  for (const int obj_id : used) {
    if (obj_id < 0) continue;
    mesh_material_of[obj_id] = static_cast<int>(mesh.materials.size());
    mesh.materials.push_back(convert_material(obj.materials[obj_id], mtl_reader.mtl_folder(obj_id), textures));
  }
  if (used.count(-1)) {
    mesh_material_of[-1] = static_cast<int>(mesh.materials.size());
    mesh.materials.push_back(default_material());
  }
  mesh.material_ids.reserve(obj.material_of.size());
  for (const int obj_id : obj.material_of) mesh.material_ids.push_back(mesh_material_of[obj_id]);
}

}  // namespace

Mesh load_mesh_file(const std::string& path) {
  std::ifstream in = open_obj(path);
  const ObjCensus census = census_obj(in);  // a first cheap pass over the text
  check_census(path, census);
  std::optional<MtlFileReader> mtl_reader;
  const ObjContent obj = read_obj(path, in, census, mtl_reader);
  check_obj(path, obj);
  const CornerNormals normals = corner_normals(obj);
  Mesh mesh;
  const bool has_uvs = std::any_of(obj.corners.begin(), obj.corners.end(),
                                   [](const auto& c) { return c[0].uv >= 0 || c[1].uv >= 0 || c[2].uv >= 0; });
  number_vertices(path, obj, normals, has_uvs, mesh);
  fill_vertices(obj, normals, has_uvs, mesh);
  add_used_materials(path, obj, *mtl_reader, mesh);
  try {
    mesh.validate();
  } catch (const std::exception& e) {
    fail(path, e.what());
  }
  return mesh;
}

void save_obj(const Mesh& mesh, const std::string& path) {
  try {
    mesh.validate();
  } catch (const std::exception& e) {
    fail(path, std::string("cannot save an invalid mesh: ") + e.what());
  }
  if (mesh.empty()) fail(path, "cannot save a mesh without triangles");
  const fs::path obj_path(path);
  if (obj_path.filename().empty()) fail(path, "not a file name");
  fs::path mtl_path = obj_path;
  mtl_path.replace_extension(".mtl");
  if (mtl_path == obj_path) fail(path, "an .obj path is needed (its .mtl goes next to it)");

  // Unique names without whitespace, which would end the MTL token.
  std::vector<std::string> names;
  std::set<std::string> taken;
  for (size_t i = 0; i < mesh.materials.size(); ++i) {
    std::string base = sanitized_name(mesh.materials[i].name);
    if (base.empty()) base = "material";
    std::string name = base;
    for (int suffix = 1; !taken.insert(name).second; ++suffix) name = base + "_" + std::to_string(suffix);
    names.push_back(name);
  }

  StagedFiles staged(path);
  std::string mtl = "# PropCam materials\n";
  for (size_t i = 0; i < mesh.materials.size(); ++i) {
    const Material& m = mesh.materials[i];
    mtl += "\nnewmtl " + names[i] + "\n";
    Vector3f kd = m.albedo, ks = Vector3f::Zero(), ke = Vector3f::Zero();
    int illum = 1;
    switch (m.type) {
      case Material::Type::Diffuse: break;
      case Material::Type::Glossy:
        ks = Vector3f::Constant(std::max(m.specular, 1e-4f));  // Ks = 0 would read back as diffuse
        illum = 2;
        break;
      case Material::Type::Metal:
        kd = Vector3f::Zero();  // metals have no diffuse term; Ks carries the colour
        ks = m.albedo;
        illum = 3;
        break;
      case Material::Type::Emissive:
        ke = m.emission.cwiseMax(1e-6f);  // Ke = 0 would read back as diffuse
        break;
      case Material::Type::Dielectric:
        ks = Vector3f::Ones();
        illum = 7;  // refraction and Fresnel: read back as Dielectric
        break;
    }
    append_vector(mtl, "Kd", kd.data(), 3);
    append_vector(mtl, "Ks", ks.data(), 3);
    const float ns = shininess_from_roughness(m.roughness);
    append_vector(mtl, "Ns", &ns, 1);
    if (m.type == Material::Type::Emissive) append_vector(mtl, "Ke", ke.data(), 3);
    if (m.type == Material::Type::Dielectric) append_vector(mtl, "Ni", &m.ior, 1);
    mtl += "illum " + std::to_string(illum) + "\n";
    if (m.texture && !m.texture->empty()) {
      if (m.texture->type() != CV_32FC3) fail(path, "texture of material '" + m.name + "' is not CV_32FC3");
      const fs::path texture_path =
          obj_path.parent_path() / (sanitized_name(obj_path.stem().string()) + "_" + names[i] + ".png");
      const fs::path temp = staged.stage(texture_path);
      if (!cv::imwrite(temp.string(), linear_rgb_to_bgr8_srgb(*m.texture)))
        fail(path, "cannot write texture '" + temp.string() + "'");
      fsync_file(temp, path);
      mtl += "map_Kd " + texture_path.filename().string() + "\n";
    }
  }
  write_text_file(staged.stage(mtl_path), mtl, path);

  std::string obj = "# PropCam mesh: " + std::to_string(mesh.positions.size()) + " vertices, " +
                    std::to_string(mesh.triangles.size()) + " triangles\n";
  std::string mtl_name = mtl_path.filename().string();
  for (size_t at = 0; (at = mtl_name.find(' ', at)) != std::string::npos; at += 2) mtl_name.insert(at, "\\");
  obj += "mtllib " + mtl_name + "\n";
  obj.reserve(obj.size() + mesh.positions.size() * 96 + mesh.triangles.size() * 40);
  for (const auto& p : mesh.positions) append_vector(obj, "v", p.data(), 3);
  for (const auto& uv : mesh.uvs) {
    const Vector2f obj_uv(uv.x(), 1.f - uv.y());  // OBJ's v runs up the image
    append_vector(obj, "vt", obj_uv.data(), 2);
  }
  for (const auto& n : mesh.normals) append_vector(obj, "vn", n.data(), 3);
  const bool has_uvs = !mesh.uvs.empty(), has_normals = !mesh.normals.empty();
  int current_material = -1;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    if (mesh.material_ids[t] != current_material) {  // keeps the triangle order intact
      current_material = mesh.material_ids[t];
      obj += "usemtl " + names[current_material] + "\n";
    }
    obj += 'f';
    for (int k = 0; k < 3; ++k) {
      const std::string index = std::to_string(mesh.triangles[t][k] + 1);
      obj += ' ' + index;
      if (has_uvs || has_normals) obj += '/' + (has_uvs ? index : std::string());
      if (has_normals) obj += '/' + index;
    }
    obj += '\n';
  }
  write_text_file(staged.stage(obj_path), obj, path);
  staged.commit();
}

}  // namespace propcam::render
