#include "listening_socket.h"

#include <grp.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <vector>

namespace propcam::capture::detail {
namespace {

sockaddr_un unix_address(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof addr.sun_path)
    throw std::runtime_error("socket path empty or too long: " + path);
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return addr;
}

// True when something accepts connections at `path`.
bool someone_listens(const std::string& path) {
  UniqueFd probe(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
  if (!probe) throw_errno("socket");
  const sockaddr_un addr = unix_address(path);
  int rc;
  do rc = ::connect(probe.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  while (rc != 0 && errno == EINTR);
  if (rc == 0) return true;
  if (errno == ECONNREFUSED || errno == ENOENT) return false;
  if (errno == EPROTOTYPE) return true;  // a listener of another socket type: not ours to remove
  throw_errno("probing " + path);
}

std::optional<gid_t> group_id(const std::string& name) {
  if (name.empty()) return std::nullopt;
  group g{};
  group* found = nullptr;
  std::vector<char> buffer(16384);
  if (::getgrnam_r(name.c_str(), &g, buffer.data(), buffer.size(), &found) != 0 || !found) return std::nullopt;
  return g.gr_gid;
}

}  // namespace

void ListeningSocket::bind(const std::string& path, const std::string& group, const Log& log) {
  const sockaddr_un addr = unix_address(path);
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (!parent.empty() && ::mkdir(parent.c_str(), 0755) != 0 && errno != EEXIST)
    throw_errno("creating " + parent.string());
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) throw std::runtime_error(path + " exists and is not a socket");
    if (someone_listens(path)) throw std::runtime_error("a server already listens on " + path);
    if (::unlink(path.c_str()) != 0 && errno != ENOENT) throw_errno("removing stale " + path);
    if (log) log("removed stale socket " + path);
  }
  fd_.reset(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (!fd_) throw_errno("socket");
  if (::bind(fd_.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) throw_errno("bind " + path);
  if (::lstat(path.c_str(), &st) != 0) throw_errno("stat " + path);
  path_ = path;
  dev_ = st.st_dev;
  ino_ = st.st_ino;
  bound_ = true;
  // Permissions before listen(), so nobody connects through a wider mode.
  if (::chmod(path.c_str(), 0660) != 0) throw_errno("chmod " + path);
  if (const auto gid = group_id(group)) {
    if (::chown(path.c_str(), static_cast<uid_t>(-1), *gid) != 0 && log)
      log("cannot give " + path + " to group " + group + ": " + std::strerror(errno));
  }
  if (::listen(fd_.get(), 16) != 0) throw_errno("listen");
}

void ListeningSocket::remove_file() {
  if (!bound_) return;
  struct stat st {};
  if (::lstat(path_.c_str(), &st) == 0 && st.st_dev == dev_ && st.st_ino == ino_) ::unlink(path_.c_str());
}

}  // namespace propcam::capture::detail
