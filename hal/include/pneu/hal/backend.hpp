// The narrow seam between the loop and the bench: open() outside the loop, read()/write() inside.
#pragma once

#include "pneu/hal/types.hpp"

namespace pneu::hal {

/// A bench backend. open()/close() run outside the loop and may throw std::runtime_error with a
/// message for the user. read()/write() run on the loop thread: real-time safe (no allocation,
/// no exception, no lock shared with another thread, no blocking beyond the backend's own bounded
/// I/O).
class Backend {
 public:
  virtual ~Backend() = default;

  /// Prepares the device; the loop's clock reads `t0_s` at the first tick.
  virtual void open(double t0_s) = 0;
  virtual void close() noexcept = 0;

  /// The newest sensor sample at loop time `t_s`. Real-time safe.
  [[nodiscard]] virtual Status read(double t_s, SensorFrame& frame) noexcept = 0;
  /// Leaves the newest command for the device; it holds until the next write. Real-time safe.
  [[nodiscard]] virtual Status write(const ActuatorCommand& command) noexcept = 0;
};

}  // namespace pneu::hal
