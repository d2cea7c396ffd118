// stratum/quadrature.hpp -- Gauss-Legendre rules on [-1, 1] and half-range rules on [0, 1].
//
// The n-point Gauss-Legendre rule integrates f over [-1, 1] as sum_i w_i f(x_i), exactly for every
// polynomial of degree <= 2n - 1. The nodes are the roots of the Legendre polynomial P_n,
//     x_k = cos(theta_k),   w_k = 2 / ((1 - x_k^2) P_n'(x_k)^2) = 2 / (dP_n(cos theta)/dtheta)^2.
//
// Accuracy. Every value is computed from the unrounded angle theta_k (or psi = pi/2 - alpha near the
// middle), in long double, and rounded once at the end:
//   * the weight is a well-conditioned function of theta (its relative error is the relative error of
//     theta), whereas 1 - x^2 at the rounded node x costs thousands of ulp for n >= 128;
//   * the half-range ordinates (1 - x)/2 = sin^2(theta/2) and (1 + x)/2 keep full relative accuracy,
//     the smallest one (~1.45 / (n + 1/2)^2) included;
//   * nodes near x = 0 keep relative accuracy (from psi, or from cos of the converged theta).
// Before the final rounding the error is below 0.1 ulp of double (Newton, n <= 200) and 0.04 ulp
// (asymptotic, n > 200), measured against __float128 references for every n in 1..1000 and for
// n = 2000, 5000, 10000 (tests/data/gen_quadrature_reference.cpp, report mode). So float and double
// results are within 1 ulp of the correctly rounded value, and equal to it for > 99% of the values;
// long double results are at least as accurate as the correctly rounded double. This needs a long
// double wider than double (x86 80-bit or IEEE quad); where long double is double (MSVC, Apple arm64)
// the same code runs, a few ulp less accurate.
//
// Method (O(n) overall for large n):
//   * n <= detail::gauss_legendre_newton_max_n (200): Newton's method in theta on the three-term
//     recurrence, written in s = 1 - x = 2 sin^2(theta/2) so that nothing cancels near x = 1, started
//     from the asymptotic formula below; one or two recurrence passes per node suffice (the weight
//     at the root follows from the pass by Legendre's equation). O(n^2).
//   * n > 200: the iteration-free asymptotic expansions of Bogaert (2014), "Iteration-free computation
//     of Gauss-Legendre quadrature nodes and weights", SIAM J. Sci. Comput. 36(3), A1008-A1026:
//         v = 1/(n + 1/2),  alpha_k = j_{0,k} v  (j_{0,k}: k-th zero of the Bessel function J_0),
//         theta_k = alpha + v^2 F1(alpha) + v^4 F2(alpha) + v^6 F3(alpha) + O(v^8),
//         w_k = 2 / (J_1(j_{0,k})^2 (alpha / sin alpha) (1/v^2 + W1 + W2 v^2 + W3 v^4)) (1 + O(v^8)),
//     with F_i, W_i closed-form functions of alpha and u = cot(alpha) (written out below). O(1) per node.
//   The crossover is set by accuracy, not cost: the expansion is 3-9x cheaper than Newton at every n,
//   but its O(v^8) truncation error, largest near x = 0, is 2.3 ulp of double at n = 100, 0.3 at 140,
//   0.11 at 160 and below 0.04 from n = 200 on (measured).
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

#include "detail/math.hpp"
#include "detail/validate.hpp"

