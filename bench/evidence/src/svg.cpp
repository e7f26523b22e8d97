#include "softatlas/evidence/svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace softatlas::evidence::svg {

namespace {

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<')
      o += "&lt;";
    else if (c == '>')
      o += "&gt;";
    else if (c == '&')
      o += "&amp;";
    else if (c == '"')
      o += "&quot;";
    else
      o += c;
  }
  return o;
}

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}

std::string tick_label(double v) {
  char b[32];
  const double a = std::abs(v);
  if (a != 0 && (a < 1e-3 || a >= 1e5))
    std::snprintf(b, sizeof b, "%.0e", v);
  else
    std::snprintf(b, sizeof b, "%g", v);
  return b;
}

void marker(std::ostringstream& o, const std::string& kind, double x, double y, const std::string& color) {
  const double r = 4.5;
  if (kind == "none") return;
  if (kind == "square") {
    o << "<rect x='" << num(x - r) << "' y='" << num(y - r) << "' width='" << num(2 * r) << "' height='" << num(2 * r)
      << "' fill='" << color << "' fill-opacity='0.8' stroke='#333' stroke-width='0.5'/>\n";
  } else if (kind == "triangle") {
    o << "<polygon points='" << num(x) << "," << num(y - r - 1) << " " << num(x - r) << "," << num(y + r) << " "
      << num(x + r) << "," << num(y + r) << "' fill='" << color
      << "' fill-opacity='0.8' stroke='#333' stroke-width='0.5'/>\n";
  } else if (kind == "diamond") {
    o << "<polygon points='" << num(x) << "," << num(y - r - 1) << " " << num(x - r - 1) << "," << num(y) << " "
      << num(x) << "," << num(y + r + 1) << " " << num(x + r + 1) << "," << num(y) << "' fill='" << color
      << "' fill-opacity='0.8' stroke='#333' stroke-width='0.5'/>\n";
  } else {
    o << "<circle cx='" << num(x) << "' cy='" << num(y) << "' r='" << num(r) << "' fill='" << color
      << "' fill-opacity='0.8' stroke='#333' stroke-width='0.5'/>\n";
  }
}

}  // namespace

