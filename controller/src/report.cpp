#include "pneu/controller/report.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

namespace pneu::controller {

namespace {

// JSON number (printf's %.*g, by std::to_chars: the same text, several times faster), or null
// for NaN / infinity. Streamed without building a string: the trajectory writes 18 per tick.
struct Num {
  char text[32];
  std::size_t size;
};
Num num(double v, int precision = 9) {
  Num n{};
  if (!std::isfinite(v)) {
    std::memcpy(n.text, "null", 4);
    n.size = 4;
    return n;
  }
  const auto r = std::to_chars(n.text, n.text + sizeof n.text, v, std::chars_format::general, precision);
  n.size = static_cast<std::size_t>(r.ptr - n.text);
  return n;
}
std::ostream& operator<<(std::ostream& os, const Num& n) {
  return os.write(n.text, static_cast<std::streamsize>(n.size));
}

// A JSON string: quotes, backslashes and control characters escaped (RFC 8259).
struct Str {
  std::string_view text;
};
std::ostream& operator<<(std::ostream& os, const Str& s) {
  os << '"';
  for (const char c : s.text) {
    if (c == '"' || c == '\\') {
      os << '\\' << c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      os << buf;
    } else {
      os << c;
    }
  }
  return os << '"';
}

// One forecast against what happened, for the summary: the restart time and its error.
std::string forecast_cell(const StopOutcome& s, const Prediction& p, double t_end_s) {
  const Verdict v = judge(s, p, t_end_s);
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
  return buf;
}

}  // namespace

RunReport::RunReport(const PredictorModel& model, bool linearized, bool nonlinear, std::ostream* events,
                     std::ostream* trajectory, double update_period_s)
    : model_(model),
      linearized_(linearized),
      nonlinear_(nonlinear),
      update_period_s_(update_period_s),
      events_(events),
      trajectory_(trajectory) {
  if (trajectory_)
    *trajectory_ << "seq,t,y_d,y,v_hat,a_hat,p_P,p_N,F,u,stuck,validity,"
                    "p_P_linearized,p_N_linearized,F_linearized,p_P_nonlinear,p_N_nonlinear,F_nonlinear\n";
}

void RunReport::drain(LoopOutputs& out) {
  // Ticks and events come on two queues. The loop pushes a tick's events before its record, so
  // the events raised up to a record are in their queue when the record is popped.
  TickRecord r;
  while (out.ticks.try_pop(r)) {
    for (const LoopEvent* e = out.events.front(); e && e->tick_seq <= r.seq; e = out.events.front()) {
      LoopEvent event;
      (void)out.events.try_pop(event);  // the one front() showed
      on_event(event);
    }
    on_tick(r);
  }
  LoopEvent e;
  while (out.events.try_pop(e)) on_event(e);
  HealthRecord h;
  while (out.health.try_pop(h))
    if (listener_) listener_->on_health(h);
}

void RunReport::on_tick(const TickRecord& r) {
  if (r.seq != next_seq_) ++sequence_gaps_;
  next_seq_ = r.seq + 1;
  ++ticks_seen_;
  t_end_s_ = r.t_s;
  if (listener_) listener_->on_tick(r);

  // A forecast holds while the carriage stays stuck under the u* it assumed: armed, same set point.
  if (!stops_.empty() && !stops_.back().ended && std::isnan(stops_.back().forecast_void_at_s) &&
      (r.mode != Mode::kArmed || r.y_d_m != stops_.back().y_d_m))
    stops_.back().forecast_void_at_s = r.t_s;
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  ForecastPoint expected[2] = {{kNaN, kNaN, kNaN}, {kNaN, kNaN, kNaN}};
  if (following_) {
    StopOutcome& s = stops_.back();
    if (s.ended || !r.stuck || !std::isnan(s.forecast_void_at_s)) {
      following_.reset();
    } else if (r.t_s >= s.snapshot.t_s) {
      if (std::isfinite(r.y_m)) {
        following_->sum_y_m += r.y_m;
        ++following_->readings;
      }
      double* gaps[2] = {&s.largest_gap_linearized_n, &s.largest_gap_nonlinear_n};
      for (int i = 0; i < 2 && follow_; ++i) {
        if (!following_->tracks[i]) continue;
        expected[i] = following_->tracks[i]->at(r.t_s);
        const double gap = std::abs(r.force_n - expected[i].force_n);
        if (std::isfinite(gap)) *gaps[i] = std::isnan(*gaps[i]) ? gap : std::max(*gaps[i], gap);
      }
      // (Not at the snapshot's own tick: that forecast is the stop's.)
      if (update_period_s_ > 0.0 && r.t_s > s.snapshot.t_s && r.t_s >= following_->next_update_s - 1e-9) {
        reforecast(s, r, expected);
        // The next whole period after this tick (a period under the loop's: every tick).
        const double periods = std::floor((r.t_s - s.snapshot.t_s) / update_period_s_ + 1e-6) + 1.0;
        following_->next_update_s = s.snapshot.t_s + periods * update_period_s_;
      }
    }
  }
  if (trajectory_) {
    *trajectory_ << r.seq << ',' << num(r.t_s, 12) << ',' << num(r.y_d_m) << ',' << num(r.y_m, 12) << ','
                 << num(r.v_hat_m_per_s) << ',' << num(r.a_hat_m_per_s2) << ',' << num(r.p_p_pa) << ','
                 << num(r.p_n_pa) << ',' << num(r.force_n) << ',' << num(r.u_v) << ',' << (r.stuck ? 1 : 0)
                 << ',' << r.sensor_validity;
    for (const ForecastPoint& x : expected) {
      if (std::isnan(x.force_n)) *trajectory_ << ",,,";
      else *trajectory_ << ',' << num(x.p_p_pa) << ',' << num(x.p_n_pa) << ',' << num(x.force_n);
    }
    *trajectory_ << '\n';
  }
}

void RunReport::reforecast(StopOutcome& s, const TickRecord& r, const ForecastPoint (&expected)[2]) {
  StopSnapshot now = s.snapshot;
  now.t_s = r.t_s;
  now.p_p_pa = r.p_p_pa;
  now.p_n_pa = r.p_n_pa;
  if (law_ && following_->readings > 0) {
    now.y_m = following_->sum_y_m / static_cast<double>(following_->readings);
    now.u_v = law_->resting_control_v(s.y_d_m, now.y_m);
  }
  if (!snapshot_is_finite(now)) return;
  ++s.updates;
  // Bounded history: past the cap, every other update kept is let go, evenly over the phase.
  if (s.reforecasts.size() + 2 > StopOutcome::kMaxReforecastsKept) {
    following_->stride *= 2;
    const std::uint32_t stride = following_->stride;
    std::erase_if(s.reforecasts, [stride](const Reforecast& f) { return f.update % stride != 0; });
  }
  const bool keep = s.updates % following_->stride == 0;
  const bool enabled[2] = {linearized_, nonlinear_};
  for (int i = 0; i < 2; ++i) {
    if (!enabled[i]) continue;
    Reforecast f;
    f.update = s.updates;
    f.t_s = r.t_s;
    f.force_n = r.force_n;
    f.u_star_v = now.u_v;
    f.stop_forecast_force_n = expected[i].force_n;
    f.prediction = predict(i == 0 ? PredictionMethod::kLinearized : PredictionMethod::kNonlinear, model_, now);
    if (keep) s.reforecasts.push_back(f);
    if (listener_) listener_->on_reforecast(s, f);
    if (!events_) continue;
    const Prediction& p = f.prediction;
    *events_ << "{\"event\":\"reforecast\",\"t\":" << num(f.t_s, 12) << ",\"stop\":" << s.index
             << ",\"t_stop\":" << num(s.t_stop_s, 12) << ",\"update\":" << f.update << ",\"method\":\""
             << to_string(p.method) << "\",\"will_restart\":" << (p.will_restart ? "true" : "false")
             << ",\"direction\":" << p.direction << ",\"t_restart\":" << num(p.t_restart_s, 12)
             << ",\"u_star\":" << num(f.u_star_v) << ",\"force\":" << num(f.force_n)
             << ",\"stop_forecast_force\":" << num(f.stop_forecast_force_n)
             << ",\"min_margin\":" << num(p.min_margin_n)
             << ",\"horizon_reached\":" << (p.horizon_reached ? "true" : "false") << "}\n";
  }
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

// The stop has ended (or the run has): its half-way forecasts are settled, and its history goes
// unless it is kept.
void RunReport::settle(StopOutcome& s) const {
  s.halfway_linearized.reset();
  s.halfway_nonlinear.reset();
  if (const Reforecast* f = halfway_reforecast(s, PredictionMethod::kLinearized)) s.halfway_linearized = *f;
  if (const Reforecast* f = halfway_reforecast(s, PredictionMethod::kNonlinear)) s.halfway_nonlinear = *f;
  if (!keep_reforecasts_) std::vector<Reforecast>().swap(s.reforecasts);
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
    following_.reset();
    if (stops_.size() >= max_stops_kept_) {  // a daemon's summary lists the last ones
      const std::size_t n = stops_.size() - max_stops_kept_ + max_stops_kept_ / 4;
      stops_.erase(stops_.begin(), stops_.begin() + static_cast<std::ptrdiff_t>(n));
      stops_forgotten_ += n;
    }
    stops_.push_back(s);
    if (forecastable && (linearized_ || nonlinear_)) {
      following_.emplace();
      if (linearized_) following_->tracks[0].emplace(PredictionMethod::kLinearized, model_, s.snapshot);
      if (nonlinear_) following_->tracks[1].emplace(PredictionMethod::kNonlinear, model_, s.snapshot);
      following_->next_update_s = s.snapshot.t_s + update_period_s_;
    }
    return;
  }
  if (e.kind == LoopEvent::Kind::kFaultReset || e.kind == LoopEvent::Kind::kResetRefused) {
    if (events_)
      *events_ << "{\"event\":\"" << (e.kind == LoopEvent::Kind::kFaultReset ? "fault_reset" : "fault_reset_refused")
               << "\",\"t\":" << num(e.t_s, 12) << ",\"cause\":\"" << fault_name(e.fault_cause) << "\"}\n";
    return;
  }
  if (e.kind == LoopEvent::Kind::kFault) {
    following_.reset();  // the safe output replaces u*
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
    following_.reset();
    StopOutcome& s = stops_.back();
    s.ended = true;
    s.restarted = e.restart;
    s.t_end_s = e.t_s;
    s.direction = e.direction;
    settle(s);
  }
}

void RunReport::finish(double t_end_s) {
  t_end_s_ = std::max(t_end_s_, t_end_s);
  for (auto& s : stops_)
    if (!s.ended) {
      s.t_end_s = t_end_s_;
      settle(s);
    }
  if (events_) *events_ << "{\"event\":\"end\",\"t\":" << num(t_end_s_, 12) << "}\n";
  if (listener_) listener_->on_end(t_end_s_);
}

void RunReport::record_command(const CommandRecord& c) {
  if (!events_) return;
  *events_ << "{\"event\":\"command\",\"t\":" << num(t_end_s_, 12) << ",\"verdict\":\""
           << (c.accepted ? "accepted" : "rejected") << "\",\"reason\":";
  if (c.accepted) *events_ << "null";
  else *events_ << Str{c.reason};
  *events_ << ",\"kind\":";
  if (c.decoded) *events_ << Str{c.kind} << ",\"seq\":" << c.seq << ",\"value\":" << num(c.value);
  else *events_ << "null,\"seq\":null,\"value\":null";
  *events_ << ",\"text\":" << Str{c.text} << "}\n";
}

void RunReport::print_live_summary(std::FILE* out) const {
  const auto followed = [](const StopOutcome& s) {
    return !std::isnan(s.largest_gap_linearized_n) || !std::isnan(s.largest_gap_nonlinear_n);
  };
  if (std::none_of(stops_.begin(), stops_.end(), followed)) return;
  std::fprintf(out, "while stuck: the largest gap between the measured force and each forecast made at the stop (until\n"
                    "the start is seen), and the forecast made again from the pressures half-way through the phase%s:\n",
               update_period_s_ > 0.0 ? "" : " (off: controller.predictor.update_period_s = 0)");
  std::fprintf(out, "  %3s %11s %12s %12s %7s  %-24s %-24s\n", "#", "stuck[s]", "gap lin[N]", "gap nl[N]",
               "updates", "half-way linearized", "half-way nonlinear");
  for (const auto& s : stops_) {
    if (!followed(s)) continue;
    std::string cells[2] = {"-", "-"};
    const std::optional<Reforecast>* halfway[2] = {&s.halfway_linearized, &s.halfway_nonlinear};
    for (int i = 0; i < 2; ++i)
      if (*halfway[i]) cells[i] = forecast_cell(s, (*halfway[i])->prediction, t_end_s_);
    std::fprintf(out, "  %3llu %11.3f %12.3f %12.3f %7u  %-24s %-24s\n", static_cast<unsigned long long>(s.index),
                 s.sticking_s(), s.largest_gap_linearized_n, s.largest_gap_nonlinear_n, s.updates, cells[0].c_str(),
                 cells[1].c_str());
  }
}

void RunReport::print_summary(std::FILE* out, const LoopTiming& timing) const {
  std::fprintf(out, "stops (sticking phases) and their restart forecasts; forecast error in %% of the sticking\n"
                    "time when it lasted 0.5 s or more, in ms (forecast - actual) otherwise:\n");
  if (linearized_ && model_.linearized_slope != LinearizedSlope::kStopTangent)
    std::fprintf(out, "(linearized: Eq. 23's flow slope is the %s (controller.predictor.linearized_slope: %s),\n"
                      " not the paper's tangent at the stop pressure)\n",
                 model_.linearized_slope == LinearizedSlope::kChord ? "chord from the stop pressure to p_null(u*)"
                                                                     : "tangent at p_null(u*)",
                 to_string(model_.linearized_slope));
  std::fprintf(out, "  %3s %9s %9s %8s %8s %8s  %-34s %-24s %-24s\n", "#", "t_stop[s]", "y*[mm]", "F[N]",
               "u*[V]", "F_e[N]", "what happened", "linearized", "nonlinear");
  for (const auto& s : stops_) {
    char happened[64];
    if (!s.ended && !std::isnan(s.forecast_void_at_s))
      std::snprintf(happened, sizeof happened, "stuck; u* changed at %.4f s", s.forecast_void_at_s);
    else if (!s.ended)
      std::snprintf(happened, sizeof happened, "stuck to the end (%.3f s)", s.sticking_s());
    else if (s.restarted)
      std::snprintf(happened, sizeof happened, "restart %c at %.4f s (%.3f s)", s.direction > 0 ? '+' : '-',
                    s.t_end_s, s.sticking_s());
    else
      std::snprintf(happened, sizeof happened, "set point moved at %.4f s", s.t_end_s);
    std::string cells[2];
    const std::optional<Prediction>* ps[2] = {&s.linearized, &s.nonlinear};
    for (int i = 0; i < 2; ++i) cells[i] = *ps[i] ? forecast_cell(s, **ps[i], t_end_s_) : "-";
    const Prediction* any = s.nonlinear ? &*s.nonlinear : (s.linearized ? &*s.linearized : nullptr);
    std::fprintf(out, "  %3llu %9.4f %9.3f %8.2f %8.4f %8.2f  %-34s %-24s %-24s\n",
                 static_cast<unsigned long long>(s.index), s.t_stop_s, s.y_stop_m * 1e3, s.force_n,
                 s.snapshot.u_v, any ? any->equilibrium_force_n : NAN, happened, cells[0].c_str(),
                 cells[1].c_str());
  }
  if (stops_.empty()) std::fprintf(out, "  (none)\n");
  if (stops_forgotten_ > 0)
    std::fprintf(out, "  (and %llu earlier stops, not kept)\n", static_cast<unsigned long long>(stops_forgotten_));
  print_live_summary(out);
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
