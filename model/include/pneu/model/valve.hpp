// The servo-distributor's mass-flow characteristic q(w, p) (docs/model.md section 3), as a parametric
// model (ISO 6358 orifices) or as a measured table, behind one interface the predictor uses.
#pragma once

#include <algorithm>
#include <cmath>

#include "pneu/model/chamber.hpp"
#include "pneu/model/dual.hpp"
#include "pneu/model/params.hpp"

namespace pneu::model {

/// Pressure ratio above which the ISO 6358 flow function is replaced by its secant to x = 1
/// (laminar region). phi has an infinite slope at x -> 1; linearising keeps dq/dp finite.
inline constexpr double kLaminarPressureRatio = 0.999;

/// ISO 6358 flow function phi(x), x = p_down / p_up in [0, 1]; linear for x > kLaminarPressureRatio.
[[nodiscard]] double flow_function(double pressure_ratio, double critical_ratio) noexcept;
/// d phi / dx, consistent with flow_function().
[[nodiscard]] double flow_function_slope(double pressure_ratio, double critical_ratio) noexcept;

namespace detail {
// phi(x) below the laminar threshold.
template <class S>
S raw_flow_function(const S& x, double b) noexcept {
  using std::sqrt;
  if (x <= b) return S(1.0);
  const S s = (x - b) / (1.0 - b);
  const S r = 1.0 - s * s;
  return sqrt(0.0 < r ? r : S(0.0));  // std::max(0.0, r)
}
// flow_function() for a scalar S (a double, or a Dual with its derivatives): the one definition.
// Inlined into the orifice's flow, the innermost call of every integration of the chambers.
template <class S>
[[gnu::always_inline]] inline S phi(const S& ratio, double b) noexcept {
  const S x = ratio < 0.0 ? S(0.0) : 1.0 < ratio ? S(1.0) : ratio;  // std::clamp(x, 0.0, 1.0)
  if (x <= kLaminarPressureRatio) return raw_flow_function(x, b);
  const double at_threshold = raw_flow_function(kLaminarPressureRatio, b);
  return at_threshold * (1.0 - x) / (1.0 - kLaminarPressureRatio);
}
// d phi / d ratio, the derivative of phi() above, branch by branch (0 where phi clamps the ratio or is
// constant).
[[gnu::always_inline]] inline double phi_slope(double ratio, double b) noexcept {
  if (ratio < 0.0 || 1.0 < ratio || ratio <= b) return 0.0;
  if (ratio <= kLaminarPressureRatio) {
    const double s = (ratio - b) / (1.0 - b);
    const double r = 1.0 - s * s;
    return 0.0 < r ? -s / ((1.0 - b) * std::sqrt(r)) : 0.0;
  }
  return -raw_flow_function(kLaminarPressureRatio, b) / (1.0 - kLaminarPressureRatio);
}
// phi() of a Dual: its value phi()'s (bit for bit), its derivatives by the chain rule in one pass
// over the directions (the innermost call of the identification's derivatives).
template <int N>
[[gnu::always_inline]] inline Dual<N> phi(const Dual<N>& ratio, double b) noexcept {
  Dual<N> r(phi(ratio.v, b));
  const double slope = phi_slope(ratio.v, b);
  for (int i = 0; i < N; ++i) r.d[i] = slope * ratio.d[i];
  return r;
}
}  // namespace detail

/// One ISO 6358 orifice. Returns the mass flow from `p_a` to `p_b` [kg/s]: positive when
/// p_a > p_b, negative (reversed) when p_b > p_a, zero when equal.
/// m_dot = C rho_0 p_up sqrt(T_0 / T) phi(p_down / p_up).
struct Orifice {
  double critical_ratio;             ///< b [-]
  double reference_density_kg_per_m3;
  double temperature_factor;         ///< sqrt(T_0 / T) [-]

