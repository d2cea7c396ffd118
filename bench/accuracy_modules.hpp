// accuracy_modules.hpp -- the module sections of the accuracy-versus-time report (bench/accuracy_report.cpp
// includes this file and calls the report_* functions; each prints one Markdown section).
//
//   stratum_accuracy::report_quadrature()           Gauss-Legendre rules: ulp error against __float128, time
//   stratum_accuracy::report_henyey_greenstein()    Fourier coefficients: Legendre terms, series vs closed form,
//                                                   delta-M vs plain truncation
//   stratum_accuracy::report_interface_operators()  azimuthal rule: points per panel against error and time
//   stratum_accuracy::report_dipole()               alpha'(R_d): exact inversion, tables, bisection
//
// Every error is against an independent reference computed here (closed forms in long double, __float128
// Newton iterations, long double bisection) or against a much finer setting of the same knob, as each section
// says. Times are processor times, the fastest of repeated runs (own helpers, so that this header stands alone).
#pragma once

#include <stratum/dipole.hpp>
#include <stratum/fresnel.hpp>
#include <stratum/henyey_greenstein.hpp>
#include <stratum/interface_operators.hpp>
#include <stratum/quadrature.hpp>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>
#include <type_traits>
#include <vector>

namespace stratum_accuracy {

/// Processor time of f() in milliseconds (std::clock: the time this process ran, so other processes on a
/// shared machine do not inflate it, unlike wall time), the fastest of `repeats` runs.
template <class F>
double best_time_ms(F&& f, int repeats = 5) {
    double best = std::numeric_limits<double>::infinity();
    for (int r = 0; r < repeats; ++r) {
        const std::clock_t start = std::clock();
        f();
        best = std::min(best, 1e3 * static_cast<double>(std::clock() - start) / CLOCKS_PER_SEC);
    }
    return best;
}

/// Time per call of f() in microseconds for short calls: batched so that one batch lasts >= ~2 ms, then the
/// fastest of `repeats` batches.
template <class F>
double time_per_call_us(F&& f, int repeats = 7) {
    int calls = 1;
    const auto batch = [&] {
        for (int c = 0; c < calls; ++c) f();
    };
    while (calls < (1 << 24) && best_time_ms(batch, 1) < 2) calls *= 2;
    return 1e3 * best_time_ms(batch, repeats) / calls;
}

/// Keeps a computed value alive so that the timed work is not optimized away.
inline volatile double sink = 0;

// =====================================================================================================
// 1. Quadrature
// =====================================================================================================

// The reference type: 113-bit significand. __float128 on GCC/Clang x86-64 (only + - * / are used: libgcc, no
// libquadmath); long double where it is IEEE quad (aarch64 Linux); elsewhere long double with a warning.
#if defined(__SIZEOF_FLOAT128__)
__extension__ typedef __float128 quad;
inline constexpr bool quad_is_113_bits = true;
#else
typedef long double quad;
inline constexpr bool quad_is_113_bits = LDBL_MANT_DIG >= 113;
#endif

inline quad quad_abs(quad a) { return a < 0 ? -a : a; }

/// A reference Gauss-Legendre node with x >= 0 and its full-range weight, in __float128.
struct QuadNode {
    quad x, w;
};

/// Node k = 1..(n+1)/2 (counted from x = 1) of the n-point rule, computed independently of stratum:
/// Tricomi's initial guess cos(pi (k - 1/4) / (n + 1/2)), Newton's method on the three-term recurrence in long
/// double, then in __float128 until the step is below 1e-24 (1 - x) (the error left is ~1e-48 relative in
/// 1 - x). w = 2 / ((1 - x^2) P_n'(x)^2) with P_n' = n (P_{n-1} - x P_n) / (1 - x^2); the last step's
/// derivative is off by ~1e-24 relative. `a`, `b` are the recurrence's (2l + 1)/(l + 1) and l/(l + 1) in quad.
/// Sets `bracket_ok` false if the root falls outside Bruns' bracket (k - 1/2) pi/(n + 1/2) < theta <
/// k pi/(n + 1/2), i.e. Newton found the wrong root.
inline QuadNode reference_gauss_node(int n, int k, const std::vector<quad>& a, const std::vector<quad>& b,
                                     bool& bracket_ok) {
    const long double pi = 3.141592653589793238462643383279502884L;
    auto legendre = [n, &a, &b](auto x, auto& pn, auto& pn1) {  // P_n(x), P_{n-1}(x)
        using T = std::decay_t<decltype(x)>;
        T p0 = 1, p1 = x;
        for (int l = 1; l < n; ++l) {
            const T p2 = static_cast<T>(a[static_cast<std::size_t>(l)]) * x * p1 -
                         static_cast<T>(b[static_cast<std::size_t>(l)]) * p0;
            p0 = p1;
            p1 = p2;
        }
        pn = p1;
        pn1 = p0;
    };
    if (2 * k - 1 == n) {  // the middle node of odd n: x = 0, w = 2 / (n P_{n-1}(0))^2
        quad pn, pn1;
        legendre(quad(0), pn, pn1);
        const quad d = n * pn1;
        return {quad(0), 2 / (d * d)};
    }
    long double xl = std::cos(pi * (static_cast<long double>(k) - 0.25L) / (static_cast<long double>(n) + 0.5L));
    for (int it = 0; it < 30; ++it) {
        long double pn, pn1;
        legendre(xl, pn, pn1);
        const long double dx = pn * (1 - xl) * (1 + xl) / (static_cast<long double>(n) * (pn1 - xl * pn));
        xl -= dx;
        if (std::fabs(dx) < 1e-14L * (1 - xl) || it > 20) break;
    }
    quad x = xl, dp = 1;
    for (int it = 0; it < 8; ++it) {
        quad pn, pn1;
        legendre(x, pn, pn1);
        dp = n * (pn1 - x * pn) / ((1 - x) * (1 + x));
        const quad dx = pn / dp;
        x -= dx;
        if (quad_abs(dx) < quad(1e-24) * (1 - x)) break;
    }
    const long double theta = std::acos(static_cast<long double>(x));
    const long double width = 1 / (static_cast<long double>(n) + 0.5L);
    if (!(theta > pi * (static_cast<long double>(k) - 0.5L) * width - 1e-15L &&
          theta < pi * static_cast<long double>(k) * width + 1e-15L))
        bracket_ok = false;
    return {x, 2 / ((1 - x) * (1 + x) * dp * dp)};
}

/// The textbook method, for comparison: Newton's method in double on the recurrence from Tricomi's guess,
/// w = 2 / ((1 - x^2) P_n'(x)^2) at the rounded node (as Numerical Recipes' gauleg, but with P_n' evaluated
/// at the final node). Node k as in reference_gauss_node.
inline void textbook_gauss_node(int n, int k, double& x, double& w) {
    const double pi = 3.141592653589793;
    x = std::cos(pi * (k - 0.25) / (n + 0.5));
    auto derivative = [n](double z, double& pn) {  // P_n(z) and P_n'(z)
        double p0 = 1, p1 = z;
        for (int l = 1; l < n; ++l) {
            const double p2 = ((2 * l + 1) * z * p1 - l * p0) / (l + 1);
            p0 = p1;
            p1 = p2;
        }
        pn = p1;
        return n * (p0 - z * p1) / (1 - z * z);
    };
    double pn = 0;
    for (int it = 0; it < 100; ++it) {
        const double dp = derivative(x, pn);
        const double dx = pn / dp;
        x -= dx;
        if (std::fabs(dx) <= 3e-16) break;
    }
    const double dp = derivative(x, pn);  // at the final node (gauleg reuses the previous iterate's)
    w = 2 / ((1 - x * x) * dp * dp);
}

/// Signed error of v against r in units of the double spacing at r (the spacing of r's own binade).
inline double ulp_error(double v, quad r) {
    const double d = std::fabs(static_cast<double>(r));
    if (d == 0) return v == 0 ? 0.0 : std::numeric_limits<double>::infinity();
    const double spacing = static_cast<quad>(d) > quad_abs(r) ? d - std::nextafter(d, 0.0)
                                                              : std::nextafter(d, 2 * d) - d;
    return static_cast<double>((static_cast<quad>(v) - r) / static_cast<quad>(spacing));
}

inline void report_quadrature_ulps() {
    std::printf("\n## Quadrature: Gauss-Legendre nodes and weights\n\n"
                "Maximum error, in ulp of double, of `gauss_legendre<double>(n)` and `gauss_legendre_half<double>(n)` "
                "against reference rules computed here with a 113-bit significand (__float128): Tricomi's initial guess, Newton's method on the "
                "three-term recurrence in long double and then in __float128, each root checked against Bruns' "
                "bracket (independent of stratum's theta-Newton and Bogaert expansions). A correctly rounded value "
                "is within 0.5 ulp. n <= 1024: every node; n = 10000: the 64 nodes at each end and every 16th node "
                "between. Time: one call building the rule (stratum uses Newton for n <= 200, Bogaert's "
                "iteration-free expansion above). For comparison, the last two columns: the textbook method (Newton in "
                "double on the recurrence, w = 2 / ((1 - x^2) P_n'(x)^2) at the final rounded node), full-range "
                "rule.%s\n\n", quad_is_113_bits ? "" : " **This platform has no 113-bit type: the references are only "
                "long double, so the ulp figures below are not meaningful.**");
    std::printf("| n | full nodes (ulp) | full weights (ulp) | half nodes (ulp) | half weights (ulp) | "
                "gauss_legendre (us) | gauss_legendre_half (us) | ns per node | textbook nodes (ulp) | textbook weights (ulp) |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
    for (int n : {4, 8, 16, 32, 64, 128, 256, 1024, 10000}) {
        std::vector<quad> a(static_cast<std::size_t>(n) + 1), b(a.size());
        for (int l = 1; l <= n; ++l) {
            a[static_cast<std::size_t>(l)] = quad(2 * l + 1) / quad(l + 1);
            b[static_cast<std::size_t>(l)] = quad(l) / quad(l + 1);
        }
        const auto full = stratum::gauss_legendre<double>(n);
        const auto half = stratum::gauss_legendre_half<double>(n);
        const int h = (n + 1) / 2;
        double e_x = 0, e_w = 0, e_hx = 0, e_hw = 0, e_tx = 0, e_tw = 0;
        bool ok = true;
        for (int k = 1; k <= h; ++k) {
            if (n > 1024 && !(k <= 64 || k > h - 64 || k % 16 == 0)) continue;
            const QuadNode r = reference_gauss_node(n, k, a, b, ok);
            const auto hi = static_cast<std::size_t>(n - k), lo = static_cast<std::size_t>(k - 1);
            e_x = std::max({e_x, std::fabs(ulp_error(full.nodes[hi], r.x)), std::fabs(ulp_error(full.nodes[lo], -r.x))});
            e_w = std::max({e_w, std::fabs(ulp_error(full.weights[hi], r.w)), std::fabs(ulp_error(full.weights[lo], r.w))});
            e_hx = std::max({e_hx, std::fabs(ulp_error(half.nodes[hi], (1 + r.x) / 2)),
                             std::fabs(ulp_error(half.nodes[lo], (1 - r.x) / 2))});
            e_hw = std::max({e_hw, std::fabs(ulp_error(half.weights[hi], r.w / 2)),
                             std::fabs(ulp_error(half.weights[lo], r.w / 2))});
            if (2 * k - 1 != n) {
                double tx, tw;
                textbook_gauss_node(n, k, tx, tw);
                e_tx = std::max(e_tx, std::fabs(ulp_error(tx, r.x)));
                e_tw = std::max(e_tw, std::fabs(ulp_error(tw, r.w)));
            }
        }
        const double t_full = time_per_call_us([&] { sink = sink + stratum::gauss_legendre<double>(n).weights[0]; });
        const double t_half = time_per_call_us([&] { sink = sink + stratum::gauss_legendre_half<double>(n).weights[0]; });
        std::printf("| %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.0f | %.1f | %.3g |%s\n", n, e_x, e_w, e_hx,
                    e_hw, t_full, t_half, 1e3 * t_full / n, e_tx, e_tw, ok ? "" : " (reference outside Bruns' bracket!)");
    }
}

/// Hemispherical integrals int_0^1 f(mu) dmu with N points per hemisphere: the N-point half-range rule against
/// the positive half of the 2N-point full-range rule (Stam's Appendix A, where int_{-1}^{1} is one rule).
inline void report_quadrature_hemispherical() {
    const long double b = 3, tau = 0.5L, eta = 1.4L;
    // References in long double ((2) and (3) checked against mpmath quadrature to 30 digits when this was written).
    // (1) int_0^1 mu e^{-b mu} dmu = (1 - (1 + b) e^{-b}) / b^2.
    const long double ref1 = (1 - (1 + b) * std::exp(-b)) / (b * b);
    // (2) 2 int_0^1 mu e^{-tau/mu} dmu = 2 E_3(tau) = e^{-tau} (1 - tau) + tau^2 E_1(tau): diffuse transmittance
    //     of a purely absorbing slab. E_1(x) = -gamma - ln x - sum_{j>=1} (-x)^j / (j j!) (converges fast for x = 0.5).
    long double series = 0, term = 1;
    for (int j = 1; j < 40; ++j) {
        term *= -tau / static_cast<long double>(j);
        series += term / static_cast<long double>(j);
    }
    const long double e1 = -0.577215664901532860606512090082402431L - std::log(tau) - series;
    const long double ref2 = std::exp(-tau) * (1 - tau) + tau * tau * e1;
    // (3) 2 int_0^1 F(mu, eta) mu dmu, the hemispherical reflectance of a dielectric seen from outside
    //     (eta = 1.4), by the closed form of that integral:
    //     1/2 + (n-1)(3n+1)/(6(n+1)^2) + n^2 (n^2-1)^2/(n^2+1)^3 ln((n-1)/(n+1))
    //         - 2n^3 (n^2+2n-1)/((n^2+1)(n^4-1)) + 8n^4 (n^4+1)/((n^2+1)(n^4-1)^2) ln n.
    const long double n = eta, n2 = n * n, n4 = n2 * n2;
    const long double ref3 = 0.5L + (n - 1) * (3 * n + 1) / (6 * (n + 1) * (n + 1)) +
                             n2 * (n2 - 1) * (n2 - 1) / ((n2 + 1) * (n2 + 1) * (n2 + 1)) * std::log((n - 1) / (n + 1)) -
                             2 * n2 * n * (n2 + 2 * n - 1) / ((n2 + 1) * (n4 - 1)) +
                             8 * n4 * (n4 + 1) / ((n2 + 1) * (n4 - 1) * (n4 - 1)) * std::log(n);
    auto f1 = [](double mu) { return mu * std::exp(-3 * mu); };
    auto f2 = [](double mu) { return mu > 0 ? 2 * mu * std::exp(-0.5 / mu) : 0.0; };
    auto f3 = [](double mu) { return 2 * mu * stratum::fresnel_dielectric(mu, 1.4); };
    std::printf("\n## Quadrature: half-range against full-range rule for hemispherical integrals\n\n"
                "Relative error of int_0^1 f(mu) dmu with N points per hemisphere: the N-point half-range rule "
                "(`gauss_legendre_half`, \"double Gauss\") against the N positive nodes of the 2N-point full-range "
                "rule (`gauss_legendre`, the rule of Stam's Appendix A), whose integrand over [-1, 1] has a kink at "
                "mu = 0. References in closed form, long double: (a) mu e^{-3 mu}, (b) 2 mu e^{-0.5/mu} = 2 E_3(0.5) "
                "(diffuse transmittance of an absorbing slab), (c) 2 mu F(mu, 1.4) (hemispherical Fresnel "
                "reflectance from outside, in closed form). The time to build either rule is in the table "
                "above.\n\n");
    std::printf("| N | (a) half | (a) full | (b) half | (b) full | (c) half | (c) full |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    for (int N : {2, 4, 8, 16, 32, 64}) {
        const auto half = stratum::gauss_legendre_half<double>(N);
        const auto full = stratum::gauss_legendre<double>(2 * N);
        double e[6];
        int i = 0;
        auto integrate = [&](auto f, long double ref) {
            long double sh = 0, sf = 0;
            for (std::size_t m = 0; m < half.size(); ++m) sh += half.weights[m] * f(half.nodes[m]);
            for (std::size_t m = 0; m < full.size(); ++m)
                if (full.nodes[m] > 0) sf += full.weights[m] * f(full.nodes[m]);
            e[i++] = static_cast<double>(std::fabs(sh - ref) / ref);
            e[i++] = static_cast<double>(std::fabs(sf - ref) / ref);
        };
        integrate(f1, ref1);
        integrate(f2, ref2);
        integrate(f3, ref3);
        std::printf("| %d | %.1e | %.1e | %.1e | %.1e | %.1e | %.1e |\n", N, e[0], e[1], e[2], e[3], e[4], e[5]);
    }
}

inline void report_quadrature() {
    report_quadrature_ulps();
    report_quadrature_hemispherical();
}

// =====================================================================================================
// 2. Henyey-Greenstein: azimuthal Fourier coefficients and delta-M
// =====================================================================================================

inline void report_hg_legendre_terms() {
    const int K = 32, M = 8;
    const auto rule = stratum::gauss_legendre_half<double>(M);
    std::printf("\n## Henyey-Greenstein: Legendre terms of the Fourier coefficients\n\n"
                "p_k(mu', mu), k = 0..%d, by the Legendre series `phase_fourier_coefficient` with moments g^l, "
                "l = 0..N-1, against the closed form `HenyeyGreenstein::fourier_coefficients` (elliptic integrals "
                "and a recurrence in k, accurate to ~1e-14 relative, tests/test_henyey_greenstein.cpp). Pairs: "
                "mu = the %d half-range ordinates, mu' = +-mu (%d pairs). Error: max over pairs and k of "
                "|p_k(series) - p_k(closed)| / p_0(closed) of the pair. Time per pair, all %d modes (the series "
                "returns 0 at once for k >= N).\n\n",
                K - 1, M, 2 * M * M, K);
    std::printf("| g | N (terms) | error / p_0 | series (us per pair) | closed form (us per pair) |\n");
    std::printf("|---|---|---|---|---|\n");
    struct Pair {
        double a, b;
    };
    std::vector<Pair> pairs;
    for (int m = 0; m < M; ++m)
        for (int n = 0; n < M; ++n) {
            pairs.push_back({rule.nodes[static_cast<std::size_t>(m)], rule.nodes[static_cast<std::size_t>(n)]});
            pairs.push_back({-rule.nodes[static_cast<std::size_t>(m)], rule.nodes[static_cast<std::size_t>(n)]});
        }
    const double npairs = static_cast<double>(pairs.size());
    for (double g : {0.5, 0.9, 0.99}) {
        const stratum::HenyeyGreenstein<double> hg(g);
        std::vector<double> closed(pairs.size() * K);
        for (std::size_t p = 0; p < pairs.size(); ++p) hg.fourier_coefficients(pairs[p].a, pairs[p].b, K, &closed[p * K]);
        const double t_closed = best_time_ms([&] {
            double out[K];
            for (const Pair& p : pairs) {
                hg.fourier_coefficients(p.a, p.b, K, out);
                sink = sink + out[K - 1];
            }
        }) * 1e3 / npairs;
        const int n_full = hg.legendre_terms_for_tolerance(1e-17);
        std::vector<int> ns;
        for (int N = 8; N < n_full; N *= 2) ns.push_back(N);
        ns.push_back(n_full);
        for (int N : ns) {
            const std::vector<double> chi = hg.legendre_moments(N);
            double err = 0;
            for (std::size_t p = 0; p < pairs.size(); ++p)
                for (int k = 0; k < K; ++k) {
                    const double s = stratum::phase_fourier_coefficient(chi, pairs[p].a, pairs[p].b, k);
                    err = std::max(err, std::fabs(s - closed[p * K + static_cast<std::size_t>(k)]) / closed[p * K]);
                }
            const double t = best_time_ms([&] {
                for (const Pair& p : pairs)
                    for (int k = 0; k < K; ++k) sink = sink + stratum::phase_fourier_coefficient(chi, p.a, p.b, k);
            }, 3) * 1e3 / npairs;
            std::printf("| %.2f | %d%s | %.1e | %.1f | %.2f |\n", g, N, N == n_full ? " (g^N = 1e-17)" : "", err, t,
                        t_closed);
        }
    }
}

inline void report_hg_matrices() {
    std::printf("\n## Henyey-Greenstein: phase matrices, Legendre series against closed form\n\n"
                "`phase_fourier_matrices` for M half-range ordinates and K = 2M modes: the moments overload with "
                "N = ln(1e-16)/ln g Legendre terms (the series' truncation below double resolution) against the "
                "`HenyeyGreenstein` overload (closed form per pair of ordinates). Difference: max over all "
                "entries of both matrices of |series - closed| / max p_0.\n\n");
    std::printf("| g | M | K | N | series (ms) | closed form (ms) | difference / max p_0 |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    for (double g : {0.9, 0.99}) {
        const stratum::HenyeyGreenstein<double> hg(g);
        const int N = hg.legendre_terms_for_tolerance(1e-16);
        const std::vector<double> chi = hg.legendre_moments(N);
        for (int M : {8, 24, 64}) {
            const int K = 2 * M;
            const std::vector<double> mu = stratum::gauss_legendre_half<double>(M).nodes;
            auto series = stratum::phase_fourier_matrices(chi, mu, K);
            auto closed = stratum::phase_fourier_matrices(hg, mu, K);
            double scale = 0, diff = 0;
            for (std::size_t i = 0; i < static_cast<std::size_t>(M * M); ++i) scale = std::max(scale, closed.same[i]);
            for (std::size_t i = 0; i < closed.same.size(); ++i)
                diff = std::max({diff, std::fabs(series.same[i] - closed.same[i]),
                                 std::fabs(series.opposite[i] - closed.opposite[i])});
            const int reps = M >= 64 ? 1 : 3;
            const double t_series = best_time_ms([&] { series = stratum::phase_fourier_matrices(chi, mu, K); }, reps);
            const double t_closed = best_time_ms([&] { closed = stratum::phase_fourier_matrices(hg, mu, K); }, reps);
            std::printf("| %.2f | %d | %d | %d | %.2f | %.2f | %.1e |\n", g, M, K, N, t_series, t_closed, diff / scale);
        }
    }
}

/// delta-M against plain truncation, measured on the single-scattering reflection of a semi-infinite layer.
inline void report_hg_delta_m() {
    const double omega = 0.9;
    const long double inv_four_pi = 0.0795774715459476678844418816862571810L;
    std::printf("\n## Henyey-Greenstein: delta-M against plain truncation\n\n"
                "Single-scattering reflection of a semi-infinite layer, albedo %.1f: I_1 = omega p(cos Theta) mu0 / "
                "(mu0 + mu) (per unit incident flux, up to a constant). With delta-M (`delta_m_scaling`, L moments) "
                "the layer has albedo omega' and the phase function with moments chi'_l; the depth scaling cancels "
                "for a semi-infinite layer, so I_1 scales as omega' p'_L. Plain truncation uses omega and the first "
                "L moments g^l. Error: max and rms relative error against the exact HG value (long double) over "
                "mu0, mu in {0.1, 0.2, ..., 1} and 19 azimuths in [0, pi] (scattering angles 11 to 180 deg). "
                "Time: `phase_fourier_matrices` with L moments, M = 16, K = min(L, 32).\n\n", omega);
    std::printf("| g | L | truncated: max | rms | delta-M: max | rms | phase matrices (ms) |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    const std::vector<double> mu16 = stratum::gauss_legendre_half<double>(16).nodes;
    for (double g : {0.8, 0.9, 0.99}) {
        for (int L : {4, 8, 16, 32, 64, 128}) {
            const auto dm = stratum::delta_m_scaling(omega, 1.0, g, L);
            double emax[2] = {0, 0}, esq[2] = {0, 0};
            int count = 0;
            for (int i = 1; i <= 10; ++i)
                for (int j = 1; j <= 10; ++j)
                    for (int a = 0; a <= 18; ++a) {
                        const long double mu0 = 0.1L * i, mu = 0.1L * j, phi = 3.14159265358979323846L * a / 18;
                        const long double c = -mu0 * mu + std::sqrt((1 - mu0 * mu0) * (1 - mu * mu)) * std::cos(phi);
                        const long double gl = g;
                        const long double exact =
                            omega * (1 - gl * gl) * inv_four_pi / std::pow(1 + gl * gl - 2 * gl * c, 1.5L);
                        // 4 pi p_L = sum_l (2l + 1) chi_l P_l(c), P_l by the three-term recurrence.
                        long double p0 = 1, p1 = c, trunc = 1, scaled = 1, gpow = 1;
                        for (int l = 1; l < L; ++l) {
                            gpow *= gl;
                            trunc += (2 * l + 1) * gpow * p1;
                            scaled += (2 * l + 1) * static_cast<long double>(dm.moments[static_cast<std::size_t>(l)]) * p1;
                            const long double p2 = ((2 * l + 1) * c * p1 - l * p0) / (l + 1);
                            p0 = p1;
                            p1 = p2;
                        }
                        const double e[2] = {static_cast<double>(std::fabs(omega * trunc * inv_four_pi - exact) / exact),
                                             static_cast<double>(std::fabs(dm.albedo * scaled * inv_four_pi - exact) / exact)};
                        for (int q = 0; q < 2; ++q) {
                            emax[q] = std::max(emax[q], e[q]);
                            esq[q] += e[q] * e[q];
                        }
                        ++count;
                    }
            const int K = std::min(L, 32);
            const double t = best_time_ms([&] { sink = sink + stratum::phase_fourier_matrices(dm.moments, mu16, K).same[0]; }, 3);
            std::printf("| %.2f | %d | %.1e | %.1e | %.1e | %.1e | %.2f |\n", g, L, emax[0], std::sqrt(esq[0] / count),
                        emax[1], std::sqrt(esq[1] / count), t);
        }
    }
}

inline void report_henyey_greenstein() {
    report_hg_legendre_terms();
    report_hg_matrices();
    report_hg_delta_m();
}

// =====================================================================================================
// 3. Interface operators: the azimuthal rule
// =====================================================================================================

inline void report_interface_operators() {
    const int M = 16, K = 32, reference_points = 64;
    const auto ordinates = stratum::gauss_legendre_half<double>(M);
    std::printf("\n## Interface operators: azimuthal rule\n\n"
                "The four Fourier-mode operators R12, T12, R21, T21 of a rough dielectric interface (air over "
                "n = 1.4, Beckmann RMS slope sigma), M = %d ordinates, K = %d modes, built with "
                "`AzimuthalQuadrature(n)`, n Gauss points per phi panel (panels graded towards the lobe at phi = 0, "
                "split at the TIR / refraction breakpoints). Error: max over the four operators and all entries "
                "(k, n, m) of |L_k(n, m) - reference| / max_n' |L_0(n', m)| (the entry against the peak of its "
                "column's mode 0; the entries are w_m mu_m I_k, so this is the error of the coefficients I_k); "
                "reference: the same operators with n = %d points per panel. Samples: phi samples per (mu_in, "
                "mu_out) pair, averaged over the four kernels (for small n the count is set by the uniform panels that "
                "resolve cos((K - 1) phi), i.e. by K, not by n). Time: building all four operators.\n\n",
                M, K, reference_points);
    std::printf("| sigma | points per panel | phi samples per pair | max error | build (ms) |\n");
    std::printf("|---|---|---|---|---|\n");
    for (double sigma : {0.02, 0.3, 1.0}) {
        const stratum::RoughDielectric<double> interface(sigma, 1.0, 1.4);
        const stratum::InterfaceOperators<double> ref(interface, ordinates, K,
                                                      stratum::AzimuthalQuadrature<double>(reference_points));
        for (int n : {4, 6, 8, 12, 16, 24, 32}) {
            const stratum::AzimuthalQuadrature<double> rule(n);
            stratum::InterfaceOperators<double> ops(interface, ordinates, K, rule);
            double err = 0;
            for (int op = 0; op < 4; ++op) {
                const auto& a = op == 0 ? ops.R12() : op == 1 ? ops.T12() : op == 2 ? ops.R21() : ops.T21();
                const auto& r = op == 0 ? ref.R12() : op == 1 ? ref.T12() : op == 2 ? ref.R21() : ref.T21();
                for (int m = 0; m < M; ++m) {
                    double scale = 0;
                    for (int i = 0; i < M; ++i) scale = std::max(scale, std::fabs(r(0, i, m)));
                    if (!(scale > 0)) continue;
                    for (int k = 0; k < K; ++k)
                        for (int i = 0; i < M; ++i) err = std::max(err, std::fabs(a(k, i, m) - r(k, i, m)) / scale);
                }
            }
            double samples = 0;
            for (int side = 0; side < 2; ++side)
                for (int t = 0; t < 2; ++t) {
                    const stratum::detail::RoughKernel<double> kernel{
                        &interface, side == 0 ? stratum::Incidence::from_above : stratum::Incidence::from_below, t == 1};
                    for (double mu_in : ordinates.nodes)
                        for (double mu_out : ordinates.nodes)
                            samples += rule.sample_count(kernel.features(mu_in, mu_out), K);
                }
            samples /= 4.0 * M * M;
            const double t = best_time_ms([&] { ops = stratum::InterfaceOperators<double>(interface, ordinates, K, rule); }, 3);
            std::printf("| %.2f | %d | %.0f | %.1e | %.1f |\n", sigma, n, samples, err, t);
        }
    }
}

// =====================================================================================================
// 4. Dipole: alpha'(R_d)
// =====================================================================================================

inline void report_dipole() {
    const auto boundary = stratum::DipoleBoundary<double>::from_eta(1.3);
    // Reference: bisection in s = sqrt(3 (1 - alpha')) on R_d(s) = (1 - s^2/3)(1 + e^{-(4/3) A s}) e^{-s} / 2
    // (decreasing on [0, sqrt 3]) in long double, 70 halvings (interval 1e-21), written here from the formula.
    const long double k = 4.0L / 3 * static_cast<long double>(boundary.A);
    auto reference = [k](long double Rd) {
        long double lo = 0, hi = std::sqrt(3.0L);
        for (int i = 0; i < 70; ++i) {
            const long double s = (lo + hi) / 2;
            const long double R = (1 - s * s / 3) * (1 + std::exp(-k * s)) * std::exp(-s) / 2;
            (R > Rd ? lo : hi) = s;
        }
        const long double s = (lo + hi) / 2;
        return 1 - s * s / 3;
    };
    std::vector<double> grid;
    const int n_grid = 100000;
    for (int i = 0; i < n_grid; ++i) grid.push_back(static_cast<double>(i) / n_grid);  // uniform in R_d
    for (int i = 0; i < n_grid; ++i) {                                                  // uniform in sqrt(R_d)
        const double y = (i + 0.5) / n_grid;
        grid.push_back(y * y);
    }
    std::vector<long double> ref(grid.size());
    for (std::size_t i = 0; i < grid.size(); ++i) ref[i] = reference(grid[i]);
    std::printf("\n## Dipole: alpha' from the total diffuse reflectance\n\n"
                "alpha'(R_d) at eta = 1.3 (Jensen's F_dr fit): the exact inversion `alpha_prime_from_reflectance` "
                "(Halley in s), `AlphaPrimeTable` of several sizes (cubic Hermite, uniform in sqrt(R_d)), and a "
                "16-step bisection on alpha' using `total_diffuse_reflectance` (the simplest robust inversion; its "
                "error is the bracket's 2^-17). Error: max |alpha' - reference| "
                "over %zu values of R_d in [0, 1) (%d uniform in R_d and %d uniform in sqrt(R_d)); reference: "
                "bisection in s on the R_d formula in long double, written independently. Time per call, over "
                "the whole grid.\n\n", grid.size(), n_grid, n_grid);
    std::printf("| method | max error | ns per call | build (ms) |\n|---|---|---|---|\n");
    auto row = [&](const char* name, auto f, double build_ms) {
        double err = 0;
        for (std::size_t i = 0; i < grid.size(); ++i)
            err = std::max(err, static_cast<double>(std::fabs(static_cast<long double>(f(grid[i])) - ref[i])));
        const double t = best_time_ms([&] {
            double s = 0;
            for (double Rd : grid) s += f(Rd);
            sink = sink + s;
        }) * 1e6 / static_cast<double>(grid.size());
        if (build_ms > 0)
            std::printf("| %s | %.1e | %.1f | %.2f |\n", name, err, t, build_ms);
        else
            std::printf("| %s | %.1e | %.1f | - |\n", name, err, t);
    };
    row("exact (Halley)", [&](double Rd) { return stratum::alpha_prime_from_reflectance(Rd, boundary); }, 0);
    for (int size : {33, 129, 513, 2001, 8193}) {
        stratum::AlphaPrimeTable<double> table(boundary, size);
        const double build = best_time_ms([&] { table = stratum::AlphaPrimeTable<double>(boundary, size); }, 3);
        char name[48];
        std::snprintf(name, sizeof name, "table, %d nodes", size);
        row(name, [&](double Rd) { return table(Rd); }, build);
    }
    row("bisection, 16 steps", [&](double Rd) {
        double lo = 0, hi = 1;
        for (int i = 0; i < 16; ++i) {
            const double a = (lo + hi) / 2;
            (stratum::total_diffuse_reflectance(a, boundary) < Rd ? lo : hi) = a;
        }
        return (lo + hi) / 2;
    }, 0);
}

}  // namespace stratum_accuracy