namespace stratum {

/// A quadrature rule: integral f ~ sum_i weights[i] f(nodes[i]); nodes ascending.
template <class Real = double>
struct Quadrature {
    std::vector<Real> nodes;
    std::vector<Real> weights;
    std::size_t size() const noexcept { return nodes.size(); }
};

namespace detail {

/// One Gauss-Legendre node of the non-negative half, x = cos(theta) >= 0, in working precision:
/// the node x, the half-range ordinates lo = (1 - x)/2 and hi = (1 + x)/2, and the full-range weight.
struct GaussLegendreNode {
    long double x, lo, hi, weight;
};

/// Largest n handled by Newton's method; above it the asymptotic expansion is used (measured crossover).
inline constexpr int gauss_legendre_newton_max_n = 200;

/// The k-th positive zero of J_0, j = beta + delta with beta = pi (k - 1/4) (delta is needed apart to
/// form pi/2 - j v without cancellation). Tabulated for k <= 20 (mpmath.besseljzero(0, k), 30 digits);
/// else McMahon's
/// expansion (DLMF 10.21.19) in r = 1/beta, whose r^11 coefficient was checked with mpmath. For k > 20,
/// delta < 2e-3: computing it in double leaves a relative error below 1e-20 in j.
struct BesselZero {
    long double j;
    double delta;
};
inline BesselZero bessel_j0_zero(int k) noexcept {
    static constexpr long double zeros[20] = {
        2.40482555769577276862163187933L, 5.52007811028631064959660411281L,
        8.65372791291101221695419871266L, 11.7915344390142816137430449119L,
        14.9309177084877859477625939974L, 18.0710639679109225431478829756L,
        21.2116366298792589590783933505L, 24.3524715307493027370579447632L,
        27.4934791320402547958772882346L, 30.6346064684319751175495789269L,
        33.7758202135735686842385463467L, 36.9170983536640439797694930633L,
        40.058425764628239294799307374L,  43.1997917131767303575240727287L,
        46.3411883716618140186857888791L, 49.4826098973978171736027615332L,
        52.6240518411149960292512853804L, 55.7655107550199793116834927735L,
        58.9069839260809421328344066346L, 62.0484691902271698828525002647L};
    const long double beta = pi_v<long double> * (static_cast<long double>(k) - 0.25L);
    if (k <= 20) return {zeros[k - 1], static_cast<double>(zeros[k - 1] - beta)};
    const double r = 1 / static_cast<double>(beta), r2 = r * r;
    const double delta =
        r * (1.0 / 8 +
             r2 * (-31.0 / 384 +
                   r2 * (3779.0 / 15360 +
                         r2 * (-6277237.0 / 3440640 + r2 * (2092163573.0 / 82575360 + r2 * -567.644412135183381)))));
    return {beta + delta, delta};
}

/// J_1(j)^2 at the k-th zero j of J_0. Tabulated for k <= 20 (mpmath.besselj(1, j)**2); else from the Wronskian at a
/// zero of J_0, J_1(j)^2 = 4 / (pi^2 j^2 M_0(j)^2), with the modulus expansion (DLMF 10.18.17)
///     M_0(x)^2 ~ (2 / (pi x)) (1 + sum_{m>=1} c_m / x^(2m)),  c_m = (-1)^m ((2m-1)!!)^3 / ((2m)!! 4^m);
/// eight terms reach long double precision for j > 62, where the sum is below 3e-5 (double suffices).
inline long double bessel_j1_squared_at_j0_zero(int k, long double j) noexcept {
    static constexpr long double values[20] = {
        0.26951412394191692613902199291L,   0.115780138582203695807812836182L,
        0.0736863511364082151406476811985L, 0.0540375731981162820417749182759L,
        0.0426614290172430912655106063497L, 0.0352421034909961013587473033648L,
        0.0300210701030546726750888157688L, 0.0261473914953080885904584675399L,
        0.0231591218246913922652676382178L, 0.0207838291222678576039808057296L,
        0.0188504506693176678161056800213L, 0.0172461575696650082995240053542L,
        0.0158935181059235978027065594287L, 0.0147376260964721895895742982591L,
        0.0137384651453871179182880484135L, 0.0128661817376151328791406637229L,
        0.0120980515486267975471075438497L, 0.0114164712244916085168627222987L,
        0.0108075927911802040115547286831L, 0.0102603729262807628110423992789L};
    if (k <= 20) return values[k - 1];
    const double y = 1 / static_cast<double>(j * j);
    const double tail =
        y * (-0.125 +
             y * (0.2109375 +
                  y * (-1.0986328125 +
                       y * (11.775970458984375 +
                            y * (-214.617061614990234375 +
                                 y * (5951.152271032333374023438 +
                                      y * (-233476.4560617506504058838 + y * 12312234.98763138195499778)))))));
    return 2 / (pi_v<long double> * j * (1 + static_cast<long double>(tail)));
}

/// sin(a) and cos(a) in long double for |a| <= pi/4, by their Taylor series to degree 21 and 20
/// (truncation below 1e-21) in nested form, with z = a^2:
///     sin a = a (1 - z/(2*3) (1 - z/(4*5) (1 - ...))),   cos a = 1 - z/(1*2) (1 - z/(3*4) (1 - ...)).
/// A few multiplications instead of two calls of glibc's sinl and cosl, which are slow in long double.
inline void sincos_pi4(long double a, long double& sin_a, long double& cos_a) noexcept {
    static constexpr long double sin_factor[10] = {1.0L / 6,   1.0L / 20,  1.0L / 42,  1.0L / 72,  1.0L / 110,
                                                   1.0L / 156, 1.0L / 210, 1.0L / 272, 1.0L / 342, 1.0L / 420};
    static constexpr long double cos_factor[10] = {1.0L / 2,   1.0L / 12,  1.0L / 30,  1.0L / 56,  1.0L / 90,
                                                   1.0L / 132, 1.0L / 182, 1.0L / 240, 1.0L / 306, 1.0L / 380};
    const long double z = a * a;
    long double s = 1, c = 1;
    for (int m = 9; m >= 0; --m) {
        s = 1 - z * sin_factor[m] * s;
        c = 1 - z * cos_factor[m] * c;
    }
    sin_a = a * s;
    cos_a = c;
}

/// sin(h) and cos(h) - 1 for |h| < 1e-2 by their Taylor series (relative error below 1e-20).
template <class T>
void small_sincos(T h, T& sin_h, T& cos_h_minus_1) noexcept {
    const T h2 = h * h;
    sin_h = h * (1 - h2 * (T(1) / 6) * (1 - h2 * (T(1) / 20)));
    cos_h_minus_1 = -h2 * T(0.5) * (1 - h2 * (T(1) / 12) * (1 - h2 * (T(1) / 30)));
}

/// Bogaert's node correction c = theta - alpha = v^2 F1 + v^4 F2 + v^6 F3, with u = cot(alpha), ia = 1/alpha:
///   F1 = (u - 1/alpha) / 8,
///   F2 = (6 (1 + u^2)/alpha + 25/alpha^3 - u (31 u^2 + 33)) / 384,
///   F3 = u (2595 + 6350 u^2 + 3779 u^4) / 15360
///        + (1 + u^2) (-(31 u^2 + 11) / (1024 alpha) + u / (512 alpha^2) - 25 / (3072 alpha^3))
///        - 1073 / (5120 alpha^5).
/// For small alpha the terms cancel (F_i ~ alpha): evaluate in long double there, in double elsewhere.
template <class T>
T bogaert_theta_correction(T u, T ia, T v2) noexcept {
    const T u2 = u * u, ia2 = ia * ia, ia3 = ia * ia2;
    const T f1 = (u - ia) * T(0.125);
    const T f2 = (6 * (1 + u2) * ia + 25 * ia3 - u * (31 * u2 + 33)) * (T(1) / 384);
    const T f3 = u * (2595 + u2 * (6350 + 3779 * u2)) * (T(1) / 15360) +
                 (1 + u2) * (-(31 * u2 + 11) * (T(1) / 1024) * ia + u * (T(1) / 512) * ia2 - (T(25) / 3072) * ia3) -
                 (T(1073) / 5120) * ia3 * ia2;
    return v2 * (f1 + v2 * (f2 + v2 * f3));
}

/// Bogaert's weight series beyond its leading term: W1 + v^2 W2 + v^4 W3, where
///   W1 = (1 + (u alpha - 1)/alpha^2) / 8,
///   W2 = (-27 - 84 u^2 - 56 u^4 + (6 u alpha - 3 + 6 u^2)/alpha^2 + (81 - 31 u alpha)/alpha^4) / 384,
///   W3 = sum_{i=0..6} d_i / alpha^i, d_i polynomials in u (below).
template <class T>
T bogaert_weight_series_tail(T u, T a, T ia, T v2) noexcept {
    const T u2 = u * u, ia2 = ia * ia, ua = u * a;
    const T w1 = (1 + (ua - 1) * ia2) * T(0.125);
    const T w2 =
        ((-27 - u2 * (84 + 56 * u2)) + (6 * ua - 3 + 6 * u2) * ia2 + (81 - 31 * ua) * ia2 * ia2) * (T(1) / 384);
    const T d0 = T(153) / 1024 + u2 * (T(295) / 256 + u2 * (T(187) / 96 + u2 * (T(151) / 160)));
    const T d1 = -u * (T(65) / 1024 + u2 * (T(119) / 768 + u2 * (T(35) / 384)));
    const T d2 = T(5) / 512 + u2 * (T(15) / 512 + u2 * (T(7) / 384));
    const T d3 = u * (u2 * (T(1) / 512) - T(13) / 1536);
    const T d4 = T(53) / 3072 - u2 * (T(7) / 384);
    const T d5 = (T(3749) / 15360) * u;
    const T d6 = -T(1125) / 1024;
    const T w3 = d0 + ia * (d1 + ia * (d2 + ia * (d3 + ia * (d4 + ia * (d5 + ia * d6)))));
    return w1 + v2 * (w2 + v2 * w3);
}

/// Bogaert's iteration-free formulas (see the top of this file) for node k = 1..(n+1)/2, theta ascending.
/// One sincos per node: of alpha/2 when alpha <= pi/4, else of psi = pi/2 - alpha, formed without
/// cancellation as pi ((n + 1)/2 - k) v - delta v; theta = alpha + c (|c| < 1e-3 alpha) then follows by
/// the addition theorems. If theta_out is given, it receives theta (the Newton path's initial guess).
inline GaussLegendreNode gauss_legendre_node_asymptotic(int n, int k, long double* theta_out = nullptr) noexcept {
    using W = long double;
    const W n_half = static_cast<W>(n) + 0.5L, v = 1 / n_half;
    const BesselZero zero = bessel_j0_zero(k);
    const W a = zero.j * v;
    GaussLegendreNode node;
    if (a <= pi_v<long double> / 4) {  // x near 1: carry sin(theta/2); corrections in long double (they cancel)
        W s2, c2;
        sincos_pi4(a / 2, s2, c2);
        const W sin_a = 2 * s2 * c2, cos_a = (c2 - s2) * (c2 + s2);
        const W u = cos_a / sin_a, ia = 1 / a, v2 = v * v;
        const W c = bogaert_theta_correction(u, ia, v2);
        const W series = n_half * n_half + bogaert_weight_series_tail(u, a, ia, v2);
        node.weight = 2 * sin_a / (bessel_j1_squared_at_j0_zero(k, zero.j) * a * series);
        W sin_h, cos_h_m1;  // sin(theta/2) = sin(alpha/2) cos(c/2) + cos(alpha/2) sin(c/2)
        small_sincos(c / 2, sin_h, cos_h_m1);
        const W sh = s2 + (s2 * cos_h_m1 + c2 * sin_h);
        node.lo = sh * sh;
        node.hi = 1 - node.lo;
        node.x = 1 - 2 * node.lo;
        if (theta_out) *theta_out = a + c;
    } else {  // away from x = 1: carry psi; corrections in double (no cancellation, scaled by v^2)
        const double vd = static_cast<double>(v);
        const W psi =
            pi_v<long double> / 2 * (static_cast<W>(n) + 1 - 2 * static_cast<W>(k)) * v - static_cast<W>(zero.delta * vd);
        W sin_a, cos_a;
        sincos_pi4(psi, cos_a, sin_a);
        const double ad = static_cast<double>(a), u = static_cast<double>(cos_a / sin_a), ia = 1 / ad;
        const double c = bogaert_theta_correction(u, ia, vd * vd);
        const W series = n_half * n_half + bogaert_weight_series_tail(u, ad, ia, vd * vd);
        node.weight = 2 * sin_a / (bessel_j1_squared_at_j0_zero(k, zero.j) * a * series);
        double sin_c, cos_c_m1;  // x = cos(alpha + c) = cos(alpha) cos(c) - sin(alpha) sin(c)
        small_sincos(c, sin_c, cos_c_m1);
        node.x = cos_a + (cos_a * cos_c_m1 - sin_a * sin_c);
        node.lo = (1 - node.x) / 2;
        node.hi = (1 + node.x) / 2;
        if (theta_out) *theta_out = a + c;
    }
    return node;
}

/// P_n(cos theta) for two angles at once (two independent chains hide the x87 latency), by the
/// three-term recurrence rewritten in s = 1 - x = 2 sin^2(theta/2) and d_l = P_l - P_{l-1}:
///     d_{l+1} = (l d_l - (2l + 1) s P_l) / (l + 1),   P_{l+1} = P_l + d_{l+1},
/// which does not cancel near x = 1. Returns P_n and q = P_{n-1} - x P_n = s P_n - d_n, so that
/// dP_n/dtheta = -n q / sin(theta).
struct LegendreThetaValue {
    long double p, q;
};
inline void legendre_theta_recurrence(int n, const long double (&s)[2], LegendreThetaValue (&out)[2]) noexcept {
    long double p0 = 1 - s[0], d0 = -s[0], p1 = 1 - s[1], d1 = -s[1];  // P_1, d_1 = P_1 - P_0
    for (int l = 1; l < n; ++l) {
        const long double fl = static_cast<long double>(l), a = 2 * fl + 1;
        const long double inv = 1 / (fl + 1);  // off the dependency chains
        d0 = (fl * d0 - a * s[0] * p0) * inv;
        d1 = (fl * d1 - a * s[1] * p1) * inv;
        p0 += d0;
        p1 += d1;
    }
    out[0] = {p0, s[0] * p0 - d0};
    out[1] = {p1, s[1] * p1 - d1};
}

/// Newton's method in theta on P_n(cos theta) = 0 for nodes k and k2 together (k2 = k for one node),
/// from the asymptotic formula's theta. A pass at theta0 gives the step h = -P_n / (dP_n/dtheta) and
/// w0 = 2 / (dP_n/dtheta)^2; the weight at the root theta0 + h follows from Legendre's equation
/// P'' + cot(theta) P' + n(n+1) P = 0:
///     log w(theta0 + h) = log w0 + 2 cot(theta0) h - (n(n+1) + 1/sin^2 theta0) h^2 + O(h^3).
/// The pass in which both relative steps are below 1e-10 is the last (the error left is ~1e-20
/// relative); where the initial guess is that good (larger n), one pass suffices.
inline void gauss_legendre_nodes_newton(int n, int k, int k2, GaussLegendreNode (&out)[2]) noexcept {
    using W = long double;
    W theta[2] = {0, 0}, weight[2] = {0, 0};
    (void)gauss_legendre_node_asymptotic(n, k, &theta[0]);
    (void)gauss_legendre_node_asymptotic(n, k2, &theta[1]);
    const W fn = static_cast<W>(n);
    for (int iter = 0; iter < 32; ++iter) {
        W sh[2], ch[2], s[2];
        LegendreThetaValue r[2];
        for (int m = 0; m < 2; ++m) {
            sincos_pi4(theta[m] / 2, sh[m], ch[m]);
            s[m] = 2 * sh[m] * sh[m];
        }
        legendre_theta_recurrence(n, s, r);
        bool converged = true;
        for (int m = 0; m < 2; ++m) {
            const W st = 2 * sh[m] * ch[m], cot = (ch[m] - sh[m]) * (ch[m] + sh[m]) / st;
            const W h = r[m].p * st / (fn * r[m].q);
            const W w0 = 2 * st * st / (fn * fn * r[m].q * r[m].q);
            const W t = 2 * cot * h - (fn * (fn + 1) + 1 / (st * st)) * h * h;
            weight[m] = w0 * (1 + t * (1 + t / 2));
            theta[m] += h;
            converged = converged && std::fabs(h) <= 1e-10L * theta[m];
        }
        if (converged) break;
    }
    for (int m = 0; m < 2; ++m) {
        W sh, ch;
        sincos_pi4(theta[m] / 2, sh, ch);
        out[m].weight = weight[m];
        out[m].lo = sh * sh;  // (1 - cos theta)/2 = sin^2(theta/2)
        out[m].hi = 1 - out[m].lo;
        out[m].x = theta[m] <= pi_v<long double> / 4 ? 1 - 2 * out[m].lo : std::cos(theta[m]);  // relative accuracy near 0
    }
}

/// Node k alone by Newton's method (see gauss_legendre_nodes_newton).
inline GaussLegendreNode gauss_legendre_node_newton(int n, int k) noexcept {
    GaussLegendreNode out[2];
    gauss_legendre_nodes_newton(n, k, k, out);
    return out[0];
}

/// Calls emit(k, node) for every node k = 1..(n+1)/2 of the n-point rule (theta ascending), by Newton's
/// method for n <= gauss_legendre_newton_max_n (two nodes per pass), else by the asymptotic formulas.
template <class Emit>
void gauss_legendre_for_each_node(int n, Emit emit) {
    const int half = (n + 1) / 2;
    if (n > gauss_legendre_newton_max_n) {
        for (int k = 1; k <= half; ++k) emit(k, gauss_legendre_node_asymptotic(n, k));
        return;
    }
    for (int k = 1; k <= half; k += 2) {
        GaussLegendreNode pair[2];
        gauss_legendre_nodes_newton(n, k, k + 1 <= half ? k + 1 : k, pair);
        emit(k, pair[0]);
        if (k + 1 <= half) emit(k + 1, pair[1]);
    }
}

}  // namespace detail

/// n-point Gauss-Legendre rule on [-1, 1]: exact for polynomials of degree <= 2n - 1; weights sum to 2.
/// Nodes ascending and exactly antisymmetric (x_{n-1-i} = -x_i, the middle node of odd n is 0);
/// weights symmetric. Each value is within 1 ulp of the correctly rounded one for float and double.
/// Cost O(n) for n > detail::gauss_legendre_newton_max_n. Throws std::invalid_argument for n < 1.
template <class Real = double>
Quadrature<Real> gauss_legendre(int n) {
    detail::require_count("n", n, 1);
    const auto size = static_cast<std::size_t>(n);
    Quadrature<Real> q;
    q.nodes.resize(size);
    q.weights.resize(size);
    detail::gauss_legendre_for_each_node(n, [&q, n](int k, const detail::GaussLegendreNode& node) {
        const auto hi = static_cast<std::size_t>(n - k), lo = static_cast<std::size_t>(k - 1);
        q.nodes[hi] = static_cast<Real>(node.x);
        q.nodes[lo] = -q.nodes[hi];
        q.weights[hi] = q.weights[lo] = static_cast<Real>(node.weight);
    });
    if (n % 2 == 1) q.nodes[size / 2] = Real(0);
    return q;
}

/// n-point half-range ("double Gauss") rule on [0, 1]: the n-point Gauss-Legendre rule mapped by
/// mu = (1 + x)/2, weights w/2; exact for polynomials of degree <= 2n - 1 on [0, 1]; weights sum to 1.
/// The ordinates of the discrete-ordinate method for one hemisphere. Every ordinate keeps full relative
/// accuracy, the smallest (~1.4 / (n + 1/2)^2) included: it is sin^2(theta/2) of the unrounded root.
/// Nodes ascending, mu_{n-1-i} = 1 - mu_i up to rounding. Throws std::invalid_argument for n < 1.
template <class Real = double>
Quadrature<Real> gauss_legendre_half(int n) {
    detail::require_count("n", n, 1);
    const auto size = static_cast<std::size_t>(n);
    Quadrature<Real> q;
    q.nodes.resize(size);
    q.weights.resize(size);
    detail::gauss_legendre_for_each_node(n, [&q, n](int k, const detail::GaussLegendreNode& node) {
        const auto hi = static_cast<std::size_t>(n - k), lo = static_cast<std::size_t>(k - 1);
        q.nodes[hi] = static_cast<Real>(node.hi);
        q.nodes[lo] = static_cast<Real>(node.lo);
        q.weights[hi] = q.weights[lo] = static_cast<Real>(node.weight / 2);
    });
    if (n % 2 == 1) q.nodes[size / 2] = Real(0.5);
    return q;
}

}  // namespace stratum