  [[nodiscard]] double mass_flow_kg_per_s(double conductance_m3_per_s_pa, double p_a_pa,
                                          double p_b_pa) const noexcept {
    return flow(conductance_m3_per_s_pa, p_a_pa, p_b_pa);
  }
  /// mass_flow_kg_per_s for scalars (doubles, or Duals with their derivatives; a constant pressure
  /// as a double).
  template <class C, class A, class B>
  [[nodiscard]] C flow(const C& c, const A& p_a, const B& p_b) const noexcept {
    if constexpr (kIsDual<C>) {  // the value the double's, bit for bit; the derivatives by the partial ones
      const Partials d = partials(value(c), value(p_a), value(p_b));
      C m(d.m_kg_per_s);
      add_scaled(m, d.by_c, c);
      add_scaled(m, d.by_a, p_a);
      add_scaled(m, d.by_b, p_b);
      return m;
    } else {
      if (p_a >= p_b) {
        return c * reference_density_kg_per_m3 * p_a * temperature_factor * detail::phi(p_b / p_a, critical_ratio);
      }
      return -c * reference_density_kg_per_m3 * p_b * temperature_factor * detail::phi(p_a / p_b, critical_ratio);
    }
  }
  /// The mass flow (mass_flow_kg_per_s's, bit for bit) with its partial derivatives by the
  /// conductance and by each pressure. With K = rho_0 sqrt(T_0 / T) and x the ratio, forward:
  /// dm/dC = K p_a phi, dm/dp_a = C K (phi - x phi'), dm/dp_b = C K phi'; reversed, mirrored.
  struct Partials {
    double m_kg_per_s, by_c, by_a, by_b;
  };
  [[nodiscard]] Partials partials(double c, double p_a, double p_b) const noexcept {
    const bool forward = p_a >= p_b;
    const double up = forward ? p_a : p_b, x = forward ? p_b / p_a : p_a / p_b;
    const double phi = detail::phi(x, critical_ratio), slope = detail::phi_slope(x, critical_ratio);
    const double k = (forward ? 1.0 : -1.0) * reference_density_kg_per_m3 * temperature_factor;
    const double by_up = c * k * (phi - x * slope), by_down = c * k * slope;
    return {flow(c, p_a, p_b), k * up * phi, forward ? by_up : by_down, forward ? by_down : by_up};
  }
  /// d m_dot / d p_b at fixed p_a [kg/(s Pa)] (<= 0).
  [[nodiscard]] double d_mass_flow_d_pb(double conductance_m3_per_s_pa, double p_a_pa,
                                        double p_b_pa) const noexcept;
  /// d m_dot / d p_a at fixed p_b [kg/(s Pa)] (>= 0).
  [[nodiscard]] double d_mass_flow_d_pa(double conductance_m3_per_s_pa, double p_a_pa,
                                        double p_b_pa) const noexcept;
};

/// A servo-distributor's static characteristic: the mass flow into a chamber at pressure p when the
/// valve is driven with voltage w. Implementations are immutable and real-time safe after
/// construction (no allocation, no throw).
class ValveCharacteristic {
 public:
  virtual ~ValveCharacteristic() = default;
  /// q(w, p): mass flow into the chamber [kg/s]; decreasing in p.
  [[nodiscard]] virtual double mass_flow_kg_per_s(double w_v, double p_pa) const noexcept = 0;
  /// dq/dp (w, p) [kg/(s Pa)], <= 0.
  [[nodiscard]] virtual double dq_dp(double w_v, double p_pa) const noexcept = 0;
  /// Pressure range over which the characteristic is defined [Pa] (p_E and p_S for the model).
  [[nodiscard]] virtual double min_pressure_pa() const noexcept = 0;
  [[nodiscard]] virtual double max_pressure_pa() const noexcept = 0;
  /// Voltage range [V].
  [[nodiscard]] virtual double min_voltage_v() const noexcept = 0;
  [[nodiscard]] virtual double max_voltage_v() const noexcept = 0;
  /// The voltages the spool's travel spans, fully open one way to fully open the other [V] (a
  /// command beyond them finds the spool at its stop): the voltage range, but for the model's null
  /// offset.
  [[nodiscard]] virtual double spool_min_v() const noexcept { return min_voltage_v(); }
  [[nodiscard]] virtual double spool_max_v() const noexcept { return max_voltage_v(); }

  /// Null-flow pressure p_null(w): q(w, p_null) = 0, the pressure gain characteristic (Fig. 6).
  /// Clamped to [min_pressure_pa, max_pressure_pa] when no root lies inside. Monotone in w.
  [[nodiscard]] double null_pressure_pa(double w_v) const noexcept;

