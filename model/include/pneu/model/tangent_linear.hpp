// The tangent-linear model of the bench and the design of the gains of Eq. 4 on it
// (docs/model.md, "The tangent-linear model and the design of the gains"): the 4th-order
// linearisation of Eq. 2 around a complete equilibrium at a position, its classical third-order
// reduction (b, k_s), pole placement on the third-order model, and the closed-loop poles of given
// gains on the continuous 4th-order model and on the sampled loop as pneud runs it.
// Start-up and tool code: these functions allocate and throw (GainDesignError); none of them runs
// on the loop thread.
#pragma once

#include <array>
#include <complex>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "pneu/model/params.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::model {

/// The gains of Eq. 4, u = K_y (y_d - y) - K_v v_hat - K_a a_hat + u_0.
struct LawGains {
  double position_gain_v_per_m = 0.0;         ///< K_y [V/m]
  double velocity_gain_v_s_per_m = 0.0;       ///< K_v [V/(m/s)]
  double acceleration_gain_v_s2_per_m = 0.0;  ///< K_a [V/(m/s^2)]
};

/// The requested closed-loop dynamics: a real pole at s = -alpha and a damped pair of natural
/// frequency omega and damping zeta, s = -zeta omega +- j omega sqrt(1 - zeta^2).
struct RequestedDynamics {
  double real_pole_1_per_s = 0.0;            ///< alpha [1/s], > 0
  double natural_frequency_rad_per_s = 0.0;  ///< omega [rad/s], > 0
  /// zeta [-]: > 0 for a stable pair (the configuration asks for that); the design itself takes
  /// any value, so that gains can be recovered from their own poles, unstable ones included.
  double damping = 0.0;
};

/// Largest gains the design may return (each > 0).
struct GainLimits {
  double max_position_gain_v_per_m = 1.0e4;
  double max_velocity_gain_v_s_per_m = 1.0e3;
  double max_acceleration_gain_v_s2_per_m = 10.0;
};

/// A design or a linearisation refused: `what()` names the gain or the quantity and why.
class GainDesignError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The classical third-order model in (y, v, F): M dv/dt = F - sigma v, dF/dt = b du - k_s v.
struct ThirdOrderModel {
  double mass_kg = 0.0;                 ///< M [kg]
  double viscous_n_s_per_m = 0.0;       ///< sigma [N s/m]
  double force_gain_n_per_v_s = 0.0;    ///< b: valve force gain [N/(V s)], > 0
  double stiffness_n_per_m = 0.0;       ///< k_s: air-spring stiffness [N/m]
};

/// The linearisation of Eq. 2 at a complete equilibrium at position y_e: state x = (dy, dv, dp_P,
/// dp_N), dx/dt = A x + B du (4th order); with the energy balance (plant.thermal) the chambers'
/// temperatures follow (dT_P, dT_N), with a spool lag the spools (dw_P, dw_N): 6th or 8th order.
struct TangentLinearModel {
  double position_m = 0.0;        ///< y_e [m]
  double voltage_v = 0.0;         ///< u_e = u_0 [V]
  double pressure_p_pa = 0.0;     ///< p_P^e = p_null(u_e) [Pa]
  double pressure_n_pa = 0.0;     ///< p_N^e = p_null(-u_e) [Pa]
  double volume_p_m3 = 0.0;       ///< V_P(y_e)
  double volume_n_m3 = 0.0;       ///< V_N(y_e)
  double dq_dw_p = 0.0;           ///< q_w,P = dq/dw at (u_e, p_P^e) [kg/(s V)]
  double dq_dw_n = 0.0;           ///< q_w,N = dq/dw at (-u_e, p_N^e) [kg/(s V)]
  double dq_dp_p = 0.0;           ///< q_p,P = dq/dp at (u_e, p_P^e) [kg/(s Pa)]
  double dq_dp_n = 0.0;           ///< q_p,N = dq/dp at (-u_e, p_N^e) [kg/(s Pa)]
  std::vector<std::vector<double>> a;  ///< A, row-major, states() x states()
  std::vector<double> b;               ///< B
  ThirdOrderModel third_order;         ///< with the q_p terms dropped (the spools settled)

  [[nodiscard]] std::size_t states() const noexcept { return b.size(); }
  /// The exact acceleration dv/dt as a row over the state (it does not depend on du).
  [[nodiscard]] const std::vector<double>& acceleration_row() const noexcept { return a[1]; }
};

