// tests/reference/rough_albedo_reference.hpp -- the rough-dielectric hemispherical integral as it was before the
// fast path (stratum commit 3df7dd5, include/stratum/interface.hpp, detail::rough_albedo): slow (2-5 ms at 16
// nodes, ~30 ms at 40) but simple; test-only. What it shares with the library, and what it does not: its
// quadrature is its own (long Gaussian range L = sqrt(ln(1/eps)) + 1, two fixed breakpoint grids, no pair
// grading, no Taylor tables: exact Lambda and the Beta function per facet), so it checks the fast path's
// panelling, maps, tables and series; the integrand's pieces are the library's (fresnel_dielectric,
// Beckmann::Lambda, detail::log_beta1), each checked on its own against mpmath (test_fresnel.cpp,
// test_microfacet.cpp, test_math.cpp; smith_g2_over_g1 below is this file's, in test_math.cpp against
// (1 + a) B(1 + a, 1 + b)) and the whole integrand against a facet-level Monte Carlo
// (test_interface_energy.cpp). Its own error at 40 nodes, measured against 56: <= 4e-9 (masking_only near the
// critical-angle / refracted-horizon tangency), <= 3e-10 otherwise.
#pragma once

#include <stratum/interface.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>

namespace stratum_test {

using stratum::HemisphericalTotals;
using stratum::Beckmann;
using stratum::Quadrature;
using stratum::Shadowing;
using stratum::detail::pi_v;

// G2 / G1(i) with G1(i) = 1 / (1 + li), finite also at li = inf (grazing incidence): the shadowing where the visible
// normal distribution (which contains G1(i)) is the integration measure. (Test-only: the library's fast path
// integrates otherwise; it lived in interface.hpp, used by nothing there.)
template <class W>
W smith_g2_over_g1(W li, W lo, Shadowing form, bool transmission) noexcept {
    const W inf = std::numeric_limits<W>::infinity();
    switch (form) {
        case Shadowing::masking_only: return W(1);
        case Shadowing::separable: return 1 / (1 + lo);
        case Shadowing::height_correlated:
        default:
            if (!transmission) return li == inf ? (lo == inf ? W(0) : W(1)) : 1 / (1 + lo / (1 + li));
            if (lo == inf) return W(0);
            if (li == inf) return lo == 0 ? W(1) : W(0);
            // (1 + li) B(1 + li, 1 + lo) < (1 + li) 4^{-m}, m = min(li, lo): 0 in every type for m > 1e15.
            if (!(std::fmin(li, lo) <= W(1e15))) return W(0);
            return std::exp(std::log1p(li) + stratum::detail::log_beta1(li, lo));
    }
}

template <class W>
HemisphericalTotals<W> rough_albedo_reference(W sigma, W mu, W eta, Shadowing form, int n) {
    const Beckmann<W> dist(sigma);
    const W alpha = dist.alpha();
    const W s = std::sqrt((1 - mu) * (1 + mu));
    const W L = std::sqrt(-std::log(std::numeric_limits<W>::epsilon())) + 1;
    const W x_edge = s > 0 ? mu / (alpha * s) : std::numeric_limits<W>::infinity();  // back-facing edge
    const W x_max = std::fmin(x_edge, L);
    const W li = dist.Lambda(mu);
    const W norm = 2 / (pi_v<W> * dist.projected_area(mu));  // 2: y in [0, L] only
    const W k2 = (eta - 1) * (eta + 1);
    // Conics A X^2 + B X + C0 + C2 Y^2 = 0.
    struct Conic { W A, B, C0, C2; };
    Conic conics[3] = {{mu, 2 * s, -mu, mu}, {mu * mu, 2 * mu * s, -mu * mu - k2, mu * mu}, {}};
    int nc = 2;
    if (eta < 1) {
        const W cc2 = -k2;
        conics[nc++] = {s * s - cc2, -2 * mu * s, mu * mu - cc2, -cc2};
    }
    const Quadrature<W> rule = stratum::gauss_legendre_half<W>(n);

    // Breakpoints: fixed ones every 1.5 (so each panel sees at most a 1.5-wide piece of the Gaussian) and
    // singular ones (the conics), where the panel map gets a vanishing derivative.
    struct Break { W at; bool singular; W scale; };  // scale > 0: a movable fixed breakpoint
    // Sorts (insertion sort: at most 64 entries) and merges coinciding breakpoints, keeping the singular
    // flag: a fixed breakpoint on top of a singular one must not hide the singularity. Returns the count.
    auto sort_breaks = [](Break* b, int count) {
        for (int i = 1; i < count; ++i)
            for (int j = i; j > 0 && b[j].at < b[j - 1].at; --j) std::swap(b[j], b[j - 1]);
        int out = 0;
        for (int i = 0; i < count; ++i) {
            const W tol = 64 * std::numeric_limits<W>::epsilon() * std::fmax(W(1), std::fabs(b[i].at));
            if (out > 0 && b[i].at - b[out - 1].at <= tol)
                b[out - 1].singular = b[out - 1].singular || b[i].singular;
            else
                b[out++] = b[i];
        }
        // A fixed breakpoint closer than a quarter of its spacing to a singular one would leave the next
        // panel with a singularity just outside its end (slow convergence): drop it.
        int kept = 0;
        for (int i = 0; i < out; ++i) {
            const bool near_prev = i > 0 && b[i - 1].singular && b[i].at - b[i - 1].at < b[i].scale / 4;
            const bool near_next = i + 1 < out && b[i + 1].singular && b[i + 1].at - b[i].at < b[i].scale / 4;
            if (!b[i].singular && b[i].scale > 0 && (near_prev || near_next)) continue;
            b[kept++] = b[i];
        }
        return kept;
    };
    auto panel = [&](const Break& lo, const Break& hi, auto&& body) {
        const W d = hi.at - lo.at;
        if (!(d > 0)) return;
        for (std::size_t k = 0; k < rule.size(); ++k) {
            const W t = rule.nodes[k], wt = rule.weights[k];
            if (lo.singular && hi.singular)
                body(lo.at + d * t * t * (3 - 2 * t), wt * 6 * d * t * (1 - t));
            else if (lo.singular)
                body(lo.at + d * t * t, wt * 2 * d * t);
            else if (hi.singular)
                body(hi.at - d * (1 - t) * (1 - t), wt * 2 * d * (1 - t));
            else
                body(lo.at + d * t, wt * d);
        }
    };

    constexpr int capacity = 64, fixed_capacity = 40;  // <= 24 singular breakpoints are added after the fixed ones
    Break ybreak[capacity];
    int ny = 0;
    ybreak[ny++] = {W(0), false, W(0)};
    ybreak[ny++] = {L, false, W(0)};
    auto add_fixed = [&](Break* b, int& count, W lo, W hi) {
        // Gaussian scale: every 2 in x; geometric in the real slope around 0 (the integrand's complex
        // singularities sit at X = +-i sqrt(1 + Y^2)): |X| = 1/2, 1, 2, 4, ...
        for (W x = 2; x < L; x += 2) {
            if (x > lo && x < hi) b[count++] = {x, false, W(2)};
            if (-x > lo && -x < hi) b[count++] = {-x, false, W(2)};
        }
        for (W X = W(0.5); X / alpha < L && count + 2 <= fixed_capacity; X *= 2) {
            const W x = X / alpha, scale = std::fmin(x / 2, W(2));
            if (x > lo && x < hi) b[count++] = {x, false, scale};
            if (-x > lo && -x < hi) b[count++] = {-x, false, scale};
        }
    };
    add_fixed(ybreak, ny, W(0), L);
    auto add_y = [&](W Y2) {
        if (Y2 > 0) {
            const W y = std::sqrt(Y2) / alpha;
            if (y < L) ybreak[ny++] = {y, true, W(0)};
        }
    };
    for (int i = 0; i < nc; ++i) {
        const Conic& q = conics[i];
        if (q.C2 == 0) continue;
        if (q.A != 0) add_y((q.B * q.B / (4 * q.A) - q.C0) / q.C2);
        if (x_edge < L) {
            const W X = alpha * x_edge;
            add_y(-(q.A * X * X + q.B * X + q.C0) / q.C2);
        }
    }
    // Where the roots of two different conics cross, the inner integral changes form: eliminate Y^2
    // between the two quadratics to get a quadratic in X, and break y there.
    for (int i = 0; i < nc; ++i) {
        for (int k = i + 1; k < nc; ++k) {
            const Conic &p = conics[i], &q = conics[k];
            if (p.C2 == 0) continue;
            const W r = q.C2 / p.C2;
            const W A = q.A - r * p.A, B = q.B - r * p.B, C = q.C0 - r * p.C0;
            W roots[2];
            int nr = 0;
            if (A == 0) {
                if (B != 0) roots[nr++] = -C / B;
            } else {
                const W disc = B * B - 4 * A * C;
                if (disc >= 0) {
                    const W qq = -(B + std::copysign(std::sqrt(disc), B)) / 2;
                    roots[nr++] = qq / A;
                    if (qq != 0) roots[nr++] = C / qq;
                }
            }
            for (int m = 0; m < nr; ++m) {
                const W X = roots[m];
                if (X / alpha < x_max && X / alpha > -L) add_y(-(p.A * X * X + p.B * X + p.C0) / p.C2);
            }
        }
    }
    ny = sort_breaks(ybreak, ny);

    W R = 0, T = 0;
    auto integrand = [&](W x, W y, W weight) {
        const W X = alpha * x, Y = alpha * y;
        const W len = std::sqrt(1 + X * X + Y * Y);
        const W proj = mu - s * X;
        if (!(proj > 0)) return;
        const W c = proj / len, hz = 1 / len;
        const W w = weight * std::exp(-x * x - y * y) * proj;
        const W F = stratum::fresnel_dielectric(c, eta);
        const W or_z = 2 * c * hz - mu;
        if (or_z > 0 && F > 0) R += w * F * smith_g2_over_g1(li, dist.Lambda(or_z), form, false);
        const W sin2_t = (1 - c) * (1 + c) / (eta * eta);
        if (sin2_t < 1 && F < 1) {
            const W cos_t = std::sqrt(1 - sin2_t);
            const W ot_z = (c / eta - cos_t) * hz - mu / eta;
            if (ot_z < 0) T += w * (1 - F) * smith_g2_over_g1(li, dist.Lambda(-ot_z), form, true);
        }
    };
    for (int j = 0; j + 1 < ny; ++j) {
        panel(ybreak[j], ybreak[j + 1], [&](W y, W wy) {
            Break xb[capacity];
            int nx = 0;
            xb[nx++] = {-L, false, W(0)};
            xb[nx++] = {x_max, x_max == x_edge, W(0)};
            if (x_max > 0 && x_max < L) xb[nx++] = {W(0), false, W(0)};
            add_fixed(xb, nx, -L, x_max);
            // For eta slightly above 1, F(c) has branch points at c = +-i sqrt(eta^2 - 1), close to the
            // back-facing edge c = 0: grade the panels geometrically towards the edge down to that scale.
            if (x_max == x_edge && k2 > 0 && k2 < W(0.25)) {
                const W scale = std::sqrt(k2) * std::sqrt(1 + alpha * alpha * (x_edge * x_edge + y * y)) / (s * alpha);
                for (W d = scale / 2; d < W(0.5) / alpha && nx < fixed_capacity; d *= 2)
                    if (x_edge - d > -L) xb[nx++] = {x_edge - d, false, d / 2};
            }
            const W Y = alpha * y;
            for (int i = 0; i < nc; ++i) {
                const Conic& q = conics[i];
                const W C = q.C0 + q.C2 * Y * Y;
                W r[2];
                int nr = 0;
                if (q.A == 0) {
                    if (q.B != 0) r[nr++] = -C / q.B;
                } else {
                    const W disc = q.B * q.B - 4 * q.A * C;
                    if (disc >= 0) {
                        const W qq = -(q.B + std::copysign(std::sqrt(disc), q.B)) / 2;
                        if (qq != 0) {
                            r[nr++] = qq / q.A;
                            r[nr++] = C / qq;
                        } else {
                            r[nr++] = 0;
                        }
                    }
                }
                for (int k = 0; k < nr; ++k) {
                    const W x = r[k] / alpha;
                    if (x > -L && x < x_max) xb[nx++] = {x, true, W(0)};
                }
            }
            nx = sort_breaks(xb, nx);
            for (int i = 0; i + 1 < nx; ++i) panel(xb[i], xb[i + 1], [&](W x, W wx) { integrand(x, y, wx * wy); });
        });
    }
    return {R * norm, T * norm};
}

}  // namespace stratum_test