  /// What the valve passes into a chamber at pressure p and temperature `chamber_k`, the supply and
  /// the exhaust at `supply_k` (the characteristic's own temperature, gas.temperature_k), each
  /// orifice's flow at its upstream temperature (docs/model.md section 2, with heat exchange). Here
  /// from q(w, p) alone (a measured table does not tell the two orifices apart): a net inflow comes
  /// from the supply; a net outflow leaves at the chamber's temperature, its mass flow scaled by
  /// sqrt(supply_k / chamber_k) as ISO 6358 scales an orifice's. At chamber_k = supply_k: q itself.
  [[nodiscard]] virtual ChamberInflow chamber_inflow(double w_v, double p_pa, double chamber_k,
                                                     double supply_k) const noexcept;
  /// p_null(w) of a chamber at `chamber_k`: the root of chamber_inflow's mass flow (the same as
  /// null_pressure_pa(w) at chamber_k = supply_k).
  [[nodiscard]] double null_pressure_pa(double w_v, double chamber_k, double supply_k) const noexcept;
};

/// The parametric model's equations (docs/model.md section 3) for a scalar S: at S = double they
/// are ValveModel's (which holds them), at S = Dual the same with the derivatives by the fitted
/// parameters (the identification's). Names as ValveCharacteristic's, for the chambers' templates.
template <class S>
struct ValveEquations {
  S max_conductance_m3_per_s_pa, leak_conductance_in_m3_per_s_pa, leak_conductance_out_m3_per_s_pa, null_offset_v;
  double max_voltage, p_supply_pa, p_exhaust_pa;
  Orifice orifice;

  ValveEquations(const ValveParams& valve, const Gas& gas) noexcept
      : max_conductance_m3_per_s_pa(valve.max_conductance_m3_per_s_pa),
        leak_conductance_in_m3_per_s_pa(valve.leak_conductance_in_m3_per_s_pa),
        leak_conductance_out_m3_per_s_pa(valve.leak_conductance_out_m3_per_s_pa),
        null_offset_v(valve.null_offset_v),
        max_voltage(valve.max_voltage_v),
        p_supply_pa(gas.supply_pressure_pa),
        p_exhaust_pa(gas.exhaust_pressure_pa),
        orifice{valve.critical_pressure_ratio, valve.reference_density_kg_per_m3,
                std::sqrt(valve.reference_temperature_k / gas.temperature_k)} {}

