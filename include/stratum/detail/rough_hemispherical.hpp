// stratum/detail/rough_hemispherical.hpp -- the hemispherical reflectance and transmittance of a rough
// dielectric interface, RoughDielectric::hemispherical_totals (interface.hpp). Not part of the public API,
// except the two types declared first (see there). For the physics (the microfacet model, its shadowing
// forms, why the integral is taken over facet slopes) see docs/physics.md, section 4; this file is the
// numerical method.
//
// What it computes: for incidence from above with cosine mu in [0, 1] and relative index eta = eta_t / eta_i,
// with wi = (s, 0, mu), facet slopes X = alpha x, Y = alpha y (alpha = 1 units x, y) and m = (-X, -Y, 1):
//   R = int int e^{-x^2-y^2} / (pi A(mu)) (mu - s X)_+ F(c) [G2/G1(i)](o_r) [o_r.z > 0] dx dy,
//   T = the same with (1 - F(c)) and the refracted direction o_t, [o_t.z < 0],
// c = (mu - s X)/|m|, A(mu) = mu (1 + Lambda(mu)) the visible projected area (Beckmann::projected_area).
//
// Method. The integrand is analytic except on a few curves, all conics in (X, Y):
//   reflected direction on the horizon    mu X^2 + 2 s X + mu (Y^2 - 1) = 0,
//   refracted direction on the horizon    mu^2 X^2 + 2 mu s X + mu^2 (Y^2 - 1) - (eta^2 - 1) = 0
//                                         (from squaring eta cos_t = c - mu |m|: only where mu |m|^2 + s X <= 0),
//   critical angle (eta < 1, c_c^2 = 1 - eta^2)   (s^2 - c_c^2) X^2 - 2 mu s X + mu^2 - c_c^2 (1 + Y^2) = 0,
// the back-facing edge X = mu / s, and two points where Lambda(o) ~ exp(-k / r^2) is smooth but not analytic:
// the facets sending o_r or o_t along the normal, (X, Y) = (-s / (1 + mu), 0) and (s / (eta - mu), 0).
// The last two conics are tangent (eliminating Y^2 gives a double root) at X = -(c_c^2 - mu^2) / (mu s).
// For each y the x range [-L, x_max] is split at the roots and points, and the y range [0, L] (the
// integrand is even in y) where two roots merge, cross, touch or cross x_max; L = 5.5 truncates the Gaussian
// (e^{-L^2} < 1e-13). Singular panel ends get the map t -> t^2 (3t^2 - 2t^3 at both ends), which turns
// square-root onsets into smooth behaviour; when a square-root point lies just beyond a panel end whose own
// singularity is a mere jump, the map is centred on that point instead; next to a pair of close branch
// points the panels are graded geometrically. Movable breakpoints grade the panels towards the complex
// singularities at X = +-i sqrt(1 + Y^2) (for large alpha) and limit them to 2 Gaussian units; one that
// would leave a sliver next to a breakpoint of higher rank is dropped. Gauss-Legendre with n nodes per
// x panel and 3n/4 per y panel, fewer on panels whose Gaussian mass bound is small (none below 1e-11).
// The shadowing factors use SmithLambdaTable, and the height-correlated transmission factor
// (1 + li) B(1 + li, 1 + lo) its Taylor series in lo (lo < 1/16) or log_gamma_ratio.
//
// Layout, in the order of the method: the tables (SmithLambdaTable, HalfRuleTable) and the special functions
// of the Taylor series (digamma_trigamma, hurwitz_zeta) in namespace detail; then, in detail::rough, the
// geometry (Geometry, Conic), the shadowing factors (OutgoingLambda, ReflectionShadowing,
// TransmissionShadowing), the breakpoints (Breakpoints, add_grid), the panel quadrature (panel_nodes,
// integrate_panel), the y breakpoints (y_breakpoints), one row (x_breakpoints, FacetIntegrand, row_integral);
// last the entry point detail::rough_hemispherical_totals. Allocation-free: every array has a fixed size; the
// two tables are built once, on first use.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>

#include "../fresnel.hpp"
#include "../microfacet.hpp"
#include "../quadrature.hpp"
#include "config.hpp"
#include "math.hpp"

namespace stratum {

namespace detail {

/// Smith's Lambda of a Gaussian surface through phi(a) = a Lambda(a) = (e^{-a^2}/sqrt(pi) - a erfc(a)) / 2,
/// an entire function: a table of Taylor expansions about the centres of 24 intervals of width 1/4 covering
/// [0, 6], built once (first use) from the exact derivatives phi' = -erfc(a)/2, phi^(k+2) = (-1)^k H_k(a)
/// e^{-a^2}/sqrt(pi) (H_k Hermite polynomials). Degree 12 (16 for wider types) leaves a truncation error below
/// 3e-17 (5e-23), checked with mpmath; beyond a = 6, Lambda < 4e-19 and is returned as 0. Used where Lambda
/// is needed many times (the hemispherical_totals integral): a table lookup and a short Horner loop instead of erfc and exp.
template <class W>
class SmithLambdaTable {
public:
    static constexpr int pieces = 24;
    static constexpr int degree = std::numeric_limits<W>::digits > 53 ? 16 : 12;
    static constexpr W a_max = W(6);

