// The digital lines of the bench beside the analog backend: the emergency-stop input and the
// valve power-enable output. A narrow seam (two calls) that a test can replace whole.
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "pneu/hal/gpio_params.hpp"
#include "pneu/hal/types.hpp"

struct gpiod_chip;  // libgpiod 1.6 handles, kept out of the public headers
struct gpiod_line;

namespace pneu::hal {

/// The e-stop input and the valve power-enable output. Both calls run on the loop thread:
/// real-time safe (no allocation, no exception, no lock, only the driver's own bounded I/O).
class GpioLines {
 public:
  virtual ~GpioLines() = default;

  /// Reads the e-stop input into `active`. On failure `active` is set to true (fail safe: an
  /// e-stop that cannot be read counts as pressed) and the status is kDeviceError.
  [[nodiscard]] virtual Status read_estop(bool& active) noexcept = 0;
  /// Switches valve power on or off; kDeviceError when the line did not take the value.
  [[nodiscard]] virtual Status set_valve_power(bool on) noexcept = 0;
};

/// GpioLines on a GPIO character device through libgpiod 1.6. Construct outside the loop.
class LibgpiodLines final : public GpioLines {
 public:
  /// Opens `params.chip` and requests the e-stop line as input and the valve power line as output,
  /// initially off, under `params.consumer`. Throws std::runtime_error naming the chip or line,
  /// the config key and the system's reason (no such chip, line busy, permission denied ...).
  explicit LibgpiodLines(const GpioConfig& params);
  /// Switches valve power off, then releases both lines and closes the chip.
  ~LibgpiodLines() override;
  LibgpiodLines(const LibgpiodLines&) = delete;
  LibgpiodLines& operator=(const LibgpiodLines&) = delete;

  [[nodiscard]] Status read_estop(bool& active) noexcept override;
  [[nodiscard]] Status set_valve_power(bool on) noexcept override;

  /// errno of the most recent failed call (0: none yet), readable from any thread for diagnosis.
  [[nodiscard]] int last_errno() const noexcept {
    return last_errno_.load(std::memory_order_relaxed);
  }

 private:
  struct ChipCloser {
    void operator()(gpiod_chip* chip) const noexcept;
  };

  std::unique_ptr<gpiod_chip, ChipCloser> chip_;  // closing the chip releases its requested lines
  gpiod_line* estop_ = nullptr;
  gpiod_line* valve_power_ = nullptr;
  std::atomic<int> last_errno_{0};
};

}  // namespace pneu::hal
