#pragma once

#include "relief/metrics.h"

namespace relief::cli {

// Human-readable lines, or one JSON object.
void print_metrics(const ErrorMetrics& m, bool json);

}  // namespace relief::cli
