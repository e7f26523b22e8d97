// softatlas: one command, subcommands like git. Thin: it parses the first words and hands the
// rest to the library that owns the subcommand. Bad input anywhere surfaces as InputError and
// becomes one line on stderr and exit status 1.
#include <cstdio>
#include <exception>
#include <filesystem>
#include <new>
#include <string>
#include <vector>

#include "softatlas/bench/cli.hpp"
#include "softatlas/io/mesh_io.hpp"
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

// `softatlas demo [--out DIR]`: the main job on the embedded data. Each part that is built runs;
// the paths of its results are printed at the end.
int demo(const std::vector<std::string>& args) {
  std::string out = "out/demo";
  for (size_t i = 1; i < args.size(); ++i) {
    if (args[i] == "--out" && i + 1 < args.size()) {
      out = args[++i];
    } else if (args[i] == "-h" || args[i] == "--help") {
      std::puts("usage: softatlas demo [--out DIR]\n  builds the embedded sample CT into an organ set, "
                "exports glTF, pulls a liver with every physics model and plays a lesson headless");
      return 0;
    } else {
      throw softatlas::InputError(args[i], "unknown option (expected --out DIR)");
    }
  }
  const std::string data = SOFTATLAS_DATA_DIR;
  std::vector<std::string> results;
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  std::fprintf(stderr, "== 1/4 physics: pull the paper-000 liver with every model\n");
  int rc = softatlas::bench::cli_main({"sim", "demo", "--out", out + "/physics"});
  if (rc != 0) return rc;
  results.push_back(out + "/physics/deformation.svg (picture), results.json (feedback force, volume change)");
#ifdef SOFTATLAS_HAVE_PIPELINE
  std::fprintf(stderr, "== 2/4 pipeline: organ set from the embedded CT (data/sample)\n");
  const std::string set = out + "/organ_set";
  std::filesystem::remove_all(set, ec);  // the demo is re-runnable; build refuses existing folders
  rc = softatlas::pipeline::cli_main({"build", data + "/sample/ct_heart_crop.nii.gz", "--labels",
                                      "heart=" + data + "/sample/heart_on_ct_heart_crop_grid.nii.gz",
                                      "--labels", "pulmonary_artery=" + data + "/sample/pulmonary_artery.nii.gz",
                                      "-o", set});
  if (rc != 0) return rc;
  rc = softatlas::pipeline::cli_main({"check", set});
  if (rc != 0) return rc;
  std::fprintf(stderr, "== 3/4 export: glTF 2.0\n");
  rc = softatlas::pipeline::cli_main({"export", set, "-o", out + "/atlas.glb"});
  if (rc != 0) return rc;
  results.push_back(set + "/ (atlas.yaml, organs/*.ply, connections.csv, quality.json)");
  results.push_back(out + "/atlas.glb (binary glTF for other VR engines)");
#endif
#ifdef SOFTATLAS_HAVE_APP
  std::fprintf(stderr, "== 4/4 lesson: liver_mobility played headless with its scripted device\n");
  rc = softatlas::app::cli_main({"lesson", "run", data + "/lessons/liver_mobility.yaml", "--device",
                                 data + "/lessons/scripts/liver_mobility.pass.yaml", "--out", out + "/lesson"});
  if (rc != 0) return rc;
  results.push_back(out + "/lesson/ (one PNG per step, report.json)");
#endif
  std::printf("\nSoftAtlas demo results:\n");
  for (const std::string& r : results) std::printf("  %s\n", r.c_str());
  return 0;
}

int dispatch(const std::vector<std::string>& args) {
  const std::string& cmd = args[0];
  const std::string sub = args.size() > 1 ? args[1] : "";
  if (cmd == "demo") return demo(args);
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
    // One line of printable text, whatever the file held (a path or value quoted from it).
    std::fprintf(stderr, "softatlas: %s\n", softatlas::io::printable_text(e.what(), 600).c_str());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "softatlas: error: out of memory (the input asks for more than this machine has)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softatlas: error: %s\n", softatlas::io::printable_text(e.what(), 600).c_str());
    return 1;
  }
}