    static const SmithLambdaTable& get() {
        static const SmithLambdaTable table;
        return table;
    }

    /// phi(a) = a Lambda(a) for 0 <= a < a_max (callers test a >= a_max, where Lambda is 0, themselves).
    STRATUM_HOST_DEVICE W phi(W a) const noexcept {
        const int j = std::min(static_cast<int>(a * 4), pieces - 1);
        const W t = a - (static_cast<W>(j) + W(0.5)) / 4;
        return polynomial4<W, padded>(coef_[j], t);
    }
    /// Lambda(a) for 0 < a < a_max.
    STRATUM_HOST_DEVICE W lambda(W a) const noexcept { return phi(a) / a; }

private:
    SmithLambdaTable() {
        for (int j = 0; j < pieces; ++j) {
            const W a = (static_cast<W>(j) + W(0.5)) / 4;
            const W g = std::exp(-a * a) / sqrt_pi_v<W>;
            const W ec = std::erfc(a);
            coef_[j][0] = (g - a * ec) / 2;
            coef_[j][1] = -ec / 2;
            W h_prev = 0, h = 1, factorial = 1;  // H_{m-1}, H_m with m = k - 2
            for (int k = 2; k <= degree; ++k) {
                const int m = k - 2;
                if (m > 0) {
                    const W next = 2 * a * h - 2 * static_cast<W>(m - 1) * h_prev;
                    h_prev = h;
                    h = next;
                }
                factorial *= static_cast<W>(k);
                coef_[j][k] = (k % 2 != 0 ? -h : h) * g / factorial;
            }
        }
    }
    static constexpr int padded = (degree + 4) / 4 * 4;  // degree + 1 coefficients, zero-padded
    W coef_[pieces][padded] = {};
};

/// Gauss-Legendre rules on [0, 1] for n = 1..max_n, computed once (first use) into fixed arrays.
template <class W>
class HalfRuleTable {
public:
    static constexpr int max_n = 32;
    static const HalfRuleTable& get() {
        static const HalfRuleTable table;
        return table;
    }
    STRATUM_HOST_DEVICE const W* nodes(int n) const noexcept { return nodes_[n]; }
    STRATUM_HOST_DEVICE const W* weights(int n) const noexcept { return weights_[n]; }

private:
    HalfRuleTable() {
        for (int n = 1; n <= max_n; ++n) {
            const Quadrature<W> q = gauss_legendre_half<W>(n);
            for (int i = 0; i < n; ++i) {
                nodes_[n][i] = q.nodes[static_cast<std::size_t>(i)];
                weights_[n][i] = q.weights[static_cast<std::size_t>(i)];
            }
        }
    }
    W nodes_[max_n + 1][max_n] = {};
    W weights_[max_n + 1][max_n] = {};
};

/// Digamma psi(x) and trigamma psi'(x) for x >= 1: recurrence to x >= 10, then the asymptotic series.
template <class W>
STRATUM_HOST_DEVICE void digamma_trigamma(W x, W& psi, W& psi1) noexcept {
    W a = 0, b = 0;
    while (x < W(10)) {
        a -= 1 / x;
        b += 1 / (x * x);
        x += 1;
    }
    const W r = 1 / x, r2 = r * r;
    psi = a + std::log(x) - r / 2 - r2 * (W(1) / 12 - r2 * (W(1) / 120 - r2 * (W(1) / 252 - r2 * (W(1) / 240))));
    psi1 = b + r + r2 / 2 + r * r2 * (W(1) / 6 - r2 * (W(1) / 30 - r2 * (W(1) / 42 - r2 * (W(1) / 30))));
}

/// Hurwitz zeta(k, x) = sum_{j >= 0} (x + j)^{-k} for k = 2..K (written to out[k]), x >= 1: ten terms, then
/// the Euler-Maclaurin tail at a = x + 10, a^{1-k}/(k-1) + a^{-k}/2 + sum_{m=1..4} B_2m/(2m)! (k)_{2m-1}
/// a^{-k-2m+1} (relative error < 1e-19 for k <= 20).
template <class W>
STRATUM_HOST_DEVICE void hurwitz_zeta(W x, int K, W* out) noexcept {
    for (int k = 2; k <= K; ++k) out[k] = 0;
    for (int j = 0; j < 10; ++j) {
        const W inv = 1 / (x + static_cast<W>(j));
        W p = inv;
        for (int k = 2; k <= K; ++k) {
            p *= inv;
            out[k] += p;
        }
    }
    const W a = x + 10, r = 1 / a, r2 = r * r;
    W ak = r;  // a^{-k}
    for (int k = 2; k <= K; ++k) {
        ak *= r;
        const W kk = static_cast<W>(k);
        const W t1 = kk * r / 12;
        const W t2 = -kk * (kk + 1) * (kk + 2) * r * r2 / 720;
        const W t3 = kk * (kk + 1) * (kk + 2) * (kk + 3) * (kk + 4) * r * r2 * r2 / 30240;
        const W t4 = -kk * (kk + 1) * (kk + 2) * (kk + 3) * (kk + 4) * (kk + 5) * (kk + 6) * r * r2 * r2 * r2 / 1209600;
        out[k] += ak * (a / (kk - 1) + W(0.5) + t1 + t2 + t3 + t4);
    }
}

namespace rough {

// ---------------------------------------------------------------------------------------------------------
// Geometry: the conics and the constants of one incidence.

/// Real roots of A X^2 + B X + C = 0, written to out; returns their number (0, 1 or 2). The cancellation-free
/// form q = -(B + sign(B) sqrt(B^2 - 4AC)) / 2, roots q / A and C / q; a linear equation when A = 0; the double
/// root 0 (B = C = 0) once.
template <class W>
int quadratic_roots(W A, W B, W C, W out[2]) noexcept {
    if (A == 0) {
        if (B == 0) return 0;
        out[0] = -C / B;
        return 1;
    }
    const W disc = B * B - 4 * A * C;
    if (!(disc >= 0)) return 0;
    const W q = -(B + std::copysign(std::sqrt(disc), B)) / 2;
    if (q == 0) {
        out[0] = 0;
        return 1;
    }
    out[0] = q / A;
    out[1] = C / q;
    return 2;
}

/// The conic A X^2 + B X + C0 + C2 Y^2 = 0 in the slopes (X, Y).
template <class W>
struct Conic {
    W A, B, C0, C2;

