#include "pneu/identify/identify.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

#include "phases.hpp"
#include "pneu/controller/run_listener.hpp"
#include "pneu/config/text.hpp"
#include "pneu/model/pressure_force.hpp"
#include "pneu/model/valve.hpp"
#include "valve_fit.hpp"

namespace pneu::identify {

namespace {

using detail::StuckPhase;

// The keys: those online identification publishes (run_listener.hpp), then the two taken as known.
constexpr std::size_t kPublished = controller::kIdentifiedParameterKeys.size();
constexpr std::array<const char*, kPublished + 2> kKeys = [] {
  std::array<const char*, kPublished + 2> k{};
  for (std::size_t i = 0; i < kPublished; ++i) k[i] = controller::kIdentifiedParameterKeys[i];
  k[kPublished] = "plant.friction.stribeck_velocity_m_per_s";
  k[kPublished + 1] = "plant.mass_kg";
  return k;
}();
// Where the valve fit's parameters lie in kKeys (and in Identification::estimates).
constexpr std::size_t kFirstValveFitKey = 5;

// A dated breakaway's weight is 1 / (how far the force had moved on + this)^2 [N].
constexpr double kOnsetWeightFloor_n = 0.05;

// A phase's first samples may still be the carriage sliding into the rest band.
constexpr double kSettleIntoPhase_s = 0.02;

// The breakaway's force brackets (Eq. 15): what one side of the stiction band is, from below and
// from above, and how many breakaways gave it.
struct Bracket {
  double lower = -std::numeric_limits<double>::infinity();  // the largest force surely held
  double upper = std::numeric_limits<double>::infinity();   // the smallest force surely moved
  int breakaways = 0;
  /// How far the force may have moved on between the breakaway and the first reading that
  /// showed it (the onset hidden in the rest band), at the breakaway that gave the bound from beyond [N].
  double onset_force = 0.0;
  /// The breakaways dated by the first moved reading (ideal sensors): F_S within each one's
  /// force at the breakaway -+ its allowance.
  struct Dated {
    double force_n, allowance_n;
  };
  std::vector<Dated> dated;
};

// The onset of a breakaway can hide within a rest band: with the force rising at `rate` past F_S,
// the carriage accelerates at about rate (t - t_b) / M (the Stribeck drop is quadratic in v), and
// covers `band` in (6 M band / rate)^(1/3). Longest at slow rates; capped at `cap`.
double onset_s(double mass_kg, double band_m, double rate_n_per_s, double cap_s) {
  if (band_m <= 0.0) return 0.0;
  if (rate_n_per_s <= 0.0) return cap_s;
  return std::min(cap_s, std::cbrt(6.0 * mass_kg * band_m / rate_n_per_s));
}

// The last sample of [first, k] at or before `dt` ahead of sample k's time.
std::size_t index_before(std::span<const Sample> s, std::size_t first, std::size_t k, double dt) {
  const double t = s[k].t_s - dt;
  while (k > first && s[k].t_s > t) --k;
  return k;
}

// Stiction from the stuck phases: for each side, every force held is a lower bound of |F_S|, every
// force at which the carriage was seen moving away an upper one.
struct Stiction {
  Bracket positive, negative;
  double force_noise_n = 0.0;
  double held_positive_n = 0.0, held_negative_n = 0.0;  // the forces held alone (Evidence)
};

// The last sample of a phase's still part that the valve fit takes: within a rest band, before the
// onset of the breakaway that ends it (or that the end of the record may hide) could have begun.
// In the last milliseconds before a slow breakaway shows, the carriage already moves within the
// band, and the chambers' volumes with it (10 um near the stroke's end changes a pressure by tens
// of pascals, which a fit of the valves takes for theirs). The onset hides for onset_s at the
// force's rate over the phase's last 50 ms (least squares): the breakaway's own, slow after a
// drift, fast after a set-point step.
std::size_t valve_fit_last(std::span<const Sample> s, std::span<const double> force, const StuckPhase& p,
                           double mass_kg, const Options& o) {
  if (o.rest_band_m <= 0.0) return p.still_last;  // an ideal sensor's still part is still
  const std::size_t from = index_before(s, p.first, p.last, 0.05);
  double n = 0.0, st = 0.0, sf = 0.0, stt = 0.0, stf = 0.0;
  for (std::size_t k = from; k <= p.last; ++k) {
    const double t = s[k].t_s - s[p.last].t_s;
    n += 1.0;
    st += t;
    sf += force[k];
    stt += t * t;
    stf += t * force[k];
  }
  const double den = n * stt - st * st;
  const double rate = den > 0.0 ? (n * stf - st * sf) / den : 0.0;
  const double onset = onset_s(mass_kg, o.rest_band_m, std::abs(rate), 0.2);
  return std::min(p.still_last, index_before(s, p.first, p.last, onset));
}

Stiction stiction_from(std::span<const Sample> s, std::span<const double> force, std::span<const StuckPhase> phases,
                       double mass_kg, const Options& o) {
  Stiction st;
  // The force's noise: second differences inside the stuck phases (the drift's slope cancels),
  // robustly (median absolute value; white noise of deviation s gives second differences of
  // deviation s sqrt(6)).
  std::vector<double> diffs;
  for (const StuckPhase& p : phases)
    for (std::size_t k = p.first + 1; k < p.last; ++k)
      diffs.push_back(std::abs(force[k + 1] - 2.0 * force[k] + force[k - 1]));
  if (!diffs.empty()) {
    std::nth_element(diffs.begin(), diffs.begin() + static_cast<std::ptrdiff_t>(diffs.size() / 2), diffs.end());
    st.force_noise_n = diffs[diffs.size() / 2] / (0.6745 * std::sqrt(6.0));
  }
  const double noise = 2.0 * st.force_noise_n;
  for (const StuckPhase& p : phases) {
    // The force's rate before sample `end`, ending 50 ms before it (the last samples may already
    // move, and the moving chambers change the force): the slower of its rates over 200 ms and
    // over the last 60 ms of those, as a slowing drift (a relaxation towards an asymptote just
    // past the bound) crosses the bound slower than it came (over 200 ms alone, 42.55 N was held
    // for a thermal bench's F_S+ of 42.13 N, the carriage already creeping within the band).
    const auto rate_before = [&](std::size_t end) {
      const std::size_t rate_end = index_before(s, p.first, end, 0.05);
      const auto rate_over = [&](double span_s) {
        const std::size_t rate_begin = index_before(s, p.first, rate_end, span_s);
        const double dt = s[rate_end].t_s - s[rate_begin].t_s;
        return dt > 0.0 ? (force[rate_end] - force[rate_begin]) / dt : 0.0;
      };
      const double long_rate = rate_over(0.2), recent = rate_over(0.06);
      return std::abs(recent) < std::abs(long_rate) ? recent : long_rate;
    };
    // How long a breakaway's onset may hide in the rest band at that rate.
    // (An ideal sensor too: the first picometre takes about a millisecond at 10 N/s.)
    const auto onset_at = [&](double r) {
      return onset_s(mass_kg, o.rest_band_m + detail::kSamePosition_m, std::abs(r), 0.2);
    };
    const double rate = rate_before(p.last);
    const double onset = onset_at(rate);
    // Held: every sample before the onset could have begun, once the carriage has settled into
    // the phase (a turning point can look still for a few ms within a rest band), in phases long
    // enough to be stuck for sure. The onset ends the phase at a breakaway; within a rest band, also
    // at the end of the record (the carriage may have begun to move in its last milliseconds: a
    // record that ended with the force rising at 24 N/s past F_S+ held 45.05 N for a bench's
    // 44.50 N; an ideal sensor's still part ends at its first moved reading); and where the
    // carriage left its still part within the phase: a carriage creeping off at a millimetre per
    // second stays within the band of a reference that follows it, so the phase goes on.
    const bool may_hide_onset = p.breakaway || o.rest_band_m > 0.0;
    std::size_t held_last = may_hide_onset ? index_before(s, p.first, p.last, onset) : p.last;
    if (p.still_last < p.last)
      held_last = std::min(held_last, index_before(s, p.first, p.still_last, onset_at(rate_before(p.still_last))));
    // Only where the carriage stood still: a creeping carriage's force is a sliding one.
    const bool long_enough = s[p.still_last].t_s - s[p.still_first].t_s >= o.min_fit_phase_s;
    double held_max = -std::numeric_limits<double>::infinity(), held_min = std::numeric_limits<double>::infinity();
    for (std::size_t k = p.still_first; long_enough && k <= std::min(held_last, p.still_last); ++k) {
      if (s[k].t_s - s[p.first].t_s < kSettleIntoPhase_s) continue;
      held_max = std::max(held_max, force[k]);
      held_min = std::min(held_min, force[k]);
    }
    st.positive.lower = std::max(st.positive.lower, held_max - noise);
    st.negative.upper = std::min(st.negative.upper, held_min + noise);
    if (!p.breakaway || p.last + 1 >= s.size()) continue;
    // Moved: the first sample out of the band. A stuck carriage leaves towards the side the force
    // pushes it; one that left the other way was not stuck (a creep at nanometres per second
    // onto a stiction bound reads still to an ideal sensor, and turns when the set point does).
    const double moved = force[p.last + 1];
    if ((p.direction > 0) != (moved > 0.0)) continue;
    // The bound this breakaway gives, and the onset it may hide, kept for the tightest one.
    const double onset_force = std::abs(rate) * onset;
    if (p.direction > 0) {
      const double upper = std::max(moved, force[p.last]) + noise;
      if (upper < st.positive.upper) {
        st.positive.upper = upper;
        st.positive.onset_force = onset_force;
      }
      ++st.positive.breakaways;
    } else {
      const double lower = std::min(moved, force[p.last]) - noise;
      if (lower > st.negative.lower) {
        st.negative.lower = lower;
        st.negative.onset_force = onset_force;
      }
      ++st.negative.breakaways;
    }
    // With an ideal position sensor the first moved reading also dates the breakaway: the force
    // crossed F_S at t_b and grows on at `local_rate`, the carriage accelerates at
    // local_rate (t - t_b) / M (the Stribeck drop is quadratic in v, nothing yet), so it has moved
    // dy = local_rate (t - t_b)^3 / (6 M) by the reading. F_S = F(t_b), within a fifth of the
    // correction. The breakaway may come up to a sample before the last still reading, whose
    // displacement is then below the still test's picometre.
    if (o.rest_band_m <= 0.0 && p.last > p.first) {
      const double local_rate = (force[p.last] - force[p.last - 1]) / (s[p.last].t_s - s[p.last - 1].t_s);
      const double dy = std::abs(s[p.last + 1].y_m - s[p.last].y_m);
      const double step = s[p.last + 1].t_s - s[p.last].t_s;
      if (local_rate * p.direction > 0.0 && dy > 0.0) {
        const double since_s = std::cbrt(6.0 * mass_kg * dy / std::abs(local_rate));
        if (since_s <= 2.0 * step) {
          const double at_breakaway = force[p.last + 1] - local_rate * since_s;
          const double allowance = 0.2 * std::abs(local_rate) * since_s + noise;
          (p.direction > 0 ? st.positive : st.negative).dated.push_back({at_breakaway, allowance});
        }
      }
    }
  }
  st.held_positive_n = st.positive.lower;
  st.held_negative_n = st.negative.upper;
  for (Bracket* side : {&st.positive, &st.negative}) {
    // Dated breakaways narrow the bracket where they agree with it, the surest (narrowest) first:
    // one that disagrees with the bracket so narrowed is left out (a fast jump's onset is not the
    // cubic one, and its allowance may not cover it: 0.28 N about 52.38 N for a bench's 52.066 N,
    // beside four slow ones within 0.3 mN of it).
    std::sort(side->dated.begin(), side->dated.end(),
              [](const Bracket::Dated& a, const Bracket::Dated& b) { return a.allowance_n < b.allowance_n; });
    for (const Bracket::Dated& d : side->dated) {
      const double lo = std::max(side->lower, d.force_n - d.allowance_n), hi = std::min(side->upper, d.force_n + d.allowance_n);
      if (lo > hi) continue;
      side->lower = lo;
      side->upper = hi;
    }
  }
  return st;
}

// The breakaway dated by the carriage's own onset (noisy sensors): the onset hides within the
// rest band for tens of milliseconds, so the reading that shows the motion comes after the force
// has moved on. From a candidate F_S, the carriage breaks away when the measured force crosses it
// and then moves as M dv/dt = F(t) - F_f(v) (the friction law of docs/model.md with the Coulomb and
// viscous values given); the candidate whose positions best match the readings, from 0.3 s before
// the reading that showed the motion to 30 ms after it, is the estimate. NaN when the window has
// too few readings or the best candidate lies at the end of the range searched.
double fit_onset(std::span<const Sample> s, std::span<const double> force, const StuckPhase& p,
                 const model::FrictionParams& f, double mass_kg) {
  const std::size_t k = p.last + 1;
  std::size_t a = k, b = k;
  while (a > p.first && s[k].t_s - s[a - 1].t_s <= 0.3) --a;
  while (b + 1 < s.size() && s[b + 1].t_s - s[k].t_s <= 0.03) ++b;
  if (b - a < 20) return std::numeric_limits<double>::quiet_NaN();
  const int d = p.direction;
  const double f_c = d > 0 ? f.coulomb_positive_n : f.coulomb_negative_n;
  const double v_s = f.stribeck_velocity_m_per_s;
  constexpr int kSub = 8;
  // What every candidate shares while its carriage is stuck at p.y_m: the mismatch summed up to
  // each sample, and the force each sample's sub-steps reach towards d (the largest, or the
  // smallest; NaN where one is NaN), which says whether a candidate may break away within it.
  std::vector<double> stuck_sum(b - a), reach(b - a);
  double stuck_total = 0.0;
  for (std::size_t j = a; j < b; ++j) {
    const double e = s[j].y_m - p.y_m;
    stuck_total += e * e;
    stuck_sum[j - a] = stuck_total;
    const double f0 = force[j], f1 = force[j + 1];
    double r = d > 0 ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
    for (int i = 0; i < kSub; ++i) {
      const double fb = f0 + (f1 - f0) * (i + 1) / kSub;
      r = std::isnan(fb) || std::isnan(r) ? fb + r : d > 0 ? std::max(r, fb) : std::min(r, fb);
    }
    reach[j - a] = r;
  }
  // The squared mismatch of the positions for a candidate stiction level. It only grows along the
  // window (a sum of squares), so once it exceeds `bound` the candidate cannot be the best: its
  // sum so far is returned, larger than `bound`, and the rest of its window is not integrated.
  const auto cost = [&](double f_s, double bound) {
    double y = p.y_m, v = 0.0, sum = 0.0;
    bool stuck = true;
    // One sample's sub-steps from (y, v): breaking away where the force crosses f_s, then sliding.
    const auto advance = [&](std::size_t j) {
      const double h = s[j + 1].t_s - s[j].t_s;
      const double f0 = force[j], f1 = force[j + 1];
      for (int i = 0; i < kSub; ++i) {
        const double fa = f0 + (f1 - f0) * i / kSub, fb = f0 + (f1 - f0) * (i + 1) / kSub;
        double dt = h / kSub;
        if (stuck) {
          if (d * (fb - f_s) <= 0.0) continue;
          // Breaks away inside this sub-step, where the force crosses F_S.
          const double frac = d * (fa - f_s) >= 0.0 ? 0.0 : (f_s - fa) / (fb - fa);
          dt *= 1.0 - frac;
          stuck = false;
        }
        const double vm = v;
        const double ff = f_c + (f_s - f_c) * std::exp(-(vm / v_s) * (vm / v_s)) + f.viscous_n_s_per_m * vm;
        const double acc = (0.5 * (fa + fb) - ff) / mass_kg;
        const double v_new = v + acc * dt;
        // Sliding towards d only: it sticks again where the velocity would turn.
        const double v_next = d * v_new < 0.0 ? 0.0 : v_new;
        y += 0.5 * (v + v_next) * dt;
        v = v_next;
      }
    };
    std::size_t j = a;
    for (; j < b; ++j) {  // stuck through whole samples: the shared sums, the same bit for bit
      sum = stuck_sum[j - a];
      if (sum > bound) return sum;
      if (!(d * (reach[j - a] - f_s) <= 0.0)) {
        advance(j++);
        break;
      }
    }
    for (; j < b; ++j) {
      const double e = s[j].y_m - y;
      sum += e * e;
      if (sum > bound) return sum;
      advance(j);
    }
    const double e = s[b].y_m - y;
    return sum + e * e;
  };
  // The candidates: from the force 0.3 s before the motion showed to the force when it showed.
  double lo = std::min(force[a], force[k]), hi = std::max(force[a], force[k]);
  lo = std::min(lo, force[k] - d * 0.5);
  hi = std::max(hi, force[k] - d * 0.5);
  // The best on the grid, the first of equals from lo. From hi down: the candidates near the force
  // at the motion come first, and the lower ones, which break away early and would slide through
  // most of the window, are mostly cut short by the best so far.
  constexpr int kGrid = 120;
  constexpr double kNone = std::numeric_limits<double>::infinity();
  double best = lo, best_cost = kNone;
  int best_i = 0;
  for (int i = kGrid; i >= 0; --i) {
    const double c = lo + (hi - lo) * i / kGrid;
    const double v = cost(c, best_cost);
    if (v <= best_cost) {
      best_cost = v;
      best = c;
      best_i = i;
    }
  }
  if (best_i == 0 || best_i == kGrid) return std::numeric_limits<double>::quiet_NaN();
  // Golden section around the best grid point.
  double x0 = best - (hi - lo) / kGrid, x1 = best + (hi - lo) / kGrid;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double c1 = x1 - g * (x1 - x0), c2 = x0 + g * (x1 - x0);
  // Each new point is cut short only when above the point kept: then it is the one let go next.
  double v1 = cost(c1, kNone), v2 = cost(c2, v1);
  for (int i = 0; i < 40; ++i) {
    if (v1 < v2) {
      x1 = c2;
      c2 = c1;
      v2 = v1;
      c1 = x1 - g * (x1 - x0);
      v1 = cost(c1, v2);
    } else {
      x0 = c1;
      c1 = c2;
      v1 = v2;
      c2 = x0 + g * (x1 - x0);
      v2 = cost(c2, v1);
    }
  }
  return 0.5 * (x0 + x1);
}

// Savitzky-Golay: velocity and acceleration at each sample from a quartic fitted over +-half_s (a
// quadratic lags behind the motion's curvature: F_C+ 1.4 N low on the exact bench). Only at the
// samples `wanted` (the others: not valid): a stuck carriage's need none. The fit is linear in the
// positions: v and a are weighted sums of them, whose weights depend only on the neighbours' times
// relative to the sample's; the loop's samples are evenly spaced, so the weights are worked out
// again only where that pattern changes (a deadline skipped, the record's ends).
struct Motion {
  std::vector<double> v, a;
  std::vector<bool> valid;
};

Motion motion_of(std::span<const Sample> s, double half_s, const std::vector<bool>& wanted) {
  Motion m{std::vector<double>(s.size(), 0.0), std::vector<double>(s.size(), 0.0), std::vector<bool>(s.size(), false)};
  // The patterns seen last (the rounding of the times puts a neighbour at +-half_s in or out, so a
  // few alternate), and their weights.
  struct Weights {
    std::vector<double> offsets;  // t_j - t_k, j over the neighbours
    std::vector<double> v, a;
  };
  std::array<Weights, 8> known;
  std::size_t next = 0;  // the one replaced next
  std::size_t lo = 0, hi = 0;
  for (std::size_t k = 0; k < s.size(); ++k) {
    while (s[k].t_s - s[lo].t_s > half_s) ++lo;
    while (hi + 1 < s.size() && s[hi + 1].t_s - s[k].t_s <= half_s) ++hi;
    if (!wanted[k]) continue;
    if (s[k].t_s - s[lo].t_s < 0.9 * half_s || s[hi].t_s - s[k].t_s < 0.9 * half_s) continue;
    const std::size_t n = hi - lo + 1;
    const auto matches = [&](const Weights& w) {
      if (w.offsets.size() != n) return false;
      for (std::size_t i = 0; i < n; ++i)
        if (std::abs(s[lo + i].t_s - s[k].t_s - w.offsets[i]) > 1e-9 * half_s) return false;
      return true;
    };
    auto found = std::find_if(known.begin(), known.end(), matches);
    if (found == known.end()) {
      Weights& w = known[next];
      next = (next + 1) % known.size();
      w.offsets.resize(n);
      w.v.resize(n);
      w.a.resize(n);
      std::vector<Eigen::Matrix<double, 5, 1>> phi(n);
      Eigen::Matrix<double, 5, 5> a = Eigen::Matrix<double, 5, 5>::Zero();
      for (std::size_t i = 0; i < n; ++i) {
        w.offsets[i] = s[lo + i].t_s - s[k].t_s;
        const double t = w.offsets[i] / half_s;
        phi[i] << 1.0, t, t * t, t * t * t, t * t * t * t;
        a += phi[i] * phi[i].transpose();
      }
      const auto ldlt = a.ldlt();
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Matrix<double, 5, 1> c = ldlt.solve(phi[i]);
        w.v[i] = c[1] / half_s;
        w.a[i] = 2.0 * c[2] / (half_s * half_s);
      }
      found = known.begin() + static_cast<std::ptrdiff_t>(&w - known.data());
    }
    double v = 0.0, acc = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double dy = s[lo + i].y_m - s[k].y_m;
      v += found->v[i] * dy;
      acc += found->a[i] * dy;
    }
    m.v[k] = v;
    m.a[k] = acc;
    m.valid[k] = true;
  }
  return m;
}

