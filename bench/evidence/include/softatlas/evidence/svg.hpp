// Plain SVG plots for the evidence (no plotting dependency: the files are small, diff well in
// git and render on GitHub). Scatter/line plots with optional log axes, and categorical heat maps.
#pragma once

#include <string>
#include <vector>

namespace softatlas::evidence::svg {

struct Series {
  std::string name;
  std::string color = "#1f77b4";
  std::string marker = "circle";  // circle | square | triangle | diamond | none
  bool line = false;              // connect the points in order
  bool dashed = false;
  std::vector<double> x, y;  // non-finite or non-positive (on log axes) points are skipped
};

struct Plot {
  std::string title, xlabel, ylabel;
  bool logx = false, logy = false;
  std::vector<Series> series;
  int width = 760, height = 500;
};
std::string render(const Plot& plot);

// One categorical map: cells[iy * nx + ix] is an index into the legend (or -1 = empty).
struct HeatMap {
  std::string title;
  std::vector<std::string> xlabels, ylabels;  // nx, ny; y runs upwards
  std::vector<int> cells;
  std::vector<std::string> cell_text;  // optional, same size as cells
};
struct Legend {
  std::vector<std::string> names, colors;
};
// Small multiples: maps laid out in `columns` columns with one shared legend.
std::string render(const std::vector<HeatMap>& maps, const Legend& legend, int columns, const std::string& title,
                   const std::string& xlabel, const std::string& ylabel);

// A qualitative palette (Tableau 10).
const std::string& color(int index);

}  // namespace softatlas::evidence::svg
