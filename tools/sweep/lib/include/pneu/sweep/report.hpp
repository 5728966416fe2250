// What a sweep writes: the summary printed from its statistics, the same figures as JSON, the
// stops file (one row per stop) and the scenarios file (one row per scenario).
#pragma once

#include <cstdio>
#include <ostream>
#include <span>
#include <string>

#include "pneu/sweep/rows.hpp"
#include "pneu/sweep/run.hpp"
#include "pneu/sweep/statistics.hpp"
#include "pneu/sweep/summary_record.hpp"

namespace pneu::sweep {

/// The summary's lines (pneu-sweep's standard output, less the "wrote" lines).
void print_summary(std::FILE* out, const Statistics& statistics);
/// The statistics' summary record (summary_record.hpp).
[[nodiscard]] SweepSummary summary_record(const Statistics& statistics);
/// The summary record as one JSON document (pneu-sweep --summary-json).
void write_summary_json(std::ostream& out, const Statistics& statistics);
/// The stops file's row of one stop of `r` (`online`: pneu-sweep --online).
[[nodiscard]] StopRow stop_row(const ScenarioResult& r, const JudgedStop& j, bool online);
/// The scenarios file's row of `r`.
[[nodiscard]] ScenarioRow scenario_row(const ScenarioResult& r);
/// The stops file's header line, and the rows of `r`'s stops (each line ending in a newline).
[[nodiscard]] std::string stops_csv_header();
[[nodiscard]] std::string stops_csv_rows(const ScenarioResult& r, bool online);
/// The scenarios file's header line, and `r`'s row (ending in a newline).
[[nodiscard]] std::string scenarios_csv_header(bool identify);
[[nodiscard]] std::string scenarios_csv_row(const ScenarioResult& r, bool identify);
/// One CSV row per judged-window stop (pneu-sweep --out).
void write_stops_csv(std::ostream& out, std::span<const ScenarioResult> results, bool online);
/// One CSV row per scenario (pneu-sweep --scenarios-out); identified_* columns with --identify.
void write_scenarios_csv(std::ostream& out, std::span<const ScenarioResult> results, bool identify);

}  // namespace pneu::sweep
