#include "pneu/model/tangent_linear.hpp"

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>
#include <algorithm>
#include <cmath>
#include <string>
#include <cstdio>

#include "pneu/model/chamber.hpp"

namespace pneu::model {

namespace {

std::string num(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

Eigen::MatrixXd a_matrix(const TangentLinearModel& m) {
  const auto n = static_cast<Eigen::Index>(m.states());
  Eigen::MatrixXd a(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) a(i, j) = m.a[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
  return a;
}

Eigen::VectorXd b_vector(const TangentLinearModel& m) {
  return Eigen::Map<const Eigen::VectorXd>(m.b.data(), static_cast<Eigen::Index>(m.states()));
}

// The state feedback of Eq. 4 with exact v and a: du = -k x.
Eigen::RowVectorXd feedback_row(const TangentLinearModel& m, const LawGains& g) {
  const auto n = static_cast<Eigen::Index>(m.states());
  Eigen::RowVectorXd k = Eigen::RowVectorXd::Zero(n);
  k(0) = g.position_gain_v_per_m;
  k(1) = g.velocity_gain_v_s_per_m;
  const auto& acc = m.acceleration_row();
  for (Eigen::Index j = 0; j < n; ++j) k(j) += g.acceleration_gain_v_s2_per_m * acc[static_cast<std::size_t>(j)];
  return k;
}

// Balances `m` by a diagonal similarity (Parlett and Reinsch, powers of 2: exact), so that the
// eigenvalues of a badly scaled matrix (pressures in Pa beside positions in m, 1/T^2 beside 1)
// come out to the precision of the well-scaled one. Eigen's EigenSolver does not balance.
Eigen::MatrixXd balanced(Eigen::MatrixXd m) {
  const Eigen::Index n = m.rows();
  for (int sweep = 0; sweep < 100; ++sweep) {
    bool done = true;
    for (Eigen::Index i = 0; i < n; ++i) {
      double c = 0.0, r = 0.0;  // off-diagonal 1-norms of column and row i
      for (Eigen::Index j = 0; j < n; ++j)
        if (j != i) {
          c += std::abs(m(j, i));
          r += std::abs(m(i, j));
        }
      if (!(c > 0.0) || !(r > 0.0) || !std::isfinite(c + r)) continue;
      const double sum = c + r;
      double f = 1.0;
      for (double g = r / 2.0; c < g; c *= 4.0) f *= 2.0;
      for (double g = r * 2.0; c > g; c /= 4.0) f /= 2.0;
      if ((c + r) / f < 0.95 * sum) {
        done = false;
        m.row(i) /= f;
        m.col(i) *= f;
      }
    }
    if (done) break;
  }
  return m;
}

std::vector<std::complex<double>> eigenvalues(const Eigen::MatrixXd& m) {
  Eigen::EigenSolver<Eigen::MatrixXd> solver(balanced(m), false);
  std::vector<std::complex<double>> out;
  for (Eigen::Index i = 0; i < solver.eigenvalues().size(); ++i) out.push_back(solver.eigenvalues()(i));
  std::sort(out.begin(), out.end(), [](auto x, auto y) {
    return x.real() != y.real() ? x.real() > y.real() : x.imag() > y.imag();
  });
  return out;
}

}  // namespace

namespace {

// With the energy balance or a spool lag: every entry of A and B by central differences of the
// chambers' own equations (ChamberProcess) and the mechanics (sliding, dry friction left out), at
// the equilibrium with the chambers where they settle (ChamberProcess::rest). State (y, v, p_P,
// p_N[, T_P, T_N][, w_P, w_N]).
void linearise_with_hidden_state(const PlantParams& plant, const ValveCharacteristic& valve, TangentLinearModel& m) {
  const ChamberProcess process(plant);
  const bool thermal = plant.has_thermal;
  const double lag = plant.valve.spool_time_constant_s;
  const std::size_t n = 4 + (thermal ? 2 : 0) + (lag > 0.0 ? 2 : 0);
  const std::size_t it = 4, iw = thermal ? 6 : 4;
  const double s_p = plant.geometry.area_p_m2(), s_n = plant.geometry.area_n_m2();
  const double mass = plant.mass_kg, sigma = plant.friction.viscous_n_s_per_m;
  const double rest_p_k = process.rest(valve, Side::kP, m.voltage_v, m.position_m).t_k;
  const double rest_n_k = process.rest(valve, Side::kN, -m.voltage_v, m.position_m).t_k;
  // d/dt of the state x under control u.
  const auto rate = [&](const std::vector<double>& x, double u) {
    std::vector<double> dx(n, 0.0);
    const double y = x[0], v = x[1];
    const double t_p = thermal ? x[it] : rest_p_k, t_n = thermal ? x[it + 1] : rest_n_k;
    const double w_p = lag > 0.0 ? x[iw] : u, w_n = lag > 0.0 ? x[iw + 1] : -u;
    const ChamberRates rp = process.rates(valve, Side::kP, x[2], t_p, w_p, y, v);
    const ChamberRates rn = process.rates(valve, Side::kN, x[3], t_n, w_n, y, v);
    dx[0] = v;
    dx[1] = (s_p * x[2] - s_n * x[3] - plant.geometry.area_rod_m2() * plant.gas.exhaust_pressure_pa - sigma * v) / mass;
    dx[2] = rp.dp_dt_pa_per_s;
    dx[3] = rn.dp_dt_pa_per_s;
    if (thermal) dx[it] = rp.dtemperature_dt_k_per_s, dx[it + 1] = rn.dtemperature_dt_k_per_s;
    if (lag > 0.0) dx[iw] = (u - x[iw]) / lag, dx[iw + 1] = (-u - x[iw + 1]) / lag;
    return dx;
  };
  std::vector<double> x0(n, 0.0);
  x0[0] = m.position_m;
  x0[2] = m.pressure_p_pa;
  x0[3] = m.pressure_n_pa;
  if (thermal) x0[it] = rest_p_k, x0[it + 1] = rest_n_k;
  if (lag > 0.0) x0[iw] = m.voltage_v, x0[iw + 1] = -m.voltage_v;
  // Steps: a micrometre, a micrometre per second, a pascal, a millikelvin, the valves' voltage step.
  const auto step = [&](std::size_t j) {
    return j == 0 ? 1e-6 : j == 1 ? 1e-6 : j < 4 ? 1.0 : (thermal && j < 6) ? 1e-3 : kValveVoltageStep_v;
  };
  m.a.assign(n, std::vector<double>(n, 0.0));
  for (std::size_t j = 0; j < n; ++j) {
    std::vector<double> up = x0, down = x0;
    up[j] += step(j);
    down[j] -= step(j);
    const std::vector<double> fu = rate(up, m.voltage_v), fd = rate(down, m.voltage_v);
    for (std::size_t i = 0; i < n; ++i) m.a[i][j] = (fu[i] - fd[i]) / (2.0 * step(j));
  }
  const double du = kValveVoltageStep_v;
  const std::vector<double> bu = rate(x0, m.voltage_v + du), bd = rate(x0, m.voltage_v - du);
  m.b.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) m.b[i] = (bu[i] - bd[i]) / (2.0 * du);
  // The third-order model: the force's rate F' = S_P p_P' - S_N p_N' against u (the spools
  // settled: w = +-u) and against v.
  const auto force_rate = [&](double u, double v) {
    std::vector<double> x = x0;
    x[1] = v;
    if (lag > 0.0) x[iw] = u, x[iw + 1] = -u;
    const std::vector<double> dx = rate(x, u);
    return s_p * dx[2] - s_n * dx[3];
  };
  m.third_order.force_gain_n_per_v_s = (force_rate(m.voltage_v + du, 0.0) - force_rate(m.voltage_v - du, 0.0)) / (2.0 * du);
  m.third_order.stiffness_n_per_m = -(force_rate(m.voltage_v, 1e-6) - force_rate(m.voltage_v, -1e-6)) / 2e-6;
}

}  // namespace

TangentLinearModel tangent_linear_model(const PlantParams& plant, const ValveCharacteristic& valve,
                                        double position_m, double voltage_v) {
  const Geometry& g = plant.geometry;
  TangentLinearModel m;
  m.position_m = position_m;
  m.voltage_v = voltage_v;
  const ChamberProcess process(plant);
  m.pressure_p_pa = process.rest(valve, Side::kP, voltage_v, position_m).p_pa;
  m.pressure_n_pa = process.rest(valve, Side::kN, -voltage_v, position_m).p_pa;
  m.volume_p_m3 = g.volume_p_m3(position_m);
  m.volume_n_m3 = g.volume_n_m3(position_m);
  const double h = kValveVoltageStep_v;
  const auto dq_dw = [&](double w, double p) {
    return (valve.mass_flow_kg_per_s(w + h, p) - valve.mass_flow_kg_per_s(w - h, p)) / (2.0 * h);
  };
  m.dq_dw_p = dq_dw(voltage_v, m.pressure_p_pa);
  m.dq_dw_n = dq_dw(-voltage_v, m.pressure_n_pa);
  m.dq_dp_p = valve.dq_dp(voltage_v, m.pressure_p_pa);
  m.dq_dp_n = valve.dq_dp(-voltage_v, m.pressure_n_pa);

  const double mass = plant.mass_kg, sigma = plant.friction.viscous_n_s_per_m;
  m.third_order.mass_kg = mass;
  m.third_order.viscous_n_s_per_m = sigma;
  if (plant.has_thermal || plant.valve.spool_time_constant_s > 0.0) {
    linearise_with_hidden_state(plant, valve, m);
  } else {
    // Eq. 2 linearised (docs/model.md): valve N sees w = -u, so its flow changes by -q_w,N du.
    const double c = plant.gas.k_r_t();
    const double k = plant.gas.polytropic_index;
    const double s_p = g.area_p_m2(), s_n = g.area_n_m2();
    const double v_p = m.volume_p_m3, v_n = m.volume_n_m3;
    m.a = {{0.0, 1.0, 0.0, 0.0},
           {0.0, -sigma / mass, s_p / mass, -s_n / mass},
           {0.0, -k * m.pressure_p_pa * s_p / v_p, c / v_p * m.dq_dp_p, 0.0},
           {0.0, k * m.pressure_n_pa * s_n / v_n, 0.0, c / v_n * m.dq_dp_n}};
    m.b = {0.0, 0.0, c / v_p * m.dq_dw_p, -c / v_n * m.dq_dw_n};
    m.third_order.force_gain_n_per_v_s = c * (s_p * m.dq_dw_p / v_p + s_n * m.dq_dw_n / v_n);
    m.third_order.stiffness_n_per_m = k * (s_p * s_p * m.pressure_p_pa / v_p + s_n * s_n * m.pressure_n_pa / v_n);
  }
  if (!(m.third_order.force_gain_n_per_v_s > 0.0))
    throw GainDesignError("at y = " + num(position_m) + " m the valves have no force gain b (" +
                          num(m.third_order.force_gain_n_per_v_s) + " N/(V s)) around u_0 = " + num(voltage_v) +
                          " V: no gain can place the poles there");
  return m;
}

LawGains place_poles(const ThirdOrderModel& m, const RequestedDynamics& p, const GainLimits& limits) {
  if (!(p.real_pole_1_per_s > 0.0))
    throw GainDesignError("real pole alpha must be > 0 1/s (got " + num(p.real_pole_1_per_s) + ")");
  if (!(p.natural_frequency_rad_per_s > 0.0))
    throw GainDesignError("natural frequency omega must be > 0 rad/s (got " + num(p.natural_frequency_rad_per_s) + ")");
  if (!std::isfinite(p.damping)) throw GainDesignError("damping zeta must be a number (got " + num(p.damping) + ")");
  if (!(m.force_gain_n_per_v_s > 0.0))
    throw GainDesignError("the plant has no force gain b (" + num(m.force_gain_n_per_v_s) + " N/(V s))");
  const double alpha = p.real_pole_1_per_s, w = p.natural_frequency_rad_per_s, z = p.damping;
  const double b = m.force_gain_n_per_v_s, mass = m.mass_kg;
  LawGains g;
  g.position_gain_v_per_m = mass * alpha * w * w / b;
  g.velocity_gain_v_s_per_m = (mass * (w * w + 2.0 * z * w * alpha) - m.stiffness_n_per_m) / b;
  g.acceleration_gain_v_s2_per_m = (mass * (alpha + 2.0 * z * w) - m.viscous_n_s_per_m) / b;
  if (g.velocity_gain_v_s_per_m < 0.0)
    throw GainDesignError("K_v would be negative (" + num(g.velocity_gain_v_s_per_m) +
                          " V/(m/s)): the air spring alone (k_s = " + num(m.stiffness_n_per_m) +
                          " N/m) is stiffer than M (omega^2 + 2 zeta omega alpha) = " +
                          num(mass * (w * w + 2.0 * z * w * alpha)) + " N/m; ask for faster poles");
  if (g.acceleration_gain_v_s2_per_m < 0.0)
    throw GainDesignError("K_a would be negative (" + num(g.acceleration_gain_v_s2_per_m) +
                          " V/(m/s^2)): the viscous friction alone (sigma = " + num(m.viscous_n_s_per_m) +
                          " N s/m) damps more than M (alpha + 2 zeta omega) = " +
                          num(mass * (alpha + 2.0 * z * w)) + " N s/m; ask for faster poles");
  if (g.position_gain_v_per_m > limits.max_position_gain_v_per_m)
    throw GainDesignError("K_y = " + num(g.position_gain_v_per_m) + " V/m is beyond its limit " +
                          num(limits.max_position_gain_v_per_m) + " V/m");
  if (g.velocity_gain_v_s_per_m > limits.max_velocity_gain_v_s_per_m)
    throw GainDesignError("K_v = " + num(g.velocity_gain_v_s_per_m) + " V/(m/s) is beyond its limit " +
                          num(limits.max_velocity_gain_v_s_per_m) + " V/(m/s)");
  if (g.acceleration_gain_v_s2_per_m > limits.max_acceleration_gain_v_s2_per_m)
    throw GainDesignError("K_a = " + num(g.acceleration_gain_v_s2_per_m) + " V/(m/s^2) is beyond its limit " +
                          num(limits.max_acceleration_gain_v_s2_per_m) + " V/(m/s^2)");
  return g;
}

std::vector<std::complex<double>> continuous_poles(const TangentLinearModel& m, const LawGains& g) {
  const Eigen::MatrixXd closed = a_matrix(m) - b_vector(m) * feedback_row(m, g);
  return eigenvalues(closed);
}

std::vector<std::complex<double>> sampled_poles(const TangentLinearModel& m, const LawGains& g,
                                                const SampledLoop& loop) {
  const double t = loop.period_s, alpha = loop.smoothing;
  const auto np = static_cast<int>(m.states());
  // Zero-order hold: exp([[A, B], [0, 0]] T) = [[Ad, Bd], [0, 1]].
  Eigen::MatrixXd aug = Eigen::MatrixXd::Zero(np + 1, np + 1);
  aug.topLeftCorner(np, np) = a_matrix(m) * t;
  aug.topRightCorner(np, 1) = b_vector(m) * t;
  const Eigen::MatrixXd e = aug.exp();
  const Eigen::MatrixXd ad = e.topLeftCorner(np, np);
  const Eigen::VectorXd bd = e.topRightCorner(np, 1);

  // State at tick k, before its update: plant x_k (np), the differentiator's y_k-1, v_k-1, a_k-1,
  // then the controls still to be applied u_k-d .. u_k-1 (oldest first).
  const int d = std::max(0, loop.delay_samples);
  const int n = np + 3 + d;
  const int iy = np, iv = np + 1, ia = np + 2, iu = np + 3;
  // This tick's outputs as rows over the state: y_k, v_k, a_k, u_k.
  Eigen::RowVectorXd y_k = Eigen::RowVectorXd::Zero(n);
  y_k(0) = 1.0;
  Eigen::RowVectorXd v_k = Eigen::RowVectorXd::Zero(n);
  v_k(iv) = 1.0 - alpha;
  v_k += alpha / t * y_k;
  v_k(iy) -= alpha / t;
  Eigen::RowVectorXd a_k = Eigen::RowVectorXd::Zero(n);
  a_k(ia) = 1.0 - alpha;
  a_k += alpha / t * v_k;
  a_k(iv) -= alpha / t;
  const Eigen::RowVectorXd u_k =
      -(g.position_gain_v_per_m * y_k + g.velocity_gain_v_s_per_m * v_k + g.acceleration_gain_v_s2_per_m * a_k);

  Eigen::MatrixXd phi = Eigen::MatrixXd::Zero(n, n);
  phi.topLeftCorner(np, np) = ad;
  // The control held over [t_k, t_k+1): u_k itself, or the oldest one waiting.
  if (d == 0) {
    phi.topRows(np) += bd * u_k;
  } else {
    phi.block(0, iu, np, 1) += bd;
    for (int i = 0; i + 1 < d; ++i) phi(iu + i, iu + i + 1) = 1.0;
    phi.row(iu + d - 1) = u_k;
  }
  phi.row(iy) = y_k;
  phi.row(iv) = v_k;
  phi.row(ia) = a_k;
  return eigenvalues(phi);
}

double max_real_part(const std::vector<std::complex<double>>& poles) noexcept {
  double r = -HUGE_VAL;
  for (const auto& p : poles) r = std::max(r, p.real());
  return r;
}

double max_magnitude(const std::vector<std::complex<double>>& poles) noexcept {
  double r = 0.0;
  for (const auto& p : poles) r = std::max(r, std::abs(p));
  return r;
}

GainSchedule::GainSchedule(double first_m, double spacing_m, const std::vector<LawGains>& gains)
    : first_m_(first_m), spacing_m_(spacing_m), count_(gains.size()) {
  if (gains.empty() || gains.size() > kMaxNodes)
    throw GainDesignError("a gain table holds 1 to " + std::to_string(kMaxNodes) + " nodes (got " +
                          std::to_string(gains.size()) + ")");
  if (gains.size() > 1 && !(spacing_m > 0.0))
    throw GainDesignError("the nodes' spacing must be > 0 m (got " + num(spacing_m) + ")");
  std::copy(gains.begin(), gains.end(), gains_.begin());
}

LawGains GainSchedule::gains_at(double y_m) const noexcept {
  if (count_ <= 1) return gains_[0];
  const double s = (y_m - first_m_) / spacing_m_;
  if (!(s > 0.0)) return gains_[0];  // below the first node, or NaN
  const auto last = count_ - 1;
  if (s >= static_cast<double>(last)) return gains_[last];
  const auto i = static_cast<std::size_t>(s);
  const double f = s - static_cast<double>(i);
  const LawGains& lo = gains_[i];
  const LawGains& hi = gains_[i + 1];
  return {lo.position_gain_v_per_m + f * (hi.position_gain_v_per_m - lo.position_gain_v_per_m),
          lo.velocity_gain_v_s_per_m + f * (hi.velocity_gain_v_s_per_m - lo.velocity_gain_v_s_per_m),
          lo.acceleration_gain_v_s2_per_m + f * (hi.acceleration_gain_v_s2_per_m - lo.acceleration_gain_v_s2_per_m)};
}

std::vector<double> stroke_nodes_m(const Geometry& geometry, double spacing_m) {
  if (!(spacing_m > 0.0)) throw GainDesignError("the nodes' spacing must be > 0 m (got " + num(spacing_m) + ")");
  const double length = geometry.stroke_m;
  const auto intervals = static_cast<std::size_t>(std::max(1.0, std::round(length / spacing_m)));
  if (intervals + 1 > GainSchedule::kMaxNodes)
    throw GainDesignError("a spacing of " + num(spacing_m) + " m makes " + std::to_string(intervals + 1) +
                          " nodes over the stroke, more than the table's " + std::to_string(GainSchedule::kMaxNodes));
  std::vector<double> nodes;
  for (std::size_t i = 0; i <= intervals; ++i)
    nodes.push_back(-geometry.half_stroke_m() + length * static_cast<double>(i) / static_cast<double>(intervals));
  return nodes;
}

GainSchedule design_schedule(const PlantParams& plant, const ValveCharacteristic& valve, double voltage_v,
                             const RequestedDynamics& poles, const GainLimits& limits, double spacing_m) {
  const std::vector<double> nodes = stroke_nodes_m(plant.geometry, spacing_m);
  std::vector<LawGains> gains;
  for (const double y : nodes) {
    const TangentLinearModel model = tangent_linear_model(plant, valve, y, voltage_v);
    try {
      gains.push_back(place_poles(model.third_order, poles, limits));
    } catch (const GainDesignError& e) {
      throw GainDesignError("at y = " + num(y) + " m: " + e.what());
    }
  }
  const double spacing = nodes.size() > 1 ? nodes[1] - nodes[0] : 0.0;
  return GainSchedule(nodes.front(), spacing, gains);
}

ScheduleDesign design_schedule_falling_back(const PlantParams& plant, const ValveCharacteristic& valve,
                                           double voltage_v, const RequestedDynamics& poles, const GainLimits& limits,
                                           double spacing_m, const SampledLoop* loop) {
  const std::vector<double> nodes = stroke_nodes_m(plant.geometry, spacing_m);
  std::vector<TangentLinearModel> models;
  for (const double y : nodes) models.push_back(tangent_linear_model(plant, valve, y, voltage_v));
  const auto stable = [&](const TangentLinearModel& m, const LawGains& g, double& z) {
    z = loop != nullptr ? max_magnitude(sampled_poles(m, g, *loop)) : 0.0;
    return z < 1.0;
  };
  std::vector<LawGains> gains(nodes.size());
  std::vector<bool> designed(nodes.size(), false);
  ScheduleDesign out;
  std::vector<std::size_t> pending;  // nodes without the requested dynamics
  std::vector<std::string> reasons(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    double z = 0.0;
    try {
      gains[i] = place_poles(models[i].third_order, poles, limits);
      if (stable(models[i], gains[i], z)) {
        designed[i] = true;
        continue;
      }
      reasons[i] = "the sampled loop is unstable (max |z| = " + num(z) + ")";
    } catch (const GainDesignError& e) {
      // (Its advice to ask for other poles is what the fallback does.)
      const std::string what = e.what();
      reasons[i] = what.substr(0, what.find("; ask for"));
    }
    pending.push_back(i);
  }
  for (const std::size_t i : pending) {
    const ThirdOrderModel& t = models[i].third_order;
    // The least omega and alpha the placement allows: K_v >= 0 and K_a >= 0 (a hair above).
    const double za = poles.damping * poles.real_pole_1_per_s;
    const double omega_min = 1.001 * (-za + std::sqrt(za * za + std::max(0.0, t.stiffness_n_per_m) / t.mass_kg));
    RequestedDynamics base = poles;
    base.natural_frequency_rad_per_s = std::max(base.natural_frequency_rad_per_s, omega_min);
    const double alpha_min = 1.001 * (t.viscous_n_s_per_m / t.mass_kg - 2.0 * poles.damping * base.natural_frequency_rad_per_s);
    base.real_pole_1_per_s = std::max(base.real_pole_1_per_s, alpha_min);
    bool found = false;
    // Scaled together: down first (the gain limits, the sampled loop), then up.
    for (int k = 0; k <= 60 && !found; ++k) {
      const double scale = k <= 30 ? std::pow(0.93, k) : std::pow(1.07, k - 30);
      RequestedDynamics d = base;
      d.real_pole_1_per_s = std::max(base.real_pole_1_per_s * scale, alpha_min);
      d.natural_frequency_rad_per_s = std::max(base.natural_frequency_rad_per_s * scale, omega_min);
      LawGains g;
      try {
        g = place_poles(t, d, limits);
      } catch (const GainDesignError&) {
        continue;
      }
      double z = 0.0;
      if (!stable(models[i], g, z)) continue;
      gains[i] = g;
      out.fallbacks.push_back({nodes[i], reasons[i], d, g, z});
      found = true;
    }
    // The nearest designed node's gains, if the loop is stable with them here.
    for (std::size_t step = 1; step < nodes.size() && !found; ++step)
      for (const std::size_t j : {i >= step ? i - step : nodes.size(), i + step}) {
        double z = 0.0;
        if (j >= nodes.size() || !designed[j] || !stable(models[i], gains[j], z)) continue;
        gains[i] = gains[j];
        out.fallbacks.push_back({nodes[i], reasons[i] + "; no dynamics placed there is stable: the gains of y = " +
                                               num(nodes[j]) + " m",
                                 poles, gains[j], z});
        found = true;
        break;
      }
    if (!found)
      throw GainDesignError("at y = " + num(nodes[i]) + " m: " + reasons[i] +
                            ", and no feasible dynamics nor a neighbour's gains give a stable sampled loop there");
  }
  std::sort(out.fallbacks.begin(), out.fallbacks.end(),
            [](const DesignFallback& a, const DesignFallback& b) { return a.position_m < b.position_m; });
  const double spacing = nodes.size() > 1 ? nodes[1] - nodes[0] : 0.0;
  out.schedule = GainSchedule(nodes.front(), spacing, gains);
  return out;
}

std::string describe_fallbacks(const std::vector<DesignFallback>& fallbacks, double spacing_m) {
  std::string text;
  for (std::size_t i = 0; i < fallbacks.size();) {
    std::size_t j = i;  // the range of nodes with the same reason, next to each other
    const auto reason_kind = [](const std::string& r) { return r.substr(0, r.find('(')); };
    while (j + 1 < fallbacks.size() && reason_kind(fallbacks[j + 1].reason) == reason_kind(fallbacks[i].reason) &&
           fallbacks[j + 1].position_m - fallbacks[j].position_m < 1.5 * spacing_m)
      ++j;
    double z = 0.0;
    for (std::size_t k = i; k <= j; ++k) z = std::max(z, fallbacks[k].max_abs_z);
    const auto range = [&](double first, double last, const char* unit) {
      return num(first) + (num(last) != num(first) ? " to " + num(last) : std::string()) + unit;
    };
    char z_text[32] = "not checked";
    if (z > 0.0) std::snprintf(z_text, sizeof z_text, "%.5f", z);
    text += (text.empty() ? "" : "\n") + std::string("at y = ") +
            range(fallbacks[i].position_m, fallbacks[j].position_m, " m") + " (" + std::to_string(j - i + 1) + " node" +
            (j > i ? "s" : "") + "): " + fallbacks[i].reason + "; placed instead alpha " +
            range(fallbacks[i].placed.real_pole_1_per_s, fallbacks[j].placed.real_pole_1_per_s, " 1/s") + ", omega " +
            range(fallbacks[i].placed.natural_frequency_rad_per_s, fallbacks[j].placed.natural_frequency_rad_per_s,
                  " rad/s") +
            ", zeta " + num(fallbacks[i].placed.damping) + " (the sampled loop there: max |z| " + z_text + ")";
    i = j + 1;
  }
  return text;
}

void require_sampled_stable(const PlantParams& plant, const ValveCharacteristic& valve, double voltage_v,
                            const GainSchedule& schedule, const SampledLoop& loop) {
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    const double y = schedule.position_m(i);
    const double z = max_magnitude(sampled_poles(tangent_linear_model(plant, valve, y, voltage_v), schedule.node(i), loop));
    if (!(z < 1.0))
      throw GainDesignError("at y = " + num(y) + " m the sampled loop is unstable (max |z| = " + num(z) + " at T = " +
                            num(loop.period_s) + " s, differentiator smoothing " + num(loop.smoothing) +
                            "): ask for slower poles, or a higher loop rate");
  }
}

}  // namespace pneu::model
