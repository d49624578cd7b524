#include "storage/storage_encode.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cctype>
#include <stdexcept>

#include "storage/storage_names.h"

namespace propcam::firmware {
namespace {

using nlohmann::json;

// EXR channel names: "<layer>.R/G/B", a one-channel layer "<layer>.Y" (depth: "depth.Z").
std::string channel_layer_name(const std::string& name) {
  std::string out;
  for (const unsigned char c : name) out += std::isalnum(c) || c == '_' ? static_cast<char>(c) : '_';
  return out.empty() ? "layer" : out;
}

std::vector<std::uint8_t> encode_image(const std::string& format_file_name, const OIIO::ImageSpec& spec,
                                       const void* pixels) {
  std::vector<unsigned char> buffer;
  OIIO::Filesystem::IOVecOutput proxy(buffer);
  auto out = OIIO::ImageOutput::create(format_file_name, &proxy);
  if (!out) throw std::runtime_error("no image writer for " + format_file_name + ": " + OIIO::geterror());
  if (!out->supports("ioproxy")) throw std::runtime_error("the " + format_file_name + " writer cannot write to memory");
  if (!out->open(format_file_name, spec) || !out->write_image(spec.format, pixels) || !out->close())
    throw std::runtime_error("cannot encode " + format_file_name + ": " + out->geterror());
  return {buffer.begin(), buffer.end()};
}

void add_metadata(OIIO::ImageSpec& spec, const ExportItem& item, const std::string& entry_id) {
  spec.attribute("Software", kSoftwareName);
  spec.attribute("DateTime", exif_date_time(item.taken));
  spec.attribute("Exif:DateTimeOriginal", exif_date_time(item.taken));  // what photo apps sort by
  spec.attribute("ImageDescription", "PropCam composite: " + item.prop_name + " (export " + entry_id + ")");
  spec.attribute("PropCam:export_id", entry_id);
  if (!item.metadata.empty()) spec.attribute("PropCam:metadata", item.metadata.dump());
}

std::vector<std::uint8_t> encode_srgb8(const ExportItem& item, const std::string& file_name, const std::string& entry_id,
                                       bool jpeg) {
  cv::Mat pixels = item.composite_srgb8.isContinuous() ? item.composite_srgb8 : item.composite_srgb8.clone();
  OIIO::ImageSpec spec(pixels.cols, pixels.rows, 3, OIIO::TypeDesc::UINT8);
  add_metadata(spec, item, entry_id);
  if (jpeg) spec.attribute("Compression", "jpeg:" + std::to_string(kJpegQuality));
  return encode_image(file_name, spec, pixels.data);
}

// All linear layers interleaved into one float image, named channels.
std::vector<std::uint8_t> encode_layers(const ExportItem& item, const std::string& entry_id) {
  std::vector<std::pair<std::string, cv::Mat>> layers;
  if (!item.composite_linear.empty()) layers.emplace_back("composite", item.composite_linear);
  for (const auto& [name, mat] : item.layers) layers.emplace_back(name, mat);
  const cv::Size size = item.composite_srgb8.size();
  std::vector<std::string> channel_names;
  std::vector<cv::Mat> planes;
  for (const auto& [name, mat] : layers) {
    if (mat.size() != size || (mat.type() != CV_32FC3 && mat.type() != CV_32FC1))
      throw std::invalid_argument("layer \"" + name + "\" must be CV_32FC3 or CV_32FC1 of the composite's size");
    const std::string layer = channel_layer_name(name);
    std::vector<cv::Mat> split;
    cv::split(mat, split);
    if (split.size() == 1) channel_names.push_back(layer + (name == "depth" ? ".Z" : ".Y"));
    else for (const char* c : {".R", ".G", ".B"}) channel_names.push_back(layer + c);
    planes.insert(planes.end(), split.begin(), split.end());
  }
  cv::Mat interleaved;
  cv::merge(planes, interleaved);
  OIIO::ImageSpec spec(size.width, size.height, static_cast<int>(planes.size()), OIIO::TypeDesc::FLOAT);
  spec.channelnames = channel_names;
  spec.attribute("compression", "zip");
  add_metadata(spec, item, entry_id);
  return encode_image("layers.exr", spec, interleaved.data);
}

std::vector<std::uint8_t> sidecar(const ExportItem& item, const std::string& entry_id) {
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(item.taken.time_since_epoch()).count();
  const json doc = {{"software", kSoftwareName},
                    {"export_id", entry_id},
                    {"prop", item.prop_name},
                    {"taken", exif_date_time(item.taken)},
                    {"taken_unix", seconds},
                    {"size", {item.composite_srgb8.cols, item.composite_srgb8.rows}},
                    {"metadata", item.metadata}};
  const std::string text = doc.dump(2) + "\n";
  return {text.begin(), text.end()};
}

}  // namespace

std::vector<EncodedFile> encode_export(const ExportItem& item, const ExportOptions& options, const std::string& entry_id) {
  if (item.composite_srgb8.empty() || item.composite_srgb8.type() != CV_8UC3)
    throw std::invalid_argument("an export needs composite_srgb8 as CV_8UC3 RGB");
  std::vector<EncodedFile> files;
  files.push_back({"composite.png", ".png", encode_srgb8(item, "composite.png", entry_id, false)});
  if (options.jpeg) files.push_back({"composite.jpg", ".jpg", encode_srgb8(item, "composite.jpg", entry_id, true)});
  files.push_back({"metadata.json", ".json", sidecar(item, entry_id)});
  if (options.layers && (!item.composite_linear.empty() || !item.layers.empty()))
    files.push_back({"layers.exr", "_layers.exr", encode_layers(item, entry_id)});
  return files;
}

}  // namespace propcam::firmware
