#include "storage/storage_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

namespace propcam::firmware {

namespace fs = std::filesystem;

namespace {

constexpr std::uint64_t kFnvOffset = 0xcbf29ce484222325ull;
constexpr std::uint64_t kFnvPrime = 0x100000001b3ull;
constexpr std::size_t kReadChunk = 1 << 16;

std::uint64_t fnv1a(std::uint64_t hash, const std::uint8_t* data, std::size_t size) {
  for (std::size_t i = 0; i < size; ++i) {
    hash ^= data[i];
    hash *= kFnvPrime;
  }
  return hash;
}

int errno_or_zero(int result) { return result == 0 ? 0 : errno; }

}  // namespace

int StorageIo::create_file(const fs::path& path, int& fd) {
  fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  return fd >= 0 ? 0 : errno;
}

int StorageIo::write(int fd, const void* data, std::size_t size, std::size_t& written) {
  written = 0;
  ssize_t n;
  do n = ::write(fd, data, size);
  while (n < 0 && errno == EINTR);
  if (n < 0) return errno;
  written = static_cast<std::size_t>(n);
  return 0;
}

int StorageIo::sync_file(int fd) { return errno_or_zero(::fsync(fd)); }

int StorageIo::close_file(int fd) { return errno_or_zero(::close(fd)); }

int StorageIo::rename_new(const fs::path& from, const fs::path& to) {
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0) return 0;
  if (errno != EINVAL && errno != ENOSYS) return errno;
  // A filesystem without RENAME_NOREPLACE: check, then rename (only this
  // process writes to the stick, so nothing appears in between).
  struct stat st{};
  if (::lstat(to.c_str(), &st) == 0) return EEXIST;
  return errno_or_zero(::rename(from.c_str(), to.c_str()));
}

int StorageIo::make_dir(const fs::path& dir) { return errno_or_zero(::mkdir(dir.c_str(), 0755)); }

int StorageIo::sync_dir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return errno;
  const int error = errno_or_zero(::fsync(fd));
  ::close(fd);
  return error;
}

int StorageIo::remove(const fs::path& path) {
  if (::unlink(path.c_str()) == 0) return 0;
  if (errno == EISDIR || errno == EPERM) return errno_or_zero(::rmdir(path.c_str()));
  return errno;
}

std::shared_ptr<StorageIo> system_storage_io() {
  static const auto io = std::make_shared<StorageIo>();
  return io;
}

StorageFailure::StorageFailure(int error, std::string step, fs::path path)
    : std::runtime_error(step + " " + path.string() + ": " + std::strerror(error)),
      error_(error),
      step_(std::move(step)),
      path_(std::move(path)) {}

void check_io(int error, const std::string& step, const fs::path& path) {
  if (error != 0) throw StorageFailure(error, step, path);
}

namespace {

// Creates `path`, writes `bytes` and fsyncs them; returns the open descriptor.
// On failure the descriptor is closed, the file removed (best effort) and
// StorageFailure thrown.
int write_synced(StorageIo& io, const fs::path& path, std::span<const std::uint8_t> bytes) {
  int fd = -1;
  check_io(io.create_file(path, fd), "create", path);
  int error = 0;
  std::string step;
  std::size_t done = 0;
  while (done < bytes.size() && error == 0) {
    std::size_t written = 0;
    error = io.write(fd, bytes.data() + done, bytes.size() - done, written);
    if (error == 0 && written == 0) error = EIO;  // no progress: the device is gone
    done += written;
    step = "write";
  }
  if (error == 0) {
    error = io.sync_file(fd);
    step = "fsync";
  }
  if (error != 0) {
    io.close_file(fd);
    io.remove(path);  // best effort: the stick may be gone
    throw StorageFailure(error, step, path);
  }
  return fd;
}

}  // namespace

void write_new_file(StorageIo& io, const fs::path& path, std::span<const std::uint8_t> bytes) {
  const int fd = write_synced(io, path, bytes);
  if (const int error = io.close_file(fd); error != 0) {
    io.remove(path);
    throw StorageFailure(error, "close", path);
  }
}

void publish_file(StorageIo& io, const fs::path& temp, const fs::path& final_path, std::span<const std::uint8_t> bytes) {
  const int fd = write_synced(io, temp, bytes);
  if (const int error = io.rename_new(temp, final_path); error != 0) {
    io.close_file(fd);
    io.remove(temp);
    throw StorageFailure(error, "rename", final_path);
  }
  // The file is fsynced again after the rename, before its folder: vfat
  // writes a renamed file's directory entry (its size and first cluster) only
  // when the inode is written back, which fsyncing the folder does not do. A
  // stick pulled in between held an empty file under the final name
  // (usb-storage in QEMU, tests/qemu).
  int error = io.sync_file(fd);
  const int close_error = io.close_file(fd);
  if (error == 0) error = close_error;
  check_io(error, "fsync", final_path);
  check_io(io.sync_dir(final_path.parent_path()), "fsync folder", final_path.parent_path());
}

void ensure_dir(StorageIo& io, const fs::path& dir) {
  const int error = io.make_dir(dir);
  if (error == EEXIST) return;
  check_io(error, "mkdir", dir);
  const fs::path parent = dir.parent_path().empty() ? fs::path(".") : dir.parent_path();  // "spool" lives in "."
  check_io(io.sync_dir(parent), "fsync folder", parent);
}

void remove_tree(StorageIo& io, const fs::path& path) {
  std::error_code ec;
  const auto status = fs::symlink_status(path, ec);
  if (ec || !fs::exists(status)) return;
  if (fs::is_directory(status)) {
    std::vector<fs::path> children;
    for (fs::directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec)) children.push_back(it->path());
    check_io(ec.value(), "list", path);
    for (const auto& child : children) remove_tree(io, child);
  }
  const int error = io.remove(path);
  if (error != ENOENT) check_io(error, "remove", path);
}

Fingerprint fingerprint(std::span<const std::uint8_t> bytes) {
  return {bytes.size(), fnv1a(kFnvOffset, bytes.data(), bytes.size())};
}

Fingerprint fingerprint_file(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw StorageFailure(errno, "read", path);
  Fingerprint print{0, kFnvOffset};
  std::vector<std::uint8_t> buffer(kReadChunk);
  for (;;) {
    const ssize_t n = ::read(fd, buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int error = errno;
      ::close(fd);
      throw StorageFailure(error, "read", path);
    }
    if (n == 0) break;
    print.size += static_cast<std::uintmax_t>(n);
    print.hash = fnv1a(print.hash, buffer.data(), static_cast<std::size_t>(n));
  }
  ::close(fd);
  return print;
}

std::string to_hex(std::uint64_t value) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

}  // namespace propcam::firmware
