// The end of a run: pneud's summary for people (the stops and their forecasts judged, the live
// predictor's gaps, the faults, the loop's timing, LCM and Modbus figures) and its figures for
// programs (--summary-json). Written once, from the runtime's account of the run (Runtime) and the
// figures the runtime does not know (RunFigures).
#pragma once

#include <cstdio>
#include <ostream>

#include "pneu/controller/run_figures.hpp"
#include "pneu/controller/runtime.hpp"

namespace pneu::controller {

/// pneud's summary, as the README shows it.
void print_summary(std::FILE* out, const RunFigures& figures, const Runtime& runtime);

/// The run's figures as one JSON object (pneud --summary-json; the README lists its members):
/// what the summary's lines say of the run, the loop, LCM and Modbus, with units in the names.
void write_summary_json(std::ostream& out, const RunFigures& figures, const Runtime& runtime);

}  // namespace pneu::controller
