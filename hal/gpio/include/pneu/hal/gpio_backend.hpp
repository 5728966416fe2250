// The `gpio` lines beside any backend: a decorator that adds the e-stop input to every frame and
// drives the valve power-enable output from every command.
#pragma once

#include "pneu/hal/backend.hpp"
#include "pneu/hal/gpio_lines.hpp"

namespace pneu::hal {

/// A Backend that forwards to `inner` and adds the digital lines of `lines`. Both are borrowed:
/// they must outlive this object.
///
/// Safety rules, applied here so that they hold whatever the loop does:
/// - an e-stop read that fails counts as pressed;
/// - valve power is forced off while the e-stop reads pressed (from the line, or from the inner
///   backend's own frame.estop), and until the first read after open();
/// - close() switches valve power off.
class GpioBackend final : public Backend {
 public:
  GpioBackend(Backend& inner, GpioLines& lines) noexcept : inner_(inner), lines_(lines) {}

  /// Opens the inner backend, then switches valve power off. Throws std::runtime_error when the
  /// valve power line refuses.
  void open(double t0_s) override;
  /// Switches valve power off, then closes the inner backend.
  void close() noexcept override;

  /// The inner backend's frame with `frame.estop` ORed with the e-stop line. Status: the inner
  /// backend's, except that a failed e-stop read turns kOk or kStale into kDeviceError.
  /// Real-time safe.
  [[nodiscard]] Status read(double t_s, SensorFrame& frame) noexcept override;
  /// Forwards `command` with its valve_power as actually driven (forced off while the e-stop
  /// reads pressed), and drives the valve power line. Status: the inner backend's error first,
  /// else kDeviceError when the line refused, else kOk. Real-time safe.
  [[nodiscard]] Status write(const ActuatorCommand& command) noexcept override;
  /// The inner backend's.
  [[nodiscard]] std::optional<LinkReport> link_report() const override { return inner_.link_report(); }

 private:
  Backend& inner_;
  GpioLines& lines_;
  bool estop_active_ = true;  // the last read's e-stop; pressed until a read says otherwise
};

}  // namespace pneu::hal