/// Step of the central difference that gives q_w = dq/dw from the valve characteristic [V].
inline constexpr double kValveVoltageStep_v = 1.0e-3;

/// The tangent-linear model at `position_m` around u_e = `voltage_v` (docs/model.md): p_null(+-u_e)
/// from the valve characteristic, q_p from its dq_dp(), q_w by a central difference of step
/// kValveVoltageStep_v. With the energy balance or a spool lag, every entry of A and B by central
/// differences of the chambers' equations (model::ChamberProcess) at the equilibrium (the chambers
/// at the wall temperature), and the third-order model's b = dF'/du and k_s = -dF'/dv from them,
/// F' the pressure force's rate with the spools settled. Throws GainDesignError when the valve
/// has no force gain there (b <= 0).
[[nodiscard]] TangentLinearModel tangent_linear_model(const PlantParams& plant, const ValveCharacteristic& valve,
                                                      double position_m, double voltage_v);

/// Eq. 4 on the third-order model with exact v and a: M s^3 + (b K_a + sigma) s^2 +
/// (b K_v + k_s) s + b K_y = 0, its roots placed at -alpha and the pair (omega, zeta):
///   K_y = M alpha omega^2 / b,  K_v = (M (omega^2 + 2 zeta omega alpha) - k_s) / b,
///   K_a = (M (alpha + 2 zeta omega) - sigma) / b.
/// Throws GainDesignError naming the gain when one would be negative (the plant's own stiffness
/// or friction already exceeds what the poles ask) or beyond its limit, or when alpha or omega is
/// not positive.
[[nodiscard]] LawGains place_poles(const ThirdOrderModel& model, const RequestedDynamics& poles,
                                   const GainLimits& limits);

/// The closed-loop poles of the continuous model under Eq. 4 with exact v and a (du = -K_y dy - K_v
/// dv - K_a dv/dt) [1/s], one per state.
[[nodiscard]] std::vector<std::complex<double>> continuous_poles(const TangentLinearModel& model,
                                                                 const LawGains& gains);

/// How pneud samples the loop.
struct SampledLoop {
  double period_s = 1.0e-3;   ///< T = 1 / controller.rate_hz
  double smoothing = 0.3;     ///< alpha of the differentiator's low-passes (controller.differentiator)
  /// Whole periods between the sample a control is computed from and the start of the interval it
  /// is held over, beyond the hold itself. 0: pneud on the sim backend (the position sampled at
  /// tick k drives the valves over [t_k, t_k+1)); a module on a bus adds its exchange's delay.
  int delay_samples = 0;
};

/// The closed-loop poles of the sampled loop [z]: the plant (its states() states, the spools' lag
/// among them) held over each period (zero-order hold, exact discretisation), pneud's
/// differentiator as coded (controller/differentiator.hpp: v_k = (1 - alpha) v_k-1 + alpha (y_k -
/// y_k-1) / T, a_k = (1 - alpha) a_k-1 + alpha (v_k - v_k-1) / T) and `delay_samples` periods of
/// delay. states() + 3 + delay_samples poles.
[[nodiscard]] std::vector<std::complex<double>> sampled_poles(const TangentLinearModel& model, const LawGains& gains,
                                                              const SampledLoop& loop);

/// max Re(s) of continuous poles; max |z| of sampled ones.
[[nodiscard]] double max_real_part(const std::vector<std::complex<double>>& poles) noexcept;
[[nodiscard]] double max_magnitude(const std::vector<std::complex<double>>& poles) noexcept;

/// A gain table over the stroke, designed at start-up and read on the loop thread: up to
/// kMaxNodes positions, equally spaced, with their gains, held in fixed storage (copying it never
/// allocates). gains_at() interpolates linearly in position between nodes and holds the end nodes'
/// gains beyond them. Real-time safe once built.
class GainSchedule {
 public:
  static constexpr std::size_t kMaxNodes = 256;

  GainSchedule() = default;
  /// Nodes at first_m + i spacing_m, i < count; throws GainDesignError when count is 0 or beyond
  /// kMaxNodes, or the spacing is not positive with more than one node.
  GainSchedule(double first_m, double spacing_m, const std::vector<LawGains>& gains);