  // The opening is measured from the null offset w_0: w = w_0 closes both orifices to their leaks.
  [[nodiscard]] S inlet_conductance_m3_per_s_pa(const S& w) const noexcept {
    const S x = (w - null_offset_v) / max_voltage;
    return leak_conductance_in_m3_per_s_pa + max_conductance_m3_per_s_pa * (x < 0.0 ? S(0.0) : 1.0 < x ? S(1.0) : x);
  }
  [[nodiscard]] S outlet_conductance_m3_per_s_pa(const S& w) const noexcept {
    const S x = (null_offset_v - w) / max_voltage;
    return leak_conductance_out_m3_per_s_pa + max_conductance_m3_per_s_pa * (x < 0.0 ? S(0.0) : 1.0 < x ? S(1.0) : x);
  }
  /// Both orifices' conductances at a command w: what an integration that holds w computes once.
  struct Opening {
    S inlet_m3_per_s_pa, outlet_m3_per_s_pa;
  };
  [[nodiscard]] Opening opening(const S& w) const noexcept {
    return {inlet_conductance_m3_per_s_pa(w), outlet_conductance_m3_per_s_pa(w)};
  }
  /// q at the opening `o` (mass_flow_kg_per_s(w, p) at o = opening(w), bit for bit).
  [[nodiscard]] S mass_flow_kg_per_s(const Opening& o, const S& p) const noexcept {
    return orifice.flow(o.inlet_m3_per_s_pa, p_supply_pa, p) - orifice.flow(o.outlet_m3_per_s_pa, p, p_exhaust_pa);
  }
  [[nodiscard]] S mass_flow_kg_per_s(const S& w, const S& p) const noexcept { return mass_flow_kg_per_s(opening(w), p); }
  /// dq/dp at the values (for step sizes: no derivatives) [kg/(s Pa)].
  [[nodiscard]] double dq_dp(const S& w, const S& p) const noexcept {
    return orifice.d_mass_flow_d_pb(value(inlet_conductance_m3_per_s_pa(w)), p_supply_pa, value(p)) -
           orifice.d_mass_flow_d_pa(value(outlet_conductance_m3_per_s_pa(w)), value(p), p_exhaust_pa);
  }
  [[nodiscard]] BasicChamberInflow<S> chamber_inflow(const S& w, const S& p, const S& chamber_k,
                                                     double supply_k) const noexcept {
    if constexpr (!kIsDual<S>) {
      return inflow_at(inlet_conductance_m3_per_s_pa(w), outlet_conductance_m3_per_s_pa(w), p, chamber_k, supply_k);
    } else {
      // The values the doubles' (bit for bit); each output's derivatives from its partial ones by
      // the inputs that carry them (the conductances' parameters, w, p, the chamber's temperature),
      // one pass over the directions per input.
      const double wv = value(w), pv = value(p), tv = value(chamber_k), null_v = value(null_offset_v);
      const double max_c = value(max_conductance_m3_per_s_pa);
      // The openings' clamp((+-(w - w_0)) / u_max, 0, 1) and whether they pass derivatives (as the
      // Dual's clamp: at a corner, the side the value stands on).
      const double x_in = (wv - null_v) / max_voltage, x_out = (null_v - wv) / max_voltage;
      const double open_in = x_in < 0.0 ? 0.0 : 1.0 < x_in ? 1.0 : x_in;
      const double open_out = x_out < 0.0 ? 0.0 : 1.0 < x_out ? 1.0 : x_out;
      const double slope_in = x_in < 0.0 || 1.0 < x_in ? 0.0 : max_c / max_voltage;
      const double slope_out = x_out < 0.0 || 1.0 < x_out ? 0.0 : max_c / max_voltage;
      const double c_in = value(leak_conductance_in_m3_per_s_pa) + max_c * open_in;
      const double c_out = value(leak_conductance_out_m3_per_s_pa) + max_c * open_out;
      const ChamberInflow v = inflow_at(c_in, c_out, pv, tv, supply_k);
      const Orifice::Partials in = orifice.partials(c_in, p_supply_pa, pv);
      const Orifice::Partials out = orifice.partials(c_out, pv, p_exhaust_pa);
      // Each flow as it enters the balance, and its enthalpy, by the orifice's raw flow (a) and by
      // the chamber's temperature (b): the outflow at the chamber's temperature, sqrt(T_s / T).
      const double to_chamber = std::sqrt(supply_k / tv), to_chamber_by_t = -0.5 * to_chamber / tv;
      double a_in = 1.0, b_in = 0.0, ah_in = supply_k, bh_in = 0.0;
      if (!(in.m_kg_per_s >= 0.0)) {
        const double flow_in = in.m_kg_per_s * to_chamber;
        a_in = to_chamber;
        b_in = in.m_kg_per_s * to_chamber_by_t;
        ah_in = tv * a_in;
        bh_in = tv * b_in + flow_in;
      }
      double a_out = 1.0, b_out = 0.0, ah_out = supply_k, bh_out = 0.0;
      if (out.m_kg_per_s >= 0.0) {
        const double flow_out = out.m_kg_per_s * to_chamber;
        a_out = to_chamber;
        b_out = out.m_kg_per_s * to_chamber_by_t;
        ah_out = tv * a_out;
        bh_out = tv * b_out + flow_out;
      }
      BasicChamberInflow<S> r{S(v.mass_kg_per_s), S(v.enthalpy_k_kg_per_s)};
      // d(raw in) = in.by_c dC_in + in.by_b dp, dC_in = dC_leak_in + open_in dC_max + slope_in (dw - dw_0);
      // d(raw out) = out.by_c dC_out + out.by_a dp, dC_out = dC_leak_out + open_out dC_max + slope_out (dw_0 - dw).
      const auto add = [&](S& x, double a, double a_o, double b, double b_o) {
        const double k_in = a * in.by_c, k_out = a_o * out.by_c;
        add_scaled(x, k_in, leak_conductance_in_m3_per_s_pa);
        add_scaled(x, -k_out, leak_conductance_out_m3_per_s_pa);
        add_scaled(x, k_in * open_in - k_out * open_out, max_conductance_m3_per_s_pa);
        add_scaled(x, k_in * slope_in + k_out * slope_out, w);
        add_scaled(x, -(k_in * slope_in + k_out * slope_out), null_offset_v);
        add_scaled(x, a * in.by_b - a_o * out.by_a, p);
        add_scaled(x, b - b_o, chamber_k);
      };
      add(r.mass_kg_per_s, a_in, a_out, b_in, b_out);
      add(r.enthalpy_k_kg_per_s, ah_in, ah_out, bh_in, bh_out);
      return r;
    }
  }
  /// w_0 -+ u_max.
  [[nodiscard]] S spool_min_v() const noexcept { return null_offset_v - max_voltage; }
  [[nodiscard]] S spool_max_v() const noexcept { return null_offset_v + max_voltage; }