    /// Y^2 on the conic at X (C2 != 0).
    W y2_at(W X) const noexcept { return -(A * X * X + B * X + C0) / C2; }
    /// The X of its points at height Y^2 (a quadratic in X), written to out; returns their number.
    int roots(W Y2, W out[2]) const noexcept { return quadratic_roots(A, B, C0 + C2 * Y2, out); }
};

/// The X where conics p and q (p.C2 != 0) meet: eliminating Y^2 leaves (q - r p)(X) = 0, r = q.C2 / p.C2.
template <class W>
int intersections(const Conic<W>& p, const Conic<W>& q, W out[2]) noexcept {
    const W r = q.C2 / p.C2;
    const W A = q.A - r * p.A, B = q.B - r * p.B, C = q.C0 - r * p.C0;
    return quadratic_roots(A, B, C, out);
}

/// The constants of one incidence: wi = (s, 0, mu), relative index eta, RMS slope alpha (x = X / alpha), the
/// truncation L of the Gaussian, the back-facing edge x_edge = mu / (alpha s) and the conics of the header
/// comment: 0 reflected horizon, 1 refracted horizon, 2 critical angle (eta < 1 only).
template <class W>
struct Geometry {
    static constexpr W L = W(5.5);  // e^{-L^2} < 1e-13
    W alpha, mu, eta, s, x_edge, x_max, k2, inv_eta;
    bool near_one;  // 0 < |eta^2 - 1| < 1/4: F has branch points close to the back-facing edge
    Conic<W> conics[3];
    int n_conics;

    Geometry(W alpha_value, W mu_value, W eta_value) noexcept
        : alpha(alpha_value), mu(mu_value), eta(eta_value), s(std::sqrt((1 - mu) * (1 + mu))),
          x_edge(s > 0 ? mu / (alpha * s) : std::numeric_limits<W>::infinity()), x_max(std::fmin(x_edge, L)),
          k2((eta - 1) * (eta + 1)), inv_eta(1 / eta), near_one(k2 != 0 && std::fabs(k2) < W(0.25)),
          conics{{mu, 2 * s, -mu, mu}, {mu * mu, 2 * mu * s, -mu * mu - k2, mu * mu}, {}}, n_conics(2) {
        if (eta < 1) {
            const W cc2 = -k2;
            conics[n_conics++] = {s * s - cc2, -2 * mu * s, mu * mu - cc2, -cc2};
        }
    }

    /// X / alpha inside the integration range (-L, x_max).
    bool in_x(W X) const noexcept { return X / alpha < x_max && X / alpha > -L; }
    /// False for a root of conic 1 with c - mu |m| < 0 (mu (X^2 + Y^2) + s X > 0): an artefact of the squaring.
    bool genuine(int conic, W X, W Y2) const noexcept {
        if (conic != 1) return true;
        const W a = mu * (X * X + Y2), b = s * X;
        return a + b <= W(1e-7) * (a + std::fabs(b));
    }
};

// ---------------------------------------------------------------------------------------------------------
// Shadowing factors G2/G1(i) as functions of the outgoing cosine o in (0, 1] (on its own side).

/// Smith's Lambda of the outgoing direction through SmithLambdaTable, a = o / (alpha sqrt(1 - o^2)); 0 (and
/// no a) where a >= a_max.
template <class W>
class OutgoingLambda {
public:
    OutgoingLambda(const SmithLambdaTable<W>& table, W alpha) noexcept
        : table_(&table), alpha_(alpha),
          a_cut2_(SmithLambdaTable<W>::a_max * SmithLambdaTable<W>::a_max * alpha * alpha) {}

