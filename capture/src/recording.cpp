#include "propcam/capture/recording.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <stdexcept>

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// ---------------------------------------------------------------------------
// Files

std::string system_error(const std::string& what, const fs::path& path) {
  return what + " " + path.string() + ": " + std::strerror(errno);
}

// Closes the descriptor however the write ends.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

void write_all(int fd, const std::uint8_t* data, std::size_t size, const fs::path& path) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw std::runtime_error(system_error("cannot write", path));
    data += n;
    size -= static_cast<std::size_t>(n);
  }
}

// Temporary name in the same folder, fsync, rename: the final name only ever
// holds a complete file.
void write_file_atomic(const fs::path& path, const std::uint8_t* data, std::size_t size) {
  std::string temp_name = ".";  // appended, not "." + name: GCC 12 warns falsely (-Wrestrict) on that
  temp_name += path.filename().string();
  temp_name += ".tmp";
  const fs::path temp = path.parent_path() / temp_name;
  {
    Fd f{::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
    if (f.fd < 0) throw std::runtime_error(system_error("cannot create", temp));
    write_all(f.fd, data, size, temp);
    if (::fsync(f.fd) != 0) throw std::runtime_error(system_error("cannot fsync", temp));
    const int fd = f.fd;
    f.fd = -1;
    if (::close(fd) != 0) throw std::runtime_error(system_error("cannot close", temp));
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string message = system_error("cannot rename to", path);
    ::unlink(temp.c_str());
    throw std::runtime_error(message);
  }
}

// Makes the renames in the folder durable.
void fsync_dir(const fs::path& dir) {
  Fd d{::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (d.fd < 0 || ::fsync(d.fd) != 0) throw std::runtime_error(system_error("cannot fsync folder", dir));
}

std::vector<std::uint8_t> read_file(const fs::path& path, std::size_t expected) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  std::vector<std::uint8_t> bytes(expected);
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(expected));
  if (static_cast<std::size_t>(in.gcount()) != expected || in.peek() != std::char_traits<char>::eof())
    throw std::runtime_error(path.string() + ": size differs from bytes_used " + std::to_string(expected) +
                             " in recording.json");
  return bytes;
}

// ---------------------------------------------------------------------------
// Formats and checks shared by writing and loading

std::string encoding_name(YcbcrEncoding e) { return e == YcbcrEncoding::Bt709 ? "bt709" : "bt601"; }
std::string range_name(QuantisationRange r) { return r == QuantisationRange::Full ? "full" : "limited"; }

// Stride 0 means packed: store the actual number.
FrameFormat normalised(FrameFormat f) {
  if (f.pixel_format == PixelFormat::MJPEG)
    f.stride = 0;
  else if (f.stride == 0)
    f.stride = minimum_stride(f.pixel_format, f.width);
  return f;
}

bool same_format(const FrameFormat& a, const FrameFormat& b) {
  return a.pixel_format == b.pixel_format && a.width == b.width && a.height == b.height && a.stride == b.stride &&
         a.encoding == b.encoding && a.range == b.range;
}

std::string describe(const FrameFormat& f) {
  return to_string(f.pixel_format) + " " + std::to_string(f.width) + "x" + std::to_string(f.height) + " stride " +
         std::to_string(f.stride) + " " + encoding_name(f.encoding) + " " + range_name(f.range);
}

// Raw formats need at least a whole frame; a JPEG between 1 byte and the bound.
void check_bytes_used(const FrameFormat& f, std::size_t bytes_used) {
  const std::size_t need = frame_bytes(f);
  if (f.pixel_format == PixelFormat::MJPEG) {
    if (bytes_used == 0 || bytes_used > need)
      throw std::runtime_error("bytes_used " + std::to_string(bytes_used) + " outside 1.." + std::to_string(need) +
                               " for " + describe(f));
  } else if (bytes_used < need) {
    throw std::runtime_error("bytes_used " + std::to_string(bytes_used) + " is less than the " +
                             std::to_string(need) + " a " + describe(f) + " frame needs");
  }
}

// A name that stays inside the folder: no separators, no leading dot (so
// neither "..", hidden files nor our temporaries), nothing odd.
bool plain_file_name(const std::string& name) {
  if (name.empty() || name.size() > 255 || name[0] == '.') return false;
  for (unsigned char c : name)
    if (!(std::isalnum(c) || c == '_' || c == '-' || c == '.')) return false;
  return true;
}