// Coulomb friction both ways and the viscous coefficient, by least squares on the sliding samples
// (Eq. 3: F_f = F - M a), with the Stribeck term of the prior's v_s and the identified stiction.
struct Sliding {
  double coulomb_positive = 0, coulomb_negative = 0, viscous = 0;
  double std_positive = 0, std_negative = 0, std_viscous = 0;
  int samples_positive = 0, samples_negative = 0;
  double seconds = 0.0;
  double speed_min = 0.0, speed_max = 0.0;  ///< of the samples fitted, either way [m/s]
  bool solved = false;
};

Sliding sliding_from(std::span<const Sample> s, std::span<const double> force, std::span<const StuckPhase> phases,
                     const model::PlantParams& p, double fs_pos, double fs_neg, const Options& o) {
  constexpr double kWindow_s = 0.015;
  Sliding out;
  // Samples near a stuck phase (the stick is a jump in acceleration) or an end stop are left out.
  std::vector<bool> use(s.size(), true);
  for (const StuckPhase& ph : phases) {
    const double t0 = s[ph.first].t_s - 2 * kWindow_s, t1 = s[ph.last].t_s + 2 * kWindow_s;
    for (std::size_t k = ph.first; k > 0 && s[k].t_s >= t0; --k) use[k] = false;
    for (std::size_t k = ph.first; k < s.size() && s[k].t_s <= t1; ++k) use[k] = false;
  }
  const double half = p.geometry.half_stroke_m() - o.end_stop_margin_m - 0.01;
  for (std::size_t k = 0; k < s.size(); ++k) use[k] = use[k] && std::abs(s[k].y_m) <= half;
  const Motion m = motion_of(s, kWindow_s, use);
  const double v_s = p.friction.stribeck_velocity_m_per_s;
  std::vector<Eigen::Vector3d> rows;
  std::vector<double> rhs;
  std::vector<std::size_t> sample_of_row;
  double v_min = std::numeric_limits<double>::infinity(), v_max = 0.0;
  for (std::size_t k = 0; k < s.size(); ++k) {
    if (!use[k] || !m.valid[k]) continue;
    const double v = m.v[k];
    if (std::abs(v) < o.sliding_min_stribeck * v_s) continue;
    const double e = std::exp(-(v / v_s) * (v / v_s));
    const double f_f = force[k] - p.mass_kg * m.a[k];
    // F_f = F_C (1 - e) + F_S e + sigma v
    if (v > 0) {
      rows.emplace_back(1.0 - e, 0.0, v);
      rhs.push_back(f_f - fs_pos * e);
      ++out.samples_positive;
    } else {
      rows.emplace_back(0.0, 1.0 - e, v);
      rhs.push_back(f_f - fs_neg * e);
      ++out.samples_negative;
    }
    v_min = std::min(v_min, std::abs(v));
    v_max = std::max(v_max, std::abs(v));
    sample_of_row.push_back(k);
    if (k > 0) out.seconds += s[k].t_s - s[k - 1].t_s;
  }
  if (!rows.empty()) {
    out.speed_min = v_min;
    out.speed_max = v_max;
  }
  if (out.samples_positive < 20 || out.samples_negative < 20) return out;
  Eigen::MatrixXd a(static_cast<Eigen::Index>(rows.size()), 3);
  Eigen::VectorXd b(static_cast<Eigen::Index>(rows.size()));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    a.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
    b[static_cast<Eigen::Index>(i)] = rhs[i];
  }
  const Eigen::Matrix3d ata = a.transpose() * a;
  const Eigen::Vector3d x = ata.ldlt().solve(a.transpose() * b);
  const double dof = static_cast<double>(rows.size()) - 3.0;
  const Eigen::VectorXd residual = a * x - b;
  const double s2 = residual.squaredNorm() / dof;
  // The residuals are not independent: each acceleration comes from a polynomial over the +-window,
  // which its neighbours share, and what the model misses runs through a motion. Their variance
  // grows by the autocorrelation over a window's samples (Bartlett weights, Newey and West 1987),
  // counted between samples of the same stretch of motion.
  const std::size_t lags = static_cast<std::size_t>(std::lround(2.0 * kWindow_s / std::max(1e-6, s[1].t_s - s[0].t_s)));
  double inflation = 1.0;
  for (std::size_t lag = 1; lag <= lags; ++lag) {
    double sum = 0.0;
    for (std::size_t i = 0; i + lag < sample_of_row.size(); ++i)
      if (sample_of_row[i + lag] == sample_of_row[i] + lag) sum += residual[static_cast<Eigen::Index>(i)] * residual[static_cast<Eigen::Index>(i + lag)];
    inflation += 2.0 * (1.0 - static_cast<double>(lag) / static_cast<double>(lags + 1)) * sum / (s2 * dof);
  }
  const Eigen::Matrix3d cov = std::max(1.0, inflation) * s2 * ata.inverse();
  out.coulomb_positive = x[0];
  out.coulomb_negative = x[1];
  out.viscous = x[2];
  out.std_positive = std::sqrt(cov(0, 0));
  out.std_negative = std::sqrt(cov(1, 1));
  out.std_viscous = std::sqrt(cov(2, 2));
  out.solved = std::isfinite(x.sum());
  return out;
}