    /// Sets a and returns true where a < a_max; false where Lambda(o) = 0.
    bool slope(W o, W& a) const noexcept {
        const W r2 = (1 - o) * (1 + o);
        if (o * o >= a_cut2_ * r2) return false;  // a = o / (alpha sqrt(1 - o^2)) >= a_max
        a = o / (alpha_ * std::sqrt(r2));
        return true;
    }
    W phi(W a) const noexcept { return table_->phi(a); }
    W operator()(W o) const noexcept {
        W a;
        return slope(o, a) ? table_->lambda(a) : W(0);
    }

private:
    const SmithLambdaTable<W>* table_;
    W alpha_, a_cut2_;
};

/// Reflection: G2/G1(i) = 1 (masking_only), 1 / (1 + lo) = a / (a + phi(a)) (separable) or
/// (1 + li) / (1 + li + lo) = (1 + li) a / ((1 + li) a + phi(a)) (height-correlated).
template <class W>
class ReflectionShadowing {
public:
    ReflectionShadowing(Shadowing form, W li, const OutgoingLambda<W>& lambda) noexcept
        : form_(form), one_li_(1 + li), li_inf_(!(li < std::numeric_limits<W>::infinity())), lambda_(lambda) {}

    W operator()(W o) const noexcept {
        if (form_ == Shadowing::masking_only) return W(1);
        W a;
        if (!lambda_.slope(o, a)) return W(1);  // lo = 0
        const W ph = lambda_.phi(a);
        if (form_ == Shadowing::separable) return a / (a + ph);
        return li_inf_ ? W(1) : one_li_ * a / (one_li_ * a + ph);
    }

private:
    Shadowing form_;
    W one_li_;
    bool li_inf_;  // mu = 0
    OutgoingLambda<W> lambda_;
};

/// Transmission: G2/G1(i) = 1 (masking_only), 1 / (1 + lo) (separable) or, height-correlated, the factor
/// beta(lo) = (1 + li) B(1 + li, 1 + lo); beta(0) = 1. Its logarithm is f(lo) - f(0), f(lo) = lnGamma(1 + lo)
/// - lnGamma(2 + li + lo), whose Taylor coefficients are c_1 = psi(1) - psi(2 + li), c_k = (-1)^k [zeta(k, 1)
/// - zeta(k, 2 + li)] / k (Hurwitz zeta); beta's own series follows by the exponential recurrence
/// b_n = (1/n) sum_k k c_k b_{n-k}. Both have radius 1 (the pole of Gamma(1 + lo) at lo = -1): 16 terms for
/// lo < 1/16 leave < 1e-19; above, log_gamma_ratio (for li >= 1000, where the series is not built, always).
template <class W>
class TransmissionShadowing {
public:
    TransmissionShadowing(Shadowing form, W li, const OutgoingLambda<W>& lambda) noexcept
        : form_(form), li_(li), one_li_(1 + li), li_inf_(!(li < std::numeric_limits<W>::infinity())),
          li_big_(!(li < W(1000))), lambda_(lambda) {
        if (!li_big_) build_series();
    }

    W operator()(W o) const noexcept {
        if (form_ == Shadowing::masking_only) return W(1);
        const W lo = lambda_(o);
        if (form_ == Shadowing::separable) return 1 / (1 + lo);
        // li = inf: (1 + li)^{-lo} -> 0 for every lo > 0 (o = 1 exactly has measure zero).
        if (li_inf_ || !(lo < W(1e15))) return W(0);
        if (lo == 0) return W(1);
        if (li_big_) return std::exp(log_gamma(1 + lo) + log_gamma_ratio(2 + li_, lo));
        if (lo < series_max) return polynomial4<W, padded>(coef_, lo);
        return std::exp(log0_ + log_gamma_ratio(1 + lo, one_li_));
    }

private:
    static constexpr int terms = 16;
    static constexpr int padded = (terms + 4) / 4 * 4;
    static constexpr W series_max = W(0.0625);

    // log0_ = -f(0) + ln(1 + li) and coef_ = b_0..b_terms, from the c_k of the class comment.
    void build_series() noexcept {
        log0_ = std::log1p(li_) + log_gamma(one_li_);
        W c[terms + 1] = {};
        W psi, psi1;
        digamma_trigamma(2 + li_, psi, psi1);
        c[1] = W(-0.5772156649015328606065120900824024L) - psi;  // psi(1) - psi(2 + li)
        W zeta_1[terms + 1], zeta_b[terms + 1];
        hurwitz_zeta(W(1), terms, zeta_1);
        hurwitz_zeta(2 + li_, terms, zeta_b);
        for (int k = 2; k <= terms; ++k) {
            const W diff = zeta_1[k] - zeta_b[k];
            c[k] = (k % 2 == 0 ? diff : -diff) / static_cast<W>(k);
        }
        coef_[0] = 1;
        for (int m = 1; m <= terms; ++m) {
            W acc = 0;
            for (int k = 1; k <= m; ++k) acc += static_cast<W>(k) * c[k] * coef_[m - k];
            coef_[m] = acc / static_cast<W>(m);
        }
    }