 private:
  // ISO 6358 scales an orifice's flow by sqrt(T_0 / T_up); the orifice's own factor is the supply's.
  template <class T>
  [[nodiscard]] BasicChamberInflow<T> inflow_at(const T& c_in, const T& c_out, const T& p, const T& chamber_k,
                                                double supply_k) const noexcept {
    using std::sqrt;
    const T to_chamber = sqrt(supply_k / chamber_k);  // an orifice fed by the chamber
    T in = orifice.flow(c_in, p_supply_pa, p);
    T out = orifice.flow(c_out, p, p_exhaust_pa);
    T enthalpy(0.0);
    if (in >= 0.0) {
      enthalpy += in * supply_k;
    } else {
      in *= to_chamber;
      enthalpy += in * chamber_k;
    }
    if (out >= 0.0) {
      out *= to_chamber;
      enthalpy -= out * chamber_k;
    } else {
      enthalpy -= out * supply_k;  // drawn in from the exhaust side
    }
    return {in - out, enthalpy};
  }
};

/// The parametric model of docs/model.md section 3:
///   C_in(w)  = C_leak_in  + C_max clamp( w / u_max, 0, 1)
///   C_out(w) = C_leak_out + C_max clamp(-w / u_max, 0, 1)
///   q(w, p)  = m_dot(C_in(w), p_S, p) - m_dot(C_out(w), p, p_E)
class ValveModel final : public ValveCharacteristic {
 public:
  ValveModel(const ValveParams& valve, const Gas& gas) noexcept;

  // (Inline: the innermost calls of the plant's and the identification's integrations.)
  [[nodiscard]] double mass_flow_kg_per_s(double w_v, double p_pa) const noexcept override {
    return eq_.mass_flow_kg_per_s(w_v, p_pa);
  }
  [[nodiscard]] double dq_dp(double w_v, double p_pa) const noexcept override { return eq_.dq_dp(w_v, p_pa); }
  /// Each orifice at its own upstream temperature: the supply -> chamber orifice at supply_k
  /// (chamber_k when reversed), the chamber -> exhaust one at chamber_k (supply_k when reversed).
  [[nodiscard]] ChamberInflow chamber_inflow(double w_v, double p_pa, double chamber_k,
                                             double supply_k) const noexcept override {
    return eq_.chamber_inflow(w_v, p_pa, chamber_k, supply_k);
  }
  [[nodiscard]] double min_pressure_pa() const noexcept override { return eq_.p_exhaust_pa; }
  [[nodiscard]] double max_pressure_pa() const noexcept override { return eq_.p_supply_pa; }
  [[nodiscard]] double min_voltage_v() const noexcept override { return -valve_.max_voltage_v; }
  [[nodiscard]] double max_voltage_v() const noexcept override { return valve_.max_voltage_v; }
  /// w_0 -+ u_max.
  [[nodiscard]] double spool_min_v() const noexcept override { return eq_.spool_min_v(); }
  [[nodiscard]] double spool_max_v() const noexcept override { return eq_.spool_max_v(); }

  [[nodiscard]] double inlet_conductance_m3_per_s_pa(double w_v) const noexcept {
    return eq_.inlet_conductance_m3_per_s_pa(w_v);
  }
  [[nodiscard]] double outlet_conductance_m3_per_s_pa(double w_v) const noexcept {
    return eq_.outlet_conductance_m3_per_s_pa(w_v);
  }
  [[nodiscard]] const Orifice& orifice() const noexcept { return eq_.orifice; }
  [[nodiscard]] const ValveEquations<double>& equations() const noexcept { return eq_; }

 private:
  ValveParams valve_;
  ValveEquations<double> eq_;
};

/// Force gain characteristic: the pressure force (Eq. 14, PressureForce) at complete equilibrium
/// under voltage u, F_e(u) = S_P p_null(u) - S_N p_null(-u) - S_r p_E [N]. Increasing in u.
[[nodiscard]] double equilibrium_force_n(const ValveCharacteristic& valve, const Geometry& geometry,
                                         double exhaust_pressure_pa, double u_v) noexcept;

/// u_e of Eq. 7: the voltage whose equilibrium force is zero (no dry friction),
/// S_P p_null(u_e) - S_N p_null(-u_e) = S_r p_E [V].
[[nodiscard]] double equilibrium_voltage_v(const ValveCharacteristic& valve, const Geometry& geometry,
                                           double exhaust_pressure_pa) noexcept;

/// The same two for a model's chambers (ChamberProcess) at rest at y, each where it settles
/// (ChamberProcess::rest): the two above but for walls at another temperature than the supply's,
/// where the rest temperatures, and so these, depend a little on y.
[[nodiscard]] double equilibrium_force_n(const ValveCharacteristic& valve, const ChamberProcess& process, double u_v,
                                         double y_m) noexcept;
[[nodiscard]] double equilibrium_voltage_v(const ValveCharacteristic& valve, const ChamberProcess& process,
                                           double y_m) noexcept;

}  // namespace pneu::model
