// `softatlas bench accuracy|stability [--quick] --out DIR` (issue 7).
#pragma once

#include <string>
#include <vector>

namespace softatlas::evidence {

// args: the whole argument list after `softatlas`, e.g. {"bench", "accuracy", "--quick", "--out", "DIR"}.
// Writes DIR/results.json and SVG plots; prints a one-line JSON summary on stdout and progress on
// stderr. Returns the exit status; throws InputError for bad input.
int cli_main(const std::vector<std::string>& args);

}  // namespace softatlas::evidence
