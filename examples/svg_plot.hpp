// examples/svg_plot.hpp -- a minimal line-plot writer for the examples (not part of the library).
// Writes a self-contained SVG with axes, tick labels, a legend and one polyline per series.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace example {

struct Series {
    std::string label;
    std::vector<std::pair<double, double>> points;  // (x, y)
};

struct Plot {
    std::string title, x_label, y_label;
    std::vector<Series> series;
    bool log_y = false;

    /// Writes the plot to `path`; returns false if the file cannot be opened.
    bool write(const std::string& path) const {
        const double width = 640, height = 420, left = 70, right = 20, top = 40, bottom = 50;
        double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
        for (const Series& s : series)
            for (const auto& p : s.points) {
                const double y = transform(p.second);
                if (!std::isfinite(y)) continue;
                x0 = std::min(x0, p.first), x1 = std::max(x1, p.first);
                y0 = std::min(y0, y), y1 = std::max(y1, y);
            }
        if (!(x1 > x0)) x1 = x0 + 1;
        if (!(y1 > y0)) y1 = y0 + 1;
        if (!log_y) y0 = std::min(y0, 0.0);
        const auto px = [&](double x) { return left + (x - x0) / (x1 - x0) * (width - left - right); };
        const auto py = [&](double y) { return height - bottom - (y - y0) / (y1 - y0) * (height - top - bottom); };
        std::FILE* f = std::fopen(path.c_str(), "w");
        if (!f) return false;
        std::fprintf(f, "<svg xmlns='http://www.w3.org/2000/svg' width='%g' height='%g' font-family='sans-serif' "
                        "font-size='12'>\n<rect width='100%%' height='100%%' fill='white'/>\n", width, height);
        std::fprintf(f, "<text x='%g' y='22' text-anchor='middle' font-size='14'>%s</text>\n", width / 2, title.c_str());
        std::fprintf(f, "<text x='%g' y='%g' text-anchor='middle'>%s</text>\n", (left + width - right) / 2, height - 12,
                     x_label.c_str());
        std::fprintf(f, "<text x='16' y='%g' text-anchor='middle' transform='rotate(-90 16 %g)'>%s</text>\n",
                     (top + height - bottom) / 2, (top + height - bottom) / 2, y_label.c_str());
        std::fprintf(f, "<g stroke='black' fill='none'><rect x='%g' y='%g' width='%g' height='%g'/></g>\n", left, top,
                     width - left - right, height - top - bottom);
        for (int i = 0; i <= 5; ++i) {
            const double x = x0 + (x1 - x0) * i / 5, y = y0 + (y1 - y0) * i / 5;
            std::fprintf(f, "<text x='%g' y='%g' text-anchor='middle'>%.3g</text>\n", px(x), height - bottom + 16, x);
            std::fprintf(f, "<text x='%g' y='%g' text-anchor='end'>%.3g</text>\n", left - 6, py(y) + 4,
                         log_y ? std::pow(10.0, y) : y);
        }
        const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf"};
        for (std::size_t s = 0; s < series.size(); ++s) {
            const char* color = colors[s % 6];
            std::fprintf(f, "<polyline fill='none' stroke='%s' stroke-width='1.5' points='", color);
            for (const auto& p : series[s].points) {
                const double y = transform(p.second);
                if (std::isfinite(y)) std::fprintf(f, "%.2f,%.2f ", px(p.first), py(y));
            }
            std::fprintf(f, "'/>\n<text x='%g' y='%g' fill='%s'>%s</text>\n", width - right - 150,
                         top + 16 + 16 * static_cast<double>(s), color, series[s].label.c_str());
        }
        std::fprintf(f, "</svg>\n");
        return std::fclose(f) == 0;
    }

private:
    double transform(double y) const { return log_y ? (y > 0 ? std::log10(y) : NAN) : y; }
};

}  // namespace example
