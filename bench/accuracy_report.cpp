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
#include <string>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "accuracy_modules.hpp"
#include "../tests/reference/mc_layer.hpp"
#include "../tests/reference/mc_stack.hpp"

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

// ---- Layer solver: how each piece grows with M ------------------------------------------------------------
// Least-squares slope of log(time) against log(M) over the M measured.
double growth_exponent(const std::vector<int>& ms, const std::vector<double>& times) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    const double n = static_cast<double>(ms.size());
    for (std::size_t i = 0; i < ms.size(); ++i) {
        const double x = std::log(static_cast<double>(ms[i])), y = std::log(times[i]);
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

void layer_growth() {
    const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    const std::vector<int> ms = {8, 12, 16, 24, 32, 48};
    std::vector<double> plain, totals, prepared, full;
    for (int m : ms) {
        stratum::LayerOptions o;
        o.ordinates = m;
        const stratum::Quadrature<double> q = stratum::gauss_legendre_half<double>(m);
        double sink = 0;
        plain.push_back(median_ms([&] {
            sink += stratum::InterfaceOperators<double>(top, q, 2 * m, stratum::AzimuthalQuadrature<double>(),
                                                       stratum::Renormalization::none).R12()(0, 0, 0);
        }, 3));
        const double renormalized = median_ms([&] {
            sink += stratum::InterfaceOperators<double>(top, q, 2 * m, stratum::AzimuthalQuadrature<double>(),
                                                       stratum::Renormalization::hemispherical_totals).R12()(0, 0, 0);
        }, 3);
        totals.push_back(std::max(renormalized - plain.back(), 1e-3));
        const stratum::PreparedBoundary<double> pt(top, o), pb = pt.turned_over();
        prepared.push_back(median_ms([&] { sink += stratum::solve_layer(slab, pt, pb).modes(); }, 3));
        full.push_back(median_ms([&] { sink += stratum::solve_layer(slab, top, bottom, o).modes(); }, 3) + 0 * sink);
    }
    std::printf("\n## Layer solver: growth of each piece with M\n\nStam's skin layer, K = 2M modes, all outputs. "
                "One rough face's operators (azimuthal integrals, no renormalization); the renormalization's 2M "
                "hemispherical integrals (the difference with it); the solve from prepared faces (the slab's 2M "
                "mode solutions and the adding); the solve from nothing (the bottom face is the top turned over, "
                "built once). Exponent: least-squares slope of log(time) against log(M).\n\n");
    std::printf("| piece |");
    for (int m : ms) std::printf(" M = %d (ms) |", m);
    std::printf(" exponent |\n|---|");
    for (std::size_t i = 0; i <= ms.size(); ++i) std::printf("---|");
    std::printf("\n");
    const std::pair<const char*, const std::vector<double>*> rows[] = {
        {"face operators", &plain}, {"renormalization", &totals}, {"solve, prepared faces", &prepared}, {"solve from nothing", &full}};
    for (const auto& row : rows) {
        std::printf("| %s |", row.first);
        for (double t : *row.second) std::printf(" %.3g |", t);
        std::printf(" %.2f |\n", growth_exponent(ms, *row.second));
    }
}

// ---- Rough faces: the hemispherical integrals' nodes over a sweep (integrals_for_tolerance's figures) -------------
void hemispherical_nodes_sweep() {
    std::printf("\n## Layer solver: the hemispherical integrals' Gauss nodes over a sweep\n\n"
                "`RoughDielectric::hemispherical_totals(mu, n)` against n = 32: the largest absolute difference in R or "
                "T over sigma 0.003 to 20 (12 values), n 1 | 1.001, 1.05, 1.33, 1.5, 2.5, 4 either way up, light from "
                "either side at the 24 ordinates of a half-range rule, every shadowing form (10,368 integrals per "
                "row); where it occurs; and the time of all of them. `integrals_for_tolerance` (layer.hpp) takes 9 / "
                "12 nodes from tolerances 1e-2 / 1e-3 (the default: 16).\n\n"
                "| nodes | worst difference | at sigma, n_below / n_above, mu, shadowing | time (s) |\n|---|---|---|---|\n");
    const double sigmas[] = {0.003, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.6, 1.0, 2.0, 5.0, 20.0};
    const double indices[] = {1.001, 1.05, 1.33, 1.5, 2.5, 4.0};
    const int nodes[] = {8, 9, 10, 12, 16};
    const stratum::Quadrature<double> q = stratum::gauss_legendre_half<double>(24);
    struct Worst { double error = 0, sigma = 0, eta = 0, mu = 0; int form = 0; double seconds = 0; };
    Worst worst[5];
    for (int form = 0; form < 3; ++form)
        for (const double sigma : sigmas)
            for (const double n : indices)
                for (const bool flip : {false, true}) {
                    const stratum::RoughDielectric<double> face(sigma, flip ? n : 1.0, flip ? 1.0 : n,
                                                                static_cast<stratum::Shadowing>(form));
                    for (const double node : q.nodes)
                        for (const double mu : {node, -node}) {
                            const auto reference = face.hemispherical_totals(mu, 32);
                            for (int i = 0; i < 5; ++i) {
                                stratum::HemisphericalTotals<double> a;
                                worst[i].seconds += median_ms([&] { a = face.hemispherical_totals(mu, nodes[i]); }, 1) / 1e3;
                                const double e = std::max(std::fabs(a.reflectance - reference.reflectance),
                                                          std::fabs(a.transmittance - reference.transmittance));
                                if (e > worst[i].error)
                                    worst[i] = {e, sigma, face.eta_below() / face.eta_above(), mu, form, worst[i].seconds};
                            }
                        }
                }
    const char* forms[] = {"height-correlated", "separable", "masking only"};
    for (int i = 0; i < 5; ++i)
        std::printf("| %d | %.1e | %g, %g, %.4f, %s | %.1f |\n", nodes[i], worst[i].error, worst[i].sigma, worst[i].eta,
                    worst[i].mu, forms[worst[i].form], worst[i].seconds);
}

// ---- Layer solver: the rough faces' integrals (hemispherical_nodes, azimuthal_points) ----------------------------
void layer_integrals() {
    std::printf("\n## Layer solver: the rough faces' integrals\n\nStam's skin layer, M = 24 (K = 48), all outputs, from "
                "nothing: `LayerOptions::hemispherical_nodes` (Gauss nodes per panel of the renormalization's 2M "
                "hemispherical integrals per face) and `LayerOptions::azimuthal_points` (Gauss points per panel of the "
                "operators' azimuthal rule). Error: max relative difference from the defaults (16, 24) over the "
                "probes of \"Layer solver: ordinates\". Time: the solve, best of 3. A solve with a tolerance (and the "
                "planner) caps them by `integrals_for_tolerance`: (9, 12) from 1e-2, (12, 12) from 1e-3, none below.\n\n| hemispherical_nodes | azimuthal_points | difference from the "
                "defaults | solve (ms) |\n|---|---|---|---|\n");
    const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    stratum::LayerOptions base;
    base.ordinates = 24;
    const SkinProbe ref = probe(stratum::solve_layer(slab, top, bottom, base));
    const int knobs[][2] = {{16, 24}, {12, 24}, {10, 24}, {8, 24}, {16, 16}, {16, 12}, {16, 8}, {12, 16}, {12, 12}, {10, 12}, {9, 12}, {8, 8}};
    for (const auto& k : knobs) {
        stratum::LayerOptions o = base;
        o.hemispherical_nodes = k[0];
        o.azimuthal_points = k[1];
        stratum::LayeredSurface<double> layer = stratum::solve_layer(slab, top, bottom, o);
        const double t = median_ms([&] { layer = stratum::solve_layer(slab, top, bottom, o); }, 3);
        const SkinProbe p = probe(layer);
        const double e = std::max({max_relative(p.reflectance, ref.reflectance, 3), max_relative(p.transmittance, ref.transmittance, 3),
                                   max_relative(p.brdf, ref.brdf, 4), max_relative(p.btdf, ref.btdf, 4)});
        std::printf("| %d | %d | %.1e | %.1f |\n", k[0], k[1], e, t);
    }
}

void layer_tabulated_faces() {
    std::printf("\n## Layer solver: the faces tabulated at the solve\n\nStam's skin layer, all outputs, with "
                "`LayerRequest::tabulate_faces` (the rough faces' couplings to the ordinates tabulated over the "
                "outside cosine, 129 nodes) and without (the azimuthal integrals at each evaluation). Difference: the "
                "largest over 50 random incidences (mu 1e-3 to 1) of |R - R'| and |T - T'| (subsurface reflectance, "
                "transmittance), and of |f - f'| |wo.z| / max f |wo.z| for the subsurface BRDF and the BTDF (random "
                "exits). Times: the solve (best of 3), and one evaluation at an incidence not requested (best of 3, "
                "mean of 200 incidences).\n\n| M | R, T difference | brdf, btdf difference (relative to the largest) "
                "| solve: integrals / tabulated (ms) | reflectance(mu): integrals / tabulated (us) | brdf: integrals / "
                "tabulated (us) |\n|---|---|---|---|---|---|\n");
    const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    stratum::LayerRequest<double> tabulate;
    tabulate.tabulate_faces = true;
    for (int m : {8, 16, 24}) {
        stratum::LayerOptions o;
        o.ordinates = m;
        auto plain = stratum::solve_layer(slab, top, bottom, o);
        auto fast = stratum::solve_layer(slab, top, bottom, o, tabulate);
        const double t_plain = median_ms([&] { plain = stratum::solve_layer(slab, top, bottom, o); }, 3);
        const double t_fast = median_ms([&] { fast = stratum::solve_layer(slab, top, bottom, o, tabulate); }, 3);
        std::mt19937_64 rng(5);
        std::uniform_real_distribution<double> u(0, 1);
        double flux = 0, angular = 0, scale = 0;
        for (int i = 0; i < 50; ++i) {
            const double mu = std::exp(std::log(1e-3) * u(rng));
            flux = std::max({flux, std::fabs(plain.reflectance(mu).subsurface - fast.reflectance(mu).subsurface),
                             std::fabs(plain.transmittance(mu) - fast.transmittance(mu))});
            const auto wi = stratum::spherical_direction(mu, 0.0);
            auto wo = stratum::spherical_direction(u(rng), 6.283185307179586 * u(rng));
            for (int side = 0; side < 2; ++side, wo.z = -wo.z) {
                const double a = (side == 0 ? plain.subsurface_brdf(wi, wo) : plain.btdf(wi, wo)) * std::fabs(wo.z);
                const double b = (side == 0 ? fast.subsurface_brdf(wi, wo) : fast.btdf(wi, wo)) * std::fabs(wo.z);
                angular = std::max(angular, std::fabs(a - b));
                scale = std::max(scale, a);
            }
        }
        const auto per_call_us = [&](const stratum::LayeredSurface<double>& layer, bool brdf) {
            stratum::LayeredSurface<double>::Workspace ws;
            double sink = 0;
            const auto wo = stratum::spherical_direction(0.5, 2.0);
            const double ms = median_ms([&] {
                for (int i = 0; i < 200; ++i) {
                    const double mu = 0.2 + 0.003 * i;
                    sink += brdf ? layer.brdf(stratum::spherical_direction(mu, 0.0), wo, ws) : layer.reflectance(mu).total();
                }
            }, 3);
            return sink < 0 ? 0.0 : ms * 1e3 / 200;
        };
        std::printf("| %d | %.1e | %.1e | %.1f / %.1f | %.0f / %.2f | %.0f / %.1f |\n", m, flux, angular / scale, t_plain, t_fast,
                    per_call_us(plain, false), per_call_us(fast, false), per_call_us(plain, true), per_call_us(fast, true));
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

// Prahl's adding-doubling: tests/data/adding_doubling_reference.txt (provenance in its header).
struct Reference {
    double n, albedo, g, tau, mu0, r, t;
};
std::vector<Reference> adding_doubling_references() {
    std::vector<Reference> refs;
    std::FILE* file = std::fopen(STRATUM_TEST_DATA_DIR "/adding_doubling_reference.txt", "r");
    if (!file) return refs;
    char line[512];
    while (std::fgets(line, sizeof line, file)) {
        Reference x{};
        if (line[0] != '#' &&
            std::sscanf(line, "%lf %lf %lf %lf %lf %lf %lf", &x.n, &x.albedo, &x.g, &x.tau, &x.mu0, &x.r, &x.t) == 7)
            refs.push_back(x);
    }
    std::fclose(file);
    return refs;
}

// ---- Layer solver: smooth Fresnel faces, one rule against the split at the critical cosine ------------------
void layer_smooth_faces() {
    const std::vector<Reference> refs = adding_doubling_references();
    if (refs.empty()) return;
    std::printf("\n## Layer solver: smooth Fresnel faces\n\nSlabs between smooth faces in air against Prahl's converged "
                "adding-doubling (tests/data/adding_doubling_reference.txt: %zu cases; 12 slabs, n 1.4 and 1.5, albedo "
                "0.5 to 1, g 0 to 0.9, tau 1 to 16, at normal incidence, and 12 oblique incidences, mu0 = 0.05 to 0.99 in "
                "air): the worst |R - ref| and |T - ref| at normal incidence, and the worst of both over the oblique "
                "cases (reflectance and transmittance with the specular reflection and the unscattered beam, mode 0), "
                "with the ordinates split at the critical cosines (`LayerOptions::critical_split`, the default) and with "
                "one half-range rule. Time: the first slab (n 1.4, albedo 0.9, g 0.8, tau 1), solve and reflectance, "
                "split.\n\n",
                refs.size());
    std::printf("| M | split: R | split: T | split: oblique | one rule: R | one rule: T | one rule: oblique | time (ms) |\n"
                "|---|---|---|---|---|---|---|---|\n");
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
        double worst[2][3] = {{0, 0, 0}, {0, 0, 0}};  // [split][R, T at normal incidence; oblique]
        for (int split = 0; split < 2; ++split)
            for (const Reference& x : refs) {
                const auto layer = solve(x, m, split == 1);
                const double er = std::fabs(layer.reflectance(x.mu0).total() - x.r), et = std::fabs(layer.transmittance(x.mu0) - x.t);
                if (x.mu0 == 1) {
                    worst[split][0] = std::max(worst[split][0], er);
                    worst[split][1] = std::max(worst[split][1], et);
                } else {
                    worst[split][2] = std::max({worst[split][2], er, et});
                }
            }
        const double t = median_ms([&] { (void)solve(refs.front(), m, true).reflectance(1.0); });
        std::printf("| %d | %.1e | %.1e | %.1e | %.1e | %.1e | %.1e | %.3f |\n", m, worst[1][0], worst[1][1], worst[1][2],
                    worst[0][0], worst[0][1], worst[0][2], t);
    }
}

// ---- Layer solver: intensities at true angles against converged DISORT ----------------------------------------
// tests/data/disort_intensity_reference.txt (provenance in its header): five slabs between black faces.
void layer_intensities() {
    struct Problem {
        const char* name;
        double g, albedo, tau, mu0;
    };
    const Problem problems[] = {{"P1", 0.75, 0.9, 1.0, 0.5}, {"P2", 0.75, 0.9, 1.0, 1.0}, {"P3", 0.0, 1.0, 2.0, 0.7},
                                {"P4", 0.9, 0.99, 4.0, 0.3}, {"P5", 0.5, 0.8, 0.1, 0.6}};
    struct Value {
        std::string problem;
        double umu, phi, reference;
    };
    std::vector<Value> values;
    std::FILE* file = std::fopen(STRATUM_TEST_DATA_DIR "/disort_intensity_reference.txt", "r");
    if (!file) return;
    char line[512], name[16], level[16];
    while (std::fgets(line, sizeof line, file)) {
        Value v;
        double sixteen = 0;
        if (line[0] == '#' || std::sscanf(line, "%15s %15s %lf %lf %lf %lf", name, level, &v.umu, &v.phi, &v.reference, &sixteen) != 6)
            continue;
        v.problem = name;
        if ((std::string(level) == "top") == (v.umu > 0)) values.push_back(v);
    }
    std::fclose(file);
    std::printf("\n## Layer solver: intensities at true angles\n\nRadiance at true angles between index-matched faces "
                "(the beam a source, the exit a source-function integral: docs/physics.md section 6) against DISORT at "
                "256 streams (tests/data/disort_intensity_reference.txt: five slabs, P1 g 0.75 albedo 0.9 tau 1 mu0 0.5; "
                "P2 the same at mu0 1; P3 g 0 albedo 1 tau 2 mu0 0.7; P4 g 0.9 albedo 0.99 tau 4 mu0 0.3; P5 g 0.5 albedo "
                "0.8 tau 0.1 mu0 0.6; 56 directions each): the worst relative error, with the single-scattering "
                "correction (`LayerOptions::single_scattering_correction`: Nakajima and Tanaka's TMS and IMS) and, in "
                "brackets, without. DISORT's own 16 "
                "streams (8 per hemisphere, with its corrections) are off by up to 4.7e-4 / 4.1e-3 / 2.9e-6 / 5.3e-3 / "
                "6.8e-4. Time: P1, the solve and its 112 intensities, with the correction.\n\n"
                "| M | P1 | P2 | P3 | P4 | P5 | time (ms) |\n|---|---|---|---|---|---|---|\n");
    for (int m : {8, 16, 24, 32, 48}) {
        std::printf("| %d |", m);
        double time = 0;
        for (const Problem& p : problems) {
            double worst[2] = {0, 0};
            for (int correction = 0; correction < 2; ++correction) {
                stratum::LayerOptions o;
                o.ordinates = m;
                o.single_scattering_correction = correction == 1;
                auto solve = [&] {
                    return stratum::solve_layer(stratum::Slab<double>(p.albedo, p.g, p.tau),
                                                stratum::Boundary<double>::index_matched(),
                                                stratum::Boundary<double>::index_matched(), o);
                };
                const auto layer = solve();
                const stratum::Vec3<double> wi{-std::sqrt(1 - p.mu0 * p.mu0), 0, p.mu0};
                auto radiance = [&](const stratum::LayeredSurface<double>& l, const Value& v) {
                    const double s = std::sqrt(1 - v.umu * v.umu), phi = v.phi * 3.14159265358979323846 / 180;
                    const stratum::Vec3<double> wo{s * std::cos(phi), s * std::sin(phi), v.umu};
                    return v.umu > 0 ? l.subsurface_brdf(wi, wo) : l.btdf(wi, wo);
                };
                for (const Value& v : values)
                    if (v.problem == p.name)
                        worst[correction] = std::max(worst[correction], std::fabs(radiance(layer, v) - v.reference) / v.reference);
                if (correction == 1 && std::string(p.name) == "P1")
                    time = median_ms([&] {
                        const auto l = solve();
                        double sum = 0;
                        for (const Value& v : values)
                            if (v.problem == p.name) sum += radiance(l, v);
                        return sum;
                    });
            }
            std::printf(" %.1e (%.1e) |", worst[1], worst[0]);
        }
        std::printf(" %.2f |\n", time);
    }
}

// ---- Layer solver: the transmitted beam's aureole against converged DISORT (the IMS) ---------------------------
// tests/data/disort_aureole_reference.txt (provenance in its header): downwelling radiance within 9 degrees of the
// transmitted beam's polar angle, at 256 streams.
void layer_aureole() {
    struct Value {
        std::string problem;
        double g, albedo, tau, mu0, umu, phi, reference;
    };
    std::vector<Value> values;
    std::FILE* file = std::fopen(STRATUM_TEST_DATA_DIR "/disort_aureole_reference.txt", "r");
    if (!file) return;
    char line[512], name[16];
    while (std::fgets(line, sizeof line, file)) {
        Value v;
        if (line[0] == '#' || std::sscanf(line, "%15s %lf %lf %lf %lf %lf %lf %lf", name, &v.g, &v.albedo, &v.tau, &v.mu0,
                                          &v.umu, &v.phi, &v.reference) != 8)
            continue;
        v.problem = name;
        values.push_back(v);
    }
    std::fclose(file);
    std::printf("\n## Layer solver: the transmitted beam's aureole\n\nDownwelling radiance within 9 degrees of the "
                "transmitted beam's polar angle (azimuths 0 to 20 degrees) against DISORT at 256 streams "
                "(tests/data/disort_aureole_reference.txt: A1 = P4 above, g 0.9 albedo 0.99 tau 4 mu0 0.3; A2 g 0.95 "
                "albedo 0.9 tau 1 mu0 0.8; 45 directions each): the worst relative error with the correction (TMS and "
                "IMS; docs/physics.md section 6) and, in brackets, without. With the TMS alone A1 at M = 16 was 3.6e-4 "
                "off.\n\n| M | A1 | A2 |\n|---|---|---|\n");
    for (int m : {8, 16, 24, 32}) {
        std::printf("| %d |", m);
        for (const char* problem : {"A1", "A2"}) {
            double worst[2] = {0, 0};
            for (int correction = 0; correction < 2; ++correction) {
                const Value* first = nullptr;
                for (const Value& v : values)
                    if (v.problem == problem && !first) first = &v;
                if (!first) return;
                stratum::LayerOptions o;
                o.ordinates = m;
                o.single_scattering_correction = correction == 1;
                const auto layer = stratum::solve_layer(stratum::Slab<double>(first->albedo, first->g, first->tau),
                                                        stratum::Boundary<double>::index_matched(),
                                                        stratum::Boundary<double>::index_matched(), o);
                const stratum::Vec3<double> wi{-std::sqrt(1 - first->mu0 * first->mu0), 0, first->mu0};
                for (const Value& v : values) {
                    if (v.problem != problem) continue;
                    const double s = std::sqrt(1 - v.umu * v.umu), phi = v.phi * 3.14159265358979323846 / 180;
                    const double f = layer.btdf(wi, {s * std::cos(phi), s * std::sin(phi), v.umu});
                    worst[correction] = std::max(worst[correction], std::fabs(f - v.reference) / v.reference);
                }
            }
            std::printf(" %.1e (%.1e) |", worst[1], worst[0]);
        }
        std::printf("\n");
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

// ---- Pareto fronts: every knob combination's error against its time ------------------------------------------
struct Run {
    std::string knobs;
    double error, ms;
    bool is_default;
};

// The runs no other run beats in both error and time, fastest first.
std::vector<Run> pareto_front(std::vector<Run> runs) {
    std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.ms < b.ms || (a.ms == b.ms && a.error < b.error); });
    std::vector<Run> front;
    for (const Run& r : runs)
        if (front.empty() || r.error < front.back().error) front.push_back(r);
    return front;
}

// A log-log scatter: every run (grey), the front (blue line), the default settings (red ring).
void write_pareto_svg(const std::string& path, const std::string& title, const std::vector<Run>& runs) {
    const std::vector<Run> front = pareto_front(runs);
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const Run& r : runs) {
        if (!(r.error > 0) || !(r.ms > 0)) continue;
        x0 = std::min(x0, std::log10(r.ms)), x1 = std::max(x1, std::log10(r.ms));
        y0 = std::min(y0, std::log10(r.error)), y1 = std::max(y1, std::log10(r.error));
    }
    x0 = std::floor(x0), x1 = std::ceil(x1), y0 = std::floor(y0), y1 = std::ceil(y1);
    if (!(x1 > x0)) x1 = x0 + 1;
    if (!(y1 > y0)) y1 = y0 + 1;
    const double w = 640, h = 420, l = 70, r = 20, t = 40, b = 50;
    auto px = [&](double ms) { return l + (std::log10(ms) - x0) / (x1 - x0) * (w - l - r); };
    auto py = [&](double e) { return h - b - (std::log10(e) - y0) / (y1 - y0) * (h - t - b); };
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (!f) return;
    std::fprintf(f, "<svg xmlns='http://www.w3.org/2000/svg' width='%g' height='%g' font-family='sans-serif' font-size='12'>\n"
                    "<rect width='100%%' height='100%%' fill='white'/>\n<text x='%g' y='22' text-anchor='middle' font-size='14'>%s</text>\n"
                    "<text x='%g' y='%g' text-anchor='middle'>time (ms)</text>\n"
                    "<text x='16' y='%g' text-anchor='middle' transform='rotate(-90 16 %g)'>error</text>\n"
                    "<rect x='%g' y='%g' width='%g' height='%g' fill='none' stroke='black'/>\n",
                 w, h, w / 2, title.c_str(), (l + w - r) / 2, h - 12, (t + h - b) / 2, (t + h - b) / 2, l, t, w - l - r, h - t - b);
    for (double e = x0; e <= x1; ++e)
        std::fprintf(f, "<text x='%g' y='%g' text-anchor='middle'>1e%g</text>\n", px(std::pow(10.0, e)), h - b + 16, e);
    for (double e = y0; e <= y1; ++e)
        std::fprintf(f, "<text x='%g' y='%g' text-anchor='end'>1e%g</text>\n", l - 6, py(std::pow(10.0, e)) + 4, e);
    for (const Run& run : runs)
        if (run.error > 0 && run.ms > 0)
            std::fprintf(f, "<circle cx='%.1f' cy='%.1f' r='3' fill='#999999'/>\n", px(run.ms), py(run.error));
    std::fprintf(f, "<polyline fill='none' stroke='#1f77b4' stroke-width='1.5' points='");
    for (const Run& run : front)
        if (run.error > 0 && run.ms > 0) std::fprintf(f, "%.1f,%.1f ", px(run.ms), py(run.error));
    std::fprintf(f, "'/>\n");
    for (const Run& run : runs)
        if (run.is_default && run.error > 0 && run.ms > 0)
            std::fprintf(f, "<circle cx='%.1f' cy='%.1f' r='7' fill='none' stroke='#d62728' stroke-width='2'/>\n",
                         px(run.ms), py(run.error));
    std::fprintf(f, "<text x='%g' y='%g' fill='#1f77b4'>Pareto front</text>\n<text x='%g' y='%g' fill='#d62728'>default "
                    "settings</text>\n<text x='%g' y='%g' fill='#999999'>every combination</text>\n</svg>\n",
                 w - r - 150, t + 16, w - r - 150, t + 32, w - r - 150, t + 48);
    std::fclose(f);
}

void print_front(const char* name, const char* svg, const std::vector<Run>& runs) {
    const std::vector<Run> front = pareto_front(runs);
    write_pareto_svg(std::string(STRATUM_DOCS_DIR) + "/" + svg, name, runs);
    std::printf("\n![%s](%s)\n\n| settings | error | time (ms) | on the front | default |\n|---|---|---|---|---|\n", name, svg);
    std::vector<Run> sorted = runs;
    std::sort(sorted.begin(), sorted.end(), [](const Run& a, const Run& b) { return a.ms < b.ms; });
    for (const Run& r : sorted) {
        const bool on = std::any_of(front.begin(), front.end(), [&](const Run& f) { return f.knobs == r.knobs; });
        std::printf("| %s | %.1e | %.3g | %s | %s |\n", r.knobs.c_str(), r.error, r.ms, on ? "yes" : "", r.is_default ? "yes" : "");
    }
}

// ---- Layer solver: energy with nearly specular rough faces, a random sweep ----------------------------------
// R + T of layers whose faces are nearly specular (light near a critical cosine is nearly trapped; README, known
// limitations). Random: indices 1 to 1.5 above, in and below the slab; the top rough (RMS slope 1e-3 to 1,
// log-uniform), the bottom smooth or rough alike; albedo 0 to 1, g -0.5 to 0.9, tau 1e-7 to 10 (log-uniform),
// M = 3 to 16; incidences 0.05, 0.168, 0.3, 0.5, 0.7, 0.9, 1. A fixed seed: the same layers on every run.
void layer_energy_sweep() {
    std::printf("\n## Layer solver: energy with nearly specular rough faces (random sweep)\n\nR + T at 7 incidences "
                "for 1000 random layers (fixed seed; bench/accuracy_report.cpp, layer_energy_sweep: indices 1 to 1.5, "
                "top RMS slope 1e-3 to 1, bottom smooth or rough, albedo 0 to 1, g -0.5 to 0.9, tau 1e-7 to 10, M = 3 to "
                "16). Energy created: R + T above 1 (README, known limitations: nearly trapped light). Before the specular "
                "spread stopped extrapolating beyond the last ordinate (towards mu = 1): 1 and 3 layers above 1 + 1e-3, "
                "worst 1.002 and 1.002; before its stencil between the ordinates was made linear (non-negative weights): "
                "5 and 11, worst 1.024 and 1.020; before the spread kept to sharp critical cosines: 32 and 29, worst 1.80 "
                "and 2.09.\n\n| faces | layers | R + T > 1 + 1e-3 | R + T > 1 + 1e-2 | worst R + T |\n|---|---|---|---|---|\n");
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u(0, 1);
    int count[2] = {0, 0}, above3[2] = {0, 0}, above2[2] = {0, 0};
    double worst[2] = {0, 0};
    for (int trial = 0; trial < 1000; ++trial) {
        const double n1 = 1 + 0.5 * u(rng), n2 = 1 + 0.5 * u(rng), n3 = 1 + 0.5 * u(rng);
        const double sigma_top = std::pow(10.0, -3 + 3 * u(rng)), sigma_bottom = std::pow(10.0, -3 + 3 * u(rng));
        const int rough = u(rng) < 0.5 ? 1 : 0;
        const double albedo = u(rng), g = -0.5 + 1.4 * u(rng), tau = std::pow(10.0, -7 + 8 * u(rng));
        stratum::LayerOptions options;
        options.ordinates = 3 + static_cast<int>(14 * u(rng));
        const stratum::Boundary<double> top = stratum::RoughDielectric<double>(sigma_top, n1, n2);
        const stratum::Boundary<double> bottom = rough ? stratum::Boundary<double>(stratum::RoughDielectric<double>(sigma_bottom, n2, n3))
                                                       : stratum::Boundary<double>(stratum::SmoothDielectric<double>(n2, n3));
        const auto layer = stratum::solve_layer(stratum::Slab<double>(albedo, g, tau), top, bottom, options);
        double w = 0;
        for (const double mu : {0.05, 0.168, 0.3, 0.5, 0.7, 0.9, 1.0})
            w = std::max(w, layer.reflectance(mu).total() + layer.transmittance(mu));
        ++count[rough];
        above3[rough] += w > 1 + 1e-3;
        above2[rough] += w > 1 + 1e-2;
        worst[rough] = std::max(worst[rough], w);
    }
    for (const int rough : {0, 1})
        std::printf("| rough top, %s bottom | %d | %d | %d | %.5f |\n", rough ? "rough" : "smooth", count[rough],
                    above3[rough], above2[rough], worst[rough]);
}

// ---- One half-range rule against ordinates split at critical cosines, over random layers (photon Monte Carlo) ---
// One random layer of a family: the Monte Carlo's description, the solver's faces and slab, and the incidence.
struct RandomLayer {
    mc_layer::Layer layer;
    stratum::Boundary<double> top, bottom;
    double mu0;
};

// Prints the table's rows: mean and worst of max(|R - R_MC|, |T - T_MC|) (subsurface R) at M = 16 and 32, one rule
// (critical_split = false) and split, over `layers` draws of `draw` (seeds first_seed, first_seed + 1, ...).
template <class Draw>
void split_rows(int layers, std::uint64_t first_seed, Draw draw) {
    double mean[2][2] = {}, worst[2][2] = {};  // [M = 16, 32][one rule, split]
    for (int trial = 0; trial < layers; ++trial) {
        const RandomLayer x = draw();
        const mc_layer::Tally t = mc_layer::trace(x.layer, x.mu0, 400000, first_seed + static_cast<std::uint64_t>(trial));
        for (int i = 0; i < 2; ++i)
            for (int split = 0; split < 2; ++split) {
                stratum::LayerOptions o;
                o.ordinates = i == 0 ? 16 : 32;
                o.critical_split = split == 1;
                stratum::LayerRequest<double> r;
                r.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
                r.incidence = {x.mu0};
                const auto l = stratum::solve_layer(stratum::Slab<double>(x.layer.albedo, x.layer.g, x.layer.tau), x.top,
                                                    x.bottom, o, r);
                const double e = std::max(std::fabs(l.reflectance(x.mu0).subsurface - t.fraction(t.subsurface)),
                                          std::fabs(l.transmittance(x.mu0) - t.fraction(t.transmitted)));
                mean[i][split] += e / layers;
                worst[i][split] = std::max(worst[i][split], e);
            }
    }
    for (int i = 0; i < 2; ++i)
        std::printf("| %d | %.1e | %.1e | %.1e | %.1e |\n", i == 0 ? 16 : 32, mean[i][0], worst[i][0], mean[i][1], worst[i][1]);
}

// The draws both families share, in this order: n 1 to 1.5, albedo 0 to 1 (three in ten exactly 1), g 0 to 0.9,
// tau 0.1 to 10, RMS slope 10^lowest_log_sigma to 1, mu0 0.2 to 1.
struct Parameters {
    double n, albedo, g, tau, sigma, mu0;
};
Parameters draw_parameters(std::mt19937_64& rng, double lowest_log_sigma) {
    std::uniform_real_distribution<double> u(0, 1);
    Parameters p{};
    p.n = 1 + 0.5 * u(rng);
    p.albedo = u(rng) < 0.3 ? 1.0 : u(rng);
    p.g = 0.9 * u(rng);
    p.tau = std::pow(10.0, -1 + 2 * u(rng));
    p.sigma = std::pow(10.0, lowest_log_sigma * (1 - u(rng)));
    p.mu0 = 0.2 + 0.8 * u(rng);
    return p;
}

// A rough coat on a smooth base.
void rough_top_split() {
    std::printf("\n## Layer solver: a rough top over a smooth or index-matched bottom (photon Monte Carlo)\n\n16 random "
                "layers (fixed seed; bench/accuracy_report.cpp, rough_top_split: a rough top of RMS slope 0.05 to 1, "
                "masking-only shadowing, from air into n 1 to 1.5, over a smooth face to air or, one in three, an "
                "index-matched one; albedo 0 to 1, g 0 to 0.9, tau 0.1 to 10, one incidence mu0 0.2 to 1), against the "
                "photon Monte Carlo of tests/reference/mc_layer.hpp (4e5 photons, standard error <= 8e-4). Error: the "
                "larger of |R - R_MC| and |T - T_MC|, fractions of the incident flux. One rule: "
                "`LayerOptions::critical_split = false`; split: the default, where the top blurs the critical cosines "
                "(detail::layer_quadrature).\n\n| ordinates | one rule: mean | worst | split: mean | worst |\n"
                "|---|---|---|---|---|\n");
    std::mt19937_64 rng(2026);
    std::uniform_real_distribution<double> u(0, 1);
    split_rows(16, 500, [&] {
        const Parameters p = draw_parameters(rng, -1.3);
        const bool matched = u(rng) < 1.0 / 3;
        return RandomLayer{{mc_layer::Boundary::gaussian(p.sigma, 1, p.n),
                            matched ? mc_layer::Boundary::index_matched(p.n) : mc_layer::Boundary::specular(p.n, 1), p.albedo,
                            p.g, p.tau},
                           stratum::RoughDielectric<double>(p.sigma, 1, p.n, stratum::Shadowing::masking_only),
                           matched ? stratum::Boundary<double>::index_matched(p.n)
                                   : stratum::Boundary<double>(stratum::SmoothDielectric<double>(p.n, 1)),
                           p.mu0};
    });
}

// A smooth top over a rough bottom.
void rough_bottom_split() {
    std::printf("\n## Layer solver: a smooth top over a rough bottom (photon Monte Carlo)\n\n24 random layers (fixed "
                "seed; bench/accuracy_report.cpp, rough_bottom_split: a smooth top from air into n 1 to 1.5, a rough "
                "bottom of RMS slope 1e-3 to 1, masking-only shadowing, back to air; albedo 0 to 1, g 0 to 0.9, tau 0.1 "
                "to 10, one incidence mu0 0.2 to 1), against the photon Monte Carlo of tests/reference/mc_layer.hpp "
                "(4e5 photons, standard error <= 8e-4). Error: the larger of |R - R_MC| and |T - T_MC|, fractions of the "
                "incident flux. One rule: `LayerOptions::critical_split = false`; split: the default "
                "(detail::layer_quadrature).\n\n| ordinates | one rule: mean | worst | split: mean | worst |\n"
                "|---|---|---|---|---|\n");
    std::mt19937_64 rng(77);
    split_rows(24, 900, [&] {
        const Parameters p = draw_parameters(rng, -3);
        return RandomLayer{{mc_layer::Boundary::specular(1, p.n), mc_layer::Boundary::gaussian(p.sigma, p.n, 1), p.albedo, p.g,
                            p.tau},
                           stratum::SmoothDielectric<double>(1, p.n),
                           stratum::RoughDielectric<double>(p.sigma, p.n, 1, stratum::Shadowing::masking_only), p.mu0};
    });
}

// ---- Stacks with refracting joints: one half-range rule against the rule split at every critical cosine ----------
void refracting_stacks() {
    std::printf("\n## Layer solver: stacks whose joints refract (photon Monte Carlo)\n\nNine stacks of two or three slabs "
                "under a smooth top (bench/accuracy_report.cpp, refracting_stacks: glass over tissue and others, "
                "indices 1.2 to 1.5; six over a smooth bottom, one of them a denser substrate, three over a Lambertian "
                "floor), each at mu0 = 1, 0.5 and 0.2, against the photon "
                "Monte Carlo of tests/reference/mc_stack.hpp (2e6 photons, standard error <= 4e-4). Error: the larger of "
                "|R - R_MC| and |T - T_MC|, fractions of the incident flux. One rule: `LayerOptions::critical_split = "
                "false`; split: the default, the slabs' shared rule split at every face's critical cosine, joints "
                "included, and over a floor at the top's escape cone in every slab (detail::layer_quadrature).\n\n"
                "| ordinates | one rule: mean | worst | split: mean | worst |\n"
                "|---|---|---|---|---|\n");
    struct Case {
        std::vector<double> eta, tau, albedo, g;
        double below, floor;  // the index below a smooth bottom; a Lambertian floor's albedo (< 0: none)
    };
    const std::vector<Case> cases = {
        {{1.5, 1.4}, {0.3, 2.0}, {0.5, 0.95}, {0.5, 0.8}, 1.0, -1},
        {{1.5, 1.4, 1.38}, {0.2, 0.5, 4.0}, {0.3, 0.9, 0.99}, {0.0, 0.8, 0.85}, 1.0, -1},
        {{1.33, 1.5}, {1.0, 1.0}, {0.9, 0.9}, {0.7, 0.0}, 1.0, -1},
        {{1.4, 1.2}, {0.5, 0.5}, {0.99, 0.8}, {0.3, 0.9}, 1.0, -1},
        {{1.5, 1.33}, {0.1, 8.0}, {0.0, 0.999}, {0.0, 0.9}, 1.0, -1},
        {{1.38, 1.45}, {2.0, 0.3}, {0.95, 0.5}, {0.8, 0.0}, 1.5, -1},
        {{1.5, 1.4}, {0.7, 1.3}, {0.9, 0.95}, {0.8, 0.5}, 1.0, 0.5},
        {{1.5, 1.4, 1.38}, {0.2, 0.5, 4.0}, {0.3, 0.9, 0.99}, {0.0, 0.8, 0.85}, 1.0, 0.6},
        {{1.33, 1.5}, {1.0, 1.0}, {0.9, 0.9}, {0.7, 0.0}, 1.0, 0.8},
    };
    const int ms[] = {8, 16, 24, 32};
    double mean[4][2] = {}, worst[4][2] = {};
    int count = 0;
    for (const Case& c : cases)
        for (const double mu0 : {1.0, 0.5, 0.2}) {
            const mc_stack::Stack s{1.0, c.below, c.eta, c.tau, c.albedo, c.g, c.floor};
            const mc_stack::Result mc = mc_stack::simulate(s, mu0, 2000000, 7);
            std::vector<stratum::Slab<double>> slabs;
            std::vector<stratum::Boundary<double>> joints;
            for (std::size_t j = 0; j < c.eta.size(); ++j) {
                slabs.emplace_back(c.albedo[j], c.g[j], c.tau[j]);
                if (j > 0) joints.push_back(stratum::SmoothDielectric<double>(c.eta[j - 1], c.eta[j]));
            }
            ++count;
            for (int i = 0; i < 4; ++i)
                for (int split = 0; split < 2; ++split) {
                    stratum::LayerOptions o;
                    o.ordinates = ms[i];
                    o.critical_split = split == 1;
                    stratum::LayerRequest<double> r;
                    r.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
                    r.incidence = {mu0};
                    const stratum::Boundary<double> bottom =
                        c.floor >= 0 ? stratum::Boundary<double>::lambertian(c.floor, c.eta.back())
                                     : stratum::Boundary<double>(stratum::SmoothDielectric<double>(c.eta.back(), c.below));
                    const auto l = stratum::solve_stack<double>(stratum::SmoothDielectric<double>(1.0, c.eta.front()), slabs,
                                                                joints, bottom, o, r);
                    const double e = std::max(std::fabs(l.reflectance(mu0).total() - mc.R()),
                                              std::fabs(l.transmittance(mu0) - mc.T()));
                    mean[i][split] += e;
                    worst[i][split] = std::max(worst[i][split], e);
                }
        }
    for (int i = 0; i < 4; ++i)
        std::printf("| %d | %.1e | %.1e | %.1e | %.1e |\n", ms[i], mean[i][0] / count, worst[i][0], mean[i][1] / count,
                    worst[i][1]);
}

// ---- The planner: its error estimate against the true error, and its cost against the full solve ----------------
// A random material of every face kind (as tests/test_planner.cpp draws them).
stratum::Material<double> random_material(std::mt19937_64& rng, bool& floor) {
    std::uniform_real_distribution<double> u(0, 1);
    const int top_kind = static_cast<int>(3 * u(rng)), bottom_kind = static_cast<int>(4 * u(rng));
    const double n = top_kind == 2 ? 1.0 : 1 + 0.6 * u(rng);
    const double albedo = u(rng) < 0.2 ? 1.0 : u(rng), g = 0.95 * u(rng), tau = std::pow(10.0, -1.3 + 2.8 * u(rng));
    const double sigma_top = std::pow(10.0, -1.5 + 1.5 * u(rng)), sigma_bottom = std::pow(10.0, -1.5 + 1.5 * u(rng));
    using B = stratum::Boundary<double>;
    const B top = top_kind == 0 ? B(stratum::SmoothDielectric<double>(1.0, n))
                  : top_kind == 1 ? B(stratum::RoughDielectric<double>(sigma_top, 1.0, n)) : B::index_matched(1.0);
    floor = bottom_kind == 3;
    const B bottom = bottom_kind == 0 ? B(stratum::SmoothDielectric<double>(n, 1.0))
                     : bottom_kind == 1 ? B(stratum::RoughDielectric<double>(sigma_bottom, n, 1.0))
                     : bottom_kind == 2 ? B::index_matched(n) : B::lambertian(u(rng), n);
    return {top, {stratum::Slab<double>(albedo, g, tau)}, {}, bottom};
}

void planner() {
    using stratum::LayerOutput;
    const int materials = 100, levels = 5;  // 4, 8, 16, 32, 64 ordinates
    std::printf("\n## Planner: the error estimate against the true error\n\n%d random materials (fixed seed; "
                "bench/accuracy_report.cpp, planner: smooth, rough or index-matched tops; smooth, rough, index-matched "
                "or Lambertian bottoms; n 1 to 1.6, albedo 0 to 1 (one in five exactly 1), g 0 to 0.95, tau 0.05 to 30, "
                "RMS slopes 0.03 to 1; one to three incidences), the subsurface reflectance and the transmittance solved "
                "(mode 0) at 4, 8, 16, 32 and 64 ordinates, the truth at 128. At each level from 8 the estimate "
                "(stratum::plan_error_estimate) is compared with the true error, the largest over the fluxes; levels whose "
                "true error is below 1e-9 are left out.\n\n| estimate | levels | bounds the true error | worst true error / "
                "estimate |\n|---|---|---|---|\n", materials);
    std::mt19937_64 rng(2027);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<std::vector<double>> errors, changes;  // per material, per level (changes from level 1)
    for (int t = 0; t < materials; ++t) {
        bool floor = false;
        const stratum::Material<double> m = random_material(rng, floor);
        stratum::LayerRequest<double> r;
        r.outputs = floor ? LayerOutput::reflectance : LayerOutput::reflectance | LayerOutput::transmittance;
        const int incidences = 1 + static_cast<int>(3 * u(rng));
        for (int i = 0; i < incidences; ++i) r.incidence.push_back(u(rng) < 0.2 ? 1.0 : 0.05 + 0.95 * u(rng));
        const auto fluxes = [&](int ordinates) {
            stratum::LayerOptions o;
            o.ordinates = ordinates;
            o.modes = 1;
            const auto s = stratum::solve_stack<double>(m.top, m.slabs, m.interior, m.bottom, o, r);
            std::vector<double> v;
            for (const double mu : r.incidence) {
                v.push_back(s.reflectance(mu).subsurface);
                if (!floor) v.push_back(s.transmittance(mu));
            }
            return v;
        };
        const auto distance = [](const std::vector<double>& a, const std::vector<double>& b) {
            double d = 0;
            for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::fabs(a[i] - b[i]));
            return d;
        };
        const std::vector<double> truth = fluxes(128);
        std::vector<double> e, c, before;
        for (int level = 0; level < levels; ++level) {
            const std::vector<double> v = fluxes(4 << level);
            e.push_back(distance(v, truth));
            if (level > 0) c.push_back(distance(v, before));
            before = v;
        }
        errors.push_back(e);
        changes.push_back(c);
    }
    for (const bool guarded : {false, true}) {
        int counted = 0, bounded = 0;
        double worst = 0;
        for (int t = 0; t < materials; ++t)
            for (int level = 1; level < levels; ++level) {
                const double error = errors[t][level];
                if (error < 1e-9) continue;
                const std::vector<double> c(changes[t].begin(), changes[t].begin() + level);
                const double estimate = guarded ? stratum::plan_error_estimate(c) : 2 * c.back();
                ++counted;
                bounded += error <= estimate;
                worst = std::max(worst, error / estimate);
            }
        std::printf("| %s | %d | %.1f%% | %.1f |\n", guarded ? "2 max(last change, previous change / 4) (used)" : "2 last change",
                    counted, 100.0 * bounded / counted, worst);
    }
    std::printf("\nThe plans at three tolerances (max_ordinates 64): how many met the tolerance by the estimate, how many "
                "of those are truly within it, and the ordinates chosen against the fewest that would do (the first "
                "level truly within the tolerance), mean over the plans that met it.\n\n| tolerance | met | truly within | "
                "ordinates chosen | ordinates needed |\n|---|---|---|---|---|\n");
    for (const double tolerance : {1e-2, 1e-3, 1e-4}) {
        int met = 0, within = 0;
        double chosen = 0, needed = 0;
        for (int t = 0; t < materials; ++t)
            for (int level = 1; level < levels; ++level) {
                const std::vector<double> c(changes[t].begin(), changes[t].begin() + level);
                if (stratum::plan_error_estimate(c) > tolerance) continue;
                ++met;
                within += errors[t][level] <= tolerance;
                chosen += 4 << level;
                int first = 0;
                while (first < levels - 1 && errors[t][first] > tolerance) ++first;
                needed += 4 << first;
                break;
            }
        std::printf("| %.0e | %d | %d | %.1f | %.1f |\n", tolerance, met, within, chosen / std::max(met, 1),
                    needed / std::max(met, 1));
    }

    std::printf("\n## Planner: the diffusion profile (dipole) against the layer solver\n\nA half-space (tau = 1e4) under a "
                "smooth face, sigma_t = 1 per unit length: the dipole's total diffuse reflectance at normal incidence, "
                "F_t(1) R_d,total, against the layer solver's subsurface reflectance R(1) at the planner's ordinates "
                "(tolerance 1e-4): Plan::profile_error, absolute and relative to R(1).\n\n| n | albedo | g | alpha' | R(1) | "
                "profile error | relative |\n|---|---|---|---|---|---|---|\n");
    for (const double n : {1.0, 1.35})
        for (const double albedo : {0.5, 0.9, 0.99, 0.999})
            for (const double g : {0.0, 0.8}) {
                using B = stratum::Boundary<double>;
                const stratum::Material<double> half_space{n == 1.0 ? B::index_matched(1.0) : B(stratum::SmoothDielectric<double>(1.0, n)),
                                                           {stratum::Slab<double>(albedo, g, 1e4)}, {}, B::index_matched(n), 1.0};
                stratum::SceneRequest<double> scene;
                scene.outputs = LayerOutput::reflectance;
                scene.incidence = {1.0};
                scene.tolerance = 1e-4;
                scene.diffusion_profile = true;
                const auto planned = stratum::solve_planned(half_space, scene);
                const double r = planned.surface.reflectance(1.0).subsurface;
                std::printf("| %.2f | %.3f | %.1f | %.4f | %.4f | %.1e | %.1f%% |\n", n, albedo, g, planned.dipole->alpha_prime(), r,
                            planned.plan.profile_error, 100 * planned.plan.profile_error / r);
            }

    std::printf("\n## Planner: cost against the full solve\n\nstratum::solve_planned (its mode-0 levels and, for angular "
                "outputs, the final solve and the estimate of its angular error) against solve_layer at the ordinates it chose with every output and all 2M "
                "modes, from nothing (processor time, best of 3). Stam's skin layer and a smooth-faced slab (n 1.4 in air, "
                "albedo 0.9, g 0.8, tau 1), incidence mu0 = 0.5.\n\n| material | outputs | tolerance | ordinates | modes "
                "| estimated error | plan (ms) | full solve (ms) | ratio |\n|---|---|---|---|---|---|---|---|---|\n");
    const stratum::Material<double> skin{stratum::RoughDielectric<double>(0.3, 1.0, 1.4), {stratum::Slab<double>(0.9, 0.8, std::log(2.0))},
                                         {}, stratum::RoughDielectric<double>(0.3, 1.4, 1.0)};
    const stratum::Material<double> smooth{stratum::SmoothDielectric<double>(1.0, 1.4), {stratum::Slab<double>(0.9, 0.8, 1.0)}, {},
                                           stratum::SmoothDielectric<double>(1.4, 1.0)};
    const std::pair<const char*, LayerOutput> outputs[] = {
        {"fluxes", LayerOutput::reflectance | LayerOutput::transmittance},
        {"reflection", LayerOutput::subsurface_reflection},
        {"all", LayerOutput::all}};
    for (const auto& [name, material] : {std::pair<const char*, const stratum::Material<double>*>{"Stam's skin", &skin},
                                         std::pair<const char*, const stratum::Material<double>*>{"smooth slab", &smooth}})
        for (const double tolerance : {1e-2, 1e-3})
            for (const auto& [what, set] : outputs) {
                stratum::SceneRequest<double> scene;
                scene.outputs = set;
                scene.incidence = {0.5};
                scene.tolerance = tolerance;
                auto planned = stratum::solve_planned(*material, scene);
                const double plan_ms = median_ms([&] { planned = stratum::solve_planned(*material, scene); }, 3);
                stratum::LayerOptions o;
                o.ordinates = planned.plan.options.ordinates;
                stratum::LayerRequest<double> all;
                all.incidence = scene.incidence;
                const double full_ms = median_ms([&] {
                    stratum_accuracy::sink = stratum::solve_stack<double>(material->top, material->slabs, material->interior,
                                                                          material->bottom, o, all).reflectance(0.5).total();
                }, 3);
                std::printf("| %s | %s | %.0e | %d | %d | %.1e | %.3g | %.3g | %.2f |\n", name, what, tolerance, o.ordinates,
                            planned.plan.modes, planned.plan.estimated_error, plan_ms, full_ms, plan_ms / full_ms);
            }
}

