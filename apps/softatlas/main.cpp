// softatlas: one command, subcommands like git, on one CLI11 command line: each library registers
// its subcommands (softatlas/io/cli.hpp). Exit status: 0 ok, 1 bad input (an InputError anywhere
// becomes one line on stderr), 2 usage error, 3 `lesson run` with a failed task.
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <new>
#include <sstream>
#include <string>
#include <vector>

#include "softatlas/bench/cli.hpp"
#include "softatlas/io/cli.hpp"
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

constexpr int kMaxErrorLines = 100;  // error lines printed for one bad file

constexpr const char* kUsage = R"(usage: softatlas <command> [options]

  demo                                  build the embedded sample, run a lesson headless
  build CT [--labels L | --seeds S.yaml] [--organs a,b] [--budget a=N,...] -o SET
  build --mesh FILE [...] -o SET        organ set from surface meshes
  segment CT --seeds S.yaml -o LABELS.nii.gz
  check SET                             validate an organ set, print its quality report
  export SET -o atlas.glb|atlas.gltf    glTF 2.0 (binary, or JSON + .bin)
  export SET --web DIR                  static WebXR page (the physics in WebAssembly)
  view SET|LESSON [--headless --frames N --screenshot out.png]
  lesson check LESSON                   validate only (FILE:LINE:COLUMN: message)
  lesson run LESSON --device SCRIPT --out DIR
  sim SET|MESH... --explain             print the compiled physics plan
  bench sim --mesh A.obj [B.obj ...] --model tmsm|cmsm|nmsm --integrator I --steps N --json
  bench restore SET --organ NAME [--pull-mm 30] [--model M] [--contact] --json
  bench contact SET [--push-mm 20] [--organ NAME] [--compare] --json
  bench pipeline|render|haptic ... --json
  bench segment [--cases ...] [--variants ...] --json   seeded segmentation, fixed random seed draws
  bench accuracy|stability [--quick] --out DIR

Run 'softatlas <command> --help' for the options of one command.
)";

// Runs f with stdout sent to `path` (the JSON a subcommand prints goes to a file, not the
// terminal); returns f's status.
template <class F>
int stdout_to(const std::string& path, F&& f) {
  std::fflush(stdout);
  const int saved = dup(1);
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0 || saved < 0) throw softatlas::InputError(path, "cannot write the demo's output");
  dup2(fd, 1);
  close(fd);
  int rc = 1;
  try {
    rc = f();
  } catch (...) {
    std::fflush(stdout);
    dup2(saved, 1);
    close(saved);
    throw;
  }
  std::fflush(stdout);
  dup2(saved, 1);
  close(saved);
  return rc;
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream f(path);
  nlohmann::json j = nlohmann::json::parse(f, nullptr, false);
  return j.is_discarded() ? nlohmann::json::object() : j;
}

// `softatlas demo [--out DIR]`: the main job on the embedded data. Each part that is built runs;
// its progress goes to stderr, its JSON to files in DIR, and a short summary to stdout.
int demo(const std::string& out) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string data = SOFTATLAS_DATA_DIR;
  std::vector<std::string> summary;
  char line[512];
  std::error_code ec;
  std::filesystem::create_directories(out + "/logs", ec);
  std::fprintf(stderr, "== 1/4 physics: pull the paper-000 liver with every model\n");
  int rc = stdout_to(out + "/logs/sim_demo.txt", [&] {
    return softatlas::bench::cli_main({"sim", "demo", "--out", out + "/physics"});
  });
  if (rc != 0) return rc;
  {
    const nlohmann::json j = read_json(out + "/physics/results.json");
    std::string models;
    for (const auto& r : j.value("runs", nlohmann::json::array()))
      if (r.contains("model") && r.contains("volume_change_pct")) {
        std::snprintf(line, sizeof line, "%s%s %+.1f %%", models.empty() ? "" : ", ",
                      r["model"].get<std::string>().c_str(), r["volume_change_pct"].get<double>());
        models += line;
      }
    summary.push_back("physics   liver pulled 20 mm, volume change per model: " + models);
    summary.push_back("          -> " + out + "/physics/results.json, deformation.svg");
  }
