// The end of a run: pneud's summary for people (the stops and their forecasts judged, the live
// predictor's gaps, the faults, the loop's timing, LCM and Modbus figures) and its figures for
// programs (--summary-json). Written once, from the runtime's account of the run (Runtime) and the
// figures the runtime does not know (RunFigures).
#pragma once

#include <cstdint>
#include <cstdio>
#include <ostream>
#include <string>

#include "pneu/controller/run_figures.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/controller/summary_record.hpp"

namespace pneu::controller {

/// How a run ended, for pneud's exit code and the first line of its summary. When both hold, the
/// safe output not confirmed wins: the module may still drive the valves, a matter for someone at
/// the bench at once, whatever the fault.
enum class RunEnding : std::uint8_t {
  kOk,                     ///< no fault latched at the end, the safe output confirmed (or no module)
  kFaultLatched,           ///< a fault still latched at the end: the outputs in the safe state
  kSafeOutputUnconfirmed,  ///< the module did not confirm the safe output on closing
};
[[nodiscard]] RunEnding run_ending(const RunFigures& figures) noexcept;
/// "ok", "fault_latched", "safe_output_unconfirmed" (--summary-json's exit_reason).
[[nodiscard]] const char* to_string(RunEnding ending) noexcept;
/// pneud's exit code for it: cli::kExitOk, kExitFaulted, kExitSafeOutputUnconfirmed.
[[nodiscard]] int exit_code(RunEnding ending) noexcept;
/// A sentence for people saying how the run ended, when not kOk (empty otherwise): the summary's
/// first line, and pneud's last line on stderr (the journal's).
[[nodiscard]] std::string ending_text(const RunFigures& figures, const Runtime& runtime);

/// pneud's summary, as docs/results.md shows it: first, when the run did not end well, why
/// (ending_text).
void print_summary(std::FILE* out, const RunFigures& figures, const Runtime& runtime);

/// The run's figures as the summary record (pneu/controller/summary_record.hpp describes it).
[[nodiscard]] RunSummaryRecord run_summary_record(const RunFigures& figures, const Runtime& runtime);

/// The run's figures as one JSON object (pneud --summary-json; docs/pneud.md lists its members):
/// what the summary's lines say of the run, the loop, LCM and Modbus, with units in the names;
/// the summary record's JSON document.
void write_summary_json(std::ostream& out, const RunFigures& figures, const Runtime& runtime);

}  // namespace pneu::controller
