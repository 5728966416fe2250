// The narrow seam between the loop and the bench: open() outside the loop, read()/write() inside.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "pneu/hal/types.hpp"

namespace pneu::hal {

/// A backend's link to a device it exchanges with (the modbus backend's I/O module): what it
/// counted while it ran, and how the safe output written just before close() reached the device.
/// For the run's summary; read outside the loop.
struct LinkReport {
  std::uint64_t transactions = 0;   ///< successful exchanges
  std::uint64_t errors = 0;         ///< failed exchanges (timeout, exception, bad data)
  std::uint64_t reconnects = 0;
  std::uint64_t out_of_range = 0;   ///< samples with a register outside its raw range
  std::uint64_t stale_reads = 0;    ///< loop reads that found the sample too old
  double oldest_sample_s = 0.0;     ///< the oldest sample the loop took [s]
  std::string last_error;           ///< the last failure's text (empty: none)
  /// The safe output written on closing: attempts made, of at most safe_output_max_attempts, and
  /// whether it was delivered: written, then read back from the device's output registers
  /// (attempts 0: the backend never ran). A reply to the write alone is no proof of delivery.
  int safe_output_attempts = 0;
  int safe_output_max_attempts = 0;
  bool safe_output_delivered = false;
  /// The output voltages last read back from the device on closing (NaN: none read back).
  double safe_output_read_back_u_p_v = std::numeric_limits<double>::quiet_NaN();
  double safe_output_read_back_u_n_v = std::numeric_limits<double>::quiet_NaN();
};

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

  /// The link to the device, when the backend has one (none for the in-process plant). Not
  /// real-time; complete after close(), which delivers the safe output.
  [[nodiscard]] virtual std::optional<LinkReport> link_report() const { return std::nullopt; }
};

}  // namespace pneu::hal
