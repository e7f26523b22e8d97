// softatlas: one command, subcommands like git. Thin: it parses the first words and hands the
// rest to the library that owns the subcommand. Bad input anywhere surfaces as InputError and
// becomes one line on stderr and exit status 1.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "softatlas/bench/cli.hpp"
#include "softatlas/sim/error.hpp"
#ifdef SOFTATLAS_HAVE_PIPELINE
#include "softatlas/pipeline/cli.hpp"
#endif
#ifdef SOFTATLAS_HAVE_APP
#include "softatlas/app/cli.hpp"
#endif
#ifdef SOFTATLAS_HAVE_EVIDENCE
#include "softatlas/evidence/cli.hpp"
#endif

namespace {

constexpr const char* kUsage = R"(usage: softatlas <command> [options]

  demo                                  build the embedded sample, run a lesson headless
  build CT [--labels L | --seeds S.yaml] [--organs a,b] [--budget a=N,...] -o SET
  build --mesh FILE [...] -o SET        organ set from surface meshes
  segment CT --seeds S.yaml -o LABELS.nii.gz
  check SET                             validate an organ set, print its quality report
  export SET -o atlas.glb               glTF 2.0 (binary)
  view SET|LESSON [--headless --frames N --screenshot out.png]
  lesson check LESSON                   validate only (FILE:LINE:COLUMN: message)
  lesson run LESSON --device SCRIPT --out DIR
  sim SET|MESH... --explain             print the compiled physics plan
  bench sim --mesh A.obj [B.obj ...] --model tmsm|cmsm|nmsm --integrator I --steps N --json
  bench pipeline|render|haptic ... --json
  bench accuracy|stability [--quick] --out DIR

Run 'softatlas <command> --help' for the options of one command.
)";

int unavailable(const std::string& what, const char* option) {
  std::fprintf(stderr, "softatlas: '%s' is not part of this build (configure with %s=ON)\n",
               what.c_str(), option);
  return 2;
}

int dispatch(const std::vector<std::string>& args) {
  const std::string& cmd = args[0];
  const std::string sub = args.size() > 1 ? args[1] : "";
  if (cmd == "bench" && (sub == "sim")) return softatlas::bench::cli_main(args);
  if (cmd == "sim") return softatlas::bench::cli_main(args);
  if (cmd == "bench" && (sub == "accuracy" || sub == "stability")) {
#ifdef SOFTATLAS_HAVE_EVIDENCE
    return softatlas::evidence::cli_main(args);
#else
    return unavailable("bench " + sub, "SOFTATLAS_BUILD_BENCH");
#endif
  }
  if (cmd == "build" || cmd == "segment" || cmd == "check" || cmd == "export" ||
      (cmd == "bench" && sub == "pipeline")) {
#ifdef SOFTATLAS_HAVE_PIPELINE
    return softatlas::pipeline::cli_main(args);
#else
    return unavailable(cmd, "SOFTATLAS_BUILD_PIPELINE");
#endif
  }
  if (cmd == "view" || cmd == "lesson" ||
      (cmd == "bench" && (sub == "render" || sub == "haptic"))) {
#ifdef SOFTATLAS_HAVE_APP
    return softatlas::app::cli_main(args);
#else
    return unavailable(cmd, "SOFTATLAS_BUILD_APP");
#endif
  }
  std::fprintf(stderr, "softatlas: unknown command '%s'\n%s", cmd.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    std::fputs(kUsage, args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  if (args[0] == "--version") {
    std::printf("softatlas %s\n", SOFTATLAS_VERSION);
    return 0;
  }
  try {
    return dispatch(args);
  } catch (const softatlas::InputError& e) {
    std::fprintf(stderr, "softatlas: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softatlas: error: %s\n", e.what());
    return 1;
  }
}
