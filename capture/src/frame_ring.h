// Internal to the capture module: one generation of the capture daemon's
// shared-memory frame ring. The camera thread copies each frame once into a
// free slot; every client that is told of the frame maps the same memfd and
// holds the slot until it releases it, and a held slot is never written.
// Not thread-safe: the server guards it with its client mutex, except for
// write(), which only the camera thread calls on a slot it claimed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "capture_socket.h"
#include "propcam/capture/capture_protocol.h"
#include "propcam/capture/frame_source.h"

namespace propcam::capture::detail {

inline constexpr std::size_t kPage = 4096;

std::size_t round_to_page(std::size_t n);

// Bytes a frame of this configuration needs (frame.h's bound; MJPEG's is its
// worst case, address space a ring slot only pays for where it is written).
// A configuration frame.h refuses gets a page: its frames are refused anyway,
// and the ring grows if one arrives larger.
std::size_t expected_frame_bytes(const StreamConfig& c);

class FrameRing {
 public:
  // A sealed memfd of `slot_count` (clamped to 1..1024) page-rounded slots of
  // at least `frame_bytes` each.
  FrameRing(std::uint32_t generation, int slot_count, std::size_t frame_bytes);

  const protocol::RingInfo& info() const { return info_; }
  int fd() const { return fd_.get(); }

  // A slot nobody holds or writes, marked as being written; round robin, so
  // the slot written longest ago is tried first.
  std::optional<std::uint32_t> claim_free_slot();
  void write(std::uint32_t slot, std::span<const std::uint8_t> bytes);
  void finish_write(std::uint32_t slot) { slots_[slot].writing = false; }

  void hold(std::uint32_t slot, std::uint32_t client) { slots_[slot].holders.push_back(client); }
  enum class Release { Released, OutOfRange, NotHeld };
  Release release(std::uint32_t slot, std::uint32_t client);
  void release_all(std::uint32_t client);

 private:
  struct Slot {
    std::vector<std::uint32_t> holders;  // client ids
    bool writing = false;
  };

  protocol::RingInfo info_;
  UniqueFd fd_;
  Mapping map_;
  std::vector<Slot> slots_;
  std::uint32_t next_ = 0;
};

}  // namespace propcam::capture::detail
