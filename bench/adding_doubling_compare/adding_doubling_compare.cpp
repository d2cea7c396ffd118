// Slabs between smooth Fresnel faces in air, total reflectance and transmittance of a collimated beam: stratum
// (M half-range ordinates split at the critical cosine, LayerOutput::reflectance | transmittance: mode 0 only)
// against Prahl's adding-doubling (ez_RT at normal incidence, ez_RT_Oblique otherwise; N quadrature points), both
// against the converged adding-doubling of tests/data/adding_doubling_reference.txt (N = 480 and 512, good to
// ~1e-8). Printed: per code and discretization the worst of |R - R_ref| and |T - T_ref| over the cases and the
// mean wall time per solve; then, for each tolerance, the cheapest discretization of each code whose worst error
// meets it, and the ratio of their times, measured in this one process (each solve repeated, doubling the
// repetitions until 0.05 s). The cases at normal incidence with g = 0.9 (a forward peak that the ordinates must
// resolve near mu = 1) are reported apart, as in tests/test_layer_critical_split.cpp.
extern "C" {
#include "ad_cone.h"
#include "ad_prime.h"
}
#include <stratum/layer.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct Case {
    double n, albedo, g, tau, mu0, r, t;
};

std::vector<Case> read_cases() {
    std::ifstream in(STRATUM_TEST_DATA_DIR "/adding_doubling_reference.txt");
    std::vector<Case> out;
    for (std::string line; std::getline(in, line);) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream row(line);
        Case c{};
        row >> c.n >> c.albedo >> c.g >> c.tau >> c.mu0 >> c.r >> c.t;
        if (!row.fail()) out.push_back(c);
    }
    return out;
}

struct Fluxes {
    double r, t;
};

Fluxes stratum_fluxes(const Case& c, int m) {
    stratum::LayerOptions options;
    options.ordinates = m;
    stratum::LayerRequest<double> request;
    request.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
    const auto layer = stratum::solve_layer(stratum::Slab<double>(c.albedo, c.g, c.tau), stratum::SmoothDielectric<double>(1.0, c.n),
                                            stratum::SmoothDielectric<double>(c.n, 1.0), options, request);
    return {layer.reflectance(c.mu0).total(), layer.transmittance(c.mu0)};
}

Fluxes adding_doubling_fluxes(const Case& c, int n) {
    double r = 0, t = 0, ru = 0, tu = 0;
    if (c.mu0 == 1)
        ez_RT(n, c.n, 1.0, 1.0, c.albedo, c.tau, c.g, &r, &t, &ru, &tu);
    else
        ez_RT_Oblique(n, c.n, 1.0, 1.0, c.albedo, c.tau, c.g, c.mu0, &r, &t, &ru, &tu);
    return {r, t};
}

// Seconds per call of f, repeated until 0.05 s.
template <class F>
double seconds_per_call(F f) {
    for (long reps = 1;; reps *= 2) {
        const auto start = std::chrono::steady_clock::now();
        double sink = 0;
        for (long i = 0; i < reps; ++i) sink += f();
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (sink == 12345.678) std::puts("");  // (keeps the calls)
        if (s >= 0.05) return s / static_cast<double>(reps);
    }
}

struct Row {
    int points;
    double error, seconds;  // worst error over the cases; mean time per solve
};

template <class Solve>
Row measure(const std::vector<Case>& cases, int points, Solve solve) {
    Row row{points, 0, 0};
    for (const Case& c : cases) {
        const Fluxes f = solve(c, points);
        row.error = std::fmax(row.error, std::fmax(std::fabs(f.r - c.r), std::fabs(f.t - c.t)));
        row.seconds += seconds_per_call([&] { const Fluxes g = solve(c, points); return g.r + g.t; });
    }
    row.seconds /= static_cast<double>(cases.size());
    return row;
}

void compare(const char* title, const std::vector<Case>& cases) {
    std::printf("\n%s (%zu cases)\n", title, cases.size());
    std::printf("%-24s %8s %12s %12s\n", "code", "points", "worst error", "ms per solve");
    std::vector<Row> ours, theirs;
    for (int m : {8, 10, 12, 14, 16, 18, 20, 24, 28, 32, 40, 48})
        ours.push_back(measure(cases, m, stratum_fluxes));
    for (int n : {8, 12, 16, 20, 24, 32, 40, 48, 64, 96})
        theirs.push_back(measure(cases, n, adding_doubling_fluxes));
    for (const Row& r : ours) std::printf("%-24s %8d %12.2e %12.4f\n", "stratum (M)", r.points, r.error, 1e3 * r.seconds);
    for (const Row& r : theirs) std::printf("%-24s %8d %12.2e %12.4f\n", "adding-doubling (N)", r.points, r.error, 1e3 * r.seconds);
    // The cheapest row meeting each tolerance (the errors need not fall monotonically: any row meeting it).
    auto cheapest = [](const std::vector<Row>& rows, double tolerance) {
        const Row* best = nullptr;
        for (const Row& r : rows)
            if (r.error <= tolerance && (!best || r.seconds < best->seconds)) best = &r;
        return best;
    };
    std::printf("%-10s %-26s %-26s %s\n", "tolerance", "stratum: M, ms", "adding-doubling: N, ms", "time ratio (AD / stratum)");
    for (double tolerance : {1e-3, 1e-4, 1e-5, 1e-6, 1e-7}) {
        const Row* a = cheapest(ours, tolerance);
        const Row* b = cheapest(theirs, tolerance);
        char left[64] = "not reached", right[64] = "not reached", ratio[32] = "-";
        if (a) std::snprintf(left, sizeof left, "%d, %.4f", a->points, 1e3 * a->seconds);
        if (b) std::snprintf(right, sizeof right, "%d, %.4f", b->points, 1e3 * b->seconds);
        if (a && b) std::snprintf(ratio, sizeof ratio, "%.1f", b->seconds / a->seconds);
        std::printf("%-10.0e %-26s %-26s %s\n", tolerance, left, right, ratio);
    }
}

}  // namespace

int main() {
    const std::vector<Case> all = read_cases();
    std::vector<Case> normal, peak, oblique;
    for (const Case& c : all) (c.mu0 != 1 ? oblique : (c.g > 0.85 ? peak : normal)).push_back(c);
    compare("Normal incidence, g <= 0.8", normal);
    compare("Normal incidence, g = 0.9 (forward peak)", peak);
    compare("Oblique incidence (mu0 0.05 to 0.99 in air)", oblique);
    return 0;
}