using text::format;

// The record's sample spacing, its median: the loop's period where it kept its deadlines [s].
double median_spacing_s(std::span<const Sample> s) {
  if (s.size() < 2) return 0.0;
  std::vector<double> dt(s.size() - 1);
  for (std::size_t k = 1; k < s.size(); ++k) dt[k - 1] = s[k].t_s - s[k - 1].t_s;
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

}  // namespace

std::span<const char* const> identified_keys() noexcept { return kKeys; }

bool from_the_valve_fit(std::string_view key) noexcept {
  for (std::size_t i = kFirstValveFitKey; i < kFirstValveFitKey + detail::kValveFitParams; ++i)
    if (key == kKeys[i]) return true;
  return false;
}

double largest_null_pressure_difference_pa(const model::PlantParams& a, const model::PlantParams& b, double u_max_v) {
  const model::ValveModel va(a.valve, a.gas), vb(b.valve, b.gas);
  double worst = 0.0;
  const int steps = static_cast<int>(std::lround(u_max_v / 0.005));
  for (int k = -steps; k <= steps; ++k)
    worst = std::max(worst, std::abs(va.null_pressure_pa(k * 0.005) - vb.null_pressure_pa(k * 0.005)));
  return worst;
}

const Estimate& Identification::at(const std::string& key) const {
  for (const Estimate& e : estimates)
    if (e.key == key) return e;
  throw std::out_of_range("no estimate of " + key);
}

