// Internal to the capture module: RAII for fds and mappings and the
// monotonic clock (the daemon, its client and the V4L2 backend), memfds, and
// packet send/receive over SOCK_SEQPACKET with an optional fd attached.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "propcam/capture/capture_protocol.h"

namespace propcam::capture::detail {

[[noreturn]] void throw_errno(const std::string& what);
std::int64_t monotonic_ns();

class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  UniqueFd(UniqueFd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  UniqueFd& operator=(UniqueFd&& o) noexcept {
    if (this != &o) reset(std::exchange(o.fd_, -1));
    return *this;
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  ~UniqueFd() { reset(); }
  int get() const { return fd_; }
  explicit operator bool() const { return fd_ >= 0; }
  void reset(int fd = -1);

 private:
  int fd_ = -1;
};

// A shared mapping of a whole fd; unmapped on destruction.
class Mapping {
 public:
  Mapping() = default;
  Mapping(int fd, std::size_t bytes, bool writable);
  Mapping(Mapping&& o) noexcept
      : data_(std::exchange(o.data_, nullptr)), size_(std::exchange(o.size_, 0)) {}
  Mapping& operator=(Mapping&& o) noexcept;
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  ~Mapping();
  std::uint8_t* data() const { return static_cast<std::uint8_t*>(data_); }
  std::size_t size() const { return size_; }

 private:
  void* data_ = nullptr;
  std::size_t size_ = 0;
};

// A memfd of `bytes`, size sealed (a client cannot shrink it under the
// server's mapping and make the server fault).
UniqueFd make_memfd(const char* name, std::size_t bytes);
// Seals writes once the writer has mapped it (best effort: older kernels).
void seal_future_writes(int fd);
// The size of a received fd, which must be a memfd-like regular file.
std::size_t fd_size(int fd);

enum class SendResult { Sent, WouldBlock, Closed };
// Never blocks when `dont_wait`; never raises SIGPIPE.
SendResult send_packet(int socket, const protocol::Packet& packet, int pass_fd = -1, bool dont_wait = true);

struct Received {
  enum class Kind { Packet, WouldBlock, Closed, Truncated } kind = Kind::Closed;
  std::vector<std::uint8_t> bytes;
  UniqueFd fd;  // the first fd that came with the packet; others are closed
};
Received recv_packet(int socket, bool dont_wait);

}  // namespace propcam::capture::detail
