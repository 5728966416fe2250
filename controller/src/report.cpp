#include "pneu/controller/report.hpp"

#include <cmath>
#include <cstdio>

namespace pneu::controller {

namespace {

// JSON number, or null for NaN / infinity.
std::string num(double v, int precision = 9) {
  if (!std::isfinite(v)) return "null";
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", precision, v);
  return buf;
}

}  // namespace

double observation_tolerance_s(const StopOutcome& s) noexcept {
  return std::max(0.010, 0.01 * s.sticking_s());
}

Verdict judge(const StopOutcome& s, const Prediction& p, double t_end_s) noexcept {
  Verdict v;
  if (s.ended && !s.restarted) return v;  // the set point moved: the forecast no longer applies
  const bool predicted = p.will_restart && p.t_restart_s <= t_end_s;
  if (s.restarted) {
    v.kind = predicted ? Verdict::Kind::kTruePositive : Verdict::Kind::kFalseNegative;
    if (predicted) {
      v.error_s = p.t_restart_s - s.t_end_s;
      v.error_percent = 100.0 * std::abs(v.error_s) / std::max(s.sticking_s(), 1e-9);
      v.direction_ok = p.direction == s.direction;
    }
  } else if (p.will_restart && p.t_restart_s > t_end_s - observation_tolerance_s(s)) {
    // A restart forecast after the end of the run, or this close to it, cannot be confirmed or
    // refuted by the signals (a start is seen only once the carriage has moved): not judged.
  } else {
    v.kind = predicted ? Verdict::Kind::kFalsePositive : Verdict::Kind::kTrueNegative;
  }
  return v;
}

RunReport::RunReport(const PredictorModel& model, bool linearized, bool nonlinear,
                     std::ostream* events, std::ostream* trajectory)
    : model_(model), linearized_(linearized), nonlinear_(nonlinear), events_(events), trajectory_(trajectory) {
  if (trajectory_) *trajectory_ << "seq,t,y_d,y,v_hat,a_hat,p_P,p_N,F,u,stuck,validity\n";
}

void RunReport::drain(LoopOutputs& out) {
  TickRecord r;
  while (out.ticks.try_pop(r)) {
    if (r.seq != next_seq_) ++sequence_gaps_;
    next_seq_ = r.seq + 1;
    ++ticks_seen_;
    t_end_s_ = r.t_s;
    if (listener_) listener_->on_tick(r);
    if (trajectory_) {
      *trajectory_ << r.seq << ',' << num(r.t_s, 12) << ',' << num(r.y_d_m) << ',' << num(r.y_m, 12) << ','
                   << num(r.v_hat_m_per_s) << ',' << num(r.a_hat_m_per_s2) << ',' << num(r.p_p_pa) << ','
                   << num(r.p_n_pa) << ',' << num(r.force_n) << ',' << num(r.u_v) << ','
                   << (r.stuck ? 1 : 0) << ',' << r.sensor_validity << '\n';
    }
  }
  LoopEvent e;
  while (out.events.try_pop(e)) on_event(e);
  HealthRecord h;
  while (out.health.try_pop(h))
    if (listener_) listener_->on_health(h);
}

void RunReport::write_prediction(const StopOutcome& s, const Prediction& p) {
  if (listener_) listener_->on_prediction(s, p);
  if (!events_) return;
  *events_ << "{\"event\":\"prediction\",\"t\":" << num(s.snapshot.t_s, 12) << ",\"stop\":" << s.index
           << ",\"t_stop\":" << num(s.t_stop_s, 12) << ",\"method\":\"" << to_string(p.method)
           << "\",\"will_restart\":" << (p.will_restart ? "true" : "false")
           << ",\"direction\":" << p.direction << ",\"t_restart\":" << num(p.t_restart_s, 12)
           << ",\"u_star\":" << num(s.snapshot.u_v) << ",\"equilibrium_force\":" << num(p.equilibrium_force_n)
           << ",\"tau_p\":" << num(p.tau_p_s) << ",\"tau_n\":" << num(p.tau_n_s)
           << ",\"min_margin\":" << num(p.min_margin_n)
           << ",\"horizon_reached\":" << (p.horizon_reached ? "true" : "false") << "}\n";
}

void RunReport::on_event(const LoopEvent& e) {
  if (listener_) listener_->on_event(e);
  if (e.kind == LoopEvent::Kind::kStop) {
    StopOutcome s;
    s.index = e.stop_index;
    s.t_stop_s = e.t_s;
    s.y_stop_m = e.y_m;
    s.force_n = e.force_n;
    s.y_d_m = e.y_d_m;
    s.snapshot = e.snapshot;
    if (events_) {
      *events_ << "{\"event\":\"stop\",\"t\":" << num(e.t_s, 12) << ",\"stop\":" << e.stop_index
               << ",\"y\":" << num(e.y_m, 12) << ",\"force\":" << num(e.force_n)
               << ",\"y_d\":" << num(e.y_d_m) << "}\n";
    }
    // Forecasts assume the law holds u* (Eq. 11): not when disarmed or faulted.
    const bool forecastable = e.controlled && snapshot_is_finite(s.snapshot);
    if (linearized_ && forecastable) s.linearized = predict_linearized(model_, s.snapshot);
    if (nonlinear_ && forecastable) s.nonlinear = predict_nonlinear(model_, s.snapshot);
    if (s.linearized) write_prediction(s, *s.linearized);
    if (s.nonlinear) write_prediction(s, *s.nonlinear);
    stops_.push_back(s);
    return;
  }
  if (e.kind == LoopEvent::Kind::kFaultReset || e.kind == LoopEvent::Kind::kResetRefused) {
    if (events_)
      *events_ << "{\"event\":\"" << (e.kind == LoopEvent::Kind::kFaultReset ? "fault_reset" : "fault_reset_refused")
               << "\",\"t\":" << num(e.t_s, 12) << ",\"cause\":\"" << fault_name(e.fault_cause) << "\"}\n";
    return;
  }
  if (e.kind == LoopEvent::Kind::kFault) {
    faults_.push_back(e);
    if (events_)
      *events_ << "{\"event\":\"fault\",\"t\":" << num(e.t_s, 12) << ",\"y\":" << num(e.y_m, 12)
               << ",\"cause\":\"" << fault_name(e.fault_cause) << "\",\"text\":\"" << fault_text(e.fault_cause)
               << "\"}\n";
    return;
  }
  if (events_) {
    *events_ << "{\"event\":\"start\",\"t\":" << num(e.t_s, 12) << ",\"stop\":" << e.stop_index
             << ",\"restart\":" << (e.restart ? "true" : "false") << ",\"direction\":" << e.direction
             << ",\"y\":" << num(e.y_m, 12) << ",\"y_d\":" << num(e.y_d_m) << "}\n";
  }
  if (!stops_.empty() && stops_.back().index == e.stop_index && !stops_.back().ended) {
    StopOutcome& s = stops_.back();
    s.ended = true;
    s.restarted = e.restart;
    s.t_end_s = e.t_s;
    s.direction = e.direction;
  }
}

void RunReport::finish(double t_end_s) {
  t_end_s_ = std::max(t_end_s_, t_end_s);
  for (auto& s : stops_)
    if (!s.ended) s.t_end_s = t_end_s_;
  if (events_) *events_ << "{\"event\":\"end\",\"t\":" << num(t_end_s_, 12) << "}\n";
  if (listener_) listener_->on_end(t_end_s_);
}

void RunReport::print_summary(std::FILE* out, const LoopTiming& timing) const {
  std::fprintf(out, "stops (sticking phases) and their restart forecasts; forecast error in %% of the sticking\n"
                    "time when it lasted 0.5 s or more, in ms (forecast - actual) otherwise:\n");
  std::fprintf(out, "  %3s %9s %9s %8s %8s %8s  %-34s %-24s %-24s\n", "#", "t_stop[s]", "y*[mm]", "F[N]",
               "u*[V]", "F_e[N]", "what happened", "linearized", "nonlinear");
  for (const auto& s : stops_) {
    char happened[64];
    if (!s.ended)
      std::snprintf(happened, sizeof happened, "stuck to the end (%.3f s)", s.sticking_s());
    else if (s.restarted)
      std::snprintf(happened, sizeof happened, "restart %c at %.4f s (%.3f s)", s.direction > 0 ? '+' : '-',
                    s.t_end_s, s.sticking_s());
    else
      std::snprintf(happened, sizeof happened, "set point moved at %.4f s", s.t_end_s);
    std::string cells[2];
    const std::optional<Prediction>* ps[2] = {&s.linearized, &s.nonlinear};
    for (int i = 0; i < 2; ++i) {
      if (!*ps[i]) {
        cells[i].assign(1, '-');
        continue;
      }
      const Prediction& p = **ps[i];
      const Verdict v = judge(s, p, t_end_s_);
      char buf[64];
      if (!p.will_restart)
        std::snprintf(buf, sizeof buf, "none%s", v.kind == Verdict::Kind::kFalseNegative ? " (MISSED)" : "");
      else if (v.kind == Verdict::Kind::kTruePositive && s.sticking_s() >= 0.5)
        std::snprintf(buf, sizeof buf, "%c %.4f s (%.2f %%)%s", p.direction > 0 ? '+' : '-', p.t_restart_s,
                      v.error_percent, v.direction_ok ? "" : " WRONG DIR");
      else if (v.kind == Verdict::Kind::kTruePositive)
        std::snprintf(buf, sizeof buf, "%c %.4f s (%+.1f ms)%s", p.direction > 0 ? '+' : '-', p.t_restart_s,
                      v.error_s * 1e3, v.direction_ok ? "" : " WRONG DIR");
      else
        std::snprintf(buf, sizeof buf, "%c %.4f s%s", p.direction > 0 ? '+' : '-', p.t_restart_s,
                      v.kind == Verdict::Kind::kFalsePositive ? " (FALSE)" : "");
      cells[i] = buf;
    }
    const Prediction* any = s.nonlinear ? &*s.nonlinear : (s.linearized ? &*s.linearized : nullptr);
    std::fprintf(out, "  %3llu %9.4f %9.3f %8.2f %8.4f %8.2f  %-34s %-24s %-24s\n",
                 static_cast<unsigned long long>(s.index), s.t_stop_s, s.y_stop_m * 1e3, s.force_n,
                 s.snapshot.u_v, any ? any->equilibrium_force_n : NAN, happened, cells[0].c_str(),
                 cells[1].c_str());
  }
  if (stops_.empty()) std::fprintf(out, "  (none)\n");
  for (const auto& f : faults_)
    std::fprintf(out, "fault at %.4f s (y = %.3f mm): %s: %s\n", f.t_s, f.y_m * 1e3, fault_name(f.fault_cause),
                 fault_text(f.fault_cause));
  const auto us = [](double s) { return s * 1e6; };
  std::fprintf(out, "loop: %llu ticks at %.0f Hz, %llu overruns (%llu deadlines skipped)\n",
               static_cast<unsigned long long>(timing.ticks), 1.0 / timing.period_s,
               static_cast<unsigned long long>(timing.overruns),
               static_cast<unsigned long long>(timing.deadlines_skipped));
  std::fprintf(out, "  wake-up latency [us]  min %8.2f  median %8.2f  p99 %8.2f  max %8.2f\n",
               us(timing.wake_latency.min_s()), us(timing.wake_latency.quantile_s(0.5)),
               us(timing.wake_latency.quantile_s(0.99)), us(timing.wake_latency.max_s()));
  std::fprintf(out, "  compute per tick [us] min %8.2f  median %8.2f  p99 %8.2f  max %8.2f\n",
               us(timing.compute.min_s()), us(timing.compute.quantile_s(0.5)),
               us(timing.compute.quantile_s(0.99)), us(timing.compute.max_s()));
}

}  // namespace pneu::controller
