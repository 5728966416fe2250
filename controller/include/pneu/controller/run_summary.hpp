// The end of a run, for people: pneud's summary (the stops and their forecasts judged, the live
// predictor's gaps, the faults, the loop's timing, LCM and Modbus figures). Written once, from the
// runtime's account of the run (Runtime) and the figures the runtime does not know (RunFigures).
#pragma once

#include <cstdio>

#include "pneu/controller/run_figures.hpp"
#include "pneu/controller/runtime.hpp"

namespace pneu::controller {

/// pneud's summary, as the README shows it.
void print_summary(std::FILE* out, const RunFigures& figures, const Runtime& runtime);

}  // namespace pneu::controller
