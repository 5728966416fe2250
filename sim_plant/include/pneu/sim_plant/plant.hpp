// The 4th-order plant of Eq. 2 with hybrid Karnopp friction and hard end stops (docs/model.md sections 2-4).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <span>

#include "pneu/model/chamber.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/pressure_force.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::plant {

/// Discrete mode of the hybrid friction model.
enum class Motion : std::uint8_t {
  kStuck,            ///< v = 0 exactly, y frozen; F inside [F_S-, F_S+] (or pushing into an end stop)
  kSlidingPositive,  ///< friction on the v > 0 branch
  kSlidingNegative,  ///< friction on the v < 0 branch
};

/// Continuous state in SI units plus the discrete mode.
struct PlantState {
  double t_s = 0.0;          ///< simulated time [s]
  double y_m = 0.0;          ///< position from mid-stroke [m]
  double v_m_per_s = 0.0;    ///< velocity [m/s]
  double p_p_pa = 1.0e5;     ///< chamber P absolute pressure [Pa]
  double p_n_pa = 1.0e5;     ///< chamber N absolute pressure [Pa]
  Motion motion = Motion::kStuck;
  /// Chamber temperatures [K]: with plant.thermal, integrated; without, gas.temperature_k throughout
  /// (NaN given to reset(): the wall temperature).
  double t_p_k = std::numeric_limits<double>::quiet_NaN();
  double t_n_k = std::numeric_limits<double>::quiet_NaN();
  /// Where each valve's spool is, as the voltage its opening corresponds to [V]: the last command
  /// (within the valve's travel) without a spool lag (NaN given to reset(): at the voltages
  /// reset_at_rest would put it, u and -u of its `u_v`; 0 with reset()).
  double w_p_v = std::numeric_limits<double>::quiet_NaN();
  double w_n_v = std::numeric_limits<double>::quiet_NaN();
};

/// A mode change located inside an integration step.
struct PlantEvent {
  enum class Kind : std::uint8_t {
    kBreakaway,  ///< stuck -> sliding: F left [F_S-, F_S+]
    kStick,      ///< sliding -> stuck: v reached 0 with F inside the stiction band
    kReversal,   ///< v reached 0 with F outside the band: sliding on in the other direction
    kEndStop,    ///< the carriage hit y = +-L/2 and stopped there
  };
  Kind kind = Kind::kStick;
  double t_s = 0.0;    ///< time of the event [s]
  double y_m = 0.0;    ///< position at the event [m]
  double force_n = 0.0;  ///< pressure force of Eq. 14 at the event [N]
  int direction = 0;   ///< +1 / -1: direction of motion after (breakaway, reversal) or before (stick, end stop)
};

/// The simulated cylinder, valves and carriage. step() is real-time safe: no allocation, no throw.
class Plant {
 public:
  /// Largest number of events one call to step() reports; more are counted in events_dropped().
  static constexpr std::size_t kMaxEventsPerStep = 16;

  explicit Plant(const model::PlantParams& params);

  /// Puts the carriage at rest at `y_m` with both pressures at their null-flow values for the
  /// valve voltages u_P = u, u_N = -u (complete equilibrium when F_e(u) is inside the stiction band),
  /// the chambers at the wall temperature and the spools where those voltages put them.
  void reset_at_rest(double y_m, double u_v, double t_s = 0.0) noexcept;
  /// Sets an arbitrary state; the motion mode is made consistent with v (v = 0 -> stuck unless the
  /// force already breaks away). Temperatures left NaN are the wall's, spools left NaN at 0 V.
  void reset(const PlantState& state) noexcept;

  /// Advances by `dt_s` with the valve voltages held (u_P = u, u_N = -u: Eq. 1), in equal
  /// sub-steps no longer than step_size_s(); mode changes are located inside the sub-steps.
  /// The same as step(dt_s, u_v, -u_v), bit for bit.
  void step(double dt_s, double u_v) noexcept { step(dt_s, u_v, -u_v); }
  /// Advances by `dt_s` with each 3-way valve driven by its own voltage held over the step: valve P
  /// at `u_p_v`, valve N at `u_n_v` (w in docs/model.md section 3). Beyond Eq. 1: e.g. both at -u_max
  /// vents both chambers to the exhaust (a safe state), a stuck spool drives one valve alone.
  void step(double dt_s, double u_p_v, double u_n_v) noexcept;

  /// An external force on the carriage from now on, towards +y (a push; 0 by default) [N]: it adds
  /// to the pressure force against friction, for breakaway, sliding and sticking alike. The events
  /// still report the pressure force.
  void set_external_force_n(double force_n) noexcept { external_n_ = force_n; }
  [[nodiscard]] double external_force_n() const noexcept { return external_n_; }