    Shadowing form_;
    W li_, one_li_;
    bool li_inf_, li_big_;  // mu = 0; li >= 1000
    OutgoingLambda<W> lambda_;
    W log0_ = 0, coef_[padded] = {};  // zero-padded for polynomial4
};

// ---------------------------------------------------------------------------------------------------------
// Breakpoints of the panels, in x (one row) or in y.

/// One breakpoint. rank: 0 = fixed (never dropped), 1 = grid, 2 = grading towards the edge for eta ~ 1.
/// singular: the integrand (or the inner integral) is not analytic there; branch: it has a branch point
/// there (not a mere jump), felt by the neighbouring panels; strong: a square-root branch point.
template <class W>
struct Break {
    W at;
    bool singular;
    int rank;
    bool branch;
    bool strong;
};

/// A fixed-capacity list of breakpoints (no allocation), sorted and cleaned in place.
template <class W>
class Breakpoints {
public:
    static constexpr int capacity = 96;

    int size() const noexcept { return count_; }
    const Break<W>& operator[](int i) const noexcept { return b_[i]; }

    /// Appends (callers keep count below capacity).
    void add(const Break<W>& b) noexcept { b_[count_++] = b; }
    void add_fixed(W at, bool singular = false) noexcept { add({at, singular, 0, false, false}); }
    void add_movable(W at, int rank) noexcept { add({at, false, rank, false, false}); }
    void add_singular(W at, bool branch, bool strong) noexcept { add({at, true, 0, branch, strong}); }

    /// Stable sort, then breakpoints within 64 ulp merged into the first (the union of their flags; rank 0
    /// when either is fixed or the result singular).
    void sort_and_merge() noexcept {
        sort();
        int out = 0;
        for (int i = 0; i < count_; ++i) {
            const W tol = 64 * std::numeric_limits<W>::epsilon() * std::fmax(W(1), std::fabs(b_[i].at));
            if (out > 0 && b_[i].at - b_[out - 1].at <= tol) {
                Break<W>& m = b_[out - 1];
                m.singular = m.singular || b_[i].singular;
                m.branch = m.branch || b_[i].branch;
                m.strong = m.strong || b_[i].strong;
                m.rank = m.singular || m.rank == 0 || b_[i].rank == 0 ? 0 : std::max(m.rank, b_[i].rank);
            } else {
                b_[out++] = b_[i];
            }
        }
        count_ = out;
    }

    /// A movable breakpoint closer to a neighbour of higher rank than a quarter of its distance to the
    /// other neighbour would leave a sliver panel next to a long one: drop it (up to three passes).
    void drop_slivers() noexcept {
        auto rank_of = [](const Break<W>& q) { return q.singular || q.rank == 0 ? 1000 : q.rank; };
        for (int pass = 0; pass < 3; ++pass) {
            int kept = 0;
            for (int i = 0; i < count_; ++i) {
                if (rank_of(b_[i]) < 1000 && kept > 0 && i + 1 < count_) {
                    const W dl = b_[i].at - b_[kept - 1].at, dr = b_[i + 1].at - b_[i].at;
                    if ((dl < dr / 4 && rank_of(b_[kept - 1]) > b_[i].rank) ||
                        (dr < dl / 4 && rank_of(b_[i + 1]) > b_[i].rank))
                        continue;
                }
                b_[kept++] = b_[i];
            }
            if (kept == count_) break;
            count_ = kept;
        }
    }

    /// Geometric grading (ratio 4) away from a pair of close branch points, so that no panel sees a branch
    /// point just beyond its end; pairs closer than 1e-11 of the panel act as one point.
    void grade_pairs() noexcept {
        Break<W> extra[32];
        int ne = 0;
        auto grade = [&](W from, W delta, W d, W sign) {
            if (delta < d / 4 && delta > W(1e-11) * d)
                for (W g = 2 * delta; g < d / 2 && ne < 32; g *= 4) extra[ne++] = {from + sign * g, false, 0, false, false};
        };
        for (int i = 0; i + 1 < count_; ++i) {
            if (!(b_[i].singular && b_[i + 1].singular && b_[i].branch && b_[i + 1].branch)) continue;
            const W delta = b_[i + 1].at - b_[i].at;
            if (i > 0) grade(b_[i].at, delta, b_[i].at - b_[i - 1].at, W(-1));
            if (i + 2 < count_) grade(b_[i + 1].at, delta, b_[i + 2].at - b_[i + 1].at, W(1));
        }
        if (ne == 0) return;
        for (int k = 0; k < ne && count_ < capacity; ++k) b_[count_++] = extra[k];
        sort();
    }

private:
    // Insertion sort, stable: of coinciding breakpoints the first added is kept by sort_and_merge.
    void sort() noexcept {
        for (int i = 1; i < count_; ++i)
            for (int j = i; j > 0 && b_[j].at < b_[j - 1].at; --j) std::swap(b_[j], b_[j - 1]);
    }

