// The pipeline's subcommands of `softatlas`: build, segment, check, export, bench pipeline,
// bench segment, registered on the one command line (softatlas/io/cli.hpp).
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}
namespace softatlas::cli {
struct Status;
}

namespace softatlas::pipeline {

// Adds the pipeline's subcommands to root (the `bench` group is shared); the one that runs sets
// status->rc.
void add_commands(CLI::App& root, cli::Status* status);

// Parses and runs the whole argument list after `softatlas` with only the pipeline's commands.
// Returns the exit status (0 ok, 2 usage error); bad input throws softatlas::InputError (one
// line, exit 1 in main).
int cli_main(const std::vector<std::string>& args);

}  // namespace softatlas::pipeline
