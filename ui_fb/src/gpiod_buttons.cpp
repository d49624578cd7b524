// libgpiod v1 (Debian bookworm's 1.6) backend: one line per button, both edges,
// all line event fds gathered in one epoll descriptor so callers poll a single fd.
#include <gpiod.h>
#include <sys/epoll.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "propcam/ui_fb/buttons.h"

namespace propcam::ui_fb {
namespace {

struct ChipCloser {
  void operator()(gpiod_chip* chip) const { gpiod_chip_close(chip); }  // releases its lines
};
using ChipPtr = std::unique_ptr<gpiod_chip, ChipCloser>;

// A kernel timestamp further than this from the read time is not CLOCK_MONOTONIC
// (Linux < 5.7 stamped line events with CLOCK_REALTIME).
// The kernel's internal ENOTSUPP can leak out of gpiolib ioctls; libc has no name for it.
constexpr int kKernelEnotsupp = 524;

constexpr std::int64_t kPlausibleSkewNs = 10'000'000'000;

bool all_digits(const std::string& s) {
  return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
}

}  // namespace

struct GpiodButtonInput::Impl {
  std::string chip_name;
  ChipPtr chip;
  int epoll_fd = -1;
  struct Line {
    Button button;
    std::string name;
    gpiod_line* line;
    int fd;
  };
  std::vector<Line> lines;

  ~Impl() {
    if (epoll_fd >= 0) ::close(epoll_fd);
  }
  [[noreturn]] void fail(const std::string& what, int err) const {
    throw std::runtime_error("ui_fb: gpio chip " + chip_name + ": " + what +
                             (err ? std::string(": ") + std::strerror(err) : std::string()));
  }
};

GpiodButtonInput::GpiodButtonInput(GpiodButtonOptions options)
    : FdButtonInput(options.debounce), impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  im.chip_name = options.chip;
  if (options.lines.empty()) im.fail("no button lines configured", 0);
  im.chip.reset(gpiod_chip_open_lookup(options.chip.c_str()));
  if (!im.chip) im.fail("cannot open (no such GPIO chip?)", errno);
  im.epoll_fd = epoll_create1(EPOLL_CLOEXEC);
  if (im.epoll_fd < 0) im.fail("epoll_create1", errno);

  for (const auto& [button, line_name] : options.lines) {
    const std::string label = "line '" + line_name + "' (" + std::string(button_name(button)) + ")";
    gpiod_line* line = gpiod_chip_find_line(im.chip.get(), line_name.c_str());
    if (!line && all_digits(line_name)) {
      line = gpiod_chip_get_line(im.chip.get(), static_cast<unsigned>(std::strtoul(line_name.c_str(), nullptr, 10)));
    }
    if (!line) im.fail(label + " not found", 0);

    int flags = options.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
    gpiod_line_request_config config{options.consumer.c_str(), GPIOD_LINE_REQUEST_EVENT_BOTH_EDGES,
                                     flags | (options.pull_up ? GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP : 0)};
    int rc = gpiod_line_request(line, &config, 0);
    if (rc < 0 && options.pull_up && (errno == EINVAL || errno == EOPNOTSUPP || errno == kKernelEnotsupp)) {
      // Older kernels and some controllers cannot set bias; the board may have
      // external pull-ups, so carry on and say so.
      notes_.push_back("bias pull-up refused on " + label + " (" + std::strerror(errno) +
                       "); requested without bias");
      std::clog << "ui_fb: gpio chip " << im.chip_name << ": " << notes_.back() << "\n";
      config.flags = flags;
      rc = gpiod_line_request(line, &config, 0);
    }
    if (rc < 0) im.fail("cannot request " + label + " for edge events (busy?)", errno);
    const int fd = gpiod_line_event_get_fd(line);
    if (fd < 0) im.fail("no event fd for " + label, errno);
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = im.lines.size();
    if (epoll_ctl(im.epoll_fd, EPOLL_CTL_ADD, fd, &ev) < 0) im.fail("epoll_ctl", errno);
    im.lines.push_back(Impl::Line{button, line_name, line, fd});
  }
}

GpiodButtonInput::~GpiodButtonInput() = default;

int GpiodButtonInput::poll_fd() const { return impl_->epoll_fd; }

std::string GpiodButtonInput::name() const {
  return "gpiod " + impl_->chip_name + " (" + std::to_string(impl_->lines.size()) + " lines)";
}

void GpiodButtonInput::read_ready(std::int64_t now_ns) {
  Impl& im = *impl_;
  epoll_event ready[kButtonCount * 2];
  const int n = epoll_wait(im.epoll_fd, ready, static_cast<int>(std::size(ready)), 0);
  if (n < 0 && errno != EINTR) im.fail("epoll_wait", errno);
  for (int k = 0; k < n; ++k) {
    const Impl::Line& line = im.lines.at(ready[k].data.u64);
    gpiod_line_event events[16];
    const int got = gpiod_line_event_read_multiple(line.line, events, std::size(events));
    if (got < 0) im.fail("reading events of line '" + line.name + "'", errno);
    for (int i = 0; i < got; ++i) {
      std::int64_t t = static_cast<std::int64_t>(events[i].ts.tv_sec) * 1'000'000'000 + events[i].ts.tv_nsec;
      if (std::llabs(now_ns - t) > kPlausibleSkewNs) t = now_ns;
      // With ACTIVE_LOW the kernel reports logical edges: rising = pressed.
      feed(RawEdge{line.button, events[i].event_type == GPIOD_LINE_EVENT_RISING_EDGE, t}, now_ns);
    }
  }
}

}  // namespace propcam::ui_fb