namespace {

// What the stuck phases are: how many, how long, over which positions and voltages.
Evidence evidence_of(std::span<const Sample> s, std::span<const StuckPhase> phases) {
  Evidence ev;
  ev.stuck_phases = static_cast<int>(phases.size());
  double y_lo = 1e9, y_hi = -1e9, u_lo = 1e9, u_hi = -1e9;
  for (const StuckPhase& p : phases) {
    ev.stuck_s += s[p.last].t_s - s[p.first].t_s;
    y_lo = std::min(y_lo, p.y_m);
    y_hi = std::max(y_hi, p.y_m);
    for (std::size_t k = p.first; k <= p.last; ++k) {
      u_lo = std::min(u_lo, s[k].u_v);
      u_hi = std::max(u_hi, s[k].u_v);
    }
  }
  ev.stuck_position_span_m = y_hi - y_lo;
  ev.voltage_span_v = u_hi - u_lo;
  return ev;
}

// The stiction bounds from the brackets of the breakaways (Eq. 15 and the forces held).
void estimate_stiction(const Stiction& st, const model::PlantParams& prior, const Options& o, Identification& id) {
  auto& f = id.plant.friction;
  const auto stiction_estimate = [&](const char* key, double prior_n, const Bracket& b, bool positive) {
    Estimate e{key, prior_n, prior_n, 0.0, false, ""};
    if (b.breakaways == 0) {
      e.basis = std::string("no breakaway in the ") + (positive ? "positive" : "negative") +
                " direction: prior kept (the forces held bound it from " + (positive ? "below" : "above") + " at " +
                format("%.2f N)", positive ? b.lower : b.upper);
      return e;
    }
    double lo = b.lower, hi = b.upper;
    if (lo > hi) std::swap(lo, hi);  // noise beyond its allowance: the spread is the uncertainty
    e.value = 0.5 * (lo + hi);
    e.std = 0.5 * (hi - lo) + b.onset_force;
    e.identified = (positive ? e.value > 0 : e.value < 0) && e.std <= o.max_relative_std * std::abs(e.value);
    e.basis = format("%d breakaways; held up to %.3f N, moved from %.3f N", b.breakaways, positive ? b.lower : b.upper,
                     positive ? b.upper : b.lower);
    if (!e.identified) {
      e.basis += ": too wide, prior kept";
      e.value = prior_n;
      e.std = 0.0;
    }
    return e;
  };
  id.estimates.push_back(stiction_estimate(kKeys[0], prior.friction.static_positive_n, st.positive, true));
  id.estimates.push_back(stiction_estimate(kKeys[1], prior.friction.static_negative_n, st.negative, false));
  f.static_positive_n = id.estimates[0].value;
  f.static_negative_n = id.estimates[1].value;
}

// Coulomb and viscous friction from the sliding phases (Eq. 3).
void estimate_sliding(std::span<const Sample> s, std::span<const double> force, std::span<const StuckPhase> phases,
                      const model::PlantParams& prior, const Options& o, Identification& id) {
  auto& f = id.plant.friction;
  const Sliding sl = sliding_from(s, force, phases, prior, f.static_positive_n, f.static_negative_n, o);
  id.evidence.sliding_s = sl.seconds;
  const auto sliding_estimate = [&](const char* key, double prior_v, double value, double sd, bool sign_ok) {
    Estimate e{key, prior_v, prior_v, 0.0, false, ""};
    if (!sl.solved) {
      e.basis = format("too little sliding faster than %.3g m/s each way (%d samples positive, %d negative): prior kept",
                       o.sliding_min_stribeck * prior.friction.stribeck_velocity_m_per_s, sl.samples_positive,
                       sl.samples_negative);
      return e;
    }
    e.basis = format("%d sliding samples at %.2g to %.2g m/s", sl.samples_positive + sl.samples_negative,
                     sl.speed_min, sl.speed_max);
    if (!sign_ok || sd > o.max_relative_std * std::abs(value)) {
      e.basis += format(": %.4g +- %.2g not separable, prior kept", value, sd);
      return e;
    }
    e.value = value;
    e.std = sd;
    e.identified = true;
    return e;
  };
  id.estimates.push_back(sliding_estimate(kKeys[2], prior.friction.coulomb_positive_n, sl.coulomb_positive, sl.std_positive,
                                          sl.coulomb_positive > 0));
  id.estimates.push_back(sliding_estimate(kKeys[3], prior.friction.coulomb_negative_n, sl.coulomb_negative, sl.std_negative,
                                          sl.coulomb_negative < 0));
  id.estimates.push_back(sliding_estimate(kKeys[4], prior.friction.viscous_n_s_per_m, sl.viscous, sl.std_viscous,
                                          sl.viscous >= 0));
  f.coulomb_positive_n = std::min(id.estimates[2].value, f.static_positive_n);
  f.coulomb_negative_n = std::max(id.estimates[3].value, f.static_negative_n);
  f.viscous_n_s_per_m = id.estimates[4].value;
  if (f.coulomb_positive_n != id.estimates[2].value) id.estimates[2].basis += "; capped at F_S+";
  if (f.coulomb_negative_n != id.estimates[3].value) id.estimates[3].basis += "; capped at F_S-";
  id.estimates[2].value = f.coulomb_positive_n;
  id.estimates[3].value = f.coulomb_negative_n;
}

// Noisy sensors: the breakaways dated by the onset itself replace the brackets, whose reading
// of the motion comes late. Each fit is weighted by how slowly the force crossed (how little it
// had moved on by the reading that showed the motion, its standard deviation): a slow crossing
// is dated best.
void date_breakaways_by_onset(std::span<const Sample> s, std::span<const double> force,
                              std::span<const StuckPhase> phases, const Stiction& st, const model::PlantParams& prior,
                              const Options& o, Identification& id) {
  auto& f = id.plant.friction;
  struct Fit {
    double value, weight;
  };
  std::vector<Fit> fits[2];
  for (const StuckPhase& p : phases) {
    if (!p.breakaway || p.last + 1 >= s.size() || (p.direction > 0) != (force[p.last + 1] > 0.0)) continue;
    const double fit = fit_onset(s, force, p, f, prior.mass_kg);
    if (!std::isfinite(fit)) continue;
    const double moved_on = std::abs(force[p.last] - fit) + kOnsetWeightFloor_n;
    fits[p.direction > 0 ? 0 : 1].push_back({fit, 1.0 / (moved_on * moved_on)});
  }
  for (int side = 0; side < 2; ++side) {
    Estimate& e = id.estimates[static_cast<std::size_t>(side)];
    if (fits[side].empty()) continue;
    double sw = 0, swx = 0, sw2 = 0;
    for (const Fit& x : fits[side]) {
      sw += x.weight;
      swx += x.weight * x.value;
      sw2 += x.weight * x.weight;
    }
    const double mean = swx / sw;
    double spread2 = 0;
    for (const Fit& x : fits[side]) spread2 += x.weight * (x.value - mean) * (x.value - mean);
    const double n_eff = sw * sw / sw2;
    // The spread of the fits about their mean. Fewer than two (effective) fits have no spread to
    // show (a set-point step's fast breakaway, dated alone): each is then taken as good to how
    // far the force moved on while the onset hid.
    const double sd = (n_eff >= 2.0 ? std::sqrt(spread2 / sw) / std::sqrt(n_eff - 1.0) : 1.0 / std::sqrt(sw)) +
                      st.force_noise_n;
    // The forces held and the breakaways' readings still bound it: F_S lies within the bracket
    // whatever the fits say (the fits of fast breakaways spread by newtons, and a mean inside a
    // force the carriage held forecasts a restart at once). The uncertainty stays the fits': a
    // wide bracket says little, and a narrow one that the fits miss says they spread.
    const Bracket& b = side == 0 ? st.positive : st.negative;
    const double value = b.lower <= b.upper ? std::clamp(mean, b.lower, b.upper) : mean;
    const bool ok = (side == 0 ? value > 0 : value < 0) && sd <= o.max_relative_std * std::abs(value);
    if (!ok) continue;
    e.value = value;
    e.std = sd;
    e.identified = true;
    e.basis = format("%d breakaways dated by their onset (%d bracketed: held up to %.3f N, moved from %.3f N%s)",
                     static_cast<int>(fits[side].size()), side == 0 ? st.positive.breakaways : st.negative.breakaways,
                     side == 0 ? st.positive.lower : st.negative.upper, side == 0 ? st.positive.upper : st.negative.lower,
                     value != mean ? format("; their mean %.3f N lies outside: the bracket's end", mean).c_str() : "");
  }
  f.static_positive_n = id.estimates[0].value;
  f.static_negative_n = id.estimates[1].value;
  for (const std::size_t i : {std::size_t{2}, std::size_t{3}}) {
    Estimate& c = id.estimates[i];
    const double capped = i == 2 ? std::min(c.value, f.static_positive_n) : std::max(c.value, f.static_negative_n);
    if (capped != c.value) c.basis += "; capped at the stiction";
    c.value = capped;
  }
  f.coulomb_positive_n = id.estimates[2].value;
  f.coulomb_negative_n = id.estimates[3].value;
}

// A disturbance the model does not have (a knock on the carriage, a link that stalled) spoils a
// phase or two of a run that is otherwise the model's. Where the other phases, nine or more for
// each spoiled one, fit without them, those are left out (in `left_out`) and the fit without them
// is the result; where they do not, the model does not fit, and the fit with them says so.
// The spoiled phases are first those the fit with them all flags; a badly spoiled phase can drag
// that fit so far that it flags good ones too (more than one in ten), so then they are left out
// one at a time instead, the worst of each fit first, while nine or more phases remain for each.
detail::ValveFit without_spoiled_phases(std::span<const Sample> s, std::span<const StuckPhase> still, detail::ValveFit vf,
                                        const model::PlantParams& plant, const Options& o,
                                        std::vector<Evidence::PhaseMisfit>& left_out) {
  // Where phase p's residual is in fit f, if it was fitted.
  const auto residual_of = [](const detail::ValveFit& f, const StuckPhase& p) {
    const auto r = std::find_if(f.phase_residuals.begin(), f.phase_residuals.end(),
                                [&](const auto& x) { return x.first >= p.first && x.last <= p.last; });
    return r == f.phase_residuals.end() ? nullptr : &*r;
  };
  const auto misfit = [&](const detail::ValveFit::PhaseResidual& r) {
    return Evidence::PhaseMisfit{s[r.first].t_s, r.y_m, r.rms_pa};
  };
  const std::size_t fitted = vf.phase_residuals.size();
  std::vector<StuckPhase> kept;
  std::vector<Evidence::PhaseMisfit> spoiled;
  for (const StuckPhase& p : still) {
    const auto* r = residual_of(vf, p);
    if (r && r->misfit) spoiled.push_back(misfit(*r));
    else kept.push_back(p);
  }
  if (spoiled.empty()) return vf;
  if (9 * spoiled.size() <= fitted - spoiled.size()) {
    detail::ValveFit without = detail::fit_valves(s, kept, plant, o);
    if (without.fits) {
      left_out = std::move(spoiled);
      return without;
    }
  }
  // One at a time, the worst first.
  kept.assign(still.begin(), still.end());
  spoiled.clear();
  detail::ValveFit current = vf;
  while (9 * (spoiled.size() + 1) <= fitted - (spoiled.size() + 1)) {
    auto worst = kept.end();
    const detail::ValveFit::PhaseResidual* worst_r = nullptr;
    for (auto p = kept.begin(); p != kept.end(); ++p) {
      const auto* r = residual_of(current, *p);
      if (r && r->misfit && (!worst_r || r->rms_pa > worst_r->rms_pa)) worst = p, worst_r = r;
    }
    if (!worst_r) break;
    spoiled.push_back(misfit(*worst_r));
    kept.erase(worst);
    current = detail::fit_valves(s, kept, plant, o);
    if (current.fits) {
      left_out = std::move(spoiled);
      return current;
    }
  }
  return vf;
}

// The valves and the dead volumes from the stuck phases' pressure transients (Eq. 19).
void estimate_valves(std::span<const Sample> s, std::span<const double> force, std::span<const StuckPhase> phases,
                     const model::PlantParams& prior, const Options& o, Identification& id) {
  Evidence& ev = id.evidence;
  detail::ValveFit vf;
  if (o.fit_valves) {
    std::vector<StuckPhase> still(phases.begin(), phases.end());
    for (StuckPhase& p : still) p.still_last = valve_fit_last(s, force, p, prior.mass_kg, o);
    vf = detail::fit_valves(s, still, id.plant, o);
    if (!vf.fits) vf = without_spoiled_phases(s, still, std::move(vf), id.plant, o, ev.left_out);
  } else {
    vf.plant = id.plant;
    vf.phases = -1;
    vf.basis.fill("not refitted: no new stuck phase long enough");
  }
  ev.fitted_phases = std::max(vf.phases, 0);
  ev.pressure_rms_residual_pa = vf.joint_rms_residual_pa;
  ev.command_delay_samples = vf.command_delay_samples;
  ev.pressure_noise_pa = vf.noise_pa;
  ev.pressure_explained_pa = vf.explained_pa;
  ev.model_fits = vf.fits;
  ev.misfit_phases_of = static_cast<int>(vf.phase_residuals.size());
  for (const auto& r : vf.phase_residuals)
    if (r.misfit) ev.misfit.push_back({s[r.first].t_s, r.y_m, r.rms_pa});
  const double period = median_spacing_s(s);
  for (const auto& r : vf.phase_residuals) {
    ev.fitted_samples += static_cast<int>(r.last - r.first + 1);
    for (std::size_t k = r.first + 1; k <= r.last && period > 0.0; ++k) {
      const double ticks = (s[k].t_s - s[k - 1].t_s) / period;
      if (ticks > 1.5) ev.fitted_deadlines_skipped += static_cast<int>(std::lround(ticks)) - 1;
    }
  }
  if (vf.phases == 0)
    throw InsufficientData(format("too little excitation: no stuck phase of %.3g s or more driven by the loop, so the "
                                  "valves' pressure transients cannot be fitted",
                                  o.min_fit_phase_s));
  id.plant.valve = vf.plant.valve;
  id.plant.geometry = vf.plant.geometry;
  id.plant.thermal = vf.plant.thermal;
  if (vf.phases > 0) {
    id.jointly_fitted = id.plant;
    id.jointly_fitted->valve = vf.joint.valve;
    id.jointly_fitted->geometry = vf.joint.geometry;
    id.jointly_fitted->thermal = vf.joint.thermal;
  }
  const double priors[] = {prior.valve.max_conductance_m3_per_s_pa, prior.valve.leak_conductance_in_m3_per_s_pa,
                           prior.valve.leak_conductance_out_m3_per_s_pa, prior.valve.null_offset_v,
                           prior.geometry.dead_volume_p_m3, prior.geometry.dead_volume_n_m3,
                           prior.thermal.heat_transfer_w_per_m2_k, prior.valve.spool_time_constant_s};
  const double values[] = {vf.plant.valve.max_conductance_m3_per_s_pa, vf.plant.valve.leak_conductance_in_m3_per_s_pa,
                           vf.plant.valve.leak_conductance_out_m3_per_s_pa, vf.plant.valve.null_offset_v,
                           vf.plant.geometry.dead_volume_p_m3, vf.plant.geometry.dead_volume_n_m3,
                           vf.plant.thermal.heat_transfer_w_per_m2_k, vf.plant.valve.spool_time_constant_s};
  for (std::size_t i = 0; i < detail::kValveFitParams; ++i) {
    Estimate e{kKeys[kFirstValveFitKey + i], priors[i], values[i], vf.std[i], vf.identified[i], vf.basis[i]};
    if (e.identified)
      e.basis = format("%d stuck phases over %.0f mm, u over %.3f V", vf.phases, ev.stuck_position_span_m * 1e3,
                       ev.voltage_span_v);
    // A model that does not fit: what the fit gives carries the misfit, and says so.
    if (!vf.fits && vf.phases > 0 && detail::has_parameter(prior, i))
      e.basis += format("; the model does not fit (%.0f Pa rms, %.0f times what the noise explains)",
                        vf.joint_rms_residual_pa, vf.joint_rms_residual_pa / vf.explained_pa);
    id.estimates.push_back(e);
  }
}

}  // namespace

