#include "softatlas/evidence/cli.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>

#include "softatlas/evidence/evidence.hpp"
#include "softatlas/io/cli.hpp"
#include "softatlas/io/output_folder.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::evidence {

namespace {

struct EvidenceArgs {
  Options opt;
  bool quick = false, no_paper = false, no_fit = false;
  std::string grid;
};

int run_evidence(const std::string& what, EvidenceArgs a) {
  auto& [opt, quick, no_paper, no_fit, grid] = a;
  opt.grid = quick ? Grid::quick : Grid::full;
  if (grid == "tiny")
    opt.grid = Grid::tiny;
  else if (grid == "quick")
    opt.grid = Grid::quick;
  else if (grid == "full")
    opt.grid = Grid::full;
  opt.paper_tables = !no_paper;
  opt.fit = !no_fit;
  // Every plot, results.json and report.md appear together or not at all (a full disk, a
  // read-only folder: one InputError naming the folder).
  io::StagedFolder staged(opt.out_dir);
  const nlohmann::json result = staged.write_and_commit([&](const std::string& dir) {
    Options staged_opt = a.opt;
    staged_opt.out_dir = dir;
    const nlohmann::json r = what == "accuracy" ? run_accuracy(staged_opt) : run_stability(staged_opt);
    write_file_atomic(dir + "/results.json", r.dump(1));
    write_file_atomic(dir + "/report.md", what == "accuracy" ? accuracy_markdown(r) : stability_markdown(r));
    return r;
  });
  nlohmann::json summary = {
      {"command", "bench " + what}, {"results", opt.out_dir + "/results.json"}, {"seconds", result["seconds"]}};
  if (what == "accuracy")
    summary["runs"] = result["runs"].size();
  else
    summary["summary"] = result["summary"];
  std::printf("%s\n", summary.dump().c_str());
  return 0;
}

void add_one(CLI::App& bench, cli::Status* status, const std::string& what) {
  CLI::App* app = bench.add_subcommand(
      what, what == "accuracy"
                ? "error against run time of every model against a FEM reference; paper 000 tables"
                : "stability maps over stiffness, time step, load and mesh quality, with and without the guard");
  auto a = std::make_shared<EvidenceArgs>();
  a->opt.data_dir = SOFTATLAS_DEFAULT_DATA;
  app->add_flag("--quick", a->quick, "small grid for CI (< 5 min for both commands)");
  app->add_option("--grid", a->grid, "tiny | quick | full (tiny is for tests)")
      ->check(CLI::IsMember({"tiny", "quick", "full"}));
  app->add_option("--out", a->opt.out_dir, "output folder (created): results.json and SVG plots")->required();
  app->add_option("--data", a->opt.data_dir, "shared data folder holding meshes/sofa/liver-smooth.obj");
  if (what == "accuracy") {
    app->add_flag("--no-paper", a->no_paper, "skip the paper 000 tables");
    app->add_flag("--no-fit", a->no_fit, "skip the parameter fitting");
  }
  cli::on_run(app, status, [a, what] { return run_evidence(what, *a); });
}

}  // namespace

void add_commands(CLI::App& root, cli::Status* status) {
  CLI::App* bench = cli::group(root, "bench", "benchmarks (JSON on stdout)");
  add_one(*bench, status, "accuracy");
  add_one(*bench, status, "stability");
}

int cli_main(const std::vector<std::string>& args) { return cli::run_only(add_commands, args); }

}  // namespace softatlas::evidence
