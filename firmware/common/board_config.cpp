#include "common/board_config.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "propcam/capture/frame.h"

namespace propcam::firmware {
namespace fs = std::filesystem;
using nlohmann::json;

BoardConfigError::BoardConfigError(fs::path file, std::string json_path, const std::string& problem)
    : std::runtime_error(file.string() + ": " + (json_path.empty() ? std::string() : json_path + ": ") + problem),
      file_(std::move(file)),
      json_path_(std::move(json_path)) {}

const char* to_string(Button button) {
  switch (button) {
    case Button::Shoot: return "shoot";
    case Button::Next: return "next";
    case Button::Prev: return "prev";
    case Button::Ok: return "ok";
    case Button::Back: return "back";
  }
  return "?";
}

namespace {

// JSON pointer escaping (RFC 6901), so an odd key still reads unambiguously.
std::string escape_key(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '~') out += "~0";
    else if (c == '/') out += "~1";
    else out += c;
  }
  return out;
}

std::string child(const std::string& ptr, const std::string& key) { return ptr + "/" + escape_key(key); }

std::string join(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

const char* type_name(const json& v) {
  if (v.is_number_integer()) return "an integer";
  if (v.is_number()) return "a number";
  if (v.is_string()) return "a string";
  if (v.is_boolean()) return "a boolean";
  if (v.is_object()) return "an object";
  if (v.is_array()) return "an array";
  return "null";
}

// Finds the first key repeated within one object while parsing; nlohmann
// would silently keep the last one, hiding a doubled button in the map.
class DuplicateKeyFinder {
 public:
  bool operator()(int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start: frames_.push_back({false, {}, -1, {}}); break;
      case json::parse_event_t::array_start: frames_.push_back({true, {}, 0, {}}); break;
      case json::parse_event_t::key: on_key(parsed.get<std::string>()); break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        frames_.pop_back();
        advance();
        break;
      case json::parse_event_t::value: advance(); break;
    }
    return true;
  }
  const std::optional<std::string>& duplicate() const { return duplicate_; }

 private:
  struct Frame {
    bool array;
    std::string key;
    int index;
    std::set<std::string> keys;
  };
  void on_key(const std::string& key) {
    Frame& f = frames_.back();
    if (!f.keys.insert(key).second && !duplicate_) duplicate_ = child(pointer(), key);
    f.key = key;
  }
  void advance() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
  }
  std::string pointer() const {
    std::string ptr;
    for (std::size_t i = 0; i + 1 < frames_.size(); ++i)
      ptr = frames_[i].array ? ptr + "/" + std::to_string(frames_[i].index) : child(ptr, frames_[i].key);
    return ptr;
  }
  std::vector<Frame> frames_;
  std::optional<std::string> duplicate_;
};

// Reads fields of one board file; every failure names the file and the field.
class Checker {
 public:
  Checker(fs::path file, fs::path dir) : file_(std::move(file)), dir_(std::move(dir)) {}

  [[noreturn]] void fail(const std::string& ptr, const std::string& problem) const {
    throw BoardConfigError(file_, ptr.empty() ? "/" : ptr, problem);
  }

  // Unknown fields are errors: a misspelt "debounce" must not silently fall
  // back to nothing. "comment" is allowed everywhere for notes.
  void only_fields(const json& obj, const std::string& ptr, std::vector<std::string> allowed) const {
    allowed.push_back("comment");
    for (const auto& [key, value] : obj.items()) {
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
        fail(child(ptr, key), "unknown field (fields here: " + join(allowed) + ")");
      if (key == "comment" && !value.is_string()) fail(child(ptr, key), "must be a string");
    }
  }

  const json& field(const json& obj, const std::string& ptr, const std::string& key) const {
    auto it = obj.find(key);
    if (it == obj.end()) fail(child(ptr, key), "missing");
    return *it;
  }

