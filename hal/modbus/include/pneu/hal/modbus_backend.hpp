// The `modbus` backend: an analog I/O module over Modbus TCP or RTU (libmodbus). The exchange runs
// on its own I/O thread (a real module answers in milliseconds; RTU at 115200 baud needs about
// 4 ms per transaction): the loop takes the newest sample with its age and leaves its newest
// command, never waiting. Failures close the connection and reconnect with back-off on the I/O
// thread (libmodbus 3.1.6 stays desynchronised after a late reply, upstream issue #255); an RTU
// line is flushed on each connection. The safe output on closing counts as delivered only once the
// valve registers, read back, hold it.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <mutex>
#include <thread>

#include "pneu/hal/backend.hpp"
#include "pneu/hal/latest_value.hpp"
#include "pneu/hal/modbus_params.hpp"
#include "pneu/model/sensors.hpp"

namespace pneu::hal {

/// What the I/O thread has seen, for health and tests. Read with relaxed atomics.
struct ModbusCounters {
  std::atomic<std::uint64_t> transactions{0};   ///< successful exchanges
  std::atomic<std::uint64_t> errors{0};         ///< failed exchanges (timeout, exception, bad data)
  std::atomic<std::uint64_t> reconnects{0};
  std::atomic<std::uint64_t> out_of_range{0};   ///< samples with a register outside its raw range
  std::atomic<int> last_errno{0};               ///< libmodbus/errno code of the last failure
  std::atomic<std::uint64_t> stale_reads{0};    ///< loop reads that found the sample too old
  std::atomic<double> max_age_s{0.0};           ///< oldest sample the loop took [s]
};

/// How the safe output written just before close() reached the module.
struct SafeOutputDelivery {
  int attempts = 0;        ///< attempts made (0: the backend never ran): a write, then a read back
  bool delivered = false;  ///< the valve registers, read back after a write, held the safe output
  bool read_back = false;  ///< the valve registers were read back at least once; the last reading:
  double read_back_u_p_v = 0.0, read_back_u_n_v = 0.0;
};

class ModbusBackend final : public Backend {
 public:
  /// close() tries this many exchanges, each on a fresh connection after a failure, to deliver the
  /// safe output before letting go of the module.
  static constexpr int kSafeOutputAttempts = 3;

  /// `calibration`: the sensors' volts -> SI (sensors.*).
  ModbusBackend(const ModbusConfig& modbus, const model::SensorParams& calibration);
  ~ModbusBackend() override;

  /// Connects (throws std::runtime_error naming the host/device and the reason) and starts the
  /// I/O thread after a first successful exchange (so a wrong unit id or register map fails here).
  void open(double t0_s) override;
  /// Stops the I/O thread, then delivers the last command written (the caller's safe output) to
  /// the module and reads the valve registers back: see link_report().
  void close() noexcept override;
  /// The newest sample and its age; kStale (and kSampleStale) when older than max_sample_age_s,
  /// kCommsError while the link is down. Real-time safe.
  [[nodiscard]] Status read(double t_s, SensorFrame& frame) noexcept override;
  /// Leaves the command for the I/O thread. Real-time safe.
  [[nodiscard]] Status write(const ActuatorCommand& command) noexcept override;

  [[nodiscard]] const ModbusCounters& counters() const noexcept { return counters_; }
  /// Human-readable description of the last failure (I/O thread's; for start-up and summaries).
  [[nodiscard]] std::string last_error() const;
  /// The counters, the last error and, after close(), the safe output's delivery.
  [[nodiscard]] std::optional<LinkReport> link_report() const override;

 private:
  struct Sample {
    // The module read the registers at some instant between these two (CLOCK_MONOTONIC): the
    // request about to go out, and the reply taken, however late the I/O thread ran to take it.
    double request_mono_s = -1.0;
    double mono_s = -1.0;
    double y_m = 0.0, p_p_pa = 0.0, p_n_pa = 0.0;
    std::uint32_t validity = 0;
  };
  void io_thread() noexcept;
  bool connect_once(std::string* why) noexcept;
  bool exchange(std::string* why) noexcept;
  /// io_command_'s voltages as the block of valve registers written (valve_p first if its address
  /// is the lower).
  void output_words(std::uint16_t out[2]) const noexcept;
  /// Reads the valve registers back (function 3): whether they hold io_command_'s words; the
  /// reading is kept in safe_output_.
  bool read_back_outputs(std::string* why) noexcept;
  void disconnect() noexcept;

  ModbusConfig cfg_;
  model::SensorChannelParams position_, pressure_p_, pressure_n_;  // their calibrations
  void* ctx_ = nullptr;  // modbus_t*
  LatestValue<Sample> sample_;
  LatestValue<ActuatorCommand> command_;
  ActuatorCommand io_command_{};  // the I/O thread's copy
  std::atomic<bool> link_up_{false};
  std::atomic<bool> running_{false};
  std::thread thread_;
  ModbusCounters counters_;
  SafeOutputDelivery safe_output_{};  // written by close(), after the I/O thread has stopped
  int read_start_ = 0, read_count_ = 0, write_start_ = 0, write_count_ = 0;
  int at_p_ = 0;  // valve_p's index in the block of valve registers (valve_n's: 1 - at_p_)
  void set_error(const std::string& why);
  mutable std::mutex error_mutex_;  // taken by the I/O thread and by readers of last_error()
  std::string last_error_;
};

}  // namespace pneu::hal
