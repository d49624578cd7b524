// Internal to the capture module: the capture daemon's listening UNIX socket
// and the file it is bound to (stale files replaced, permissions set before
// anyone can connect, only our own file removed at the end).
#pragma once

#include <sys/types.h>

#include <functional>
#include <string>

#include "capture_socket.h"

namespace propcam::capture::detail {

class ListeningSocket {
 public:
  using Log = std::function<void(const std::string&)>;

  // Binds a non-blocking SOCK_SEQPACKET socket at `path` (its folder made
  // when missing) with mode 0660, given to `group` when that group exists,
  // and listens. A stale socket file nobody listens on is replaced; a live
  // one, or a file that is not a socket, throws.
  void bind(const std::string& path, const std::string& group, const Log& log);
  int fd() const { return fd_.get(); }
  // Closes the socket (no more connections); the file stays.
  void close() { fd_.reset(); }
  // Removes the socket file if bind() made it and it is still that file:
  // a newer server may have replaced it.
  void remove_file();

 private:
  UniqueFd fd_;
  std::string path_;
  dev_t dev_ = 0;
  ino_t ino_ = 0;
  bool bound_ = false;
};

}  // namespace propcam::capture::detail