  [[nodiscard]] const PlantState& state() const noexcept { return state_; }
  /// F = S_P p_P - S_N p_N - S_r p_E (Eq. 14) at the current state [N].
  [[nodiscard]] double pressure_force_n() const noexcept;
  /// Events located during the last call to step().
  [[nodiscard]] std::span<const PlantEvent> last_events() const noexcept {
    return {events_.data(), event_count_};
  }
  [[nodiscard]] std::uint64_t events_dropped() const noexcept { return events_dropped_; }
  /// The sliding carriage's step at the stiffest state: min(max_step_s, 2.5 / |lambda_max|),
  /// lambda_max the fastest pressure eigenvalue (smallest chamber volume, valve wide open, laminar
  /// slope), so explicit RK4 (stable for h |lambda| < 2.78) is stable anywhere in the stroke. Each
  /// step() takes equal sub-steps of at most max_step_s (max_stuck_step_s while stuck) and at most
  /// 2.5 / lambda of that step's openings and volumes, never shorter than 2.5 / |lambda_max|.
  [[nodiscard]] double step_size_s() const noexcept { return std::min(params_.max_step_s, stable_step_s_); }
  /// Number of right-hand-side evaluations since construction (for benchmarks).
  [[nodiscard]] std::uint64_t rhs_evaluations() const noexcept { return rhs_evaluations_; }

  [[nodiscard]] const model::PlantParams& params() const noexcept { return params_; }
  [[nodiscard]] const model::ValveModel& valve() const noexcept { return valve_; }
  /// The chambers' gas process: polytropic, or the energy balance with plant.thermal.
  [[nodiscard]] const model::ChamberProcess& process() const noexcept { return process_; }
  /// Friction force in the current sliding mode at velocity v [N] (docs/model.md section 4).
  [[nodiscard]] double sliding_friction_n(Motion motion, double v_m_per_s) const noexcept;

 private:
  using Vec = Eigen::Matrix<double, 6, 1>;  // (y, v, p_P, p_N, T_P, T_N)

  /// The two valve voltages commanded over a step [V], and where the spools start from.
  struct Drive {
    double u_p_v;
    double u_n_v;
    double from_p_v;
    double from_n_v;
  };
  /// The voltages the valves' openings correspond to `dt_s` into a step (the spools on their way).
  struct Voltages {
    double w_p_v;
    double w_n_v;
  };
  [[nodiscard]] Voltages voltages_at(const Drive& d, double dt_s) const noexcept;

  [[nodiscard]] Vec derivative(const Vec& x, Motion motion, Voltages w) const noexcept;
  [[nodiscard]] Vec rk4(const Vec& x, double h, Motion motion, const Drive& u) const noexcept;
  [[nodiscard]] Vec rk4_held(const Vec& x, double h, Voltages w) const noexcept;
  [[nodiscard]] double force_of(const Vec& x) const noexcept;
  /// What friction opposes: the pressure force and the external one [N].
  [[nodiscard]] double driving_force_of(const Vec& x) const noexcept { return force_of(x) + external_n_; }
  /// The sub-step of a step of dt_s towards the valve voltages w: the mode's largest step, or less
  /// where the step's fastest pressure mode needs it (2.5 / lambda), never below 2.5 / |lambda_max|.
  [[nodiscard]] double sub_step_s(double dt_s, double w_p_v, double w_n_v) const noexcept;
  void advance(double h, Drive u) noexcept;
  void record(PlantEvent::Kind kind, int direction) noexcept;
  void settle_mode_at_rest() noexcept;

  model::PlantParams params_;
  model::ValveModel valve_;
  model::PressureForce force_;
  model::ChamberProcess process_;
  model::SpoolLag spool_;
  double area_p_m2_, area_n_m2_, half_stroke_m_, k_r_t_;
  double piston_index_;                     // k of the piston's term k S v / V (adiabatic: plant.thermal)
  double stable_step_s_;                    // 2.5 / |lambda_max|: stable in any state
  double pressure_rate_per_opening_ = 0.0;  // a chamber's lambda per unit of opening / volume
  double wall_rate_per_s_ = 0.0;            // the wall's heat exchange at its fastest (plant.thermal)
  PlantState state_;
  double external_n_ = 0.0;
  std::array<PlantEvent, kMaxEventsPerStep> events_{};
  std::size_t event_count_ = 0;
  std::uint64_t events_dropped_ = 0;
  mutable std::uint64_t rhs_evaluations_ = 0;
};

/// The sum of the pushes acting at `t_s` (each from its t_s, for its duration) [N].
[[nodiscard]] double push_force_n(std::span<const model::Push> pushes, double t_s) noexcept;
/// The first time after `t_s` at which a push starts or ends; +infinity when none.
[[nodiscard]] double next_push_change_s(std::span<const model::Push> pushes, double t_s) noexcept;

/// Steps `plant` to `t_end_s` with the valves held (P at `u_p_v`, N at `u_n_v`), in pieces at each
/// push's start and end, each piece under the pushes acting at its start (one piece without
/// pushes: Plant::step itself). `on_events(plant.last_events())` after each piece. Real-time safe.
template <typename OnEvents>
void step_with_pushes(Plant& plant, double t_end_s, double u_p_v, double u_n_v, std::span<const model::Push> pushes,
                      OnEvents&& on_events) noexcept {
  for (double t = plant.state().t_s; t_end_s - t > 0.0; t = plant.state().t_s) {
    const double until = std::min(t_end_s, next_push_change_s(pushes, t));
    plant.set_external_force_n(push_force_n(pushes, t));
    plant.step(until - t, u_p_v, u_n_v);
    on_events(plant.last_events());
    if (until == t_end_s) break;
  }
}

}  // namespace pneu::plant