void pareto_fronts() {
    std::printf("\n## Pareto fronts: error against time for every combination of knobs\n\nEach point is one combination "
                "of the solver's knobs; the front joins those that no other combination beats in both error and time, "
                "and the ring marks the default settings (`LayerOptions{}` and the default request, M = 16). Times are "
                "processor times of the solve (and, where stated, the evaluation), best of 3.\n");
    using stratum::LayerOutput;
    // 1. Stam's skin layer: ordinates, a request tolerance, delta-M; error as in "Layer solver: ordinates".
    {
        const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
        const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
        stratum::LayerOptions o48;
        o48.ordinates = 48;
        const SkinProbe ref = probe(stratum::solve_layer(slab, top, bottom, o48));
        std::vector<Run> runs;
        for (int m : {4, 8, 12, 16, 24, 32})
            for (double tol : {0.0, 1e-2, 1e-3})
                for (bool dm : {true, false}) {
                    stratum::LayerOptions o;
                    o.ordinates = m;
                    o.delta_m = dm;
                    stratum::LayerRequest<double> r;
                    r.tolerance = tol;
                    stratum::LayeredSurface<double> layer = stratum::solve_layer(slab, top, bottom, o, r);
                    const double t = median_ms([&] { layer = stratum::solve_layer(slab, top, bottom, o, r); }, 3);
                    const SkinProbe p = probe(layer);
                    const double e = std::max({max_relative(p.reflectance, ref.reflectance, 3),
                                               max_relative(p.transmittance, ref.transmittance, 3),
                                               max_relative(p.brdf, ref.brdf, 4), max_relative(p.btdf, ref.btdf, 4)});
                    char k[96];
                    std::snprintf(k, sizeof k, "M = %d, tolerance %g, delta-M %s", m, tol, dm ? "on" : "off");
                    runs.push_back({k, e, t, m == 16 && tol == 0 && dm});
                }
        std::printf("\n### Stam's skin layer\n\nError: the largest relative difference from M = 48 over the subsurface "
                    "reflectance and transmittance at mu0 = 1, 0.7, 0.3 and r_s, t_s at 4 directions (mu0 = 0.8), all "
                    "outputs solved. Knobs: ordinates M, the request's tolerance (modes skipped), delta-M.\n");
        print_front("Stam's skin layer", "pareto_skin.svg", runs);
    }
    // 2. A smooth-faced tissue slab: ordinates, the critical split, delta-M; fluxes against adding-doubling.
    {
        const std::vector<Reference> refs = adding_doubling_references();
        stratum::LayerRequest<double> request;
        request.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
        std::vector<Run> runs;
        for (int m : {4, 6, 8, 12, 16, 24, 32, 48, 64})
            for (bool split : {true, false})
                for (bool dm : {true, false}) {
                    stratum::LayerOptions o;
                    o.ordinates = m;
                    o.critical_split = split;
                    o.delta_m = dm;
                    auto solve = [&](const Reference& x) {
                        return stratum::solve_layer(stratum::Slab<double>(x.albedo, x.g, x.tau),
                                                    stratum::SmoothDielectric<double>(1.0, x.n),
                                                    stratum::SmoothDielectric<double>(x.n, 1.0), o, request);
                    };
                    double e = 0;
                    for (const Reference& x : refs) {
                        const auto layer = solve(x);
                        e = std::max({e, std::fabs(layer.reflectance(x.mu0).total() - x.r), std::fabs(layer.transmittance(x.mu0) - x.t)});
                    }
                    const double t = refs.empty() ? 0.0 : median_ms([&] { (void)solve(refs.front()).reflectance(1.0); }, 3);
                    char k[96];
                    std::snprintf(k, sizeof k, "M = %d, split %s, delta-M %s", m, split ? "on" : "off", dm ? "on" : "off");
                    runs.push_back({k, e, t, m == 16 && split && dm});
                }
        std::printf("\n### A smooth-faced tissue slab\n\nError: the largest absolute difference in reflectance or "
                    "transmittance from Prahl's converged adding-doubling over its 24 cases, normal and oblique (grazing "
                    "included) (tests/data/adding_doubling_reference.txt); time: one slab (n 1.4, albedo 0.9, g 0.8, tau 1), "
                    "fluxes only. Knobs: ordinates M, the critical split, delta-M.\n");
        print_front("Smooth-faced tissue slab", "pareto_smooth_slab.svg", runs);
    }
    // 3. DISORT test problem 1 (van de Hulst's isotropic slab): tau = 1, albedo 0.99, beam at mu0 = 0.1.
    {
        const stratum::Slab<double> slab(0.99, 0.0, 1.0);
        const auto matched = stratum::Boundary<double>::index_matched();
        stratum::LayerOptions o128;
        o128.ordinates = 128;
        stratum::LayerRequest<double> flux;
        flux.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
        const auto ref = stratum::solve_layer(slab, matched, matched, o128, flux);
        const double r_ref = ref.reflectance(0.1).total(), t_ref = ref.transmittance(0.1);
        std::vector<Run> runs;
        for (int m : {2, 3, 4, 6, 8, 12, 16, 24, 32})
            for (bool fluxes_only : {true, false}) {
                stratum::LayerOptions o;
                o.ordinates = m;
                stratum::LayerRequest<double> r;
                if (fluxes_only) r = flux;
                stratum::LayeredSurface<double> layer = stratum::solve_layer(slab, matched, matched, o, r);
                const double t = median_ms([&] {
                    layer = stratum::solve_layer(slab, matched, matched, o, r);
                    (void)layer.reflectance(0.1);
                }, 3);
                const double e = std::max(std::fabs(layer.reflectance(0.1).total() - r_ref) / r_ref,
                                          std::fabs(layer.transmittance(0.1) - t_ref) / t_ref);
                char k[96];
                std::snprintf(k, sizeof k, "M = %d, %s", m, fluxes_only ? "fluxes only (mode 0)" : "all outputs");
                runs.push_back({k, e, t, m == 16 && !fluxes_only});
            }
        std::printf("\n### DISORT test problem 1 (van de Hulst, Table 12)\n\nAn isotropic slab (tau = 1, albedo 0.99) "
                    "lit at mu0 = 0.1, index-matched faces (tests/test_slab.cpp checks the solver against DISORT's listed "
                    "values). Error: the largest relative difference of the reflected and transmitted fluxes from M = 128. "
                    "Knobs: ordinates M, the request (fluxes only, mode 0, or everything).\n");
        print_front("DISORT test problem 1", "pareto_disort1.svg", runs);
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
    layer_growth();
    hemispherical_nodes_sweep();
    layer_integrals();
    layer_tabulated_faces();
    layer_tolerance();
    layer_smooth_faces();
    layer_intensities();
    layer_aureole();
    layer_energy_sweep();
    rough_top_split();
    rough_bottom_split();
    refracting_stacks();
    planner();
    tabulated_bsdf_tolerance();
    pareto_fronts();
    stratum_accuracy::report_dipole();
    return 0;
}