    Break<W> b_[capacity];  // b_[0..count_) in use; left uninitialized (2 kB, once per row)
    int count_ = 0;
};

/// Grid in (lo, hi): symmetric about 0, first at min(R / (2 alpha), 1) (R / alpha: distance of the complex
/// singularities), then spacing doubling up to 2 (the Gaussian's scale). At most half the capacity.
template <class W>
void add_grid(Breakpoints<W>& b, W lo, W hi, W R, const Geometry<W>& g) noexcept {
    const W L = Geometry<W>::L;
    W p = std::fmin(R / (2 * g.alpha), W(1));
    while (p < L && b.size() + 2 <= Breakpoints<W>::capacity / 2) {
        if (p > lo && p < hi) b.add_movable(p, 1);
        if (-p > lo && -p < hi) b.add_movable(-p, 1);
        p += std::fmin(p, W(2));
    }
}

// ---------------------------------------------------------------------------------------------------------
// Gauss-Legendre on one panel.

/// Nodes for a panel [lo, hi] from its Gaussian mass bound (length times the largest e^{-x^2}): the base count
/// for mass >= 1, proportionally fewer down to 4 as the mass falls towards 1e-11, none below.
template <class W>
int panel_nodes(W lo, W hi, int base) noexcept {
    const W mass_floor = W(1e-11), log_floor = std::log(mass_floor);
    const W m0 = lo > 0 ? lo : (hi < 0 ? -hi : W(0));
    const W mass = (hi - lo) * std::exp(-m0 * m0);
    if (!(mass > mass_floor)) return 0;
    const W frac = std::fmin(W(1), 1 - std::log(mass) / log_floor);
    const int k = static_cast<int>(std::ceil(static_cast<W>(base) * frac));
    return std::max(4, k);
}

/// The u in [0, 1] with g(u) = 3u^2 - 2u^3 = target (clamped), by Newton from the square-root asymptotes.
template <class W>
W smoothstep_inverse(W target) noexcept {
    if (target <= 0) return W(0);
    if (target >= 1) return W(1);
    W u = target < W(0.5) ? std::sqrt(target / 3) : 1 - std::sqrt((1 - target) / 3);
    for (int it = 0; it < 6; ++it) {
        const W g = u * u * (3 - 2 * u) - target, dg = 6 * u * (1 - u);
        if (!(dg > 0)) break;
        u -= g / dg;
    }
    return u;
}

/// Calls body(x, weight) for the nodes of panel i of the sorted breakpoints b, with `base` nodes at most
/// (panel_nodes). A singular end gets the map x = c + D u^2 (both ends: x = c_lo + D g(u), g(u) = 3u^2 - 2u^3),
/// centred on the end itself or, when the end is a mere jump and a strong (square-root) point lies beyond it
/// within a quarter of the panel, on that point: the map then starts at the u where x reaches the end.
template <class W, class Body>
void integrate_panel(const Breakpoints<W>& b, int i, int base, const HalfRuleTable<W>& rules, Body&& body) noexcept {
    const Break<W>& lo = b[i];
    const Break<W>& hi = b[i + 1];
    const W d = hi.at - lo.at;
    if (!(d > 0)) return;
    const int m = panel_nodes(lo.at, hi.at, base);
    if (m == 0) return;
    const W* ts = rules.nodes(m);
    const W* ws = rules.weights(m);
    W c_lo = lo.at, c_hi = hi.at;  // centres of the maps
    if (lo.singular && !lo.strong && i > 0 && b[i - 1].strong && lo.at - b[i - 1].at < d / 4) c_lo = b[i - 1].at;
    if (hi.singular && !hi.strong && i + 2 < b.size() && b[i + 2].strong && b[i + 2].at - hi.at < d / 4)
        c_hi = b[i + 2].at;
    const W D = c_hi - c_lo;
    if (lo.singular && hi.singular) {
        // x = c_lo + D g(u), u in [ua, ub] (x(ua) = lo, x(ub) = hi).
        const W ua = c_lo == lo.at ? W(0) : smoothstep_inverse((lo.at - c_lo) / D);
        const W ub = c_hi == hi.at ? W(1) : smoothstep_inverse((hi.at - c_lo) / D);
        const W du = ub - ua;
        for (int k = 0; k < m; ++k) {
            const W u = ua + du * ts[k];
            body(c_lo + D * u * u * (3 - 2 * u), ws[k] * du * 6 * D * u * (1 - u));
        }
    } else if (lo.singular) {
        const W ua = c_lo == lo.at ? W(0) : std::sqrt((lo.at - c_lo) / D);  // x = c_lo + D u^2
        const W du = 1 - ua;
        for (int k = 0; k < m; ++k) {
            const W u = ua + du * ts[k];
            body(c_lo + D * u * u, ws[k] * du * 2 * D * u);
        }
    } else if (hi.singular) {
        const W ub = c_hi == hi.at ? W(0) : std::sqrt((c_hi - hi.at) / D);  // x = c_hi - D u^2
        const W du = 1 - ub;
        for (int k = 0; k < m; ++k) {
            const W u = ub + du * ts[k];
            body(c_hi - D * u * u, ws[k] * du * 2 * D * u);
        }
    } else {
        for (int k = 0; k < m; ++k) body(lo.at + d * ts[k], ws[k] * d);
    }
}

// ---------------------------------------------------------------------------------------------------------
// The y breakpoints: where roots merge, cross x_max, cross each other or touch.

/// Adds the y of a Y^2 > 0 inside [0, L) as a strong singular breakpoint (keeping 32 places for grading).
template <class W>
void add_y_event(Breakpoints<W>& ys, W Y2, const Geometry<W>& g) noexcept {
    if (Y2 > 0 && ys.size() < Breakpoints<W>::capacity - 32) {
        const W y = std::sqrt(Y2) / g.alpha;
        if (y < Geometry<W>::L) ys.add_singular(y, true, true);
    }
}

/// Where a conic's two roots merge (its vertex, X = -B / 2A) and where a root crosses the back-facing edge.
template <class W>
void add_vertex_and_edge_events(Breakpoints<W>& ys, const Geometry<W>& g) noexcept {
    for (int i = 0; i < g.n_conics; ++i) {
        const Conic<W>& q = g.conics[i];
        if (q.C2 == 0) continue;
        if (q.A != 0) {
            const W X = -q.B / (2 * q.A), Y2 = (q.B * q.B / (4 * q.A) - q.C0) / q.C2;
            if (g.in_x(X) && g.genuine(i, X, Y2)) add_y_event(ys, Y2, g);
        }
        if (g.x_edge < Geometry<W>::L) {
            const W X = g.alpha * g.x_edge, Y2 = q.y2_at(X);
            if (g.genuine(i, X, Y2)) add_y_event(ys, Y2, g);
        }
    }
}

/// Where two conics cross (intersections), and where the refracted horizon and the critical-angle conic are
/// tangent (eliminating Y^2 gives a double root), at X = -(c_c^2 - mu^2) / (mu s) in closed form.
template <class W>
void add_crossing_events(Breakpoints<W>& ys, const Geometry<W>& g) noexcept {
    for (int i = 0; i < g.n_conics; ++i) {
        for (int k = i + 1; k < g.n_conics; ++k) {
            if (i == 1 && k == 2) continue;  // tangent: added below
            const Conic<W>& p = g.conics[i];
            if (p.C2 == 0) continue;
            W roots[2];
            const int nr = intersections(p, g.conics[k], roots);
            for (int m = 0; m < nr; ++m) {
                const W X = roots[m], Y2 = p.y2_at(X);
                if (g.in_x(X) && g.genuine(i, X, Y2) && g.genuine(k, X, Y2)) add_y_event(ys, Y2, g);
            }
        }
    }
    if (g.eta < 1 && g.mu > 0 && g.s > 0) {
        const W X = -(-g.k2 - g.mu * g.mu) / (g.mu * g.s);
        if (g.in_x(X)) add_y_event(ys, g.conics[1].y2_at(X), g);
    }
}

/// The y panels: [0, L] with the grid (R = 1: the complex singularities at Y = 0) and the events above,
/// sorted, merged, cleared of slivers and graded.
template <class W>
Breakpoints<W> y_breakpoints(const Geometry<W>& g) noexcept {
    Breakpoints<W> ys;
    ys.add_fixed(W(0));
    ys.add_fixed(Geometry<W>::L);
    add_grid(ys, W(0), Geometry<W>::L, W(1), g);
    add_vertex_and_edge_events(ys, g);
    add_crossing_events(ys, g);
    ys.sort_and_merge();
    ys.drop_slivers();
    ys.grade_pairs();
    return ys;
}

// ---------------------------------------------------------------------------------------------------------
// One row: the x integral at fixed y.

/// eta ~ 1: F(c) has branch points at c = +-i sqrt(eta^2 - 1), close to the back-facing edge c = 0: grade
/// geometrically (ratio 2, rank 2) towards the edge down to that scale.
template <class W>
void add_edge_grading(Breakpoints<W>& xb, const Geometry<W>& g, W Y2) noexcept {
    const W scale = std::sqrt(std::fabs(g.k2)) * std::sqrt(1 + g.alpha * g.alpha * g.x_edge * g.x_edge + Y2) / (g.s * g.alpha);
    for (W d = scale / 2; d < W(0.5) / g.alpha && xb.size() < Breakpoints<W>::capacity / 2; d *= 2)
        if (g.x_edge - d > -Geometry<W>::L) xb.add_movable(g.x_edge - d, 2);
}

/// The conics' roots at height Y^2. The critical angle is a square-root branch point of F; the refracted
/// horizon one of the height-correlated factor ~ a^{1 + li}; the reflected horizon only a jump.
template <class W>
void add_conic_roots(Breakpoints<W>& xb, const Geometry<W>& g, Shadowing form, W Y2) noexcept {
    for (int i = 0; i < g.n_conics; ++i) {
        W r[2];
        const int nr = g.conics[i].roots(Y2, r);
        const bool branch = i == 2 || (i == 1 && form == Shadowing::height_correlated);
        for (int k = 0; k < nr; ++k) {
            const W x = r[k] / g.alpha;
            if (x > -Geometry<W>::L && x < g.x_max && g.genuine(i, r[k], Y2)) xb.add_singular(x, branch, i == 2);
        }
    }
}

/// The x panels of the row at height Y^2: [-L, x_max] (x_max singular when it is the back-facing edge) with
/// the grid (R = sqrt(1 + Y^2)), the edge grading for eta ~ 1, the conics' roots and, unless masking_only, the
/// x of the two points where Lambda(o) is smooth but not analytic (o_r or o_t along the normal: X = -s / (1 + mu)
/// and, where eta mu > 1, X = s / (eta - mu)).
template <class W>
Breakpoints<W> x_breakpoints(const Geometry<W>& g, Shadowing form, W Y2) noexcept {
    const W L = Geometry<W>::L;
    Breakpoints<W> xb;
    xb.add_fixed(-L);
    xb.add_fixed(g.x_max, g.x_max == g.x_edge);
    add_grid(xb, -L, g.x_max, std::sqrt(1 + Y2), g);
    if (g.x_max == g.x_edge && g.near_one) add_edge_grading(xb, g, Y2);
    add_conic_roots(xb, g, form, Y2);
    if (form != Shadowing::masking_only) {
        const W xr = -g.s / ((1 + g.mu) * g.alpha);
        if (xr > -L && xr < g.x_max) xb.add_singular(xr, true, true);
        if (g.eta * g.mu > 1) {
            const W xt = g.s / ((g.eta - g.mu) * g.alpha);
            if (xt > -L && xt < g.x_max) xb.add_singular(xt, true, true);
        }
    }
    xb.sort_and_merge();
    xb.drop_slivers();
    xb.grade_pairs();
    return xb;
}

/// The integrand at the facet (x, y) (Y2 = (alpha y)^2) with quadrature weight wx, without the Gaussian in y:
/// adds wx e^{-x^2} (mu - s X) F(c) [G2/G1(i)](o_r) to r_sum where o_r.z > 0 and the same with (1 - F(c)) and
/// o_t to t_sum where the refracted direction exists and o_t.z < 0. c = (mu - s X) / |m|.
template <class W>
struct FacetIntegrand {
    const Geometry<W>& g;
    ReflectionShadowing<W> reflected;
    TransmissionShadowing<W> transmitted;

