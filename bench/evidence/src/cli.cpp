#include "softatlas/evidence/cli.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>

#include "softatlas/evidence/evidence.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::evidence {

int cli_main(const std::vector<std::string>& args) {
  if (args.size() < 2 || args[0] != "bench" || (args[1] != "accuracy" && args[1] != "stability"))
    throw InputError("command line", "expected 'bench accuracy' or 'bench stability'");
  const std::string what = args[1];
  CLI::App app{what == "accuracy"
                   ? "Error against run time of every model against a FEM reference; paper 000 tables"
                   : "Stability maps over stiffness, time step, load and mesh quality, with and without the guard",
               "softatlas bench " + what};
  Options opt;
  bool quick = false;
  std::string grid;
  opt.data_dir = SOFTATLAS_DEFAULT_DATA;
  app.add_flag("--quick", quick, "small grid for CI (< 5 min for both commands)");
  app.add_option("--grid", grid, "tiny | quick | full (tiny is for tests)")->check(CLI::IsMember({"tiny", "quick", "full"}));
  app.add_option("--out", opt.out_dir, "output folder (created): results.json and SVG plots")->required();
  app.add_option("--data", opt.data_dir, "shared data folder holding meshes/sofa/liver-smooth.obj");
  bool no_paper = false, no_fit = false;
  if (what == "accuracy") {
    app.add_flag("--no-paper", no_paper, "skip the paper 000 tables");
    app.add_flag("--no-fit", no_fit, "skip the parameter fitting");
  }
  std::vector<std::string> rest(args.begin() + 2, args.end());
  std::reverse(rest.begin(), rest.end());  // CLI11 parses a reversed vector
  try {
    app.parse(rest);
  } catch (const CLI::CallForHelp&) {
    std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const CLI::ParseError& e) {
    throw InputError("softatlas bench " + what, e.what());
  }
  opt.grid = quick ? Grid::quick : Grid::full;
  if (grid == "tiny") opt.grid = Grid::tiny;
  else if (grid == "quick") opt.grid = Grid::quick;
  else if (grid == "full") opt.grid = Grid::full;
  opt.paper_tables = !no_paper;
  opt.fit = !no_fit;
  std::error_code ec;
  std::filesystem::create_directories(opt.out_dir, ec);
  if (ec || !std::filesystem::is_directory(opt.out_dir))
    throw InputError(opt.out_dir, "cannot create the output folder (" + ec.message() + ")");
  const nlohmann::json result = what == "accuracy" ? run_accuracy(opt) : run_stability(opt);
  write_file_atomic(opt.out_dir + "/results.json", result.dump(1));
  write_file_atomic(opt.out_dir + "/report.md", what == "accuracy" ? accuracy_markdown(result) : stability_markdown(result));
  nlohmann::json summary = {{"command", "bench " + what}, {"results", opt.out_dir + "/results.json"},
                            {"seconds", result["seconds"]}};
  if (what == "accuracy") summary["runs"] = result["runs"].size();
  else summary["summary"] = result["summary"];
  std::printf("%s\n", summary.dump().c_str());
  return 0;
}

}  // namespace softatlas::evidence