// For messages: a hostile name may hold NULs or control characters.
std::string printable(const std::string& s) {
  std::string out;
  for (unsigned char c : s) {
    if (std::isprint(c) && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    }
  }
  return out;
}

std::string frame_file_name(std::size_t index) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%06zu.raw", index);
  return name;
}

// ---------------------------------------------------------------------------
// JSON out

json metadata_json(const FrameMetadata& m) {
  json j{{"timestamp_ns", m.timestamp_ns}, {"sequence", m.sequence}};
  const std::pair<const char*, const std::optional<double>*> optional[] = {
      {"exposure_us", &m.exposure_us},           {"analogue_gain", &m.analogue_gain},
      {"colour_gain_red", &m.colour_gain_red},   {"colour_gain_blue", &m.colour_gain_blue},
      {"colour_temperature_k", &m.colour_temperature_k}};
  for (const auto& [key, value] : optional)
    if (value->has_value() && std::isfinite(**value)) j[key] = **value;
  return j;
}

json recording_json(const Recording& r) {
  json frames = json::array();
  for (const RecordedFrame& f : r.frames)
    frames.push_back({{"file", f.file}, {"bytes_used", f.bytes_used}, {"metadata", metadata_json(f.metadata)}});
  return {{"version", r.version},
          {"camera", {{"id", r.camera_id}, {"description", r.camera_description}}},
          {"format",
           {{"pixel_format", to_string(r.format.pixel_format)},
            {"width", r.format.width},
            {"height", r.format.height},
            {"stride", r.format.stride},
            {"encoding", encoding_name(r.format.encoding)},
            {"range", range_name(r.format.range)}}},
          {"frames", frames}};
}

// ---------------------------------------------------------------------------
// JSON in: every read names the file and the field.

class ManifestReader {
 public:
  explicit ManifestReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    throw std::runtime_error(file_ + ": " + where + (where.empty() ? "" : ": ") + what);
  }

  const json& field(const json& obj, const std::string& key, const std::string& where) const {
    if (!obj.is_object()) fail(where, "is not an object");
    const auto it = obj.find(key);
    if (it == obj.end()) fail(where, "missing field '" + key + "'");
    return *it;
  }

  std::int64_t integer(const json& obj, const std::string& key, const std::string& where, std::int64_t lo,
                       std::int64_t hi) const {
    const json& v = field(obj, key, where);
    const std::string name = join(where, key);
    if (!v.is_number_integer()) fail(name, "is not an integer");
    const std::string bounds = " is outside " + std::to_string(lo) + ".." + std::to_string(hi);
    if (v.is_number_unsigned() && v.get<std::uint64_t>() > static_cast<std::uint64_t>(hi))
      fail(name, std::to_string(v.get<std::uint64_t>()) + bounds);
    const std::int64_t x = v.get<std::int64_t>();
    if (x < lo || x > hi) fail(name, std::to_string(x) + bounds);
    return x;
  }

  std::uint64_t unsigned_integer(const json& obj, const std::string& key, const std::string& where) const {
    const json& v = field(obj, key, where);
    if (!v.is_number_unsigned()) fail(join(where, key), "is not a non-negative integer");
    return v.get<std::uint64_t>();
  }

  std::string string(const json& obj, const std::string& key, const std::string& where) const {
    const json& v = field(obj, key, where);
    if (!v.is_string()) fail(join(where, key), "is not a string");
    return v.get<std::string>();
  }

  std::optional<double> optional_number(const json& obj, const std::string& key, const std::string& where) const {
    const auto it = obj.find(key);
    if (it == obj.end() || it->is_null()) return std::nullopt;
    if (!it->is_number() || !std::isfinite(it->get<double>())) fail(join(where, key), "is not a finite number");
    return it->get<double>();
  }

  static std::string join(const std::string& where, const std::string& key) {
    return where.empty() ? key : where + "." + key;
  }

 private:
  std::string file_;
};

