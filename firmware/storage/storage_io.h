// The write syscalls of export and spool, in one place. Every create, write,
// fsync, rename, mkdir and delete the storage code makes goes through a
// StorageIo, so tests can derive from it and inject the faults a USB stick
// produces (ENOSPC after N bytes, EIO at step K, the stick pulled) into the
// real export code. The default implementation is the plain syscalls.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>

namespace propcam::firmware {

class StorageIo {
 public:
  virtual ~StorageIo() = default;
  // Each returns 0 or the errno of the failed call.
  // open(O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644); the descriptor in `fd`.
  virtual int create_file(const std::filesystem::path& path, int& fd);
  // One write(2); `written` may be less than `size`.
  virtual int write(int fd, const void* data, std::size_t size, std::size_t& written);
  virtual int sync_file(int fd);
  virtual int close_file(int fd);
  // renameat2(RENAME_NOREPLACE): EEXIST when `to` exists (a rename never replaces).
  virtual int rename_new(const std::filesystem::path& from, const std::filesystem::path& to);
  virtual int make_dir(const std::filesystem::path& dir);   // mkdir 0755; EEXIST when there
  virtual int sync_dir(const std::filesystem::path& dir);   // open(O_DIRECTORY) + fsync + close
  virtual int remove(const std::filesystem::path& path);    // unlink, or rmdir for a folder
};

// The real syscalls.
std::shared_ptr<StorageIo> system_storage_io();

// A failed storage step: what was being done, where, and the errno.
class StorageFailure : public std::runtime_error {
 public:
  StorageFailure(int error, std::string step, std::filesystem::path path);
  int error() const { return error_; }
  const std::string& step() const { return step_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  int error_;
  std::string step_;
  std::filesystem::path path_;
};

// Throws StorageFailure when `error` is not 0.
void check_io(int error, const std::string& step, const std::filesystem::path& path);

// Writes `bytes` to a new file `path` (which must not exist), fsyncs and closes
// it. On failure the partial file is removed (best effort) and StorageFailure thrown.
void write_new_file(StorageIo& io, const std::filesystem::path& path, std::span<const std::uint8_t> bytes);

// The durable publish of one file: `bytes` to `temp` (same folder as
// `final_path`), fsync, rename to `final_path` (never replacing), fsync the
// file again (vfat writes the renamed entry's size only then), fsync the
// folder. No torn file is ever visible under `final_path`.
void publish_file(StorageIo& io, const std::filesystem::path& temp, const std::filesystem::path& final_path,
                  std::span<const std::uint8_t> bytes);

// Creates `dir` if missing (EEXIST is fine) and fsyncs its parent so the
// new entry survives a power cut.
void ensure_dir(StorageIo& io, const std::filesystem::path& dir);

// Removes a file or a folder tree through `io` (deepest first). Missing is fine.
void remove_tree(StorageIo& io, const std::filesystem::path& path);

// Content fingerprint of a file: its size and 64-bit FNV-1a hash. It tells a
// complete copy from a torn or foreign one, not an adversary's forgery.
struct Fingerprint {
  std::uintmax_t size = 0;
  std::uint64_t hash = 0;
  bool operator==(const Fingerprint&) const = default;
};
Fingerprint fingerprint(std::span<const std::uint8_t> bytes);
// Reads the file; throws StorageFailure (step "read") when it cannot.
Fingerprint fingerprint_file(const std::filesystem::path& path);
std::string to_hex(std::uint64_t value);

}  // namespace propcam::firmware
