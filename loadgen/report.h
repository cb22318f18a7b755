// Output of loadgen scenarios: JSON (nlohmann), a console table, and gnuplot charts.
#pragma once

#include <string>
#include <vector>

#include "loadgen/relay_compare.h"

namespace edgephys::loadgen {

// {"scenario":"relay-compare","results":[...]} per the schema, plus options echoed.
std::string RelayCompareJson(const RelayCompareOptions& options,
                             const std::vector<RelayCompareResult>& results);
// A table beside the paper's columns.
std::string RelayCompareTable(const std::vector<RelayCompareResult>& results);
// Writes <prefix>.dat, <prefix>_bandwidth.gp/.png/.svg and <prefix>_error.gp/.png/.svg (charts
// only if gnuplot is on PATH). Returns false if a file could not be written.
bool WriteRelayCompareCharts(const std::vector<RelayCompareResult>& results,
                             const std::string& prefix);

}  // namespace edgephys::loadgen
