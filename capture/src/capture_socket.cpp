#include "capture_socket.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace propcam::capture::detail {

void throw_errno(const std::string& what) {
  throw std::system_error(errno, std::generic_category(), what);
}

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

void UniqueFd::reset(int fd) {
  // close() is not retried on EINTR: on Linux the fd is gone either way.
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
}

Mapping::Mapping(int fd, std::size_t bytes, bool writable) : size_(bytes) {
  const int prot = writable ? PROT_READ | PROT_WRITE : PROT_READ;
  void* p = ::mmap(nullptr, bytes, prot, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) throw_errno("mmap");
  data_ = p;
}

Mapping& Mapping::operator=(Mapping&& o) noexcept {
  if (this != &o) {
    if (data_) ::munmap(data_, size_);
    data_ = std::exchange(o.data_, nullptr);
    size_ = std::exchange(o.size_, 0);
  }
  return *this;
}

Mapping::~Mapping() {
  if (data_) ::munmap(data_, size_);
}

UniqueFd make_memfd(const char* name, std::size_t bytes) {
  UniqueFd fd(::memfd_create(name, MFD_CLOEXEC | MFD_ALLOW_SEALING));
  if (!fd) throw_errno("memfd_create");
  if (::ftruncate(fd.get(), static_cast<off_t>(bytes)) != 0) throw_errno("ftruncate memfd");
  if (::fcntl(fd.get(), F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW) != 0) throw_errno("seal memfd");
  return fd;
}

void seal_future_writes(int fd) {
#ifdef F_SEAL_FUTURE_WRITE
  // Clients then cannot map it writable; EINVAL on kernels before 5.1.
  (void)::fcntl(fd, F_ADD_SEALS, F_SEAL_FUTURE_WRITE);
#else
  (void)fd;
#endif
}

std::size_t fd_size(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw_errno("fstat");
  if (!S_ISREG(st.st_mode) || st.st_size < 0) throw std::runtime_error("received fd is not a memory file");
  return static_cast<std::size_t>(st.st_size);
}

SendResult send_packet(int socket, const protocol::Packet& packet, int pass_fd, bool dont_wait) {
  iovec iov{const_cast<std::uint8_t*>(packet.data()), packet.size()};
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))];
  if (pass_fd >= 0) {
    std::memset(control, 0, sizeof control);
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    cmsghdr* c = CMSG_FIRSTHDR(&msg);
    c->cmsg_level = SOL_SOCKET;
    c->cmsg_type = SCM_RIGHTS;
    c->cmsg_len = CMSG_LEN(sizeof(int));
    std::memcpy(CMSG_DATA(c), &pass_fd, sizeof(int));
  }
  const int flags = MSG_NOSIGNAL | (dont_wait ? MSG_DONTWAIT : 0);
  for (;;) {
    const ssize_t n = ::sendmsg(socket, &msg, flags);
    if (n >= 0) return SendResult::Sent;  // SEQPACKET: all or nothing
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return SendResult::WouldBlock;
    if (errno == ENOBUFS || errno == ENOMEM) return SendResult::WouldBlock;
    return SendResult::Closed;  // EPIPE, ECONNRESET, ENOTCONN, EBADF ...
  }
}

Received recv_packet(int socket, bool dont_wait) {
  Received out;
  out.bytes.resize(protocol::kMaxMessageBytes);
  iovec iov{out.bytes.data(), out.bytes.size()};
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  constexpr std::size_t kMaxFds = 8;
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int) * kMaxFds)];
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  const int flags = MSG_CMSG_CLOEXEC | (dont_wait ? MSG_DONTWAIT : 0);
  ssize_t n;
  for (;;) {
    n = ::recvmsg(socket, &msg, flags);
    if (n >= 0 || errno != EINTR) break;
  }
  if (n < 0) {
    out.kind = (errno == EAGAIN || errno == EWOULDBLOCK) ? Received::Kind::WouldBlock : Received::Kind::Closed;
    out.bytes.clear();
    return out;
  }
  // Keep the first fd passed; close any others so a client cannot leak fds into us.
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_RIGHTS) continue;
    const std::size_t count = (c->cmsg_len - CMSG_LEN(0)) / sizeof(int);
    for (std::size_t i = 0; i < count; ++i) {
      int fd;
      std::memcpy(&fd, CMSG_DATA(c) + i * sizeof(int), sizeof fd);
      if (!out.fd) out.fd.reset(fd);
      else ::close(fd);
    }
  }
  if (n == 0) {
    out.kind = Received::Kind::Closed;  // SEQPACKET: orderly shutdown by the peer
    out.bytes.clear();
    return out;
  }
  out.bytes.resize(static_cast<std::size_t>(n));
  out.kind = (msg.msg_flags & MSG_TRUNC) ? Received::Kind::Truncated : Received::Kind::Packet;
  return out;
}

}  // namespace propcam::capture::detail