FrameFormat read_format(const ManifestReader& in, const json& root) {
  const json& j = in.field(root, "format", "");
  FrameFormat f;
  const std::string name = in.string(j, "pixel_format", "format");
  const auto pixel_format = pixel_format_from_string(name);
  if (!pixel_format) in.fail("format.pixel_format", "unknown pixel format '" + name + "'");
  f.pixel_format = *pixel_format;
  f.width = static_cast<int>(in.integer(j, "width", "format", 1, kMaxFrameDimension));
  f.height = static_cast<int>(in.integer(j, "height", "format", 1, kMaxFrameDimension));
  f.stride = static_cast<int>(in.integer(j, "stride", "format", 0, std::numeric_limits<int>::max()));
  const std::string encoding = in.string(j, "encoding", "format");
  if (encoding != "bt601" && encoding != "bt709")
    in.fail("format.encoding", "unknown encoding '" + encoding + "' (bt601 or bt709)");
  f.encoding = encoding == "bt709" ? YcbcrEncoding::Bt709 : YcbcrEncoding::Bt601;
  const std::string range = in.string(j, "range", "format");
  if (range != "limited" && range != "full") in.fail("format.range", "unknown range '" + range + "' (limited or full)");
  f.range = range == "full" ? QuantisationRange::Full : QuantisationRange::Limited;
  try {
    validate_frame_format(f);
  } catch (const std::exception& e) {
    in.fail("format", e.what());
  }
  return normalised(f);
}

FrameMetadata read_metadata(const ManifestReader& in, const json& frame, const std::string& where) {
  const json& j = in.field(frame, "metadata", where);
  const std::string w = where + ".metadata";
  if (!j.is_object()) in.fail(w, "is not an object");
  FrameMetadata m;
  m.timestamp_ns = in.integer(j, "timestamp_ns", w, 0, std::numeric_limits<std::int64_t>::max());
  m.sequence = in.unsigned_integer(j, "sequence", w);
  m.exposure_us = in.optional_number(j, "exposure_us", w);
  m.analogue_gain = in.optional_number(j, "analogue_gain", w);
  m.colour_gain_red = in.optional_number(j, "colour_gain_red", w);
  m.colour_gain_blue = in.optional_number(j, "colour_gain_blue", w);
  m.colour_temperature_k = in.optional_number(j, "colour_temperature_k", w);
  return m;
}

// The raw file must be a regular file (not a link out of the folder) of bytes_used bytes.
void check_raw_file(const ManifestReader& in, const fs::path& path, std::size_t bytes_used, const std::string& where) {
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(path, ec);
  if (ec || !fs::exists(status)) in.fail(where, "raw file " + path.string() + " is missing");
  if (!fs::is_regular_file(status)) in.fail(where, "raw file " + path.string() + " is not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) in.fail(where, "cannot read the size of " + path.string());
  if (size != bytes_used)
    in.fail(where, "raw file " + path.string() + " has " + std::to_string(size) + " bytes, bytes_used says " +
                       std::to_string(bytes_used));
}

RecordedFrame read_frame(const ManifestReader& in, const json& j, std::size_t index, const Recording& r) {
  const std::string where = "frames[" + std::to_string(index) + "]";
  RecordedFrame frame;
  frame.file = in.string(j, "file", where);
  if (!plain_file_name(frame.file))
    in.fail(where + ".file", "'" + printable(frame.file) + "' is not a plain file name inside the recording folder");
  frame.bytes_used = static_cast<std::size_t>(
      in.integer(j, "bytes_used", where, 1, static_cast<std::int64_t>(kMaxRecordingBytes)));
  try {
    check_bytes_used(r.format, frame.bytes_used);
  } catch (const std::exception& e) {
    in.fail(where, e.what());
  }
  frame.metadata = read_metadata(in, j, where);
  check_raw_file(in, r.dir / frame.file, frame.bytes_used, where);
  return frame;
}

json parse_manifest(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw std::runtime_error(path.string() + ": missing (not a recording folder?)");
  // A few hundred bytes per frame: anything near this is not a manifest.
  constexpr std::uintmax_t kMaxManifestBytes = 64u << 20;
  if (fs::file_size(path, ec) > kMaxManifestBytes)
    throw std::runtime_error(path.string() + ": larger than " + std::to_string(kMaxManifestBytes >> 20) + " MB");
  std::ifstream file(path);
  if (!file) throw std::runtime_error(path.string() + ": cannot open");
  try {
    return json::parse(file);
  } catch (const json::exception& e) {
    throw std::runtime_error(path.string() + ": not valid JSON (" + e.what() + ")");
  }
}

}  // namespace

std::size_t Recording::total_bytes() const {
  std::size_t total = 0;
  for (const RecordedFrame& f : frames) total += f.bytes_used;
  return total;
}

// ---------------------------------------------------------------------------

