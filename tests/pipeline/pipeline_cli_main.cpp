// softatlas_pipeline_cli: `softatlas` restricted to the pipeline subcommands (same error handling).
#include <cstdio>
#include <string>
#include <vector>

#include "softatlas/pipeline/cli.hpp"
#include "softatlas/sim/error.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty()) {
    std::fputs("usage: softatlas_pipeline_cli build|segment|check|export|bench pipeline ...\n", stderr);
    return 2;
  }
  try {
    return softatlas::pipeline::cli_main(args);
  } catch (const softatlas::InputError& e) {
    std::fprintf(stderr, "softatlas: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softatlas: error: %s\n", e.what());
    return 1;
  }
}
