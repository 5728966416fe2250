// Lock-free hand-over of the newest value from one thread to another (triple buffer): the writer
// never waits, the reader always gets the newest complete value. Neither side allocates or locks.
#pragma once

#include <atomic>
#include <cstdint>
#include <type_traits>

namespace pneu::hal {

template <typename T>
class LatestValue {
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  /// Writer side: publishes `value`. Wait-free.
  void store(const T& value) noexcept {
    slots_[back_] = value;
    const std::uint8_t old = middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    back_ = old & kIndex;
  }
  /// Reader side: the newest value; false if nothing was ever stored. `fresh` tells whether it
  /// was stored since the last load. Wait-free.
  bool load(T& out, bool* fresh = nullptr) noexcept {
    const bool is_fresh = (middle_.load(std::memory_order_relaxed) & kFresh) != 0;
    if (is_fresh) {
      const std::uint8_t old = middle_.exchange(front_, std::memory_order_acq_rel);
      front_ = old & kIndex;
      has_value_ = true;
    }
    if (fresh) *fresh = is_fresh;
    if (!has_value_) return false;
    out = slots_[front_];
    return true;
  }

 private:
  static constexpr std::uint8_t kIndex = 0x3, kFresh = 0x4;
  T slots_[3]{};
  std::atomic<std::uint8_t> middle_{1};
  std::uint8_t back_ = 0;   // writer's
  std::uint8_t front_ = 2;  // reader's
  bool has_value_ = false;  // reader's
};

}  // namespace pneu::hal
