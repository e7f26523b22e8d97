// `softatlas sim SET|MESH... --explain`, `sim demo`, `bench sim`, `bench restore`, `bench contact`, registered on
// the one command line (softatlas/io/cli.hpp).
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}
namespace softatlas::cli {
struct Status;
}

namespace softatlas::bench {

// Adds sim (with sim demo), bench sim and bench restore to root (the `bench` group is shared).
void add_commands(CLI::App& root, cli::Status* status);
void add_sim_demo(CLI::App& sim, cli::Status* status);         // physics_demo.cpp
void add_bench_restore(CLI::App& bench, cli::Status* status);  // bench_restore.cpp
void add_bench_contact(CLI::App& bench, cli::Status* status);  // bench_contact.cpp

// Parses and runs the whole argument list after `softatlas` with only these commands; returns
// the exit status (0 ok, 2 usage error, 3 non-finite state); bad input throws InputError.
int cli_main(const std::vector<std::string>& args);

}  // namespace softatlas::bench