Recorder::Recorder(std::filesystem::path dir, std::string camera_id, std::string camera_description) {
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) throw std::runtime_error("recording folder " + dir.string() + " is not a folder");
    if (!fs::is_empty(dir, ec)) throw std::runtime_error("recording folder " + dir.string() + " is not empty");
  } else if (fs::create_directories(dir, ec); !fs::is_directory(dir)) {  // (its result is false for "a/b/")
    throw std::runtime_error("cannot create the recording folder " + dir.string() + ": " + ec.message());
  }
  recording_.dir = std::move(dir);
  recording_.camera_id = std::move(camera_id);
  recording_.camera_description = std::move(camera_description);
}

void Recorder::append(const Frame& frame) {
  if (finished_) throw std::logic_error("Recorder::append after finish (" + recording_.dir.string() + ")");
  validate_frame_format(frame.format);
  const FrameFormat format = normalised(frame.format);
  if (recording_.frames.empty())
    recording_.format = format;
  else if (!same_format(format, recording_.format))
    throw std::runtime_error("recording " + recording_.dir.string() + ": frame format " + describe(format) +
                             " differs from the recording's " + describe(recording_.format));
  if (!frame.buffer || frame.bytes_used > frame.buffer->bytes().size())
    throw std::runtime_error("recording " + recording_.dir.string() + ": the frame's bytes_used exceeds its buffer");
  check_bytes_used(format, frame.bytes_used);
  if (recording_.total_bytes() + frame.bytes_used > kMaxRecordingBytes)
    throw std::runtime_error("recording " + recording_.dir.string() + ": more than " +
                             std::to_string(kMaxRecordingBytes >> 20) + " MB of frames");
  RecordedFrame entry{frame_file_name(recording_.frames.size()), frame.bytes_used, frame.metadata};
  const auto bytes = frame.data();
  write_file_atomic(recording_.dir / entry.file, bytes.data(), bytes.size());
  recording_.frames.push_back(std::move(entry));
}

const Recording& Recorder::finish() {
  if (finished_) return recording_;
  if (recording_.frames.empty())
    throw std::runtime_error("recording " + recording_.dir.string() + ": no frames to finish with");
  const std::string text = recording_json(recording_).dump(2) + "\n";
  write_file_atomic(recording_.dir / kRecordingManifest, reinterpret_cast<const std::uint8_t*>(text.data()),
                    text.size());
  fsync_dir(recording_.dir);
  finished_ = true;
  return recording_;
}

// ---------------------------------------------------------------------------

Recording load_recording(const std::filesystem::path& dir) {
  const fs::path manifest = dir / kRecordingManifest;
  const json root = parse_manifest(manifest);
  const ManifestReader in(manifest.string());
  if (!root.is_object()) in.fail("", "is not a JSON object");

  Recording r;
  r.dir = dir;
  r.version = static_cast<int>(in.integer(root, "version", "", 1, std::numeric_limits<int>::max()));
  if (r.version > kRecordingVersion)
    in.fail("version", std::to_string(r.version) + " is newer than this build reads (" +
                           std::to_string(kRecordingVersion) + ")");
  const json& camera = in.field(root, "camera", "");
  r.camera_id = in.string(camera, "id", "camera");
  r.camera_description = in.string(camera, "description", "camera");
  r.format = read_format(in, root);

  const json& frames = in.field(root, "frames", "");
  if (!frames.is_array()) in.fail("frames", "is not an array");
  if (frames.empty()) in.fail("frames", "no frames");
  std::set<std::string> names;
  std::size_t total = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    RecordedFrame frame = read_frame(in, frames[i], i, r);
    const std::string where = "frames[" + std::to_string(i) + "]";
    if (!names.insert(frame.file).second) in.fail(where + ".file", "'" + frame.file + "' is listed twice");
    if (!r.frames.empty() && frame.metadata.timestamp_ns < r.frames.back().metadata.timestamp_ns)
      in.fail(where + ".metadata.timestamp_ns", "goes backwards");
    total += frame.bytes_used;
    if (total > kMaxRecordingBytes)
      in.fail("frames", "more than " + std::to_string(kMaxRecordingBytes >> 20) + " MB of frames");
    r.frames.push_back(std::move(frame));
  }
  return r;
}

std::vector<Frame> load_recording_frames(const Recording& recording) {
  std::vector<Frame> frames;
  frames.reserve(recording.frames.size());
  for (const RecordedFrame& entry : recording.frames) {
    frames.push_back(
        frame_from_bytes(recording.format, read_file(recording.dir / entry.file, entry.bytes_used), entry.metadata));
  }
  return frames;
}

}  // namespace propcam::capture