const std::string& color(int index) {
  static const std::vector<std::string> p = {"#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                                             "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"};
  return p[static_cast<size_t>(((index % 10) + 10) % 10)];
}

std::string render(const Plot& p) {
  const double L = 80, R = 190, T = 40, B = 60;
  const double W = p.width, H = p.height, pw = W - L - R, ph = H - T - B;
  auto ok = [&](double v, bool lg) { return std::isfinite(v) && (!lg || v > 0); };
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (const auto& s : p.series)
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i)
      if (ok(s.x[i], p.logx) && ok(s.y[i], p.logy)) {
        const double xv = p.logx ? std::log10(s.x[i]) : s.x[i], yv = p.logy ? std::log10(s.y[i]) : s.y[i];
        x0 = std::min(x0, xv), x1 = std::max(x1, xv), y0 = std::min(y0, yv), y1 = std::max(y1, yv);
      }
  if (!(x0 <= x1)) x0 = 0, x1 = 1;
  if (!(y0 <= y1)) y0 = 0, y1 = 1;
  if (p.logx) x0 = std::floor(x0), x1 = std::max(std::ceil(x1), x0 + 1);
  if (p.logy) y0 = std::floor(y0), y1 = std::max(std::ceil(y1), y0 + 1);
  if (!p.logx) {
    const double m = 0.05 * std::max(x1 - x0, 1e-12);
    x0 -= m;
    x1 += m;
  }
  if (!p.logy) {
    const double m = 0.05 * std::max(y1 - y0, 1e-12);
    y0 -= m;
    y1 += m;
  }
  auto X = [&](double v) { return L + pw * ((p.logx ? std::log10(v) : v) - x0) / (x1 - x0); };
  auto Y = [&](double v) { return T + ph * (1.0 - ((p.logy ? std::log10(v) : v) - y0) / (y1 - y0)); };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H << "' viewBox='0 0 " << W << " " << H
    << "' font-family='Helvetica,Arial,sans-serif' font-size='12'>\n";
  o << "<rect width='100%' height='100%' fill='white'/>\n";
  o << "<text x='" << num(L + pw / 2) << "' y='22' text-anchor='middle' font-size='15'>" << esc(p.title) << "</text>\n";
  // Axes and ticks.
  auto ticks = [&](double a, double b, bool lg) {
    std::vector<double> t;
    if (lg) {
      for (double e = std::ceil(a); e <= b + 1e-9; e += 1) t.push_back(std::pow(10.0, e));
    } else {
      const double span = b - a, raw = span / 6, mag = std::pow(10.0, std::floor(std::log10(raw)));
      const double step = raw / mag < 2 ? 2 * mag : raw / mag < 5 ? 5 * mag : 10 * mag;
      for (double v = std::ceil(a / step) * step; v <= b + 1e-12; v += step)
        t.push_back(std::abs(v) < 1e-12 * step ? 0 : v);
    }
    return t;
  };
  o << "<rect x='" << L << "' y='" << T << "' width='" << num(pw) << "' height='" << num(ph)
    << "' fill='none' stroke='#333'/>\n";
  for (double t : ticks(x0, x1, p.logx)) {
    const double x = X(t);
    o << "<line x1='" << num(x) << "' y1='" << T << "' x2='" << num(x) << "' y2='" << num(T + ph)
      << "' stroke='#ddd'/>\n<text x='" << num(x) << "' y='" << num(T + ph + 16) << "' text-anchor='middle'>"
      << tick_label(t) << "</text>\n";
  }
  for (double t : ticks(y0, y1, p.logy)) {
    const double y = Y(t);
    o << "<line x1='" << L << "' y1='" << num(y) << "' x2='" << num(L + pw) << "' y2='" << num(y)
      << "' stroke='#ddd'/>\n<text x='" << num(L - 6) << "' y='" << num(y + 4) << "' text-anchor='end'>"
      << tick_label(t) << "</text>\n";
  }
  o << "<text x='" << num(L + pw / 2) << "' y='" << num(H - 18) << "' text-anchor='middle'>" << esc(p.xlabel)
    << "</text>\n";
  o << "<text transform='translate(18," << num(T + ph / 2) << ") rotate(-90)' text-anchor='middle'>" << esc(p.ylabel)
    << "</text>\n";
  // Data.
  for (const auto& s : p.series) {
    if (s.line) {
      o << "<polyline fill='none' stroke='" << s.color << "' stroke-width='1.6'"
        << (s.dashed ? " stroke-dasharray='6,4'" : "") << " points='";
      for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i)
        if (ok(s.x[i], p.logx) && ok(s.y[i], p.logy)) o << num(X(s.x[i])) << "," << num(Y(s.y[i])) << " ";
      o << "'/>\n";
    }
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i)
      if (ok(s.x[i], p.logx) && ok(s.y[i], p.logy)) marker(o, s.marker, X(s.x[i]), Y(s.y[i]), s.color);
  }
  // Legend.
  double ly = T + 8;
  for (const auto& s : p.series) {
    if (s.name.empty()) continue;
    const double lx = L + pw + 14;
    if (s.line) {
      o << "<line x1='" << num(lx - 6) << "' y1='" << num(ly) << "' x2='" << num(lx + 14) << "' y2='" << num(ly)
        << "' stroke='" << s.color << "' stroke-width='1.6'" << (s.dashed ? " stroke-dasharray='6,4'" : "") << "/>\n";
    }
    marker(o, s.marker, lx + 4, ly, s.color);
    o << "<text x='" << num(lx + 20) << "' y='" << num(ly + 4) << "'>" << esc(s.name) << "</text>\n";
    ly += 18;
  }
  o << "</svg>\n";
  return o.str();
}

