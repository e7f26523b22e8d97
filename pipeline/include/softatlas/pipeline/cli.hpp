// Entry point of the pipeline subcommands of `softatlas`: build, segment, check, export,
// bench pipeline. `args` is the whole argument list after `softatlas`.
#pragma once

#include <string>
#include <vector>

namespace softatlas::pipeline {

// Returns the process exit status. Bad input throws softatlas::InputError (one line, exit 1 in
// main); usage errors print CLI11's message and return 2.
int cli_main(const std::vector<std::string>& args);

}  // namespace softatlas::pipeline