    void operator()(W x, W wx, W Y2, W& r_sum, W& t_sum) const noexcept {
        const W X = g.alpha * x;
        const W proj = g.mu - g.s * X;
        if (!(proj > 0)) return;
        const W inv_len = 1 / std::sqrt(1 + X * X + Y2);
        const W c = proj * inv_len;
        const W w = wx * std::exp(-x * x) * proj;
        const W F = fresnel_dielectric(c, g.eta);
        const W or_z = 2 * c * inv_len - g.mu;
        if (or_z > 0 && F > 0) r_sum += w * F * reflected(or_z);
        const W sin2_t = (1 - c) * (1 + c) * g.inv_eta * g.inv_eta;
        if (sin2_t < 1 && F < 1) {
            const W cos_t = std::sqrt(1 - sin2_t);
            const W ot_z = (c * g.inv_eta - cos_t) * inv_len - g.mu * g.inv_eta;
            if (ot_z < 0) t_sum += w * (1 - F) * transmitted(-ot_z);
        }
    }
};

/// The inner integrals over x of the row at y (n_x nodes per panel at most): {reflected, transmitted}.
template <class W>
HemisphericalTotals<W> row_integral(const FacetIntegrand<W>& facet, Shadowing form, const HalfRuleTable<W>& rules,
                                    int n_x, W y) noexcept {
    const W Y = facet.g.alpha * y, Y2 = Y * Y;
    const Breakpoints<W> xb = x_breakpoints(facet.g, form, Y2);
    W r_sum = 0, t_sum = 0;
    for (int i = 0; i + 1 < xb.size(); ++i)
        integrate_panel(xb, i, n_x, rules, [&](W x, W wx) { facet(x, wx, Y2, r_sum, t_sum); });
    return {r_sum, t_sum};
}

}  // namespace rough

/// Hemispherical reflectance and transmittance of a rough dielectric of RMS slope sigma for incidence from
/// above with cosine mu in [0, 1], relative index eta = eta_t / eta_i, n Gauss-Legendre nodes per x panel
/// (2 <= n <= 32): the integral of this header's comment, as the sum over y panels of the Gaussian-weighted
/// rows. The factor 2 of the normalization is the half range y in [0, L] (the integrand is even in y).
template <class W>
HemisphericalTotals<W> rough_hemispherical_totals(W sigma, W mu, W eta, Shadowing form, int n) {
    const Beckmann<W> dist(sigma);
    const SmithLambdaTable<W>& lambda_table = SmithLambdaTable<W>::get();
    const HalfRuleTable<W>& rules = HalfRuleTable<W>::get();
    const rough::Geometry<W> g(dist.alpha(), mu, eta);
    const W li = dist.Lambda(mu);
    const rough::OutgoingLambda<W> lambda_o(lambda_table, g.alpha);
    const rough::FacetIntegrand<W> facet{g, {form, li, lambda_o}, {form, li, lambda_o}};
    const int n_x = n, n_y = (3 * n + 3) / 4;

    const rough::Breakpoints<W> ys = rough::y_breakpoints(g);
    W R = 0, T = 0;
    for (int j = 0; j + 1 < ys.size(); ++j) {
        rough::integrate_panel(ys, j, n_y, rules, [&](W y, W wy) {
            const HemisphericalTotals<W> row = rough::row_integral(facet, form, rules, n_x, y);
            const W gy = wy * std::exp(-y * y);
            R += gy * row.reflectance;
            T += gy * row.transmittance;
        });
    }
    const W norm = 2 / (pi_v<W> * dist.projected_area(mu));
    return {R * norm, T * norm};
}

}  // namespace detail
}  // namespace stratum