  const json& object(const json& obj, const std::string& ptr, const std::string& key) const {
    const json& v = field(obj, ptr, key);
    if (!v.is_object()) fail(child(ptr, key), std::string("must be an object, not ") + type_name(v));
    return v;
  }

  std::string string(const json& v, const std::string& ptr) const {
    if (!v.is_string()) fail(ptr, std::string("must be a string, not ") + type_name(v));
    const auto& s = v.get_ref<const std::string&>();
    if (s.empty()) fail(ptr, "must not be empty");
    if (std::any_of(s.begin(), s.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; }))
      fail(ptr, "must not contain control characters");
    return s;
  }

  std::string string(const json& obj, const std::string& ptr, const std::string& key) const {
    return string(field(obj, ptr, key), child(ptr, key));
  }

  std::optional<std::string> optional_string(const json& obj, const std::string& ptr, const std::string& key) const {
    if (!obj.contains(key)) return std::nullopt;
    return string(obj.at(key), child(ptr, key));
  }

  long long integer(const json& v, const std::string& ptr, long long lo, long long hi) const {
    if (!v.is_number_integer()) fail(ptr, std::string("must be an integer, not ") + type_name(v));
    const bool too_big = v.is_number_unsigned() && v.get<std::uint64_t>() > static_cast<std::uint64_t>(hi);
    const long long n = too_big ? hi + 1 : v.get<long long>();
    if (n < lo || n > hi) fail(ptr, "out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]: " + v.dump());
    return n;
  }

  int integer(const json& obj, const std::string& ptr, const std::string& key, int lo, int hi) const {
    return static_cast<int>(integer(field(obj, ptr, key), child(ptr, key), lo, hi));
  }

  // A finite number in (lo, hi].
  double positive_number(const json& obj, const std::string& ptr, const std::string& key, double hi) const {
    const json& v = field(obj, ptr, key);
    const std::string p = child(ptr, key);
    if (!v.is_number()) fail(p, std::string("must be a number, not ") + type_name(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(p, "must be finite");
    if (x <= 0.0 || x > hi) {
      std::ostringstream os;
      os << "out of range (0, " << hi << "]: " << x;
      fail(p, os.str());
    }
    return x;
  }

  // A finite number in [-bound, bound].
  double number(const json& obj, const std::string& ptr, const std::string& key, double bound) const {
    const json& v = field(obj, ptr, key);
    const std::string p = child(ptr, key);
    if (!v.is_number()) fail(p, std::string("must be a number, not ") + type_name(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(p, "must be finite");
    if (std::abs(x) > bound) {
      std::ostringstream os;
      os << "out of range [" << -bound << ", " << bound << "]: " << x;
      fail(p, os.str());
    }
    return x;
  }

  // "WxH", each side in [lo, hi].
  Size size(const json& obj, const std::string& ptr, const std::string& key, int lo, int hi) const {
    const std::string p = child(ptr, key);
    const std::string s = string(field(obj, ptr, key), p);
    const auto x = s.find('x');
    const auto digits = [](const std::string& t) {
      return !t.empty() && t.size() <= 6 && std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; });
    };
    if (x == std::string::npos || !digits(s.substr(0, x)) || !digits(s.substr(x + 1)))
      fail(p, "must be WIDTHxHEIGHT like \"640x480\", not \"" + s + "\"");
    const Size out{std::stoi(s.substr(0, x)), std::stoi(s.substr(x + 1))};
    if (out.width < lo || out.width > hi || out.height < lo || out.height > hi)
      fail(p, "\"" + s + "\": each side must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return out;
  }

  // A path inside the board folder: relative, no "..", resolved.
  fs::path board_path(const std::string& text, const std::string& ptr) const {
    const fs::path p(text);
    if (p.is_absolute()) fail(ptr, "\"" + text + "\" must be relative to the board folder");
    for (const auto& part : p)
      if (part == "..") fail(ptr, "\"" + text + "\" leaves the board folder (\"..\" is not allowed)");
    return (dir_ / p).lexically_normal();
  }

  // A relative path (inside the board folder) or an absolute one.
  fs::path any_path(const std::string& text, const std::string& ptr) const {
    const fs::path p(text);
    if (!p.is_absolute()) return board_path(text, ptr);
    for (const auto& part : p)
      if (part == "..") fail(ptr, "\"" + text + "\" must not contain \"..\"");
    return p.lexically_normal();
  }

  // An absolute device path below `prefix` ("/dev/").
  fs::path device(const std::string& text, const std::string& ptr, const std::string& prefix) const {
    const fs::path p(text);
    bool dots = false;
    for (const auto& part : p) dots = dots || part == "..";
    if (!p.is_absolute() || dots || text.rfind(prefix, 0) != 0 || text.size() == prefix.size())
      fail(ptr, "\"" + text + "\" must be a device path under " + prefix);
    return p;
  }

  // One of the names, else an error listing them.
  std::string choice(const json& obj, const std::string& ptr, const std::string& key,
                     const std::vector<std::string>& names, const char* what) const {
    const std::string s = string(obj, ptr, key);
    if (std::find(names.begin(), names.end(), s) == names.end())
      fail(child(ptr, key), std::string("unknown ") + what + " \"" + s + "\" (" + what + "s: " + join(names) + ")");
    return s;
  }

  const fs::path& dir() const { return dir_; }

 private:
  fs::path file_;
  fs::path dir_;
};

// All five buttons, each once, each with a distinct value.
template <class T, class Read>
std::map<Button, T> button_map(const Checker& c, const json& obj, const std::string& ptr, Read read) {
  std::vector<std::string> names;
  for (Button b : kAllButtons) names.push_back(to_string(b));
  c.only_fields(obj, ptr, names);
  std::map<Button, T> out;
  std::map<T, Button> owner;
  for (Button b : kAllButtons) {
    const std::string p = child(ptr, to_string(b));
    if (!obj.contains(to_string(b))) c.fail(p, "missing (all five buttons are required: " + join(names) + ")");
    const T value = read(obj.at(to_string(b)), p);
    if (auto it = owner.find(value); it != owner.end()) {
      std::ostringstream os;
      os << value;
      c.fail(p, "\"" + os.str() + "\" is already the " + to_string(it->second) + " button");
    }
    owner.emplace(value, b);
    out.emplace(b, value);
  }
  return out;
}

ButtonsConfig read_buttons(const Checker& c, const json& root) {
  const std::string ptr = "/buttons";
  const json& j = c.object(root, "", "buttons");
  ButtonsConfig b;
  const std::string backend = c.choice(j, ptr, "backend", {"gpiod", "evdev", "script"}, "backend");
  std::vector<std::string> fields{"backend", "debounce_ms", "long_press_ms"};
  if (backend == "gpiod") fields.insert(fields.end(), {"chip", "lines"});
  if (backend == "evdev") fields.insert(fields.end(), {"device", "device_name", "keys"});
  if (backend == "script") fields.insert(fields.end(), {"script"});
  c.only_fields(j, ptr, fields);
  b.debounce_ms = c.integer(j, ptr, "debounce_ms", 0, 200);
  b.long_press_ms = c.integer(j, ptr, "long_press_ms", 100, 10000);
  if (b.long_press_ms <= b.debounce_ms)
    c.fail(ptr + "/long_press_ms", "must be longer than debounce_ms (" + std::to_string(b.debounce_ms) + ")");
  if (backend == "gpiod") {
    b.backend = ButtonBackend::Gpiod;
    b.gpio_chip = c.string(j, ptr, "chip");
    b.gpio_lines = button_map<std::string>(c, c.object(j, ptr, "lines"), ptr + "/lines",
                                           [&](const json& v, const std::string& p) { return c.string(v, p); });
  } else if (backend == "evdev") {
    b.backend = ButtonBackend::Evdev;
    const auto path = c.optional_string(j, ptr, "device");
    const auto name = c.optional_string(j, ptr, "device_name");
    if (path.has_value() == name.has_value())
      c.fail(ptr, "needs exactly one of \"device\" (a path) and \"device_name\"");
    if (path) b.evdev_device = c.device(*path, ptr + "/device", "/dev/input/");
    if (name) b.evdev_device_name = *name;
    // Linux key codes run from 1 to KEY_MAX (0x2ff).
    b.evdev_keys = button_map<int>(c, c.object(j, ptr, "keys"), ptr + "/keys", [&](const json& v, const std::string& p) {
      return static_cast<int>(c.integer(v, p, 1, 0x2ff));
    });
  } else {
    b.backend = ButtonBackend::Script;
    b.script = c.board_path(c.string(j, ptr, "script"), ptr + "/script");
  }
  return b;
}

DisplayConfig read_display(const Checker& c, const json& root) {
  const std::string ptr = "/display";
  const json& j = c.object(root, "", "display");
  DisplayConfig d;
  const std::string backend = c.choice(j, ptr, "backend", {"fbdev", "drm", "file"}, "backend");
  if (backend == "fbdev") {
    c.only_fields(j, ptr, {"backend", "device", "rotation"});
    d.backend = DisplayBackend::Fbdev;
    d.device = c.device(c.string(j, ptr, "device"), ptr + "/device", "/dev/");
    if (j.contains("rotation")) {
      d.rotation = c.integer(j, ptr, "rotation", 0, 270);
      if (d.rotation % 90 != 0) c.fail(ptr + "/rotation", "must be 0, 90, 180 or 270");
    }
  } else if (backend == "drm") {
    c.only_fields(j, ptr, {"backend", "card"});
    d.backend = DisplayBackend::Drm;
    d.device = c.device(c.string(j, ptr, "card"), ptr + "/card", "/dev/dri/");
  } else {
    c.only_fields(j, ptr, {"backend", "path", "size"});
    d.backend = DisplayBackend::File;
    // "runtime": the screen file lives in the appliance's data folder, not
    // beside the board file (which may be a read-only or source tree).
    const std::string path = c.string(j, ptr, "path");
    if (path != "runtime") d.device = c.any_path(path, ptr + "/path");
    const Size s = c.size(j, ptr, "size", 32, 8192);
    d.width = s.width;
    d.height = s.height;
  }
  return d;
}

void read_camera_id(const Checker& c, const std::string& id, const std::string& ptr, CameraConfig& cam) {
  const auto colon = id.find(':');
  const std::string scheme = id.substr(0, colon), rest = colon == std::string::npos ? "" : id.substr(colon + 1);
  if (colon == std::string::npos || (scheme != "v4l2" && scheme != "libcamera" && scheme != "replay"))
    c.fail(ptr, "unknown camera \"" + id + "\" (ids: v4l2:/dev/videoN, libcamera:auto, libcamera:<id>, replay:<folder>)");
  if (rest.empty()) c.fail(ptr, "\"" + id + "\" names no camera after \"" + scheme + ":\"");
  if (scheme == "v4l2") {
    cam.backend = CameraBackend::V4l2;
    cam.id = "v4l2:" + c.device(rest, ptr, "/dev/").string();
  } else if (scheme == "libcamera") {
    cam.backend = CameraBackend::Libcamera;
    cam.id = id;
  } else {
    cam.backend = CameraBackend::Replay;
    cam.replay_dir = c.board_path(rest, ptr);
    cam.id = "replay:" + cam.replay_dir.string();
  }
}

CameraConfig read_camera(const Checker& c, const json& root) {
  const std::string ptr = "/camera";
  const json& j = c.object(root, "", "camera");
  c.only_fields(j, ptr, {"id", "viewfinder", "still", "vignetting"});
  CameraConfig cam;
  read_camera_id(c, c.string(j, ptr, "id"), ptr + "/id", cam);

  const std::string vp = ptr + "/viewfinder";
  const json& vf = c.object(j, ptr, "viewfinder");
  c.only_fields(vf, vp, {"format", "size", "fps"});
  cam.viewfinder_format = c.string(vf, vp, "format");
  if (!capture::pixel_format_from_string(cam.viewfinder_format))
    c.fail(vp + "/format", "unknown pixel format \"" + cam.viewfinder_format + "\" (formats: RGB24, BGR24, YUYV, UYVY, NV12, MJPEG, GREY)");
  cam.viewfinder_size = c.size(vf, vp, "size", 16, 16384);
  cam.viewfinder_fps = c.positive_number(vf, vp, "fps", 240.0);

  const std::string sp = ptr + "/still";
  const json& still = c.object(j, ptr, "still");
  c.only_fields(still, sp, {"size"});
  cam.still_size = c.size(still, sp, "size", 16, 16384);

  // Optional: the lens's calibrated fall-off (`propcam calibrate vignetting`).
  if (j.contains("vignetting")) {
    const std::string gp = ptr + "/vignetting";
    const json& v = c.object(j, ptr, "vignetting");
    c.only_fields(v, gp, {"r2", "r4"});
    cam.vignetting.r2 = c.number(v, gp, "r2", render::kMaxVignettingCoefficient);
    if (v.contains("r4")) cam.vignetting.r4 = c.number(v, gp, "r4", render::kMaxVignettingCoefficient);
    if (const std::string problem = render::vignetting_problem(cam.vignetting); !problem.empty()) c.fail(gp, problem);
  }
  return cam;
}

StorageLocation read_location(const Checker& c, const json& obj, const std::string& ptr, const std::string& key,
                              bool allow_auto) {
  const std::string s = c.string(obj, ptr, key);
  if (s == "runtime") return StorageLocation{StorageLocation::Kind::Runtime, {}};
  if (s == "auto") {
    if (!allow_auto) c.fail(child(ptr, key), "\"auto\" is for the USB mount only");
    return StorageLocation{StorageLocation::Kind::Auto, {}};
  }
  return StorageLocation{StorageLocation::Kind::Path, c.any_path(s, child(ptr, key))};
}

StorageConfig read_storage(const Checker& c, const json& root) {
  const std::string ptr = "/storage";
  const json& j = c.object(root, "", "storage");
  c.only_fields(j, ptr, {"usb", "spool_dir", "data_dir"});
  StorageConfig s;
  s.usb = read_location(c, j, ptr, "usb", true);
  s.spool_dir = read_location(c, j, ptr, "spool_dir", false);
  s.data_dir = read_location(c, j, ptr, "data_dir", false);
  return s;
}

// Optional; each field defaults to job_budget.h's. The working size must fit
// the memory budget with the still held at its full size.
JobBudget read_budgets(const Checker& c, const json& root, const CameraConfig& camera) {
  JobBudget b;
  if (!root.contains("budgets")) return b;
  const std::string ptr = "/budgets";
  const json& j = c.object(root, "", "budgets");
  c.only_fields(j, ptr, {"working_size", "memory_mb", "render_seconds"});
  if (j.contains("working_size")) {
    const Size s = c.size(j, ptr, "working_size", kMinWorkingSide, kMaxWorkingSide);
    b.working_pixels = static_cast<long>(s.width) * s.height;
  }
  if (j.contains("memory_mb"))
    b.memory_mb = static_cast<long>(c.integer(j.at("memory_mb"), ptr + "/memory_mb", kMinMemoryBudgetMb, kMaxMemoryBudgetMb));
  if (j.contains("render_seconds")) b.render_seconds = c.positive_number(j, ptr, "render_seconds", kMaxRenderSeconds);
  const long still_pixels = static_cast<long>(camera.still_size.width) * camera.still_size.height;
  if (const std::string problem = memory_budget_problem(b, still_pixels); !problem.empty())
    c.fail(j.contains("working_size") ? ptr + "/working_size" : ptr + "/memory_mb", problem);
  return b;
}

json parse_file(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw BoardConfigError(file, "", "no such board file");
  const auto bytes = fs::file_size(file, ec);
  if (ec) throw BoardConfigError(file, "", "cannot read: " + ec.message());
  if (bytes > kMaxBoardFileBytes)
    throw BoardConfigError(file, "", "too large (" + std::to_string(bytes) + " bytes; a board file is at most " +
                                         std::to_string(kMaxBoardFileBytes) + ")");
  std::ifstream in(file, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in && !in.eof()) throw BoardConfigError(file, "", "cannot read");
  DuplicateKeyFinder dups;
  json root;
  try {
    root = json::parse(text, std::ref(dups));
  } catch (const json::exception& e) {
    std::string what = e.what();
    if (auto pos = what.find("] "); what.rfind("[json.exception", 0) == 0 && pos != std::string::npos)
      what = what.substr(pos + 2);
    throw BoardConfigError(file, "", "not valid JSON: " + what);
  }
  if (dups.duplicate()) throw BoardConfigError(file, *dups.duplicate(), "appears twice");
  return root;
}


bool valid_board_name(const std::string& name) {
  return !name.empty() && name.size() <= 64 && name[0] != '-' &&
         std::all_of(name.begin(), name.end(), [](char ch) {
           return (ch >= 'a' && ch <= 'z') || (ch >= '0' && ch <= '9') || ch == '-' || ch == '_';
         });
}

}  // namespace

BoardConfig load_board_file(const fs::path& board_json) {
  const fs::path file = fs::absolute(board_json).lexically_normal();
  const json root = parse_file(file);
  Checker c(file, file.parent_path());
  if (!root.is_object()) c.fail("", std::string("must be a JSON object, not ") + type_name(root));
  c.only_fields(root, "",
                {"name", "description", "buttons", "display", "camera", "camera_mount_height_m", "storage", "budgets"});

  BoardConfig b;
  b.file = file;
  b.dir = file.parent_path();
  b.name = c.string(root, "", "name");
  const std::string folder = b.dir.filename().string();
  if (b.name != folder) c.fail("/name", "\"" + b.name + "\" must be the board folder's name, \"" + folder + "\"");
  b.description = c.optional_string(root, "", "description").value_or("");
  b.buttons = read_buttons(c, root);
  b.display = read_display(c, root);
  b.camera = read_camera(c, root);
  b.camera_mount_height_m = c.positive_number(root, "", "camera_mount_height_m", 10.0);
  b.storage = read_storage(c, root);
  b.budgets = read_budgets(c, root, b.camera);
  return b;
}

std::vector<std::string> list_boards(const fs::path& board_root) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(board_root, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code e2;
    if (it->is_directory(e2) && fs::is_regular_file(it->path() / "board.json", e2))
      names.push_back(it->path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

BoardConfig load_board(const std::vector<fs::path>& board_roots, const std::string& name) {
  const fs::path where = board_roots.empty() ? fs::path{} : board_roots.back();
  if (!valid_board_name(name))
    throw BoardConfigError(where, "", "\"" + name + "\" is not a board name (lower-case letters, digits, - and _)");
  std::vector<std::string> all;
  std::vector<std::string> roots;
  for (const fs::path& root : board_roots) {
    const auto boards = list_boards(root);
    if (std::find(boards.begin(), boards.end(), name) != boards.end()) return load_board_file(root / name / "board.json");
    all.insert(all.end(), boards.begin(), boards.end());
    roots.push_back(root.string());
  }
  std::sort(all.begin(), all.end());
  all.erase(std::unique(all.begin(), all.end()), all.end());
  // One folder is the error's file; several are named.
  const std::string in = roots.size() > 1 ? " in " + join(roots) : "";
  throw BoardConfigError(where, "", "no board \"" + name + "\"" + in + " (boards: " + (all.empty() ? "none" : join(all)) + ")");
}

BoardConfig load_board(const fs::path& board_root, const std::string& name) {
  return load_board(std::vector<fs::path>{board_root}, name);
}

}  // namespace propcam::firmware