  [[nodiscard]] bool empty() const noexcept { return count_ == 0; }
  [[nodiscard]] std::size_t size() const noexcept { return count_; }
  [[nodiscard]] double position_m(std::size_t i) const noexcept { return first_m_ + static_cast<double>(i) * spacing_m_; }
  [[nodiscard]] const LawGains& node(std::size_t i) const noexcept { return gains_[i]; }
  /// The gains at position y [m], interpolated, clamped to the end nodes. Real-time safe.
  [[nodiscard]] LawGains gains_at(double y_m) const noexcept;
  /// The same table with every gain multiplied by `factor` (a mistuned copy, for sweeps).
  [[nodiscard]] GainSchedule scaled(double factor) const noexcept {
    GainSchedule s = *this;
    for (std::size_t i = 0; i < count_; ++i) {
      s.gains_[i].position_gain_v_per_m *= factor;
      s.gains_[i].velocity_gain_v_s_per_m *= factor;
      s.gains_[i].acceleration_gain_v_s2_per_m *= factor;
    }
    return s;
  }

 private:
  double first_m_ = 0.0;
  double spacing_m_ = 0.0;
  std::size_t count_ = 0;
  std::array<LawGains, kMaxNodes> gains_{};
};

/// The positions of a table over the stroke, from -L/2 to +L/2 inclusive, equally spaced: the
/// number of intervals is L / `spacing_m` rounded (at least 1), so the spacing is about
/// `spacing_m`. Throws GainDesignError beyond GainSchedule::kMaxNodes nodes.
[[nodiscard]] std::vector<double> stroke_nodes_m(const Geometry& geometry, double spacing_m);

/// The gains placed at every node of the stroke (stroke_nodes_m) for `poles`, around u_0 =
/// `voltage_v`. Throws GainDesignError naming the node's position, the gain and the reason.
[[nodiscard]] GainSchedule design_schedule(const PlantParams& plant, const ValveCharacteristic& valve,
                                           double voltage_v, const RequestedDynamics& poles,
                                           const GainLimits& limits, double spacing_m);

/// Where a node's requested dynamics could not be had, what was placed instead.
struct DesignFallback {
  double position_m = 0.0;
  std::string reason;         ///< why not the requested dynamics there (a gain negative or beyond its
                              ///< limit, the sampled loop unstable)
  RequestedDynamics placed;   ///< the dynamics placed instead (on the third-order model)
  LawGains gains;             ///< their gains
  double max_abs_z = 0.0;     ///< the sampled loop's largest pole there, with them (< 1)
};

/// A table designed node by node, and where it fell back.
struct ScheduleDesign {
  GainSchedule schedule;
  std::vector<DesignFallback> fallbacks;
};

/// The gains of design_schedule() where the requested poles can be placed and the sampled loop
/// `loop` (the spool lag among the plant's states, its delay) is stable with them; elsewhere, node
/// by node, the nearest feasible dynamics: omega raised until K_v >= 0 (the air spring stiffer than
/// M omega^2 asks), alpha until K_a >= 0, then alpha and omega scaled together (down first: within
/// the gain limits, and slower for the sampled loop; then up) until the gains are within their
/// limits and the sampled loop is stable there; as a last resort the nearest designed node's gains
/// if the sampled loop is stable with them. Each fallback is reported. Throws GainDesignError
/// naming the node where nothing is stable. Without `loop`, no sampled loop is checked (the
/// placement's own refusals only).
[[nodiscard]] ScheduleDesign design_schedule_falling_back(const PlantParams& plant, const ValveCharacteristic& valve,
                                                          double voltage_v, const RequestedDynamics& poles,
                                                          const GainLimits& limits, double spacing_m,
                                                          const SampledLoop* loop);

/// The fallbacks of a design in a few lines for people: neighbouring nodes (`spacing_m` apart) that
/// fell back for the same reason as one range.
[[nodiscard]] std::string describe_fallbacks(const std::vector<DesignFallback>& fallbacks, double spacing_m);

/// Refuses (GainDesignError, naming the first position, its max |z| and the loop) a table whose
/// sampled loop (sampled_poles at each node, around u_0 = `voltage_v`) is not stable: poles placed
/// on the continuous model that the loop's period or differentiator cannot follow.
void require_sampled_stable(const PlantParams& plant, const ValveCharacteristic& valve, double voltage_v,
                            const GainSchedule& schedule, const SampledLoop& loop);

}  // namespace pneu::model