std::string render(const std::vector<HeatMap>& maps, const Legend& legend, int columns, const std::string& title,
                   const std::string& xlabel, const std::string& ylabel) {
  const double cw = 34, ch = 22, gap_x = 70, gap_y = 70, left = 80, top = 50;
  size_t nx = 1, ny = 1;
  for (const auto& m : maps) nx = std::max(nx, m.xlabels.size()), ny = std::max(ny, m.ylabels.size());
  columns = std::max(1, columns);
  const int rows = static_cast<int>((maps.size() + columns - 1) / columns);
  const double mw = cw * nx, mh = ch * ny;
  const double W = left + columns * (mw + gap_x) + 20, H = top + rows * (mh + gap_y) + 40;
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << num(W) << "' height='" << num(H) << "' viewBox='0 0 "
    << num(W) << " " << num(H) << "' font-family='Helvetica,Arial,sans-serif' font-size='10'>\n";
  o << "<rect width='100%' height='100%' fill='white'/>\n";
  o << "<text x='" << num(W / 2) << "' y='20' text-anchor='middle' font-size='15'>" << esc(title) << "</text>\n";
  double lx = left;
  for (size_t k = 0; k < legend.names.size(); ++k) {
    o << "<rect x='" << num(lx) << "' y='30' width='12' height='12' fill='" << legend.colors[k]
      << "' stroke='#333' stroke-width='0.5'/>";
    o << "<text x='" << num(lx + 16) << "' y='40' font-size='12'>" << esc(legend.names[k]) << "</text>\n";
    lx += 30 + 7.0 * legend.names[k].size();
  }
  for (size_t mi = 0; mi < maps.size(); ++mi) {
    const HeatMap& m = maps[mi];
    const double ox = left + (mi % columns) * (mw + gap_x), oy = top + 20 + (mi / columns) * (mh + gap_y);
    o << "<text x='" << num(ox + mw / 2) << "' y='" << num(oy - 6) << "' text-anchor='middle' font-size='12'>"
      << esc(m.title) << "</text>\n";
    const size_t mx = m.xlabels.size(), my = m.ylabels.size();
    for (size_t iy = 0; iy < my; ++iy)
      for (size_t ix = 0; ix < mx; ++ix) {
        const size_t c = iy * mx + ix;
        const int cat = c < m.cells.size() ? m.cells[c] : -1;
        const std::string fill =
            cat >= 0 && cat < static_cast<int>(legend.colors.size()) ? legend.colors[cat] : "#f4f4f4";
        const double x = ox + ix * cw, y = oy + (my - 1 - iy) * ch;
        o << "<rect x='" << num(x) << "' y='" << num(y) << "' width='" << cw - 1 << "' height='" << ch - 1 << "' fill='"
          << fill << "'/>";
        if (c < m.cell_text.size() && !m.cell_text[c].empty())
          o << "<text x='" << num(x + cw / 2) << "' y='" << num(y + ch / 2 + 3)
            << "' text-anchor='middle' font-size='8'>" << esc(m.cell_text[c]) << "</text>";
        o << "\n";
      }
    for (size_t ix = 0; ix < mx; ++ix)
      o << "<text transform='translate(" << num(ox + ix * cw + cw / 2 + 3) << "," << num(oy + my * ch + 4)
        << ") rotate(60)' font-size='9'>" << esc(m.xlabels[ix]) << "</text>\n";
    for (size_t iy = 0; iy < my; ++iy)
      o << "<text x='" << num(ox - 4) << "' y='" << num(oy + (my - 1 - iy) * ch + ch / 2 + 3)
        << "' text-anchor='end' font-size='9'>" << esc(m.ylabels[iy]) << "</text>\n";
  }
  o << "<text x='" << num(W / 2) << "' y='" << num(H - 8) << "' text-anchor='middle' font-size='12'>" << esc(xlabel)
    << "</text>\n";
  o << "<text transform='translate(14," << num(H / 2) << ") rotate(-90)' text-anchor='middle' font-size='12'>"
    << esc(ylabel) << "</text>\n";
  o << "</svg>\n";
  return o.str();
}

}  // namespace softatlas::evidence::svg