Identification identify(std::span<const Sample> s, const model::PlantParams& prior, const Options& o) {
  const model::PressureForce pf(prior.geometry, prior.gas.exhaust_pressure_pa);
  std::vector<double> force(s.size());
  for (std::size_t k = 0; k < s.size(); ++k) force[k] = pf.force_n(s[k].p_p_pa, s[k].p_n_pa);
  const std::vector<StuckPhase> phases = detail::stuck_phases(s, prior.geometry.half_stroke_m(), o);
  if (phases.empty())
    throw InsufficientData(format("no sticking phase: the carriage never stood still for %.3g s away from the end stops",
                                  o.min_stuck_s));
  Identification id;
  id.plant = prior;
  id.evidence = evidence_of(s, phases);
  const Stiction st = stiction_from(s, force, phases, prior.mass_kg, o);
  if (st.positive.breakaways + st.negative.breakaways == 0)
    throw InsufficientData("no breakaway: the carriage never left a stuck phase under its own pressure force, so "
                           "neither stiction bound can be bounded from beyond");
  id.evidence.breakaways_positive = st.positive.breakaways;
  id.evidence.breakaways_negative = st.negative.breakaways;
  id.evidence.held_positive_n = st.held_positive_n;
  id.evidence.held_negative_n = st.held_negative_n;
  // In this order: each estimate is made on the friction the ones before it identified.
  estimate_stiction(st, prior, o, id);
  estimate_sliding(s, force, phases, prior, o, id);
  if (o.rest_band_m > 0.0) date_breakaways_by_onset(s, force, phases, st, prior, o, id);
  estimate_valves(s, force, phases, prior, o, id);
  id.estimates.push_back({kKeys[kPublished], prior.friction.stribeck_velocity_m_per_s,
                          prior.friction.stribeck_velocity_m_per_s, 0.0, false, "not identified: taken from the configuration"});
  id.estimates.push_back({kKeys[kPublished + 1], prior.mass_kg, prior.mass_kg, 0.0, false,
                          "not identified: taken from the configuration (friction is F - M a with it)"});
  return id;
}

}  // namespace pneu::identify
