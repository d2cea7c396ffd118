// accuracy_report: what accuracy costs in time, for every knob of stratum.
//
// For each knob (ordinates, Fourier modes, azimuthal samples, Legendre terms, table sizes) it measures the
// error against an independent or converged reference and the wall time, and prints Markdown tables
// (docs/accuracy.md is this program's output). Build with the bench preset, then run
//     ./build/bench/bench/stratum_accuracy_report > docs/accuracy.md
// Times are processor times, the best of repeated runs, on the machine it runs on; errors do not depend on it.
#include <stratum/stratum.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <vector>

#include "accuracy_modules.hpp"

namespace {

/// Processor time of f() in milliseconds, best of `repeats` runs (robust on a loaded machine).
double median_ms(const std::function<void()>& f, int repeats = 5) { return stratum_accuracy::best_time_ms(f, repeats); }

// ---- Layer solver: ordinates M (with K = 2M modes) on Stam's skin layer -------------------------------------
struct SkinProbe {
    double reflectance[3], transmittance[3], brdf[4], btdf[4];
};

SkinProbe probe(const stratum::LayeredSurface<double>& layer) {
    SkinProbe p{};
    const double mus[3] = {1.0, 0.7, 0.3};
    for (int i = 0; i < 3; ++i) {
        p.reflectance[i] = layer.reflectance(mus[i]).subsurface;
        p.transmittance[i] = layer.transmittance(mus[i]);
    }
    const stratum::Vec3<double> wi = stratum::spherical_direction(0.8, 0.0);
    const double out[4][2] = {{0.9, 3.0}, {0.5, 0.0}, {0.5, 1.6}, {0.2, 3.1}};
    for (int j = 0; j < 4; ++j) {
        p.brdf[j] = layer.subsurface_brdf(wi, stratum::spherical_direction(out[j][0], out[j][1]));
        p.btdf[j] = layer.btdf(wi, stratum::spherical_direction(-out[j][0], out[j][1]));
    }
    return p;
}

double max_relative(const double* a, const double* b, int n) {
    double e = 0;
    for (int i = 0; i < n; ++i) e = std::max(e, std::fabs(a[i] - b[i]) / std::fabs(b[i]));
    return e;
}

void layer_ordinates() {
    const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    auto solve = [&](int m) {
        stratum::LayerOptions o;
        o.ordinates = m;
        return stratum::solve_layer(slab, top, bottom, o);
    };
    const int reference_m = 48;
    const SkinProbe ref = probe(solve(reference_m));
    std::printf("\n## Layer solver: ordinates\n\nStam's skin layer (n 1 | 1.4 | 1, sigma 0.3, albedo 0.9, g 0.8, "
                "e^-tau 0.5), K = 2M modes, delta-M. Error: max relative difference from M = %d over the "
                "subsurface reflectance and transmittance at mu0 = 1, 0.7, 0.3 and r_s, t_s at 4 directions "
                "(mu0 = 0.8). Time: solve_layer, all outputs.\n\n", reference_m);
    std::printf("| M | K | reflectance/transmittance error | r_s error | t_s error | solve (ms) | r_s eval (us) |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    for (int m : {4, 8, 12, 16, 24, 32}) {
        stratum::LayeredSurface<double> layer = solve(m);
        const double t = median_ms([&] { layer = solve(m); }, 3);
        const SkinProbe p = probe(layer);
        const double e_flux = std::max(max_relative(p.reflectance, ref.reflectance, 3), max_relative(p.transmittance, ref.transmittance, 3));
        stratum::LayeredSurface<double>::Workspace ws;
        const stratum::Vec3<double> wi = stratum::spherical_direction(0.8, 0.0), wo = stratum::spherical_direction(0.5, 2.0);
        double sink = 0;
        const double eval_us = 1e3 * median_ms([&] { for (int i = 0; i < 20; ++i) sink += layer.subsurface_brdf(wi, wo, ws); }, 3) / 20;
        std::printf("| %d | %d | %.1e | %.1e | %.1e | %.1f | %.0f |\n", m, layer.modes(), e_flux,
                    max_relative(p.brdf, ref.brdf, 4), max_relative(p.btdf, ref.btdf, 4), t, eval_us + 0 * sink);
    }
}

void layer_tolerance() {
    const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    stratum::LayerOptions o;
    o.ordinates = 16;
    const auto full = stratum::solve_layer(slab, top, bottom, o);
    const SkinProbe ref = probe(full);
    std::printf("\n## Layer solver: Fourier modes chosen by a tolerance\n\nM = 16 (at most K = 32 modes). The "
                "request names the outputs and a tolerance; the solver stops after two consecutive modes whose "
                "BRDF/BTDF coefficients are below it. Error: max relative difference from all 32 modes.\n\n");
    std::printf("| outputs | tolerance | modes | r_s error | t_s error | solve (ms) |\n|---|---|---|---|---|---|\n");
    using stratum::LayerOutput;
    const struct {
        const char* name;
        LayerOutput outputs;
    } kinds[] = {{"reflection", LayerOutput::surface_reflection | LayerOutput::subsurface_reflection},
                 {"transmission", LayerOutput::transmission},
                 {"all", LayerOutput::all}};
    for (const auto& kind : kinds) {
        for (double tol : {1e-1, 1e-2, 1e-3, 1e-4, 0.0}) {
            stratum::LayerRequest<double> r;
            r.outputs = kind.outputs;
            r.tolerance = tol;
            stratum::LayeredSurface<double> layer = stratum::solve_layer(slab, top, bottom, o, r);
            const double t = median_ms([&] { layer = stratum::solve_layer(slab, top, bottom, o, r); }, 3);
            const SkinProbe p = probe(layer);
            const bool refl = stratum::includes(kind.outputs, LayerOutput::subsurface_reflection);
            const bool trans = stratum::includes(kind.outputs, LayerOutput::transmission);
            char er[32] = "-", et[32] = "-";
            if (refl) std::snprintf(er, sizeof er, "%.1e", max_relative(p.brdf, ref.brdf, 4));
            if (trans) std::snprintf(et, sizeof et, "%.1e", max_relative(p.btdf, ref.btdf, 4));
            std::printf("| %s | %g | %d | %s | %s | %.1f |\n", kind.name, tol, layer.modes(), er, et, t);
        }
    }
    stratum::LayerRequest<double> ambient;
    ambient.outputs = LayerOutput::ambient;
    double t_amb = median_ms([&] { (void)stratum::solve_layer(slab, top, bottom, o, ambient); }, 3);
    std::printf("| ambient only | - | 1 | - | - | %.1f |\n", t_amb);
}

// ---- Layer solver: smooth Fresnel faces, one rule against the split at the critical cosine ------------------
void layer_smooth_faces() {
    // Prahl's adding-doubling at N = 512: tests/data/adding_doubling_reference.txt (provenance in its header).
    struct Reference {
        double n, albedo, g, tau, mu0, r, t;
    };
    std::vector<Reference> refs;
    std::FILE* file = std::fopen(STRATUM_TEST_DATA_DIR "/adding_doubling_reference.txt", "r");
    if (!file) return;
    char line[512];
    while (std::fgets(line, sizeof line, file)) {
        Reference x{};
        if (line[0] != '#' && std::sscanf(line, "%lf %lf %lf %lf %lf %lf %lf", &x.n, &x.albedo, &x.g, &x.tau, &x.mu0, &x.r,
                                          &x.t) == 7)
            refs.push_back(x);
    }
    std::fclose(file);
    std::printf("\n## Layer solver: smooth Fresnel faces\n\nSlabs between smooth faces in air against Prahl's converged "
                "adding-doubling (tests/data/adding_doubling_reference.txt: %zu slabs, n 1.4 and 1.5, albedo 0.5 to 1, "
                "g 0 to 0.9, tau 1 to 16, normal incidence and one at mu0 = 0.5): the worst |R - ref| and |T - ref| "
                "(reflectance and transmittance with the specular reflection and the unscattered beam, mode 0), "
                "with the ordinates split at the critical cosines (`LayerOptions::critical_split`, the default) and with "
                "one half-range rule. Time: the first slab (n 1.4, albedo 0.9, g 0.8, tau 1), solve and reflectance, "
                "split.\n\n",
                refs.size());
    std::printf("| M | split: R | split: T | one rule: R | one rule: T | time (ms) |\n|---|---|---|---|---|---|\n");
    stratum::LayerRequest<double> request;
    request.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
    auto solve = [&](const Reference& x, int m, bool split) {
        stratum::LayerOptions o;
        o.ordinates = m;
        o.critical_split = split;
        return stratum::solve_layer(stratum::Slab<double>(x.albedo, x.g, x.tau), stratum::SmoothDielectric<double>(1.0, x.n),
                                    stratum::SmoothDielectric<double>(x.n, 1.0), o, request);
    };
    for (int m : {8, 12, 16, 24, 32, 48, 64}) {
        double worst[2][2] = {{0, 0}, {0, 0}};  // [split][R, T]
        for (int split = 0; split < 2; ++split)
            for (const Reference& x : refs) {
                const auto layer = solve(x, m, split == 1);
                worst[split][0] = std::max(worst[split][0], std::fabs(layer.reflectance(x.mu0).total() - x.r));
                worst[split][1] = std::max(worst[split][1], std::fabs(layer.transmittance(x.mu0) - x.t));
            }
        const double t = median_ms([&] { (void)solve(refs.front(), m, true).reflectance(1.0); });
        std::printf("| %d | %.1e | %.1e | %.1e | %.1e | %.3f |\n", m, worst[1][0], worst[1][1], worst[0][0], worst[0][1], t);
    }
}

// ---- Tabulated BSDF: the table's size, build time and error against its tolerance ---------------------------
void tabulated_bsdf_tolerance() {
    stratum::LayerOptions o;
    o.ordinates = 16;
    const auto layer = stratum::solve_layer(stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5),
                                            stratum::RoughDielectric<double>(0.3, 1.0, 1.4),
                                            stratum::RoughDielectric<double>(0.3, 1.4, 1.0), o);
    // Each lobe's largest azimuthal mean of f |wi.z| |wo.z| (the unit of the tolerance), on a 101 x 101 grid.
    double scale[2] = {0, 0};
    std::vector<double> mu(101);
    for (std::size_t j = 0; j < mu.size(); ++j) mu[j] = static_cast<double>(j) / 100;
    const stratum::LayerOutput lobes[2] = {stratum::LayerOutput::subsurface_reflection, stratum::LayerOutput::transmission};
    for (int w = 0; w < 2; ++w) {
        const std::vector<double> a = layer.fourier_coefficients(lobes[w], mu, mu);
        for (std::size_t i = 0; i < mu.size(); ++i)
            for (std::size_t k = 0; k < mu.size(); ++k)
                scale[w] = std::max(scale[w], mu[i] * a[(i * mu.size() + k) * static_cast<std::size_t>(layer.modes())]);
    }
    // 2000 random pairs of directions (wo above and below alternately) and the layer's own values there.
    struct Pair {
        stratum::Vec3<double> wi, wo;
        double f;
    };
    std::vector<Pair> pairs;
    unsigned long long state = 12345;
    auto uniform = [&state] {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return static_cast<double>(state >> 11) * 0x1p-53;
    };
    for (int n = 0; n < 2000; ++n) {
        Pair p{stratum::spherical_direction(uniform(), 6.283185307179586 * uniform()),
               stratum::spherical_direction(uniform(), 6.283185307179586 * uniform()), 0};
        if (n % 2) p.wo.z = -p.wo.z;
        p.f = n % 2 ? layer.btdf(p.wi, p.wo) : layer.brdf(p.wi, p.wo);
        pairs.push_back(p);
    }
    std::printf("\n## Tabulated BSDF: table size, build time and error against the tolerance\n\nStam's skin layer at "
                "M = 16 (32 modes) tabulated by `TabulatedBSDF` (docs/physics.md section 9). Error: |f_table - f| "
                "|wi.z| |wo.z| over the lobe's largest azimuthal mean of f |wi.z| |wo.z|, as measured by the table "
                "at construction (the next finer grid's nodes, every dphi) and at 2000 random pairs of true "
                "directions (reflection, transmission). The grid stops refining at 129 nodes. Evaluation and "
                "sampling times: `bench/bench_tabulated_bsdf.cpp`.\n\n");
    std::printf("| tolerance | nodes | memory (kB) | build (ms) | error at construction | random pairs: r | t |\n"
                "|---|---|---|---|---|---|---|\n");
    for (double tol : {1e-2, 3e-3, 1e-3, 1e-4, 1e-5}) {
        const stratum::TabulatedBSDF<double> table(layer, tol);
        const double t = median_ms([&] { const stratum::TabulatedBSDF<double> again(layer, tol); }, 1);
        double worst[2] = {0, 0};
        for (const Pair& p : pairs) {
            const int w = p.wo.z > 0 ? 0 : 1;
            worst[w] = std::max(worst[w], std::fabs(table.eval(p.wi, p.wo) - p.f) * p.wi.z * std::fabs(p.wo.z) / scale[w]);
        }
        std::printf("| %g | %d | %.0f | %.0f | %.1e | %.1e | %.1e |\n", tol, table.grid_size(),
                    static_cast<double>(table.memory_bytes()) / 1024, t, table.error(), worst[0], worst[1]);
    }
}

}  // namespace

int main() {
    std::printf("# stratum: accuracy against time\n\nGenerated by bench/accuracy_report.cpp "
                "(`cmake --workflow --preset bench`, then `./build/bench/bench/stratum_accuracy_report`).\n");
    stratum_accuracy::report_quadrature();
    stratum_accuracy::report_henyey_greenstein();
    stratum_accuracy::report_interface_operators();
    layer_ordinates();
    layer_tolerance();
    layer_smooth_faces();
    tabulated_bsdf_tolerance();
    stratum_accuracy::report_dipole();
    return 0;
}