#ifdef SOFTATLAS_HAVE_PIPELINE
  std::fprintf(stderr, "== 2/4 pipeline: organ set from the embedded CT (data/sample)\n");
  const std::string set = out + "/organ_set";
  std::filesystem::remove_all(set, ec);  // the demo is re-runnable; build refuses existing folders
  rc = softatlas::pipeline::cli_main({"build", data + "/sample/ct_heart_crop.nii.gz", "--labels",
                                      "heart=" + data + "/sample/heart_on_ct_heart_crop_grid.nii.gz", "--labels",
                                      "pulmonary_artery=" + data + "/sample/pulmonary_artery.nii.gz", "-o", set});
  if (rc != 0) return rc;
  rc = stdout_to(out + "/check.json", [&] { return softatlas::pipeline::cli_main({"check", set}); });
  if (rc != 0) return rc;
  std::fprintf(stderr, "== 3/4 export: glTF 2.0\n");
  rc = softatlas::pipeline::cli_main({"export", set, "-o", out + "/atlas.glb"});
  if (rc != 0) return rc;
  {
    const nlohmann::json q = read_json(set + "/quality.json");
    std::string organs;
    const nlohmann::json list = q.contains("organs") ? q["organs"] : nlohmann::json::object();
    for (const auto& [name, o] : list.items()) {
      std::snprintf(line, sizeof line, "%s%s %d faces %s, %.0f mL", organs.empty() ? "" : ", ", name.c_str(),
                    o.value("faces", 0), o.value("closed", false) ? "closed" : "OPEN",
                    o.value("volume_mm3", 0.0) * 1e-3);
      organs += line;
    }
    summary.push_back("pipeline  organ set from the sample CT: " +
                      (organs.empty() ? std::string("see check.json") : organs));
    summary.push_back("          -> " + set + "/, " + out + "/check.json");
    summary.push_back("export    " + out + "/atlas.glb (glTF 2.0: anterior +Z, superior +Y, centred)");
  }
#endif
#ifdef SOFTATLAS_HAVE_APP
  std::fprintf(stderr, "== 4/4 lesson: liver_mobility played headless with its scripted device\n");
  rc = stdout_to(out + "/logs/lesson.json", [&] {
    return softatlas::app::cli_main({"lesson", "run", data + "/lessons/liver_mobility.yaml", "--device",
                                     data + "/lessons/scripts/liver_mobility.pass.yaml", "--out", out + "/lesson"});
  });
  if (rc != 0) return rc;
  {
    const nlohmann::json r = read_json(out + "/lesson/report.json");
    const nlohmann::json score = r.value("score", nlohmann::json::object());
    std::snprintf(line, sizeof line, "lesson    %s: %s, %d of %d tasks", r.value("lesson", std::string("?")).c_str(),
                  r.value("passed", false) ? "passed" : "failed", score.value("passed", 0), score.value("tasks", 0));
    summary.push_back(line);
    summary.push_back("          -> " + out + "/lesson/ (step_NN_*.png, end.png, report.json)");
  }
#endif
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("SoftAtlas demo: done in %.0f s (JSON reports in %s, subcommand output in %s/logs)\n", s, out.c_str(),
              out.c_str());
  for (const std::string& l : summary) std::printf("  %s\n", l.c_str());
  return 0;
}

// The one command line: every library registers its subcommands on one CLI::App (each part that
// is built; softatlas/io/cli.hpp has the exit convention).
int dispatch(const std::vector<std::string>& args) {
  CLI::App root{"SoftAtlas: CT -> physically simulated anatomy atlas", "softatlas"};
  root.require_subcommand(1);
  softatlas::cli::Status status;
  CLI::App* demo_cmd = root.add_subcommand(
      "demo",
      "build the embedded sample CT into an organ set, export glTF, pull a liver with every physics model "
      "and play a lesson headless; prints a short summary, writes every JSON report under --out");
  auto demo_out = std::make_shared<std::string>("out/demo");
  demo_cmd->add_option("--out", *demo_out, "output folder (default out/demo)");
  softatlas::cli::on_run(demo_cmd, &status, [demo_out] { return demo(*demo_out); });
  softatlas::bench::add_commands(root, &status);
#ifdef SOFTATLAS_HAVE_EVIDENCE
  softatlas::evidence::add_commands(root, &status);
#endif
#ifdef SOFTATLAS_HAVE_PIPELINE
  softatlas::pipeline::add_commands(root, &status);
#endif
#ifdef SOFTATLAS_HAVE_APP
  softatlas::app::add_commands(root, &status);
#endif
  bool known = false;
  for (const CLI::App* s : root.get_subcommands([](CLI::App*) { return true; }))
    known = known || s->get_name() == args[0];
  if (!known) {
    std::fprintf(stderr, "softatlas: unknown command '%s' (or not part of this build)\n%s",
                 softatlas::io::printable_text(args[0], 80).c_str(), kUsage);
    return softatlas::cli::kUsageError;
  }
  return softatlas::cli::run(root, status, args);
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
    // One line of printable text per error, whatever the file held (a path or value quoted from
    // it). Readers stop at their first error; lessons and device scripts report every error of
    // the file, one FILE:LINE:COLUMN line each (docs/lessons.md), so each line is kept a line.
    std::istringstream lines(e.what());
    int shown = 0, total = 0;
    for (std::string line; std::getline(lines, line);)
      if (++total <= kMaxErrorLines) {
        std::fprintf(stderr, "softatlas: %s\n", softatlas::io::printable_text(line, 600).c_str());
        ++shown;
      }
    if (total > shown) std::fprintf(stderr, "softatlas: ... and %d more errors\n", total - shown);
    return softatlas::cli::kBadInput;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "softatlas: error: out of memory (the input asks for more than this machine has)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softatlas: error: %s\n", softatlas::io::printable_text(e.what(), 600).c_str());
    return 1;
  }
}
