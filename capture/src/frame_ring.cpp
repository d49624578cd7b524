#include "frame_ring.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "propcam/capture/frame.h"

namespace propcam::capture::detail {

std::size_t round_to_page(std::size_t n) { return std::max<std::size_t>(kPage, (n + kPage - 1) / kPage * kPage); }

std::size_t expected_frame_bytes(const StreamConfig& c) {
  FrameFormat format;
  format.pixel_format = c.pixel_format;
  format.width = c.width;
  format.height = c.height;
  try {
    return frame_bytes(format);
  } catch (const std::runtime_error&) {
    return kPage;
  }
}

FrameRing::FrameRing(std::uint32_t generation, int slot_count, std::size_t frame_bytes) {
  info_.generation = generation;
  info_.slot_count = static_cast<std::uint32_t>(std::clamp(slot_count, 1, 1024));
  info_.slot_bytes = round_to_page(frame_bytes);
  const std::size_t total = info_.slot_bytes * info_.slot_count;
  fd_ = make_memfd("propcam-ring", total);
  map_ = Mapping(fd_.get(), total, true);
  seal_future_writes(fd_.get());
  slots_.resize(info_.slot_count);
}

std::optional<std::uint32_t> FrameRing::claim_free_slot() {
  const auto n = static_cast<std::uint32_t>(slots_.size());
  for (std::uint32_t k = 0; k < n; ++k) {
    const std::uint32_t i = (next_ + k) % n;
    if (slots_[i].holders.empty() && !slots_[i].writing) {
      next_ = (i + 1) % n;
      slots_[i].writing = true;
      return i;
    }
  }
  return std::nullopt;
}

void FrameRing::write(std::uint32_t slot, std::span<const std::uint8_t> bytes) {
  std::memcpy(map_.data() + slot * info_.slot_bytes, bytes.data(), bytes.size());
}

FrameRing::Release FrameRing::release(std::uint32_t slot, std::uint32_t client) {
  if (slot >= slots_.size()) return Release::OutOfRange;
  auto& holders = slots_[slot].holders;
  const auto h = std::find(holders.begin(), holders.end(), client);
  if (h == holders.end()) return Release::NotHeld;
  holders.erase(h);
  return Release::Released;
}

void FrameRing::release_all(std::uint32_t client) {
  for (auto& slot : slots_) std::erase(slot.holders, client);
}

}  // namespace propcam::capture::detail
