#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <system_error>

#include <OpenImageIO/imageio.h>

#include "propcam/ui_fb/display.h"

namespace propcam::ui_fb {

namespace {

// Writes next to the target and renames over it: rename within one folder is
// atomic, so whoever watches the snapshot sees the old or the new frame, whole.
constexpr int kSnapshotPngCompression = 1;

void write_png_atomically(const Canvas& image, const std::filesystem::path& path) {
  static std::atomic<unsigned> temp_counter{0};
  // Hidden, and unique per process and call so concurrent writers never collide.
  std::string temp_name = ".";
  temp_name += path.filename().string();
  temp_name += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(temp_counter++);
  const std::filesystem::path temp = path.parent_path() / temp_name;
  // Asked for by format name, since the temporary name has no .png extension.
  auto output = OIIO::ImageOutput::create("png");
  if (!output) throw std::runtime_error("ui_fb: OpenImageIO has no PNG writer: " + OIIO::geterror());
  OIIO::ImageSpec spec(image.width(), image.height(), 3, OIIO::TypeDesc::UINT8);
  // A snapshot is written on every present: speed matters more than size
  // (level 1 is about 3x faster than zlib's default and ~15% larger).
  spec.attribute("png:compressionLevel", kSnapshotPngCompression);
  bool written = output->open(temp.string(), spec);
  if (written) {
    written = output->write_image(OIIO::TypeDesc::UINT8, image.pixels().data, 3,
                                  static_cast<OIIO::stride_t>(image.pixels().step));
    written = output->close() && written;
  }
  std::error_code error;
  if (!written) {
    const std::string reason = output->geterror();
    std::filesystem::remove(temp, error);
    throw std::runtime_error("ui_fb: cannot write snapshot " + temp.string() + ": " + reason);
  }
  std::filesystem::rename(temp, path, error);
  if (error) {
    std::error_code ignored;
    std::filesystem::remove(temp, ignored);
    throw std::runtime_error("ui_fb: cannot rename snapshot to " + path.string() + ": " +
                             error.message());
  }
}

}  // namespace

FileDisplay::FileDisplay(FileDisplayOptions options)
    : options_(std::move(options)), packer_(options_.format) {
  const Size size = options_.size;
  if (size.width <= 0 || size.height <= 0) {
    throw std::invalid_argument("ui_fb: FileDisplay size " + std::to_string(size.width) + "x" +
                                std::to_string(size.height) + " is not positive");
  }
  const std::size_t row_bytes = static_cast<std::size_t>(size.width) * packer_.bytes_per_pixel();
  if (options_.line_length < 0 ||
      (options_.line_length > 0 && static_cast<std::size_t>(options_.line_length) < row_bytes)) {
    throw std::invalid_argument("ui_fb: FileDisplay line length " +
                                std::to_string(options_.line_length) + " is shorter than a row (" +
                                std::to_string(row_bytes) + " bytes)");
  }
  if (!options_.snapshot_path.has_filename()) {
    throw std::invalid_argument("ui_fb: FileDisplay snapshot path '" +
                                options_.snapshot_path.string() + "' names no file");
  }
  line_length_ = options_.line_length > 0 ? static_cast<std::size_t>(options_.line_length) : row_bytes;
  framebuffer_.assign(line_length_ * static_cast<std::size_t>(size.height), 0);
  const std::filesystem::path folder = options_.snapshot_path.parent_path();
  if (!folder.empty()) std::filesystem::create_directories(folder);
}

std::string FileDisplay::name() const {
  return "file " + options_.snapshot_path.string() + (options_.numbered ? " (numbered) " : " ") +
         std::to_string(options_.size.width) + "x" + std::to_string(options_.size.height) + " " +
         packer_.format().describe();
}

std::filesystem::path FileDisplay::snapshot_path_for_frame(int frame_number) const {
  if (!options_.numbered) return options_.snapshot_path;
  char number[16];
  std::snprintf(number, sizeof number, "_%06d", frame_number);
  const std::filesystem::path& base = options_.snapshot_path;
  return base.parent_path() / (base.stem().string() + number + base.extension().string());
}

Canvas FileDisplay::screen_contents() const {
  Canvas screen(options_.size);
  packer_.unpack(framebuffer_, line_length_, screen);
  return screen;
}

void FileDisplay::present(const Canvas& canvas) {
  require_canvas_size(canvas);
  packer_.pack(canvas, canvas.bounds(), framebuffer_, line_length_);
  // The snapshot decodes the packed bytes, so it shows the screen, not the canvas.
  const std::filesystem::path path = snapshot_path_for_frame(frames_presented_ + 1);
  write_png_atomically(screen_contents(), path);
  ++frames_presented_;
  last_snapshot_ = path;
}

}  // namespace propcam::ui_fb
