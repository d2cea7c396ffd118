// stratum/tabulated_bsdf.hpp -- a solved layer as a renderer's BSDF: the subsurface reflection and the transmission
// tabulated once as azimuthal Fourier series on a grid of cosines, evaluated and importance-sampled in a shader's
// time; the top's own reflection kept analytic (RoughDielectric), the specular beams as deltas.
//
// Frame and conventions as RoughDielectric (vec3.hpp, interface.hpp): wi towards the light, wo towards the
// viewer, both pointing away from the surface, z the normal; values per steradian without the cosine; BsdfSample
// as there. docs/physics.md section 9 gives the representation, the interpolation and the sampling.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "interface.hpp"
#include "layer.hpp"
#include "vec3.hpp"

namespace stratum {

namespace detail {

// The table's variable t in [0, 1] and its grid. Mode k of the coefficients behaves like sin^k(theta) near the
// normal and like a power of mu near grazing, square roots in mu; so does a lobe beside a kink, where total
// internal reflection begins at a critical cosine mu_c seen from outside (like sqrt(mu - mu_c) on one side, 0 on
// the other; TabulatedBSDF::kink_cosines). [0, 1] is cut at the kinks into pieces; on piece p, between the cosines
// mu_a and mu_b (0, the kinks, 1) and the parameters t_a and t_b,
//     mu = mu_a + (mu_b - mu_a) sin^2(pi s / 2),   s = (t - t_a) / (t_b - t_a),
// whose slope vanishes at both ends: every such square root is smooth in t on each side. Without kinks one piece,
// mu = sin^2(pi t / 2). Each piece is ruled uniformly: ends[p] and ends[p + 1] are the nodes that bound it
// (ends[0] = 0, ends.back() = n - 1), scale[p] its intervals per unit of t, edge[p] and edge[p + 1] its cosines.
template <class Real>
struct Grid {
    std::vector<Real> t;
    std::vector<int> ends;
    std::vector<Real> scale, edge;
    int n() const noexcept { return static_cast<int>(t.size()); }
    // The piece holding interval [t_j, t_j+1].
    std::size_t piece(int j) const noexcept {
        std::size_t p = 0;
        while (p + 2 < ends.size() && j >= ends[p + 1]) ++p;
        return p;
    }
    // The piece holding the parameter u (the first of two at a cut).
    std::size_t piece_at(Real u) const noexcept {
        std::size_t p = 0;
        while (p + 2 < ends.size() && u > t[static_cast<std::size_t>(ends[p + 1])]) ++p;
        return p;
    }
    // The length in t of piece p.
    Real length_of(std::size_t p) const noexcept {
        return t[static_cast<std::size_t>(ends[p + 1])] - t[static_cast<std::size_t>(ends[p])];
    }
    // mu at t, and dmu/dt, from the same sine. (One piece: the map without kinks, in as few operations as before
    // kinks were cut: eval, pdf and sample call these.)
    struct Point {
        Real mu, jacobian;
    };
    Point at(Real u) const noexcept {
        if (edge.size() == 2) {
            const Real sine = std::sin(pi_v<Real> / 2 * u), cosine = std::cos(pi_v<Real> / 2 * u), mu = sine * sine;
            return {mu > Real(1) ? Real(1) : (mu > Real(0) ? mu : Real(0)), pi_v<Real> * sine * cosine};
        }
        const std::size_t p = piece_at(u);
        const Real length = length_of(p), width = edge[p + 1] - edge[p];
        const Real x = pi_v<Real> / 2 * ((u - t[static_cast<std::size_t>(ends[p])]) / length);
        const Real sine = std::sin(x), cosine = std::cos(x), mu = edge[p] + width * (sine * sine);
        return {mu > Real(1) ? Real(1) : (mu > Real(0) ? mu : Real(0)), width * (pi_v<Real> * sine * cosine) / length};
    }
    Real cosine(Real u) const noexcept { return at(u).mu; }
    // dmu/dt at t (one sine).
    Real jacobian(Real u) const noexcept {
        if (edge.size() == 2) return pi_v<Real> / 2 * std::sin(pi_v<Real> * u);
        const std::size_t p = piece_at(u);
        const Real length = length_of(p), s = (u - t[static_cast<std::size_t>(ends[p])]) / length;
        return (edge[p + 1] - edge[p]) * (pi_v<Real> / 2 * std::sin(pi_v<Real> * s)) / length;
    }
    // t at the cosine mu (clamped to [0, 1]).
    Real parameter(Real mu) const noexcept {
        mu = mu > Real(1) ? Real(1) : (mu > Real(0) ? mu : Real(0));
        if (edge.size() == 2) return Real(2) / pi_v<Real> * std::asin(std::sqrt(mu));
        std::size_t p = 0;
        while (p + 2 < edge.size() && mu > edge[p + 1]) ++p;
        const Real r = (mu - edge[p]) / (edge[p + 1] - edge[p]), r1 = r > Real(1) ? Real(1) : (r > 0 ? r : Real(0));
        return t[static_cast<std::size_t>(ends[p])] + length_of(p) * (Real(2) / pi_v<Real> * std::asin(std::sqrt(r1)));
    }
};

// Cubic Hermite (Catmull-Rom) interpolation on the grid (n >= 4) of the values f_j of a function of t: on
// [t_j, t_j+1], with s = (u - t_j) / h (h the interval's width),
//   p(s) = h00(s) f_j + h01(s) f_j+1 + h10(s) d_j + h11(s) d_j+1,   d_j = (f_j+1 - f_j-1) / 2 (slope times step),
// one-sided at the ends of a piece (d_j = f_j+1 - f_j at its start, f_j+1 - f_j at its end): at t = 0, and on
// both sides of a kink, where a centred slope would carry the other side's behaviour across it. At t = 1 (the
// normal) the end rule follows the parity of the azimuthal mode k, since a_k(-theta) = (-1)^k a_k(theta): an even
// mode has slope 0 there; an odd one vanishes there, and its mirror value -f_n-2 gives d_n-1 = (-f_n-2 - f_n-2) / 2
// = f_n-1 - f_n-2, the one-sided difference.
// The value is linear in the data: sum_a w[a] f[first + a] over four consecutive nodes, with the weights `even`
// for even modes and `odd` for odd ones (they differ only in the last interval: `split`).
template <class Real>
struct SplineWeights {
    int first = 0;
    bool split = false;
    Real even[4] = {0, 0, 0, 0}, odd[4] = {0, 0, 0, 0};
    int interval = 0;  // j: u in [t_j, t_j+1]
    Real s = 0;        // (u - t_j) / (t_j+1 - t_j)
};

// x clamped to [0, 1] (NaN to 0), without the library calls that std::fmin and std::fmax compile to.
template <class Real>
Real clamp_unit(Real x) noexcept {
    return x > Real(1) ? Real(1) : (x > Real(0) ? x : Real(0));
}

template <class Real>
SplineWeights<Real> spline_weights(const Grid<Real>& g, Real u) noexcept {
    u = clamp_unit(u);
    const std::size_t p = g.piece_at(u);
    const int a = g.ends[p], b = g.ends[p + 1], n = g.n();  // (a piece has at least two intervals: table_grid)
    const Real x = (u - g.t[static_cast<std::size_t>(a)]) * g.scale[p];
    const int j = a + std::min(static_cast<int>(x), b - a - 1);
    const Real s = clamp_unit(x - Real(j - a)), s2 = s * s, s3 = s2 * s;
    const Real h00 = 2 * s3 - 3 * s2 + 1, h01 = 3 * s2 - 2 * s3, h10 = s3 - 2 * s2 + s, h11 = s3 - s2;
    SplineWeights<Real> w;
    w.interval = j;
    w.s = s;
    Real* e = w.even;
    if (j == a) {  // d_j = f_j+1 - f_j, d_j+1 = (f_j+2 - f_j) / 2 (nodes j .. j + 2; from j - 1 where j + 3 is past n - 1)
        w.first = std::min(j, n - 4);
        e += j - w.first;
        e[0] = h00 - h10 - h11 / 2;
        e[1] = h01 + h10;
        e[2] = h11 / 2;
    } else if (j + 1 < b) {  // both slopes centred
        w.first = j - 1;
        e[0] = -h10 / 2;
        e[1] = h00 - h11 / 2;
        e[2] = h01 + h10 / 2;
        e[3] = h11 / 2;
    } else if (b < n - 1) {  // the last interval before a kink: d_j+1 = f_j+1 - f_j
        w.first = j - 1;
        e[0] = -h10 / 2;
        e[1] = h00 - h11;
        e[2] = h01 + h10 / 2 + h11;
    } else {  // the last interval: d_n-2 centred, d_n-1 by parity (0 for even modes)
        w.first = n - 4;
        e[1] = -h10 / 2;
        e[2] = h00;
        e[3] = h01 + h10 / 2;
    }
    for (int k = 0; k < 4; ++k) w.odd[k] = w.even[k];
    if (j + 1 == n - 1) {  // odd modes: d_n-1 = f_n-1 - f_n-2
        w.split = true;
        w.odd[2] -= h11;
        w.odd[3] += h11;
    }
    return w;
}

// One interval [t_j, t_j+1] of the spline through f (a function giving the value at a node; `even`: the end rule
// at t = 1), and int_{t_j}^{t_j + s h} p = h (f_j (s - s^3 + s^4/2) + f_j+1 (s^3 - s^4/2) + d_j (s^4/4 - 2s^3/3 + s^2/2)
// + d_j+1 (s^4/4 - s^3/3)), whose derivative in s is h p(s).
template <class Real>
struct HermiteSegment {
    Real h, f0, f1, d0, d1;
    Real value(Real s) const noexcept {
        const Real s2 = s * s, s3 = s2 * s;
        return (2 * s3 - 3 * s2 + 1) * f0 + (3 * s2 - 2 * s3) * f1 + (s3 - 2 * s2 + s) * d0 + (s3 - s2) * d1;
    }
    Real integral(Real s) const noexcept {
        const Real s2 = s * s, s3 = s2 * s, s4 = s3 * s;
        constexpr Real third = Real(1) / 3;  // (a product: a division by 3 is a divide instruction)
        return h * (f0 * (s - s3 + s4 / 2) + f1 * (s3 - s4 / 2) + d0 * (s4 / 4 - 2 * third * s3 + s2 / 2) +
                    d1 * (s4 / 4 - third * s3));
    }
};

template <class Real, class F>
HermiteSegment<Real> hermite_segment(const Grid<Real>& grid, int j, bool even, F f) noexcept {
    const std::size_t p = grid.piece(j);
    const int b = grid.ends[p + 1];
    HermiteSegment<Real> g;
    g.h = Real(1) / grid.scale[p];
    g.f0 = f(j);
    g.f1 = f(j + 1);
    g.d0 = j == grid.ends[p] ? g.f1 - g.f0 : (g.f1 - f(j - 1)) / 2;
    g.d1 = j + 1 < b ? (f(j + 2) - g.f0) / 2 : (b == grid.n() - 1 && even ? Real(0) : g.f1 - g.f0);
    return g;
}

// Where interval j lies against the cuts: its piece, and whether it starts or ends at a cut (not at t = 0 or 1).
struct CutContact {
    std::size_t piece = 0;
    bool starts = false, ends = false;
};
template <class Real>
CutContact cut_contact(const Grid<Real>& grid, int j) noexcept {
    if (grid.ends.size() == 2) return {};  // (no cuts)
    const std::size_t p = grid.piece(j);
    return {p, p > 0 && j == grid.ends[p], p + 2 < grid.ends.size() && j + 1 == grid.ends[p + 1]};
}
// The segment of the marginal m = a_0 dmu/dt (m: its values at the nodes, a0: a_0 there). At a cut dmu/dt
// vanishes, and m starts like a_0 (t_c) J'(t_c) (t - t_c) + O((t - t_c)^2): that slope, times the step, where a
// piece begins or ends at a cut (J' = +-(mu_b - mu_a) pi^2 / (2 l^2) on a piece of length l). The one-sided
// difference there made m start linearly where a lobe that starts like sqrt(mu - mu_c) has m ~ (t - t_c)^2, and the
// sampled density was up to 7.5 times the value's share beside a cut (found by review). Elsewhere hermite_segment's.
template <class Real, class M, class A>
HermiteSegment<Real> marginal_segment(const Grid<Real>& grid, int j, M m, A a0) noexcept {
    HermiteSegment<Real> g = hermite_segment<Real>(grid, j, false, m);
    const CutContact c = cut_contact(grid, j);
    if (!c.starts && !c.ends) return g;
    const Real w = grid.edge[c.piece + 1] - grid.edge[c.piece], l = grid.length_of(c.piece);
    const Real k = w * pi_v<Real> * pi_v<Real> / (2 * l * l) / grid.scale[c.piece];  // J' times the step
    if (c.starts) g.d0 = a0(j) * k;
    if (c.ends) g.d1 = -a0(j + 1) * k;
    return g;
}
// Whether interval j touches a cut (marginal_segment differs from hermite_segment there).
template <class Real>
bool touches_cut(const Grid<Real>& grid, int j) noexcept {
    const CutContact c = cut_contact(grid, j);
    return c.starts || c.ends;
}

// The t in [0, 1] where the segment's integral reaches r (0 <= r <= its integral up to rounding): Newton's method
// kept inside a bracket that bisection shrinks, stopped at a residual of eps^(2/3) `scale` (as
// sample_cosine_series). It starts from the root of the integral of the chord f0 + (f1 - f0) s,
// h (f0 s + (f1 - f0) s^2 / 2) = r, written s = 2 q / (f0 + sqrt(f0^2 + 2 (f1 - f0) q)) with q = r / h (no
// cancellation): exact for a linear segment, and within the cubic terms otherwise.
template <class Real>
Real invert_segment(const HermiteSegment<Real>& seg, Real r, Real scale) noexcept {
    const Real q = r / seg.h, disc = seg.f0 * seg.f0 + 2 * (seg.f1 - seg.f0) * q;
    const Real denom = seg.f0 + std::sqrt(disc > 0 ? disc : Real(0));
    Real lo = 0, hi = 1, x = denom > 0 ? clamp_unit(2 * q / denom) : Real(0.5);
    const Real tolerance = std::cbrt(std::numeric_limits<Real>::epsilon() * std::numeric_limits<Real>::epsilon()) * scale;
    // |p'(s)| <= 3/2 |f0 - f1| + |d0| + |d1| on [0, 1] (p the cubic): bounds the integral's second derivative / h
    const Real slope = Real(1.5) * std::fabs(seg.f0 - seg.f1) + std::fabs(seg.d0) + std::fabs(seg.d1);
    for (int it = 0; it < 60; ++it) {
        const Real res = seg.integral(x) - r;
        if (std::fabs(res) <= tolerance) break;
        if (res > 0) hi = x; else lo = x;
        const Real d = seg.h * seg.value(x);
        const Real next = d > 0 ? x - res / d : Real(-1);
        const Real step = next - x;
        // A Newton step leaves a residual of at most h slope step^2 / 2 (Taylor): taken unevaluated where that is
        // below half the tolerance.
        if (next > lo && next < hi && seg.h * slope * step * step <= tolerance) return next;
        x = (next > lo && next < hi) ? next : (lo + hi) / 2;
        if (hi - lo <= 4 * std::numeric_limits<Real>::epsilon()) break;
    }
    return x;
}

// sum_k c_k cos(k phi) over k < order, from x = cos(phi): cos(k phi) by the recurrence
// cos((k + 2) phi) = 2 cos(2 phi) cos(k phi) - cos((k - 2) phi), run for the even and the odd k side by side. Two
// independent chains of half the length, where Clenshaw's single chain waits on a multiply, an add and a subtract
// per mode (it was a large part of TabulatedBSDF::eval). The forward recurrence's rounding grows like k^2 eps
// near x = +-1 (as Clenshaw's), worst at phi ~ 1e-4 .. 1e-3 (tests/test_tabulated_bsdf.cpp measures it).
template <class Real>
Real cosine_series(const Real* c, int order, Real x) noexcept {
    if (order <= 1) return order == 1 ? c[0] : Real(0);
    const Real y = 2 * (2 * x * x - 1);  // 2 cos(2 phi)
    Real e_prev = y / 2, e = 1;          // cos(-2 phi), cos(0)
    Real o_prev = x, o = x;              // cos(-phi), cos(phi)
    Real even = 0, odd = 0;
    int k = 0;
    for (; k + 1 < order; k += 2) {
        even += c[k] * e;
        odd += c[k + 1] * o;
        const Real e_next = y * e - e_prev, o_next = y * o - o_prev;
        e_prev = e;
        e = e_next;
        o_prev = o;
        o = o_next;
    }
    if (k < order) even += c[k] * e;
    return even + odd;
}

// sin(m pi / 32), m = 0..63 (sample_cosine_series: G at the coarse bracket's points, the even m; cos and sin at the
// centres of its intervals, the odd m), and 1 / k, k = 0..255 (0 at 0).
template <class Real>
struct AzimuthTables {
    std::array<Real, 64> sines{};
    std::array<Real, 256> reciprocals{};
};
template <class Real>
const AzimuthTables<Real>& azimuth_tables() noexcept {
    static const AzimuthTables<Real> tables = [] {
        AzimuthTables<Real> t;
        for (int m = 0; m < 64; ++m) t.sines[static_cast<std::size_t>(m)] = static_cast<Real>(std::sin(pi_v<long double> * m / 32));
        for (int k = 1; k < 256; ++k) t.reciprocals[static_cast<std::size_t>(k)] = Real(1) / Real(k);
        return t;
    }();
    return tables;
}

// A sampled azimuth: phi, its cosine and sine (from the last step, so the caller needs no second sincos).
template <class Real>
struct AzimuthSample {
    Real phi, cos_phi, sin_phi;
};

// cos(a + d) and sin(a + d) from cos a, sin a and |d| <= pi / 32: Taylor to d^8 and d^9 (the first terms left out are
// below 2.3e-17, a tenth of double's spacing at 1), by products with constants (no divisions, no sincos).
template <class Real>
void rotate_small_angle(Real cos_a, Real sin_a, Real d, Real& cos_out, Real& sin_out) noexcept {
    constexpr Real c2 = Real(1) / 2, c4 = Real(1) / 24, c6 = Real(1) / 720, c8 = Real(1) / 40320;
    constexpr Real s3 = Real(1) / 6, s5 = Real(1) / 120, s7 = Real(1) / 5040, s9 = Real(1) / 362880;
    const Real d2 = d * d;
    const Real cd = 1 - d2 * (c2 - d2 * (c4 - d2 * (c6 - d2 * c8)));
    const Real sd = d - d * d2 * (s3 - d2 * (s5 - d2 * (s7 - d2 * s9)));
    cos_out = cos_a * cd - sin_a * sd;
    sin_out = sin_a * cd + cos_a * sd;
}

// Samples phi in [0, pi] with density proportional to g(phi) = sum_k c_k cos(k phi) (c_0 > 0, order <= 256) by
// inverting G(phi) = c_0 phi + sum_{k >= 1} c_k sin(k phi) / k = u c_0 pi. A coarse pass brackets the root between
// two of phi_j = j pi / 16 by bisection over j (G there from a table of sines, no sincos; four evaluations) and
// starts from the secant in the bracket; then Halley's method, phi -= 2 r g / (2 g^2 - r g') with r = G - u c_0 pi
// (cubic convergence: fewer evaluations of G than Newton's method, each one pass over the modes), kept
// inside the bracket, which bisection shrinks, and stopped at a residual of eps^(2/3) c_0 pi (the next step would reach
// rounding; the caller evaluates pdf at the phi returned, so a residual moves the sample, never the density it
// reports). Where the truncated series dips below 0 the CDF is not monotone; bisection keeps
// G(lo) <= target < G(hi), so the bracket still holds a root, and the caller's pdf (the clamped g) tells the truth.
// cos phi and sin phi rotate the coarse bracket's centre (a table) by at most pi / 32 (rotate_small_angle): no sincos.
template <class Real>
AzimuthSample<Real> sample_cosine_series(const Real* c, int order, Real u) noexcept {
    const Real pi = pi_v<Real>, target = u * c[0] * pi;
    const Real tolerance = std::cbrt(std::numeric_limits<Real>::epsilon() * std::numeric_limits<Real>::epsilon()) * c[0] * pi;
    const AzimuthTables<Real>& tables = azimuth_tables<Real>();
    Real b[256], kc[256];  // c_k / k and k c_k
    Real a3 = 0;  // sum k^2 |c_k|, which bounds |g''| (G's third derivative) everywhere
    for (int k = 1; k < order; ++k) {
        b[k] = c[k] * tables.reciprocals[static_cast<std::size_t>(k)];
        kc[k] = Real(k) * c[k];
        a3 += Real(k) * std::fabs(kc[k]);
    }
    int j_lo = 0, j_hi = 16;
    Real g_lo = 0, g_hi = c[0] * pi;
    while (j_hi - j_lo > 1) {
        const int j = (j_lo + j_hi) / 2;
        Real G = c[0] * pi * Real(j) / 16;
        for (int k = 1; k < order; ++k) G += b[k] * tables.sines[static_cast<std::size_t>((2 * k * j) & 63)];
        if (G > target) {
            j_hi = j;
            g_hi = G;
        } else {
            j_lo = j;
            g_lo = G;
        }
    }
    const Real a3_6 = a3 / 6;
    Real lo = pi * Real(j_lo) / 16, hi = pi * Real(j_hi) / 16;
    const Real centre = pi * Real(2 * j_lo + 1) / 32;  // phi stays within pi / 32 of it
    const Real cos_centre = tables.sines[static_cast<std::size_t>((2 * j_lo + 17) & 63)];
    const Real sin_centre = tables.sines[static_cast<std::size_t>(2 * j_lo + 1)];
    Real phi = g_hi > g_lo ? lo + (hi - lo) * ((target - g_lo) / (g_hi - g_lo)) : (lo + hi) / 2;
    phi = phi > lo && phi < hi ? phi : (lo + hi) / 2;
    AzimuthSample<Real> out{};
    for (int it = 0; it < 60; ++it) {
        Real cp, sp;
        rotate_small_angle(cos_centre, sin_centre, phi - centre, cp, sp);
        Real G = c[0] * phi, g = c[0], dg = 0;  // G, g = G' and g'
        Real s_prev = 0, s_k = sp, c_prev = 1, c_k = cp;  // sin(k phi), cos(k phi) by recurrence
        for (int k = 1; k < order; ++k) {
            G += b[k] * s_k;
            g += c[k] * c_k;
            dg -= kc[k] * s_k;
            const Real s_next = 2 * cp * s_k - s_prev, c_next = 2 * cp * c_k - c_prev;
            s_prev = s_k;
            s_k = s_next;
            c_prev = c_k;
            c_k = c_next;
        }
        out = {phi, cp, sp};
        const Real r = G - target;
        if (std::fabs(r) <= tolerance) return out;
        if (r > 0) hi = phi; else lo = phi;
        const Real denominator = 2 * g * g - r * dg;
        const Real next = g > 0 && denominator > 0 ? phi - 2 * r * g / denominator : Real(-1);
        if (next > lo && next < hi) {
            // Taken unevaluated where the residual it leaves is surely below half the tolerance: for Halley's d the
            // quadratic model r + g d + g' d^2 / 2 leaves r (g' d / (2 g))^2 in magnitude (= d^3 g'^2 / (2 (2 g - g'
            // d)) in exact arithmetic; that form cancels where g is near 0 and accepted steps that left almost all
            // of r: found by review), and the rest of G(phi + d) - G(phi) is at most |d|^3 a3 / 6 (Taylor).
            const Real d = next - phi, d2 = d * d, q = dg * d / (2 * g);
            if (std::fabs(d) <= Real(1) / 32 && std::fabs(r) * q * q + std::fabs(d) * d2 * a3_6 <= tolerance / 2) {
                AzimuthSample<Real> taken{next, 0, 0};
                rotate_small_angle(cos_centre, sin_centre, next - centre, taken.cos_phi, taken.sin_phi);
                return taken;
            }
        }
        phi = (next > lo && next < hi) ? next : (lo + hi) / 2;
        if (hi - lo <= 4 * std::numeric_limits<Real>::epsilon() * pi) break;
    }
    rotate_small_angle(cos_centre, sin_centre, phi - centre, out.cos_phi, out.sin_phi);  // (stopped by the bracket's width)
    out.phi = phi;
    return out;
}

// t = (2 / pi) asin(sqrt(mu)): the grid's variable without kinks, which places the kinks' nodes.
template <class Real>
Real cosine_parameter(Real mu) noexcept {
    return Real(2) / pi_v<Real> * std::asin(std::sqrt(clamp_unit(mu)));
}

// The grid of refinement `level` with kinks at the cosines `kinks` (ascending, inside (0, 1)), at the parameters
// cosine_parameter gives them: piece p, of length l_p in t, ruled with max(2, round(8 l_p)) 2^level intervals (9
// nodes at level 0 without kinks). The grid of level + 1 holds these nodes and the midpoints, where the error is
// measured.
template <class Real>
Grid<Real> table_grid(const std::vector<Real>& kinks, int level) {
    Grid<Real> g;
    g.edge.push_back(Real(0));
    g.edge.insert(g.edge.end(), kinks.begin(), kinks.end());
    g.edge.push_back(Real(1));
    g.t.push_back(Real(0));
    g.ends.push_back(0);
    for (std::size_t p = 0; p + 1 < g.edge.size(); ++p) {
        const Real a = cosine_parameter(g.edge[p]), b = p + 2 == g.edge.size() ? Real(1) : cosine_parameter(g.edge[p + 1]);
        const Real length = b - a;
        const int count = std::max(2, static_cast<int>(std::lround(8 * length))) << level;
        for (int i = 1; i <= count; ++i) g.t.push_back(i == count ? b : a + length * (Real(i) / Real(count)));
        g.ends.push_back(g.n() - 1);
        g.scale.push_back(Real(count) / length);
    }
    return g;
}

// The table's rough surface lobe: RoughDielectric's reflection with the facet term F D / 4 exact
// (RoughDielectric::facet_brdf) and the shadowing from the projected area A(mu) = mu (1 + Lambda(mu))
// (Beckmann::projected_area) without erfc: with a = mu / (alpha s), s = sqrt(1 - mu^2),
//   A = mu + alpha s L(a),   L(a) = a Lambda(a) = (e^{-a^2} / sqrt(pi) - a erfc(a)) / 2,
// L universal and smooth (L(0) = 1 / (2 sqrt(pi)), below 1e-17 beyond a = 6), tabulated at 513 points of [0, 6] and
// interpolated by cubic Lagrange polynomials (within 9e-10 of L, measured; the BRDF within 4.4e-9 relative). Then
//   G2 / (mu_i mu_o) = 1 / (A_i mu_o + A_o mu_i - mu_i mu_o)  (height-correlated: 1 / (1 + Lambda_i + Lambda_o)),
//                      1 / (A_i A_o) (separable),  1 / (A_i mu_o) (masking only),
// finite at grazing directions, and the density of sampling a visible normal and reflecting wi in it is
// D(h) / (4 A_i). Two table lookups replace two erfc and two exp (tests/test_tabulated_bsdf.cpp compares with
// RoughDielectric).
template <class Real>
struct SurfaceLobe {
    static constexpr int kIntervals = 512;
    static constexpr Real kLast = 6;  // a beyond which L is 0
    RoughDielectric<Real> interface;
    Real alpha;
    std::vector<Real> l;  // L(j kLast / kIntervals), j = 0..kIntervals

    explicit SurfaceLobe(const RoughDielectric<Real>& r)
        : interface(r), alpha(r.distribution().alpha()), l(static_cast<std::size_t>(kIntervals) + 1) {
        using W = wide_t<Real>;
        for (int j = 0; j <= kIntervals; ++j) {
            const W a = W(kLast) * W(j) / W(kIntervals);
            l[static_cast<std::size_t>(j)] =
                static_cast<Real>(j == 0 ? 1 / (2 * sqrt_pi_v<W>) : a * smith_lambda_gaussian<W>(a));
        }
    }

    // A(mu), mu in [0, 1] (s from mu, as RoughDielectric does: a direction is its cosine, whatever its length).
    Real projected_area(Real mu) const noexcept {
        const Real s = std::sqrt((1 - mu) * (1 + mu));
        const Real x = mu / (alpha * s) * (Real(kIntervals) / kLast);  // a in units of the table's step
        if (!(x < Real(kIntervals))) return mu;                          // (also s = 0)
        const int first = std::min(std::max(static_cast<int>(x) - 1, 0), kIntervals - 3);
        const Real t = x - Real(first);  // the nodes first .. first + 3 at t = 0 .. 3
        const Real t1 = t - 1, t2 = t - 2, t3 = t - 3;
        const Real* f = l.data() + first;
        const Real value = -t1 * t2 * t3 / 6 * f[0] + t * t2 * t3 / 2 * f[1] - t * t1 * t3 / 2 * f[2] + t * t1 * t2 / 6 * f[3];
        return mu + alpha * s * value;
    }

    // brdf(wi, wo) for wi and wo above.
    Real brdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        const wide_t<Real> facet = interface.facet_brdf(wi, wo);
        if (!(facet > 0)) return Real(0);
        const Real mi = clamp_unit(wi.z), mo = clamp_unit(wo.z);
        const Real ai = projected_area(mi), ao = projected_area(mo);
        Real denominator;
        switch (interface.shadowing()) {
            case Shadowing::separable: denominator = ai * ao; break;
            case Shadowing::masking_only: denominator = ai * mo; break;
            case Shadowing::height_correlated:
            default: denominator = ai * mo + ao * mi - mi * mo;
        }
        return saturate_to<Real>(facet / static_cast<wide_t<Real>>(denominator));
    }

    // The density of reflecting wi in a normal sampled from those visible from it (RoughDielectric's reflection
    // without its Fresnel choice): D(h) / (4 A_i), 0 where h faces away from either direction.
    Real pdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        const Vec3<Real> h = normalize(wi + wo);
        if (!(dot(wo, h) > 0) || !(dot(wi, h) > 0)) return Real(0);
        const Real d = interface.distribution().D(h);
        return d > 0 ? saturate_to<Real>(static_cast<wide_t<Real>>(d) / (4 * static_cast<wide_t<Real>>(projected_area(clamp_unit(wi.z)))))
                     : Real(0);
    }
};

// One tabulated lobe on the grid t[0..n-1] x t[0..n-1] (incidence, exit): the Fourier coefficients of f |mu_o| of
// each pair, truncated to the order L the pair needs, for `series` functions (one channel; or, with several
// channels, the luminance and all channels but one, which follows from them): pair p = a n + b holds series s at
// coeffs[offset[p] + s L .. offset[p] + (s + 1) L). Per row a, the running integral over the exit of
// m(t) = a_0(t_a, t) dmu/dt (series 0) along the row's spline: cdf[b n + a] = int_0^{t_b} m dt (so
// cdf[(n - 1) n + a] is the lobe's albedo over 2 pi at mu_a), and a copy of each pair's a_0, mean[b n + a]; both
// are stored by exit node first, so that the four incidence nodes a sampler interpolates lie side by side (the
// search over b touches one or two cache lines per step, not four). The coefficients are stored in float for any Real:
// their rounding (6e-8 relative) lies far below any table's interpolation error (1e-4 at the finest grid,
// docs/accuracy.md), and it halves a double table (pbrt-v3's and layerlab's files store float too); the cdf is
// built from the stored values, so sampling and pdf agree with them exactly. (error() is measured before the
// rounding, which adds at most ~5e-8 of the lobe's scale: measured at the nodes of an isotropic slab.)
template <class Real>
struct FourierTable {
    std::vector<std::uint32_t> offset;
    std::vector<float> coeffs;
    std::vector<Real> cdf;
    std::vector<float> mean;
    int series = 1;
    bool empty() const noexcept { return coeffs.empty(); }
    int order(std::size_t p) const noexcept {
        const std::uint32_t all = offset[p + 1] - offset[p];
        return static_cast<int>(series == 1 ? all : all / static_cast<std::uint32_t>(series));
    }
    const float* pair(std::size_t p, int s = 0) const noexcept {
        return coeffs.data() + offset[p] + static_cast<std::size_t>(s) * static_cast<std::size_t>(order(p));
    }
    float first_coefficient(std::size_t p) const noexcept { return offset[p + 1] > offset[p] ? coeffs[offset[p]] : 0.0f; }
};

}  // namespace detail

/// The whole layer (LayeredSurface::brdf and ::btdf, plus the specular beams they leave out) as a table that a
/// renderer evaluates and samples in constant time, whatever the solver's settings were.
///
/// Representation (docs/physics.md section 9): the subsurface reflection and the transmission as
/// f(wi, wo) |wo.z| = sum_k a_k(mu_i, mu_o) cos(k dphi) (dphi the azimuth between -wi and wo), the a_k tabulated at
/// n x n pairs of cosines mu = sin^2(pi t / 2), t uniform in [0, 1] (cut at the critical cosines of specular faces
/// seen from outside, with the map on each piece: detail::Grid), and interpolated by cubic Hermite (Catmull-Rom)
/// splines in t_i and t_o; each pair keeps the modes it needs. The top's rough reflection r_12 is the
/// RoughDielectric itself; a smooth top's mirror reflection, and between specular faces the unscattered beam and
/// delta-M's forward peak (the layer's direct_* and forward_peak_*), are deltas.
///
/// Accuracy: the grid is refined (n = 9, 17, 33, 65, 129 at most without kinks) until, at the nodes of the next finer grid, the
/// table's f |wi.z| |wo.z| differs from the layer's by at most `tolerance` times the lobe's largest azimuthal mean
/// of f |wi.z| |wo.z|, at every dphi (the bound sums the |a_k| differences); each pair's series is cut where the
/// dropped |a_k| sum to a quarter of that. error() reports the value measured (under a smooth top into a denser
/// medium, of the stored shares f |wi.z| |wo.z| / (1 - F(mu_i)): see Side::entry). Between the grazing node (mu = 0,
/// where the layer is evaluated at a tenth of the next node's cosine) and the next, the table holds what the
/// spline gives, but for the exit's value: f is held at its value at the first node above grazing (Side::first_cosine).
///
/// Sampling: a lobe by the albedos at mu_i (the surface's, the tabulated reflection's and transmission's, the
/// deltas'); for a tabulated lobe, t_o by inverting the exact integral of the spline of a_0 dmu/dt, then dphi by
/// inverting the CDF of the interpolated Fourier series (no rejection). The density is f |wo.z| / albedo up to the
/// ratio of the spline of a_0 dmu/dt to dmu/dt times the spline of a_0 (1 within the table's error); pdf() gives it
/// exactly, wherever the interpolated series is >= 0 (a truncated series that rings below 0 is clamped to 0). (In
/// float, pdf() reads the cosine back from the rounded direction, where t changes like 1 / sqrt(1 - mu) near the
/// normal: for a forward peak (g = 0.999) at wo.z = 1 - 3e-5 the two differ by 0.26%; renderer sweep.) In radiance
/// transport a two-sided table's transmission is the other side's series with the arguments exchanged while the
/// density is this side's: where one truncated series rings below 0 and the other does not, eval is > 0 where pdf is
/// 0, and a path tracer misses that light (measured up to 0.95% of the transmitted energy for g = 0.999 at mu =
/// 0.03, 0.6% for tau = 0; importance transport below 1e-4).
///
/// Sides: built from one layer, the BSDF is one-sided (light from above, wi.z > 0; two_sided() is false, and
/// wi.z < 0 gives 0 and invalid samples). In radiance transport, where wi is the viewer, one exception: a viewer
/// below seeing light from above through the layer gets its value from eval (generalized reciprocity), but pdf is 0
/// and sample() fails there, as the table cannot sample the light's side from the viewer's (found by review): such
/// light reaches the viewer through light sampling alone, and a path tracer misses what arrives there indirectly;
/// build the table two-sided where viewers below matter. Built from two, the second is the layer turned over
/// (solved with its bottom face first and the indices swapped) and answers for light from below: all four
/// combinations of sides, sampled in both transport modes.
/// Evaluation is noexcept, allocation-free and const (thread-safe); degenerate directions (NaN or infinite
/// components, on the horizon) give 0 and invalid samples. Directions are expected to be unit vectors and are not
/// normalized: a finite non-unit vector gives finite values >= 0 that mean nothing in particular.
template <class Real = double>
class TabulatedBSDF {
public:
    /// Tabulates `layer` (solved with LayerOutput::subsurface_reflection and ::transmission for the tabulated
    /// lobes, ::surface_reflection for the top's reflection; lobes that were not requested are 0).
    /// tolerance in [1e-7, 0.5]; throws std::invalid_argument otherwise. A layer solved with
    /// LayerRequest::tabulate_faces builds the same table several times faster (its face tables' nodes are this grid's
    /// cosines: README, speed table; tests/test_tabulated_bsdf.cpp; at the finest grid, 129 nodes, error() may differ
    /// in its third digit: the points between the nodes where it is measured fall between the face tables' too).
    template <class LayerReal>
    TabulatedBSDF(const LayeredSurface<LayerReal>& layer, Real tolerance) : tolerance_(check_tolerance(tolerance)) {
        sides_[0] = tabulate(std::vector<const LayeredSurface<LayerReal>*>{&layer}, {}, tolerance);
    }
    /// Two-sided: `from_above` lit from above, `from_below` the same layer turned over (its faces are checked:
    /// std::invalid_argument where they are not from_above's exchanged and turned over, or a face is a floor).
    template <class LayerReal>
    TabulatedBSDF(const LayeredSurface<LayerReal>& from_above, const LayeredSurface<LayerReal>& from_below,
                  Real tolerance)
        : tolerance_(check_tolerance(tolerance)) {
        require_turned_over(from_above, from_below);
        sides_[0] = tabulate(std::vector<const LayeredSurface<LayerReal>*>{&from_above}, {}, tolerance);
        sides_[1] = tabulate(std::vector<const LayeredSurface<LayerReal>*>{&from_below}, {}, tolerance);
    }
    /// Several channels (RGB, spectral samples) on one grid: one layer per channel, all with the same outer faces
    /// and outputs (solve_spectral makes them), and their luminance weights (> 0; normalized to sum 1; equal when
    /// empty; for linear sRGB, 0.2126, 0.7152, 0.0722). The luminance is tabulated beside all channels but the one
    /// of largest weight, which follows from them; it drives sampling, and eval, pdf and sample without a `values`
    /// argument answer for it. The grid and each pair's order serve every channel within the tolerance.
    template <class LayerReal>
    TabulatedBSDF(const std::vector<LayeredSurface<LayerReal>>& channels, Real tolerance, std::vector<Real> luminance = {})
        : tolerance_(check_tolerance(tolerance)) {
        const auto layers = channel_layers(channels);
        sides_[0] = tabulate(layers, luminance_weights(std::move(luminance), layers.size()), tolerance);
    }
    /// Several channels, two-sided (the second vector: the same channels' layers turned over).
    template <class LayerReal>
    TabulatedBSDF(const std::vector<LayeredSurface<LayerReal>>& from_above,
                  const std::vector<LayeredSurface<LayerReal>>& from_below, Real tolerance, std::vector<Real> luminance = {})
        : tolerance_(check_tolerance(tolerance)) {
        const auto above = channel_layers(from_above), below = channel_layers(from_below);
        if (above.size() != below.size())
            detail::fail_invalid_argument("stratum: TabulatedBSDF: as many channels from below as from above");
        for (std::size_t c = 0; c < above.size(); ++c) require_turned_over(*above[c], *below[c]);
        const std::vector<Real> w = luminance_weights(std::move(luminance), above.size());
        sides_[0] = tabulate(above, w, tolerance);
        sides_[1] = tabulate(below, w, tolerance);
    }

    /// The number of channels (1 for a table built from one layer).
    int channels() const noexcept { return sides_[0]->channels; }

    bool two_sided() const noexcept { return sides_[1].has_value(); }

    /// Raw access, for export (pbrt_bsdf.hpp) and inspection. The longest series a pair keeps:
    static constexpr int max_order = 256;
    /// The tabulated cosines of a side (0 = mu_0 < ... < mu_n-1 = 1); empty for the lower side of a one-sided table.
    std::vector<Real> grid_cosines(bool from_below = false) const {
        std::vector<Real> mu;
        if (const Side* s = from_below ? (sides_[1] ? &*sides_[1] : nullptr) : &*sides_[0])
            for (Real t : s->grid.t) mu.push_back(s->grid.cosine(t));
        return mu;
    }
    /// The interpolated series of f |wo.z| = sum_k a_k cos(k dphi) of the subsurface reflection (transmitted =
    /// false) or the transmission, for light arriving from above (from_below = false) at cosine mu_i and leaving at
    /// |cosine| mu_o (both in [0, 1]): writes a_0 .. a_{L-1} to out (room for max_order) and returns L (0 where
    /// nothing is tabulated). At the grid's nodes these are the stored coefficients (times 1 - F(mu_i) under a smooth top
    /// into a denser medium, Side::entry). `channel`: one of channels(),
    /// or -1 for the luminance (the one channel of a table built from one layer).
    int coefficients(bool from_below, bool transmitted, Real mu_i, Real mu_o, Real* out, int channel = -1) const noexcept {
        const Side* s = from_below ? (sides_[1] ? &*sides_[1] : nullptr) : &*sides_[0];
        if (!s || channel >= s->channels) return 0;
        const detail::FourierTable<Real>& tab = transmitted ? s->transmission : s->reflection;
        if (tab.empty()) return 0;
        const detail::SplineWeights<Real> si = s->weights(detail::clamp_unit(mu_i)), so = s->weights(detail::clamp_unit(mu_o));
        const int order = channel < 0 ? s->interpolate(tab, si, so, out) : s->channel_series(tab, si, so, channel, out);
        const Real in = s->entering(detail::clamp_unit(mu_i));
        for (int k = 0; k < order; ++k) out[k] *= in;
        return order;
    }
    /// The top's rough interface whose reflection the table keeps analytic (none for a smooth or index-matched top,
    /// or when the surface reflection was not requested).
    const std::optional<RoughDielectric<Real>>& surface(bool from_below = false) const noexcept {
        static const std::optional<RoughDielectric<Real>> none;
        const Side* s = from_below ? (sides_[1] ? &*sides_[1] : nullptr) : &*sides_[0];
        return s ? s->surface : none;
    }
    /// Indices outside the top and below the bottom of the side lit from above.
    Real eta_above() const noexcept { return sides_[0]->eta_above; }
    Real eta_below() const noexcept { return sides_[0]->eta_below; }
    Real tolerance() const noexcept { return tolerance_; }
    /// The largest error measured at construction, in the units of `tolerance` (the worse side).
    Real error() const noexcept { return std::fmax(sides_[0]->error, sides_[1] ? sides_[1]->error : Real(0)); }
    /// The largest difference, as fractions of the incident flux, between the table's albedo (albedo(): what a white
    /// furnace measures of sample()) and the layer's own fluxes (reflectance(mu).total() with the surface lobe where
    /// it was requested, transmittance(mu); the luminance's for several channels), at the grid's nodes but mu = 0
    /// and midway between them, for the lobes the layer was solved for. error() measures the table against the
    /// layer's BRDF and BTDF; this measures the layer's BRDF and BTDF against its fluxes, which the discretization
    /// does not make agree everywhere: light leaving through a nearly specular rough face near the normal (README,
    /// known limitations), strongly backward-scattering media; and splines across a kink of the layer's fluxes,
    /// which the grid's cuts at the critical cosines now prevent (kink_cosines; at the nodes alone this missed it,
    /// found by review). R and T are compared apart: the table creates or loses up to their sum.
    Real energy_error() const noexcept {
        return std::fmax(sides_[0]->energy_error, sides_[1] ? sides_[1]->energy_error : Real(0));
    }
    /// Grid nodes per cosine of the side lit from above.
    int grid_size() const noexcept { return sides_[0]->n(); }
    /// Bytes held by the tables (both sides).
    std::size_t memory_bytes() const noexcept {
        return sides_[0]->bytes() + (sides_[1] ? sides_[1]->bytes() : std::size_t(0));
    }

    /// f(wi, wo) (per steradian, no cosine): the layer's brdf or btdf, whichever the hemispheres call for. Deltas
    /// are not evaluated (0), as in RoughDielectric. TransportMode::radiance exchanges the arguments; on a one-sided
    /// table, whose light from below is not tabulated, a transmission seen from above is then the importance value
    /// times (eta_above / eta_below)^2 (generalized reciprocity, the factor of TransportMode).
    Real eval(Vec3<Real> wi, Vec3<Real> wo, TransportMode mode = TransportMode::importance) const noexcept {
        if (mode == TransportMode::radiance) {
            if (one_sided_transmission(wi, wo)) return eval(wi, wo) * sides_[0]->radiance_factor();
            std::swap(wi, wo);
        }
        const Side* s = side(wi, wo);
        if (!s || !(wo.z != 0)) return Real(0);
        const Real mu_o = detail::clamp_unit(std::fabs(wo.z));
        const Real a = s->lobe(wo.z > 0 ? s->reflection : s->transmission, s->weights(detail::clamp_unit(wi.z)), wi, wo,
                               false).value;
        const Real surface = (wo.z > 0 && s->surface) ? s->surface_lobe->brdf(wi, wo) : Real(0);
        return surface + a / mu_o;
    }

    /// Every channel's f(wi, wo) into values[0 .. channels()) (eval gives their luminance).
    void eval(Vec3<Real> wi, Vec3<Real> wo, Real* values, TransportMode mode = TransportMode::importance) const noexcept {
        eval_channels(wi, wo, values, mode, nullptr);
    }

    /// The solid-angle density of sample(wi, ...) at wo (the deltas excluded: 0 there, as in RoughDielectric).
    /// The same in both transport modes; `allowed` as given to sample().
    Real pdf(Vec3<Real> wi, Vec3<Real> wo, TransportMode = TransportMode::importance,
             Lobe allowed = Lobe::all) const noexcept {
        const Side* s = side(wi, wo);
        if (!s || !(wo.z != 0) || !allows(allowed, wo.z > 0, false)) return Real(0);
        const detail::SplineWeights<Real> si = s->weights(detail::clamp_unit(wi.z));
        const Albedos al = s->albedos(si, detail::clamp_unit(wi.z), allowed);
        if (!(al.total > 0)) return Real(0);
        const Real p = s->lobe(wo.z > 0 ? s->reflection : s->transmission, si, wi, wo, true).density / al.total;
        if (wo.z < 0 || !s->surface || !(al.surface > 0)) return p;
        return p + al.surface / al.total * s->surface_pdf(wi, wo);
    }

    /// Samples wo from wi with three uniforms in [0, 1): the lobe by u_lobe, then (tabulated lobes) t_o by u1 and
    /// dphi by u2 (its sign by u_lobe's place within the lobe's share), or (surface) a visible facet normal by u1
    /// and u2. value and pdf as eval and pdf give them; a delta sample has delta = true, pdf = its selection
    /// probability and value = its power fraction / |wo.z| (BsdfSample). A failed sample has pdf = 0.
    /// `allowed` restricts the lobes chosen (Lobe): the surface's and the tabulated reflection are glossy
    /// reflection, the tabulated transmission glossy transmission, the mirror and the direct beam specular.
    BsdfSample<Real> sample(Vec3<Real> wi, Real u_lobe, Real u1, Real u2, TransportMode mode = TransportMode::importance,
                            Lobe allowed = Lobe::all) const noexcept {
        return sample_channels<false>(wi, u_lobe, u1, u2, mode, allowed, nullptr);
    }

    /// As sample(), and every channel's value at the sample into values[0 .. channels()): f(wi, wo) as eval gives
    /// it (to rounding: a tabulated lobe's channels come from the sampler's own interpolation, in the cosine it
    /// drew rather than the one read back from wo), or for a delta each channel's power fraction / |wo.z|. The
    /// weight of channel c is values[c] |wo.z| / pdf.
    BsdfSample<Real> sample(Vec3<Real> wi, Real u_lobe, Real u1, Real u2, Real* values,
                            TransportMode mode = TransportMode::importance, Lobe allowed = Lobe::all) const noexcept {
        for (int c = 0; c < channels(); ++c) values[c] = 0;
        return sample_channels<true>(wi, u_lobe, u1, u2, mode, allowed, values);
    }

private:
    // sample(), and with `values` (with_values) every channel's value at the sample, computed with the luminance's
    // where they can share its work: in importance transport a tabulated lobe's channels from the sampler's stencil,
    // in radiance transport (the arguments exchanged) one evaluation of all channels that also gives the luminance.
    // (A template so that sample() without values compiles to what it was before the values shared its work.)
    template <bool with_values>
    BsdfSample<Real> sample_channels(Vec3<Real> wi, Real u_lobe, Real u1, Real u2, TransportMode mode, Lobe allowed,
                                     Real* values) const noexcept {
        const bool below = wi.z < 0;
        const Side* s = below ? (sides_[1] ? &*sides_[1] : nullptr) : &*sides_[0];
        if (!s || !all_finite(wi) || !(std::fabs(wi.z) >= std::numeric_limits<Real>::min())) return {};
        Vec3<Real> w = wi;
        if (below) w.z = -w.z;
        const detail::SplineWeights<Real> si = s->weights(detail::clamp_unit(w.z));
        const Albedos al = s->albedos(si, detail::clamp_unit(w.z), allowed);
        if (!(al.total > 0)) return {};
        const Real p[5] = {al.surface, al.reflection, al.transmission, al.mirror, al.straight};
        int lobe = 0, last = 4;
        while (!(p[last] > 0)) --last;  // some lobe has albedo > 0
        Real u = u_lobe * al.total;
        while (lobe < last && (u >= p[lobe] || !(p[lobe] > 0))) u -= p[lobe++];
        u = detail::clamp_unit(u / p[lobe]);
        BsdfSample<Real> out;
        if (lobe >= 3) {  // a delta: the mirror direction, or the beam's Snell direction below
            out.wo = lobe == 3 ? Vec3<Real>{-w.x, -w.y, w.z} : s->straight_through(w);
            if (!(out.wo.z != 0)) return {};
            out.delta = true;
            out.reflected = lobe == 3;
            out.pdf = p[lobe] / al.total;
            const Real factor = mode == TransportMode::radiance && !out.reflected ? s->radiance_factor() : Real(1);
            out.value = p[lobe] / std::fabs(out.wo.z) * factor;
            const Real scale = factor / std::fabs(out.wo.z), mu_i = detail::clamp_unit(w.z);
            const int nc = channels();
            const Real in = with_values ? s->entering(mu_i) : Real(1);
            const Real mirror = with_values && out.reflected && s->mirror ? s->mirror->reflectance(mu_i) : Real(0);
            for (int c = 0; with_values && c < nc; ++c) {  // each channel's power fraction
                const int row = nc > 1 ? c + 1 : 0;
                values[c] = scale * (out.reflected ? mirror + s->beam(s->beam_reflected, si, row, in)
                                                   : s->beam(s->beam_transmitted, si, row, in));
            }
        } else {
            // value and pdf as eval and pdf give them, computed once (in the side's frame): a tabulated lobe's
            // from the series its sampler interpolated, the surface lobe's with the tabulated reflection there
            LobeValue v;
            const int nc = channels();
            // the tabulated lobe's channels in importance transport (several channels), from the sampler's stencil
            const bool shared = with_values && nc > 1 && lobe != 0 && mode == TransportMode::importance;
            if (lobe == 0) {
                out.wo = s->sample_surface(w, u1, u2);
                // (a non-unit wi near the largest double reflects to inf - inf: found by fuzz_renderer)
                if (!all_finite(out.wo) || !(out.wo.z != 0)) return {};
                v = s->lobe(s->reflection, si, w, out.wo, true);
            } else {
                const typename Side::LobeSample ls = s->sample_lobe(lobe == 1, si, w, u, u1, u2, shared ? values : nullptr);
                out.wo = ls.wo;
                v = ls.at;
                if (!all_finite(out.wo) || !(out.wo.z != 0)) {
                    for (int c = 0; with_values && c < nc; ++c) values[c] = 0;
                    return {};
                }
            }
            out.reflected = out.wo.z > 0;
            out.pdf = v.density / al.total;
            const Real mu_o = detail::clamp_unit(std::fabs(out.wo.z));
            const Real surface = out.reflected && s->surface ? s->surface_lobe->brdf(w, out.wo) : Real(0);
            out.value = v.value / mu_o + surface;
            if (out.reflected && s->surface && al.surface > 0) out.pdf += al.surface / al.total * s->surface_pdf(w, out.wo);
            if (!(out.pdf > 0)) {
                for (int c = 0; with_values && c < nc; ++c) values[c] = 0;
                return {};
            }
            Vec3<Real> wo = out.wo;  // in the caller's frame
            if (below) wo.z = -wo.z;
            if (mode == TransportMode::radiance) {  // the arguments exchanged: the value (and the channels) anew
                if (with_values) eval_channels(wi, wo, values, mode, &out.value); else out.value = eval(wi, wo, mode);
            } else if (shared) {
                for (int c = 0; c < nc; ++c) values[c] = surface + values[c] / mu_o;
            } else if (with_values) {
                if (nc == 1) values[0] = out.value; else eval_channels(wi, wo, values, mode, nullptr);
            }
        }
        if (below) out.wo.z = -out.wo.z;
        return out;
    }

    // eval(wi, wo, values, mode) and, with `luminance`, eval(wi, wo, mode) from the same interpolation.
    void eval_channels(Vec3<Real> wi, Vec3<Real> wo, Real* values, TransportMode mode, Real* luminance) const noexcept {
        if (mode == TransportMode::radiance) {
            if (one_sided_transmission(wi, wo)) {
                eval_channels(wi, wo, values, TransportMode::importance, luminance);
                for (int c = 0; c < channels(); ++c) values[c] *= sides_[0]->radiance_factor();
                if (luminance) *luminance *= sides_[0]->radiance_factor();
                return;
            }
            std::swap(wi, wo);
        }
        const int nc = channels();
        for (int c = 0; c < nc; ++c) values[c] = 0;
        if (luminance) *luminance = 0;
        const Side* s = side(wi, wo);
        if (!s || !(wo.z != 0)) return;
        const Real mu_o = detail::clamp_unit(std::fabs(wo.z));
        Real a = 0;
        s->lobe_channels(wo.z > 0 ? s->reflection : s->transmission, wi, wo, values, luminance ? &a : nullptr);
        const Real surface = (wo.z > 0 && s->surface) ? s->surface_lobe->brdf(wi, wo) : Real(0);
        for (int c = 0; c < nc; ++c) values[c] = surface + values[c] / mu_o;
        if (luminance) *luminance = surface + a / mu_o;
    }

public:

    /// The albedo of the whole BSDF for light arriving at cosine mu (> 0: from above, < 0: from below), deltas
    /// included (what a white furnace measures of sample()): {reflectance, transmittance}; {0, 0} where the side is
    /// not tabulated.
    struct Albedo {
        Real reflectance, transmittance;
    };
    Albedo albedo(Real mu) const noexcept {
        const Side* s = mu < 0 ? (sides_[1] ? &*sides_[1] : nullptr) : &*sides_[0];
        if (!s || !(std::fabs(mu) > 0)) return {Real(0), Real(0)};
        const Albedos a = s->albedos(s->weights(detail::clamp_unit(std::fabs(mu))), detail::clamp_unit(std::fabs(mu)));
        return {a.surface + a.reflection + a.mirror, a.transmission + a.straight};
    }

private:
    // Albedos of the five lobes at one incidence (the surface's interpolated, for choosing lobes only).
    struct Albedos {
        Real surface = 0, reflection = 0, transmission = 0, mirror = 0, straight = 0, total = 0;
    };
    // A tabulated lobe at (wi, wo): value = f |wo.z| (clamped to >= 0), density = value times the ratio of the
    // sampled marginal to the interpolated mean (see the class comment) and times albedo / (2 pi): the lobe's share
    // of the mixture density times the albedos' total.
    struct LobeValue {
        Real value = 0, density = 0;
    };

    struct Side {
        detail::Grid<Real> grid;                       // the nodes t_j (cut at the kinks: kink_cosines)
        std::vector<Real> jacobian;                    // dmu/dt at the nodes
        // The cosine of the first exit node above grazing, mu_1 at t_1. Below it the value f |wo.z| is a(t_1) mu_o / mu_1:
        // f held at its value there (grazing_exit). The spline of a = f |wo.z| in t, whose slope at t = 0 is not 0
        // where a vanishes like mu_o ~ t^2, gave f ~ 1 / sqrt(mu_o): eval 834 at wo.z = 1e-12 where the layer's brdf
        // is 0.019, and camera paths (radiance transport) whose view is the table's exit had weights growing without
        // bound at grazing views, 34 on average at wo.z = 1e-8 (found by a review sweep). The density keeps the
        // spline, which the sampler draws from: over mu_o < mu_1 only the value changes.
        Real first_cosine = 0;
        detail::FourierTable<Real> reflection, transmission;
        std::optional<RoughDielectric<Real>> surface;  // the top's rough reflection (analytic; sampled by it)
        std::optional<detail::SurfaceLobe<Real>> surface_lobe;  // the same, evaluated faster (SurfaceLobe)
        std::vector<Real> surface_albedo;              // its directional reflectance at the nodes (lobe choice)
        std::optional<SmoothDielectric<Real>> mirror;  // a smooth top's Fresnel reflection
        // Deltas between specular faces at the nodes: [c n + j], c = 0 the luminance (or the one channel), then the
        // channels.
        std::vector<Real> beam_reflected, beam_transmitted;
        // A smooth top into a denser medium: the tabulated lobes and the beams are stored as shares of the light it
        // lets in, 1 - F(mu_i) (entering(), exact at any mu_i), which vanishes at grazing incidence where the shares
        // do not. Splined whole beside the top's analytic reflection, they summed to more than 1 near grazing, where
        // F changes fast, and the lobes' node at mu = 0 (taken at a tenth of the next node's cosine) held light that
        // cannot arrive there: a glass slab's albedo 1.048 at mu = 0.004 with tau = 0, 1.038 at 0.006 with tau = 1
        // (renderer sweep). A non-absorbing slab's shares sum to 1 at every node, and so do their splines.
        std::optional<SmoothDielectric<Real>> entry;
        Real entering(Real mu_i) const noexcept { return entry ? entry->transmittance(mu_i) : Real(1); }
        Real eta_above = 1, eta_below = 1;             // outside the top and below the bottom
        Real error = 0, energy_error = 0;
        // Channels: their luminance weights, and the one not stored (it follows from the luminance and the others).
        int channels = 1, derived = 0;
        std::vector<Real> luminance;

        int n() const noexcept { return grid.n(); }
        std::size_t bytes() const noexcept {
            const std::size_t reals = grid.t.size() + grid.scale.size() + jacobian.size() + reflection.cdf.size() + transmission.cdf.size() +
                                      surface_albedo.size() + beam_reflected.size() + beam_transmitted.size() +
                                      luminance.size() + (surface_lobe ? surface_lobe->l.size() : std::size_t(0));
            const std::size_t floats = reflection.coeffs.size() + transmission.coeffs.size() + reflection.mean.size() +
                                       transmission.mean.size();
            return sizeof(Real) * reals + sizeof(float) * floats +
                   sizeof(std::uint32_t) * (reflection.offset.size() + transmission.offset.size()) + sizeof(int) * grid.ends.size();
        }
        detail::SplineWeights<Real> weights(Real mu) const noexcept {
            return detail::spline_weights(grid, grid.parameter(mu));
        }
        std::size_t pair(const detail::SplineWeights<Real>& si, int a, const detail::SplineWeights<Real>& so, int b) const noexcept {
            return static_cast<std::size_t>(si.first + a) * grid.t.size() + static_cast<std::size_t>(so.first + b);
        }
        // The incidence-interpolated running integral of m at exit node b.
        Real cdf(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si, int b) const noexcept {
            const Real* x = tab.cdf.data() + static_cast<std::size_t>(b) * grid.t.size() + static_cast<std::size_t>(si.first);
            return si.even[0] * x[0] + si.even[1] * x[1] + si.even[2] * x[2] + si.even[3] * x[3];
        }
        // The incidence-interpolated m = a_0 dmu/dt at exit node b.
        Real marginal(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si, int b) const noexcept {
            return mean_at(tab, si, b) * jacobian[static_cast<std::size_t>(b)];
        }
        // The incidence-interpolated a_0 at exit node b.
        Real mean_at(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si, int b) const noexcept {
            const float* x = tab.mean.data() + static_cast<std::size_t>(b) * grid.t.size() + static_cast<std::size_t>(si.first);
            return si.even[0] * Real(x[0]) + si.even[1] * Real(x[1]) + si.even[2] * Real(x[2]) + si.even[3] * Real(x[3]);
        }

        // The 16 pairs around (t_i, t_o): where series `first` of each starts, its length and its weights.
        struct Stencil {
            const float* src[16];
            int len[16];
            Real w_even[16], w_odd[16];
            int order = 0;  // the longest
            int shortest = std::numeric_limits<int>::max();
        };
        Stencil stencil(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si,
                        const detail::SplineWeights<Real>& so, int first) const noexcept {
            Stencil st;
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b) {
                    const std::size_t p = pair(si, a, so, b);
                    const int q = 4 * a + b;
                    st.len[q] = tab.order(p);
                    st.src[q] = tab.pair(p, first);  // (series first + s at src[q] + s len[q])
                    st.w_even[q] = si.even[a] * so.even[b];
                    st.w_odd[q] = si.odd[a] * so.odd[b];
                    st.order = std::max(st.order, st.len[q]);
                    st.shortest = std::min(st.shortest, st.len[q]);
                }
            return st;
        }

        // The series interpolated at (t_i, t_o): c[k] = sum over the 16 pairs of weight x a_k, each mode with the
        // weights of its parity; returns its length (c must hold kMaxOrder). Summing the coefficients first and
        // the series once is cheaper than a series per pair; the sums run over the pairs for two modes at a time in
        // registers (not one pair at a time through c, whose every element would wait on the previous pair's store).
        int interpolate(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si,
                        const detail::SplineWeights<Real>& so, Real* c, int series = 0) const noexcept {
            const Stencil st = stencil(tab, si, so, series);
            int k = 0;
            for (; k + 1 < st.shortest; k += 2) {  // modes every pair holds: no tests of the lengths
                Real even = 0, odd = 0;
                for (int q = 0; q < 16; ++q) {
                    even += st.w_even[q] * Real(st.src[q][k]);
                    odd += st.w_odd[q] * Real(st.src[q][k + 1]);
                }
                c[k] = even;
                c[k + 1] = odd;
            }
            for (; k < st.order; k += 2) {
                Real even = 0, odd = 0;
                for (int q = 0; q < 16; ++q) {
                    if (k < st.len[q]) even += st.w_even[q] * Real(st.src[q][k]);
                    if (k + 1 < st.len[q]) odd += st.w_odd[q] * Real(st.src[q][k + 1]);
                }
                c[k] = even;
                if (k + 1 < st.order) c[k + 1] = odd;
            }
            return st.order;
        }
        // As interpolate, Count consecutive series from `first` at once (c[s kMaxOrder + k] for series first + s),
        // the stencil and the tests of the lengths shared by all of them (one series alone stays in interpolate:
        // through this template it was slower in eval, back to back).
        template <int Count>
        int interpolate_series(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si,
                               const detail::SplineWeights<Real>& so, int first, Real* c) const noexcept {
            const Stencil st = stencil(tab, si, so, first);
            int k = 0;
            for (; k + 1 < st.shortest; k += 2) {  // modes every pair holds: no tests of the lengths
                Real even[Count] = {}, odd[Count] = {};
                for (int q = 0; q < 16; ++q)
                    for (int s = 0; s < Count; ++s) {
                        even[s] += st.w_even[q] * Real(st.src[q][s * st.len[q] + k]);
                        odd[s] += st.w_odd[q] * Real(st.src[q][s * st.len[q] + k + 1]);
                    }
                for (int s = 0; s < Count; ++s) {
                    c[s * kMaxOrder + k] = even[s];
                    c[s * kMaxOrder + k + 1] = odd[s];
                }
            }
            for (; k < st.order; k += 2) {
                Real even[Count] = {}, odd[Count] = {};
                for (int q = 0; q < 16; ++q) {
                    if (k < st.len[q])
                        for (int s = 0; s < Count; ++s) even[s] += st.w_even[q] * Real(st.src[q][s * st.len[q] + k]);
                    if (k + 1 < st.len[q])
                        for (int s = 0; s < Count; ++s) odd[s] += st.w_odd[q] * Real(st.src[q][s * st.len[q] + k + 1]);
                }
                for (int s = 0; s < Count; ++s) {
                    c[s * kMaxOrder + k] = even[s];
                    if (k + 1 < st.order) c[s * kMaxOrder + k + 1] = odd[s];
                }
            }
            return st.order;
        }

        // value = f |wo.z| clamped to >= 0; with `density`, also the mixture density times the albedos' total.
        // (si: the weights of wi.z)
        LobeValue lobe(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si, Vec3<Real> wi,
                       Vec3<Real> wo, bool density) const noexcept {
            if (tab.empty()) return {};
            const Real mu_o = detail::clamp_unit(std::fabs(wo.z));
            const Real t_o = grid.parameter(mu_o);
            const detail::SplineWeights<Real> so = detail::spline_weights(grid, t_o);
            Real c[kMaxOrder];
            const int order = interpolate(tab, si, so, c);
            const Real x = cos_dphi(wi, wo), in = entering(detail::clamp_unit(wi.z));
            const Real g = detail::cosine_series(c, order, x) * in;
            LobeValue v;
            v.value = g > 0 ? g : Real(0);
            if (density && order > 0 && c[0] > 0) v.density = sampled_density(tab, si, so, t_o, c[0], v.value);
            if (mu_o < first_cosine) v.value = grazing_exit(tab, si, x, mu_o) * in;
            return v;
        }

        // f |wo.z| of the luminance (or the one channel), clamped to >= 0, at exit cosines mu_o below first_cosine:
        // the series at t_1 times mu_o / mu_1 (see first_cosine). (Without the entering factor.)
        Real grazing_exit(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si, Real x,
                          Real mu_o) const noexcept {
            const detail::SplineWeights<Real> s1 = detail::spline_weights(grid, grid.t[1]);
            Real c[kMaxOrder];
            const Real g = detail::cosine_series(c, interpolate(tab, si, s1, c), x);
            return g > 0 ? g * (mu_o / first_cosine) : Real(0);
        }

        // value x (m / (dmu/dt)) / mean: the sampled density over the mixture's (see the class comment), m the
        // spline of a_0 dmu/dt at t_o; where dmu/dt vanishes (mu_o = 0 or 1, measure zero) the ratio is 1.
        Real sampled_density(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si,
                             const detail::SplineWeights<Real>& so, Real t_o, Real mean, Real value) const noexcept {
            Real m = 0;
            if (detail::touches_cut(grid, so.interval)) {  // (the sampler's segment: marginal_segment)
                m = detail::marginal_segment(grid, so.interval, [&](int b) { return marginal(tab, si, b); },
                                             [&](int b) { return mean_at(tab, si, b); })
                        .value(so.s);
            } else {
                for (int b = 0; b < 4; ++b) m += so.odd[b] * marginal(tab, si, so.first + b);  // m is odd at t = 1
            }
            return density_ratio(m, grid.jacobian(t_o), mean, value);
        }
        // The same from m and dmu/dt at t_o.
        static Real density_ratio(Real m, Real jac, Real mean, Real value) noexcept {
            const Real ratio = jac > std::numeric_limits<Real>::epsilon() ? m / (jac * mean) : Real(1);
            return ratio > 0 ? value * ratio : Real(0);
        }

        // The series of channel `channel` interpolated at (t_i, t_o) (see interpolate): a stored series, or the
        // derived channel from the luminance and the others, (Y - sum_c w_c a_c) / w_derived.
        int channel_series(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si,
                           const detail::SplineWeights<Real>& so, int channel, Real* c) const noexcept {
            if (channels == 1) return interpolate(tab, si, so, c);
            if (channel != derived) return interpolate(tab, si, so, c, stored_series(channel));
            const int order = interpolate(tab, si, so, c);
            Real other[kMaxOrder];
            for (int ch = 0; ch < channels; ++ch) {
                if (ch == derived) continue;
                const int len = interpolate(tab, si, so, other, stored_series(ch));
                for (int k = 0; k < len; ++k) c[k] -= luminance[static_cast<std::size_t>(ch)] * other[k];
            }
            for (int k = 0; k < order; ++k) c[k] /= luminance[static_cast<std::size_t>(derived)];
            return order;
        }
        int stored_series(int channel) const noexcept { return 1 + (channel < derived ? channel : channel - 1); }

        // f |wo.z| of every channel (clamped to >= 0) into out: each stored series summed, the derived channel from
        // their values (the relation is linear). With `luminance_value`, also the luminance's (clamped), the same sums as
        // lobe()'s value (interpolate_series's first series is interpolate's, term for term).
        void lobe_channels(const detail::FourierTable<Real>& tab, Vec3<Real> wi, Vec3<Real> wo, Real* out,
                           Real* luminance_value = nullptr) const noexcept {
            for (int ch = 0; ch < channels; ++ch) out[ch] = 0;
            if (luminance_value) *luminance_value = 0;
            if (tab.empty()) return;
            const detail::SplineWeights<Real> si = weights(detail::clamp_unit(wi.z));
            const Real mu_o = detail::clamp_unit(std::fabs(wo.z));  // (below first_cosine: at t_1, then scaled)
            const detail::SplineWeights<Real> so = weights(std::fmax(mu_o, first_cosine));
            const Real x = cos_dphi(wi, wo);
            if (channels == 1) {
                Real c[kMaxOrder];
                out[0] = detail::cosine_series(c, interpolate(tab, si, so, c), x);
                if (luminance_value) *luminance_value = out[0] > 0 ? out[0] : Real(0);
            } else {
                // The luminance (series 0) and the stored channels (series 1 .. channels - 1), four series a pass.
                Real c[4 * kMaxOrder];
                Real rest = 0;
                for (int first = 0; first < channels; first += 4) {
                    const int count = std::min(4, channels - first);
                    const int order = count == 4   ? interpolate_series<4>(tab, si, so, first, c)
                                      : count == 3 ? interpolate_series<3>(tab, si, so, first, c)
                                      : count == 2 ? interpolate_series<2>(tab, si, so, first, c)
                                                   : interpolate_series<1>(tab, si, so, first, c);
                    for (int s = 0; s < count; ++s) {
                        const Real value = detail::cosine_series(c + s * kMaxOrder, order, x);
                        const int series = first + s;
                        if (series == 0) {
                            rest += value;
                            if (luminance_value) *luminance_value = value > 0 ? value : Real(0);
                        } else {
                            const int ch = series - 1 < derived ? series - 1 : series;
                            out[ch] = value;
                            rest -= luminance[static_cast<std::size_t>(ch)] * value;
                        }
                    }
                }
                out[derived] = rest / luminance[static_cast<std::size_t>(derived)];
            }
            const Real in = entering(detail::clamp_unit(wi.z)) * (mu_o < first_cosine ? mu_o / first_cosine : Real(1));
            for (int ch = 0; ch < channels; ++ch) out[ch] = out[ch] > 0 ? out[ch] * in : Real(0);
            if (luminance_value) *luminance_value *= in;
        }

        // The deltas' power fractions of channel `series` (0: the luminance or the one channel; c + 1: channel c).
        // (`in`: entering(mu_i).)
        Real beam(const std::vector<Real>& v, const detail::SplineWeights<Real>& si, int series, Real in) const noexcept {
            if (v.empty()) return Real(0);
            Real s = 0;
            for (int a = 0; a < 4; ++a) s += si.even[a] * v[static_cast<std::size_t>(series * n() + si.first + a)];
            s *= in;
            return s > 0 ? s : Real(0);
        }

        // The lobes' albedos at mu_i (si: its weights), those not in `allowed` 0.
        Albedos albedos(const detail::SplineWeights<Real>& si, Real mu_i, Lobe allowed = Lobe::all) const noexcept {
            Albedos al;
            auto interpolate = [&](const std::vector<Real>& v) {
                if (v.empty()) return Real(0);
                Real s = 0;
                for (int a = 0; a < 4; ++a) s += si.even[a] * v[static_cast<std::size_t>(si.first + a)];
                return s > 0 ? s : Real(0);
            };
            const Real in = entering(mu_i);
            auto lobe_albedo = [&](const detail::FourierTable<Real>& tab) {
                if (tab.empty()) return Real(0);
                const Real c = cdf(tab, si, n() - 1);
                return c > 0 ? 2 * detail::pi_v<Real> * c * in : Real(0);
            };
            al.surface = surface ? interpolate(surface_albedo) : Real(0);
            al.reflection = lobe_albedo(reflection);
            al.transmission = lobe_albedo(transmission);
            al.mirror = (mirror ? mirror->reflectance(mu_i) : Real(0)) + beam(beam_reflected, si, 0, in);
            al.straight = beam(beam_transmitted, si, 0, in);
            if (!allows(allowed, true, false)) al.surface = al.reflection = 0;
            if (!allows(allowed, false, false)) al.transmission = 0;
            if (!allows(allowed, true, true)) al.mirror = 0;
            if (!allows(allowed, false, true)) al.straight = 0;
            al.total = al.surface + al.reflection + al.transmission + al.mirror + al.straight;
            return al;
        }

        // Reflection only: a facet normal visible from wi and wo the mirror image of wi in it; density
        // D_wi(h) / (4 wo.h), the RoughDielectric's reflection without its Fresnel choice.
        Vec3<Real> sample_surface(Vec3<Real> wi, Real u1, Real u2) const noexcept {
            const Vec3<Real> h = surface->distribution().sample_visible_normal(wi, u1, u2);
            const Real c = dot(wi, h);
            if (!(c > 0)) return {};
            const Vec3<Real> wo = 2 * c * h - wi;
            return wo.z > 0 ? wo : Vec3<Real>{};
        }
        Real surface_pdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept { return surface_lobe->pdf(wi, wo); }

        // t_o by inverting the integral of the spline of m (u1), then dphi by inverting the interpolated series
        // (u2), its sign by u_sign.
        // The direction, with the lobe's value and density there (as lobe() gives them, from the same series).
        struct LobeSample {
            Vec3<Real> wo{};
            LobeValue at;
        };
        // With `channel_values` (a table of several channels), also every channel's value at wo (as lobe_channels
        // gives them, clamped to >= 0) from the same stencil: the stored channels' series interpolated beside the
        // luminance's, the derived one from them.
        LobeSample sample_lobe(bool reflected, const detail::SplineWeights<Real>& si, Vec3<Real> wi, Real u_sign, Real u1,
                               Real u2, Real* channel_values = nullptr) const noexcept {
            const detail::FourierTable<Real>& tab = reflected ? reflection : transmission;
            const int nn = n();
            const Real total = cdf(tab, si, nn - 1);
            if (!(total > 0)) return {};
            const Real target = u1 * total;
            int lo = 0, hi = nn - 1;  // the interval holding the target
            while (hi - lo > 1) {  // (selects, not branches: the comparisons are unpredictable)
                const int mid = (lo + hi) / 2;
                const bool below = cdf(tab, si, mid) <= target;
                lo = below ? mid : lo;
                hi = below ? hi : mid;
            }
            const detail::HermiteSegment<Real> seg =
                detail::marginal_segment(grid, lo, [&](int b) { return marginal(tab, si, b); },
                                         [&](int b) { return mean_at(tab, si, b); });
            const Real x = detail::invert_segment(seg, target - cdf(tab, si, lo), total);
            const Real t_o = detail::clamp_unit(grid.t[static_cast<std::size_t>(lo)] + x * seg.h);
            // mu_o and dmu/dt from the same sine (Grid::at)
            const typename detail::Grid<Real>::Point at_o = grid.at(t_o);
            const Real mu_o = at_o.mu;
            // A subnormal cosine (t_o below ~1e-154: u1 below ~1e-300) has too few digits for pdf() to find t_o
            // again from it (found by fuzz_renderer: the two densities 0.17% apart); such a grazing sample fails.
            if (!(mu_o >= std::numeric_limits<Real>::min())) return {};
            // The Fourier series at (mu_i, mu_o).
            const detail::SplineWeights<Real> so = detail::spline_weights(grid, t_o);
            Real c[kMaxOrder];
            const int order = interpolate(tab, si, so, c);
            if (!(order > 0 && c[0] > 0)) return {};
            const detail::AzimuthSample<Real> az = detail::sample_cosine_series(c, order, u2);
            // wo's azimuth is dphi = +-phi from the propagation direction -wi (the x axis when wi is the normal).
            const Real r = std::hypot(wi.x, wi.y);
            const Real ex = r > 0 ? -wi.x / r : Real(1), ey = r > 0 ? -wi.y / r : Real(0);
            const Real cp = az.cos_phi, sp = u_sign < Real(0.5) ? az.sin_phi : -az.sin_phi;
            const Real st = std::sqrt(detail::clamp_unit((1 - mu_o) * (1 + mu_o)));
            LobeSample out;
            out.wo = {st * (cp * ex - sp * ey), st * (cp * ey + sp * ex), reflected ? mu_o : -mu_o};
            // The value as lobe() (eval, pdf) computes it at wo: the same summation at cos_dphi(wi, wo), which is
            // 1 at the pole (wi or wo along the normal, only mode 0 seen). (The sampler's own g at phi, from another
            // recurrence, differs by ~1e-15 of sum |c_k|: too much, relative to g, in a lobe's tails at 100 modes.)
            const Real cos_dphi_o = cos_dphi(wi, out.wo), in = entering(detail::clamp_unit(wi.z));
            const Real g = detail::cosine_series(c, order, cos_dphi_o);
            out.at.value = g > 0 ? g * in : Real(0);
            // (m at t_o is the segment's value at x: the spline of sampled_density, on the interval it was inverted on)
            out.at.density = density_ratio(seg.value(x), at_o.jacobian, c[0], out.at.value);
            if (mu_o < first_cosine) {  // the value as lobe() and lobe_channels() give it there (first_cosine)
                out.at.value = grazing_exit(tab, si, cos_dphi_o, mu_o) * in;
                if (channel_values && channels > 1) lobe_channels(tab, wi, out.wo, channel_values);
                return out;
            }
            if (channel_values && channels > 1) {
                stored_channel_values(tab, si, so, cos_dphi_o, g, channel_values);
                for (int ch = 0; ch < channels; ++ch) channel_values[ch] *= in;
            }
            return out;
        }

        // Every channel's f |wo.z| (clamped to >= 0) at the stencil (si, so) and cos(dphi) = x, given the luminance's
        // (unclamped) value y there: the stored series interpolated three at a time, the derived channel from them.
        void stored_channel_values(const detail::FourierTable<Real>& tab, const detail::SplineWeights<Real>& si,
                                   const detail::SplineWeights<Real>& so, Real x, Real y, Real* out) const noexcept {
            Real c[3 * kMaxOrder];
            Real rest = y;
            for (int first = 1; first < channels; first += 3) {
                const int count = std::min(3, channels - first);
                const int order = count == 3   ? interpolate_series<3>(tab, si, so, first, c)
                                  : count == 2 ? interpolate_series<2>(tab, si, so, first, c)
                                               : interpolate_series<1>(tab, si, so, first, c);
                for (int k = 0; k < count; ++k) {
                    const int ch = first + k - 1 < derived ? first + k - 1 : first + k;
                    out[ch] = detail::cosine_series(c + k * kMaxOrder, order, x);
                    rest -= luminance[static_cast<std::size_t>(ch)] * out[ch];
                }
            }
            out[derived] = rest / luminance[static_cast<std::size_t>(derived)];
            for (int ch = 0; ch < channels; ++ch) out[ch] = out[ch] > 0 ? out[ch] : Real(0);
        }

        // The Snell direction of the beam leaving below (indices eta_above -> eta_below: the tangential part scales).
        Vec3<Real> straight_through(Vec3<Real> wi) const noexcept {
            const Real r = eta_above / eta_below;
            const Real tx = -wi.x * r, ty = -wi.y * r;
            const Real c2 = 1 - (tx * tx + ty * ty);
            if (!(c2 > 0)) return {};
            return {tx, ty, -std::sqrt(c2)};
        }
        // A transmitted delta's coefficient in radiance mode: (eta_wi / eta_wo)^2 (see TransportMode).
        Real radiance_factor() const noexcept { return (eta_above / eta_below) * (eta_above / eta_below); }

        // cos(dphi), dphi between -wi and wo (1 when either is along the normal): -(wi.xy . wo.xy) / sqrt(|wi.xy|^2
        // |wo.xy|^2), one square root and one division, where the squares and their product neither overflow nor
        // underflow (unit vectors, and any whose components lie within about 1e-75 .. 1e75 in double); others take
        // hypot's path, which does neither.
        static Real cos_dphi(Vec3<Real> wi, Vec3<Real> wo) noexcept {
            const Real pi2 = wi.x * wi.x + wi.y * wi.y, po2 = wo.x * wo.x + wo.y * wo.y, p = pi2 * po2;
            Real c;
            if (pi2 >= std::numeric_limits<Real>::min() && po2 >= std::numeric_limits<Real>::min() &&
                p >= std::numeric_limits<Real>::min() && p <= std::numeric_limits<Real>::max()) {
                c = -(wi.x * wo.x + wi.y * wo.y) / std::sqrt(p);
            } else {
                const Real ri = std::hypot(wi.x, wi.y), ro = std::hypot(wo.x, wo.y);
                if (!(ri > 0) || !(ro > 0)) return Real(1);
                c = -((wi.x / ri) * (wo.x / ro) + (wi.y / ri) * (wo.y / ro));
            }
            return c > Real(1) ? Real(1) : (c < Real(-1) ? Real(-1) : c);
        }
    };

    // The longest series a pair keeps (sample() sums the interpolated series in a buffer of this size).
    static constexpr int kMaxOrder = max_order;

    // The side for wi, with both directions mirrored into the frame where light arrives from above; null for
    // degenerate directions and for light from below on a one-sided table.
    const Side* side(Vec3<Real>& wi, Vec3<Real>& wo) const noexcept {
        if (!all_finite(wi) || !all_finite(wo) || !(wi.z != 0)) return nullptr;
        if (wi.z > 0) return &*sides_[0];
        if (!sides_[1]) return nullptr;
        wi.z = -wi.z;
        wo.z = -wo.z;
        return &*sides_[1];
    }


    // Radiance mode on a one-sided table with the viewer (wi) above and the light below: exchanging the arguments
    // would ask for light from below, which is not tabulated.
    bool one_sided_transmission(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        return !sides_[1] && wi.z > 0 && wo.z < 0;
    }

    // That `below` is `above` turned over, as far as the faces tell (the slabs are not compared): each face of one is
    // the other's opposite face with its indices exchanged, of the same roughness and shadowing. Unchecked, the same
    // asymmetric layer given twice, or another layer, built a table that answered light from below with the wrong
    // layer (found by a review sweep).
    template <class LayerReal>
    static void require_turned_over(const LayeredSurface<LayerReal>& above, const LayeredSurface<LayerReal>& below) {
        const auto opposite = [](const Boundary<LayerReal>& a, const Boundary<LayerReal>& b) {
            if (a.lambertian() || b.lambertian() || a.eta_above() != b.eta_below() || a.eta_below() != b.eta_above() ||
                a.rough() != b.rough())
                return false;
            return !a.rough() || (a.rough_interface()->sigma() == b.rough_interface()->sigma() &&
                                  a.rough_interface()->shadowing() == b.rough_interface()->shadowing());
        };
        if (!opposite(above.top(), below.bottom()) || !opposite(above.bottom(), below.top()))
            detail::fail_invalid_argument("stratum: TabulatedBSDF: the layer from below is not the layer from above turned "
                                          "over (its faces exchanged, each with its indices swapped; no Lambertian floor)");
    }

    static Real check_tolerance(Real tolerance) {
        return detail::require_closed("TabulatedBSDF tolerance", tolerance, Real(1e-7), Real(0.5));
    }

    template <class LayerReal>
    static Side tabulate(const std::vector<const LayeredSurface<LayerReal>*>& layers, const std::vector<Real>& luminance,
                         Real tolerance);

    // The kinks of the lobes in a cosine outside (unsorted; merged_kinks sorts them):
    // where light outside, of index n_o, at cosine mu meets a face into a medium of index n < n_o at its critical
    // angle, n_o sin(theta) = n, through faces that do not spread it (specular): mu_c = sqrt(1 - (n / n_o)^2).
    // There the layer's lobes and fluxes change abruptly (total internal reflection begins), and a spline whose
    // slopes reach across carried light over the kink: a lossless slab of index 1 between glass had an albedo of
    // 1.26 at mu 0.745 (docs/physics.md section 9). Above (the incidence and the reflected exits): n_o the medium
    // above, through a specular top; below (the transmitted exits): the medium below, through a specular bottom.
    // (A rough face spreads the directions, and the kink with them.)
    template <class LayerReal>
    static std::vector<Real> kink_cosines(const LayeredSurface<LayerReal>& layer) {
        std::vector<Real> mu;
        const auto add = [&mu](LayerReal n_o, LayerReal n) {
            if (!(n < n_o)) return;
            const LayerReal r = n / n_o;
            mu.push_back(static_cast<Real>(std::sqrt((1 - r) * (1 + r))));
        };
        const Boundary<LayerReal>& top = layer.top();
        const Boundary<LayerReal>& bottom = layer.bottom();
        const bool top_specular = !top.rough() && !top.lambertian(), bottom_specular = !bottom.rough() && !bottom.lambertian();
        if (top_specular) {
            for (const LayerReal n : layer.slab_indices()) add(top.eta_above(), n);
            if (bottom_specular) add(top.eta_above(), bottom.eta_below());
        }
        if (bottom_specular && includes(layer.outputs(), LayerOutput::transmission)) {
            for (const LayerReal n : layer.slab_indices()) add(bottom.eta_below(), n);
            if (top_specular) add(bottom.eta_below(), top.eta_above());
        }
        return mu;
    }
    // Ascending, without those within 1e-4 in t of another (the same kink, to the table) or within 1/64 of 0 or 1
    // (an index ratio within 2e-7 of 1). (Within 1/64 of another, a kink was dropped: 1.5 | 1.34 | 1.33 | 1 lost the
    // 1.33's, 0.008 in t from the 1.34's, and its albedo reached 1.010; found by review. A piece between two near
    // kinks gets two intervals, as every piece.)
    static std::vector<Real> merged_kinks(std::vector<Real> mu) {
        std::sort(mu.begin(), mu.end());
        std::vector<Real> kinks;
        for (const Real m : mu) {
            const Real x = detail::cosine_parameter(m);
            if (x >= Real(1) / 64 && x <= 1 - Real(1) / 64 &&
                (kinks.empty() || x - detail::cosine_parameter(kinks.back()) >= Real(1e-4)))
                kinks.push_back(m);
        }
        return kinks;
    }
    template <class LayerReal>
    static Real energy_mismatch(const Side& s, const std::vector<const LayeredSurface<LayerReal>*>& layers,
                                const std::vector<Real>& luminance);

    // The layers of every channel (validated: the same faces), and the luminance weights (normalized to sum 1).
    template <class LayerReal>
    static std::vector<const LayeredSurface<LayerReal>*> channel_layers(const std::vector<LayeredSurface<LayerReal>>& layers) {
        if (layers.empty()) detail::fail_invalid_argument("stratum: TabulatedBSDF: no channels");
        std::vector<const LayeredSurface<LayerReal>*> out;
        for (const LayeredSurface<LayerReal>& l : layers) {
            const auto& a = layers.front();
            // (the top's shadowing too: the surface lobe is channel 0's; a separable top beside a height-correlated
            // one gave its channel 15% off at grazing; found by review)
            const bool same = l.top().eta_above() == a.top().eta_above() && l.top().eta_below() == a.top().eta_below() &&
                              l.bottom().eta_below() == a.bottom().eta_below() && l.top().rough() == a.top().rough() &&
                              (!l.top().rough() || (l.top().rough_interface()->sigma() == a.top().rough_interface()->sigma() &&
                                                    l.top().rough_interface()->shadowing() == a.top().rough_interface()->shadowing())) &&
                              l.outputs() == a.outputs();
            if (!same)
                detail::fail_invalid_argument("stratum: TabulatedBSDF: the channels' layers must share their outer "
                                              "faces (indices, top roughness and shadowing) and their requested outputs");
            out.push_back(&l);
        }
        return out;
    }
    static std::vector<Real> luminance_weights(std::vector<Real> w, std::size_t channels) {
        if (w.empty()) w.assign(channels, Real(1));
        if (w.size() != channels)
            detail::fail_invalid_argument("stratum: TabulatedBSDF: " + std::to_string(w.size()) + " luminance weights for " +
                                          std::to_string(channels) + " channels");
        Real largest = 0;
        for (Real x : w)
            largest = std::fmax(largest, detail::require_open("TabulatedBSDF luminance weight", x, Real(0),
                                                              std::numeric_limits<Real>::infinity()));
        // Scaled by the largest first: weights near the largest finite value summed to inf, and every weight became 0
        // (found by the renderer sweep).
        Real sum = 0;
        for (Real& x : w) sum += (x /= largest);
        for (Real& x : w) x /= sum;
        return w;
    }

    std::optional<Side> sides_[2];
    Real tolerance_;
};

namespace detail {

// A lobe's coefficients on a grid of n nodes, as LayeredSurface::fourier_coefficients gives them (K per pair).
template <class Real>
struct DenseLobe {
    int n = 0, modes = 0;
    std::vector<Real> a;
    const Real* pair(int i, int o) const noexcept {
        return a.data() + (static_cast<std::size_t>(i) * static_cast<std::size_t>(n) + static_cast<std::size_t>(o)) *
                              static_cast<std::size_t>(modes);
    }
};

// The incidence cosine at which the layer is evaluated for node j of the grid t: the node's, and at t = 0 a tenth
// of the next node's (the BRDF does not vanish at grazing incidence, although no light arrives there).
template <class L, class Real>
L node_incidence(const Grid<Real>& g, std::size_t j) {
    return j == 0 ? static_cast<L>(g.cosine(g.t[1])) / 10 : static_cast<L>(g.cosine(g.t[j]));
}

// The coefficients of both lobes of `layer` on the grid t (incidences node_incidence), each row divided by
// `entry` of its incidence cosine where that is given (TabulatedBSDF::Side::entry).
template <class Real, class L>
void layer_lobes(const LayeredSurface<L>& layer, const Grid<Real>& grid, const SmoothDielectric<L>* entry,
                 DenseLobe<L> out[2]) {
    const std::vector<Real>& t = grid.t;
    std::vector<L> mu_o(t.size()), mu_i(t.size());
    for (std::size_t j = 0; j < t.size(); ++j) {
        mu_o[j] = static_cast<L>(grid.cosine(t[j]));
        mu_i[j] = node_incidence<L>(grid, j);
    }
    const LayerOutput which[2] = {LayerOutput::subsurface_reflection, LayerOutput::transmission};
    for (int w = 0; w < 2; ++w) {
        out[w] = {static_cast<int>(t.size()), layer.modes(), layer.fourier_coefficients(which[w], mu_i, mu_o)};
        const std::size_t row = t.size() * static_cast<std::size_t>(out[w].modes);
        for (std::size_t i = 0; entry && i < t.size(); ++i) {
            const L in = entry->transmittance(mu_i[i]);
            for (std::size_t j = 0; in > 0 && j < row; ++j) out[w].a[i * row + j] /= in;
        }
    }
}

// The largest mu_i sum_k |a_k(table) - a_k(fine)| over the fine grid's nodes (2n - 1 of them, every other one
// the table's): the worst error of f |wi.z| |wo.z| at any dphi.
template <class Real, class L>
L table_error(const Grid<Real>& grid, const Grid<Real>& fine_grid, const DenseLobe<L>& fine, const std::vector<int>& orders) {
    const int n = grid.n(), k_max = fine.modes;
    L worst = 0;
    std::vector<L> c(static_cast<std::size_t>(k_max));
    for (int i = 0; i < fine.n; ++i) {
        const Real t_i = fine_grid.t[static_cast<std::size_t>(i)];
        const L mu_i = static_cast<L>(fine_grid.cosine(t_i));
        const SplineWeights<Real> si = spline_weights(grid, t_i);
        for (int o = 0; o < fine.n; ++o) {
            const SplineWeights<Real> so = spline_weights(grid, fine_grid.t[static_cast<std::size_t>(o)]);
            std::fill(c.begin(), c.end(), L(0));
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b) {
                    const L w[2] = {static_cast<L>(si.even[a] * so.even[b]), static_cast<L>(si.odd[a] * so.odd[b])};
                    const int p = (si.first + a) * n + so.first + b;
                    const L* src = fine.pair(2 * (si.first + a), 2 * (so.first + b));
                    for (int k = 0; k < orders[static_cast<std::size_t>(p)]; ++k) c[static_cast<std::size_t>(k)] += w[k & 1] * src[k];
                }
            const L* exact = fine.pair(i, o);
            L e = 0;
            for (int k = 0; k < k_max; ++k) e += std::fabs(c[static_cast<std::size_t>(k)] - exact[k]);
            worst = std::fmax(worst, mu_i * e);
        }
    }
    return worst;
}

// Per pair of the coarse grid (every other node of `fine`), the shortest series whose dropped tail
// sum_{k >= L} |a_k| is at most `budget` (and at most `cap` terms), keeping the mean a_0 (the pair's energy).
template <class L>
std::vector<int> truncated_orders(const DenseLobe<L>& fine, L budget, int cap) {
    const int n = (fine.n + 1) / 2;
    std::vector<int> orders(static_cast<std::size_t>(n) * static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i)
        for (int o = 0; o < n; ++o) {
            const L* a = fine.pair(2 * i, 2 * o);
            int len = std::min(fine.modes, cap);
            L tail = 0;
            for (int k = fine.modes - 1; k >= len; --k) tail += std::fabs(a[k]);
            while (len > 1 && tail + std::fabs(a[len - 1]) <= budget) tail += std::fabs(a[--len]);
            if (len == 1 && a[0] == 0) len = 0;  // the mean (the pair's energy) is never cut
            orders[static_cast<std::size_t>(i * n + o)] = len;
        }
    return orders;
}

// The packed table of the coarse grid's pairs for the given series (every other node of each `fine` lobe), each
// pair with the order `orders` gives it, and each row's running integral of m = a_0 dmu/dt of series 0.
template <class Real, class L>
FourierTable<Real> pack_table(const Grid<Real>& grid, const std::vector<Real>& jacobian,
                              const std::vector<const DenseLobe<L>*>& series, const std::vector<int>& orders) {
    FourierTable<Real> tab;
    const int n = grid.n();
    const std::uint32_t count = static_cast<std::uint32_t>(series.size());
    tab.series = static_cast<int>(count);
    tab.offset.assign(orders.size() + 1, 0);
    for (std::size_t p = 0; p < orders.size(); ++p) tab.offset[p + 1] = tab.offset[p] + count * static_cast<std::uint32_t>(orders[p]);
    if (tab.offset.back() == 0) return FourierTable<Real>{};
    tab.coeffs.reserve(tab.offset.back());
    for (int i = 0; i < n; ++i)
        for (int o = 0; o < n; ++o)
            for (const DenseLobe<L>* lobe : series) {
                const int len = orders[static_cast<std::size_t>(i * n + o)];
                const L* a = lobe->pair(2 * i, 2 * o);
                for (int k = 0; k < len; ++k) tab.coeffs.push_back(k < lobe->modes ? static_cast<float>(a[k]) : 0.0f);
            }
    const std::size_t nn = static_cast<std::size_t>(n);
    tab.cdf.assign(nn * nn, Real(0));
    tab.mean.assign(nn * nn, 0.0f);
    for (std::size_t i = 0; i < nn; ++i)
        for (std::size_t o = 0; o < nn; ++o) tab.mean[o * nn + i] = tab.first_coefficient(i * nn + o);
    for (std::size_t i = 0; i < nn; ++i) {
        auto m = [&](int o) { return Real(tab.mean[static_cast<std::size_t>(o) * nn + i]) * jacobian[static_cast<std::size_t>(o)]; };
        for (int o = 0; o + 1 < n; ++o)
            tab.cdf[static_cast<std::size_t>(o + 1) * nn + i] =
                tab.cdf[static_cast<std::size_t>(o) * nn + i] +
                marginal_segment(grid, o, m, [&](int b) { return Real(tab.mean[static_cast<std::size_t>(b) * nn + i]); }).integral(Real(1));
    }
    return tab;
}

// sum_c w_c lobe_c (padded to the most modes): the luminance of several channels.
template <class L, class Real>
DenseLobe<L> weighted_sum(const std::vector<DenseLobe<L>>& lobes, const std::vector<Real>& weights) {
    DenseLobe<L> out;
    out.n = lobes.front().n;
    for (const DenseLobe<L>& l : lobes) out.modes = std::max(out.modes, l.modes);
    const std::size_t pairs = static_cast<std::size_t>(out.n) * static_cast<std::size_t>(out.n);
    out.a.assign(pairs * static_cast<std::size_t>(out.modes), L(0));
    for (std::size_t c = 0; c < lobes.size(); ++c)
        for (std::size_t p = 0; p < pairs && lobes[c].modes > 0; ++p)
            for (int k = 0; k < lobes[c].modes; ++k)
                out.a[p * static_cast<std::size_t>(out.modes) + static_cast<std::size_t>(k)] +=
                    static_cast<L>(weights[c]) * lobes[c].a[p * static_cast<std::size_t>(lobes[c].modes) + static_cast<std::size_t>(k)];
    return out;
}

}  // namespace detail

template <class Real>
template <class LayerReal>
typename TabulatedBSDF<Real>::Side TabulatedBSDF<Real>::tabulate(const std::vector<const LayeredSurface<LayerReal>*>& layers,
                                                                  const std::vector<Real>& luminance, Real tolerance) {
    using L = LayerReal;
    const LayeredSurface<L>& layer = *layers.front();
    const int channels = static_cast<int>(layers.size());
    Side s;
    s.channels = channels;
    if (channels > 1) {
        s.luminance = luminance;
        s.derived = static_cast<int>(std::max_element(luminance.begin(), luminance.end()) - luminance.begin());
    }
    s.eta_above = static_cast<Real>(layer.top().eta_above());
    s.eta_below = static_cast<Real>(layer.bottom().eta_below());
    const bool surface = includes(layer.outputs(), LayerOutput::surface_reflection);
    if (surface && layer.top().rough()) {
        const RoughDielectric<L>& r = *layer.top().rough_interface();
        s.surface.emplace(static_cast<Real>(r.sigma()), static_cast<Real>(r.eta_above()),
                          static_cast<Real>(r.eta_below()), r.shadowing());
        s.surface_lobe.emplace(*s.surface);
    } else if (surface) {
        s.mirror.emplace(s.eta_above, static_cast<Real>(layer.top().eta_below()));
    }
    // (Into a denser medium only: from a denser one 1 - F vanishes at the critical cosine, like a square root, and the
    // shares would be singular there; found by review: error() 0.22 -> 0.51 for a 1.5 | 1 top.)
    if (!layer.top().rough() && !layer.top().lambertian() && layer.top().eta_above() < layer.top().eta_below())
        s.entry.emplace(s.eta_above, static_cast<Real>(layer.top().eta_below()));
    // Refine until every channel's table of n nodes is within tolerance at the nodes of 2n - 1 (level 4 at most: 129
    // nodes without kinks). fine[w][c]: lobe w (reflection, transmission) of channel c on the finer grid; the
    // luminance last.
    std::vector<detail::DenseLobe<L>> fine[2];
    std::vector<int> orders[2];
    // (every channel's: their slabs' indices may differ; channel 0's alone left channel 1's lobe albedo 0.55 for 0.42
    // at its kink, found by review)
    std::vector<Real> kinks;
    for (const LayeredSurface<L>* l : layers) {
        const std::vector<Real> own = kink_cosines(*l);
        kinks.insert(kinks.end(), own.begin(), own.end());
    }
    kinks = merged_kinks(std::move(kinks));
    for (int level = 0;; ++level) {
        s.grid = detail::table_grid(kinks, level);
        const detail::Grid<Real> finer = detail::table_grid(kinks, level + 1);
        const int n = s.n();
        for (int w = 0; w < 2; ++w) fine[w].assign(static_cast<std::size_t>(channels), {});
        for (int c = 0; c < channels; ++c) {
            detail::DenseLobe<L> pair[2];
            detail::layer_lobes(*layers[static_cast<std::size_t>(c)], finer,
                                s.entry ? &layer.top().smooth_interface() : nullptr, pair);
            for (int w = 0; w < 2; ++w) fine[w][static_cast<std::size_t>(c)] = std::move(pair[w]);
        }
        L err = 0;
        for (int w = 0; w < 2; ++w) {
            if (channels > 1) fine[w].push_back(detail::weighted_sum(fine[w], luminance));
            orders[w].assign(static_cast<std::size_t>(n * n), 0);
            for (const detail::DenseLobe<L>& f : fine[w]) {
                L scale = 0;  // the lobe's largest azimuthal mean of f |wi.z| |wo.z|
                for (int i = 0; i < f.n; ++i)
                    for (int o = 0; o < f.n && f.modes > 0; ++o)
                        scale = std::fmax(scale, std::fabs(f.pair(i, o)[0]) *
                                                     static_cast<L>(finer.cosine(finer.t[static_cast<std::size_t>(i)])));
                const std::vector<int> own = detail::truncated_orders(f, L(tolerance) * scale / 4, max_order);
                if (scale > 0) err = std::fmax(err, detail::table_error(s.grid, finer, f, own) / scale);
                for (std::size_t p = 0; p < own.size(); ++p) orders[w][p] = std::max(orders[w][p], own[p]);
            }
        }
        s.error = static_cast<Real>(err);
        if (err <= L(tolerance) || level >= 4) break;
    }
    const std::vector<Real>& nodes_t = s.grid.t;
    s.jacobian.resize(nodes_t.size());
    for (std::size_t j = 0; j < nodes_t.size(); ++j) s.jacobian[j] = s.grid.jacobian(nodes_t[j]);
    s.first_cosine = s.grid.cosine(nodes_t[1]);
    for (int w = 0; w < 2; ++w) {
        // Stored: the one channel; or the luminance, then every channel but the derived one.
        std::vector<const detail::DenseLobe<L>*> series;
        if (channels > 1) series.push_back(&fine[w].back());
        for (int c = 0; c < channels; ++c)
            if (channels == 1 || c != s.derived) series.push_back(&fine[w][static_cast<std::size_t>(c)]);
        (w == 0 ? s.reflection : s.transmission) = detail::pack_table(s.grid, s.jacobian, series, orders[w]);
    }
    const std::size_t nodes = nodes_t.size();
    if (s.surface) {  // for choosing lobes, and albedo(); at node 0 the value at node_incidence, as the lobes have it
        // (it held node 1's, and albedo() missed the top's growing reflectance towards grazing: 0.554 for 0.593 at
        // mu 0.001 under a rough 0.2 top; found by review)
        s.surface_albedo.resize(nodes);
        for (std::size_t j = 0; j < nodes; ++j)
            s.surface_albedo[j] = static_cast<Real>(layer.reflectance(detail::node_incidence<L>(s.grid, j)).surface);
    }
    bool beams = false;
    for (const LayeredSurface<L>* l : layers)
        beams = beams || l->direct_reflectance(L(1)) > 0 || l->direct_transmittance(L(1)) > 0 ||
                l->forward_peak_reflectance(L(1)) > 0 || l->forward_peak_transmittance(L(1)) > 0;
    if (beams) {
        const std::size_t rows = channels > 1 ? static_cast<std::size_t>(channels) + 1 : 1;
        s.beam_reflected.assign(rows * nodes, Real(0));
        s.beam_transmitted.assign(rows * nodes, Real(0));

        for (int c = 0; c < channels; ++c) {
            const LayeredSurface<L>& l = *layers[static_cast<std::size_t>(c)];
            const std::size_t row = channels > 1 ? static_cast<std::size_t>(c) + 1 : 0;
            const Real w = channels > 1 ? luminance[static_cast<std::size_t>(c)] : Real(1);
            for (std::size_t j = 0; j < nodes; ++j) {
                // At mu = 0, where no light arrives and the layer answers 0, a tenth of the next node's cosine, as the
                // lobes are evaluated: a 0 there made the spline overshoot towards the next node (the albedo of an
                // empty index-matched layer 1.074 at mu = 0.067, a glass slab's 1.036 at 0.006; renderer sweep).
                const L mu = detail::node_incidence<L>(s.grid, j);
                const L in = s.entry ? l.top().smooth_interface().transmittance(mu) : L(1);
                const Real r = in > 0 ? static_cast<Real>((l.direct_reflectance(mu) + l.forward_peak_reflectance(mu)) / in) : Real(0);
                const Real t = in > 0 ? static_cast<Real>((l.direct_transmittance(mu) + l.forward_peak_transmittance(mu)) / in) : Real(0);
                s.beam_reflected[row * nodes + j] = r;
                s.beam_transmitted[row * nodes + j] = t;
                if (channels > 1) {
                    s.beam_reflected[j] += w * r;
                    s.beam_transmitted[j] += w * t;
                }
            }
        }
    }
    s.energy_error = energy_mismatch(s, layers, luminance);
    return s;
}

// TabulatedBSDF::energy_error of one side: its albedo at the nodes (mu > 0) against the layers' fluxes, weighted by
// the luminance for several channels; reflection where the subsurface reflection was tabulated (the surface's
// reflectance with it where the surface lobe was), transmission where the transmission was.
template <class Real>
template <class LayerReal>
Real TabulatedBSDF<Real>::energy_mismatch(const Side& s, const std::vector<const LayeredSurface<LayerReal>*>& layers,
                                          const std::vector<Real>& luminance) {
    const LayerOutput outputs = layers.front()->outputs();
    const bool reflection = includes(outputs, LayerOutput::subsurface_reflection);
    const bool surface = includes(outputs, LayerOutput::surface_reflection);
    const bool transmission = includes(outputs, LayerOutput::transmission);
    Real worst = 0;
    const std::vector<Real>& nodes_t = s.grid.t;
    for (std::size_t j = 1; j < 2 * nodes_t.size() - 1; ++j) {  // (the nodes, and midway between them)
        const Real mu = s.grid.cosine(j % 2 == 0 ? nodes_t[j / 2] : (nodes_t[j / 2] + nodes_t[j / 2 + 1]) / 2);
        const Albedos a = s.albedos(s.weights(mu), mu);
        LayerReal r = 0, t = 0;
        for (std::size_t c = 0; c < layers.size(); ++c) {
            const LayerReal w = layers.size() > 1 ? static_cast<LayerReal>(luminance[c]) : LayerReal(1);
            if (reflection || surface) {
                const auto flux = layers[c]->reflectance(static_cast<LayerReal>(mu));
                r += w * ((surface ? flux.surface : LayerReal(0)) + (reflection ? flux.subsurface : LayerReal(0)));
            }
            if (transmission) t += w * layers[c]->transmittance(static_cast<LayerReal>(mu));
        }
        if (reflection || surface) worst = std::fmax(worst, std::fabs(a.surface + a.reflection + a.mirror - static_cast<Real>(r)));
        if (transmission) worst = std::fmax(worst, std::fabs(a.transmission + a.straight - static_cast<Real>(t)));
    }
    return worst;
}

}  // namespace stratum
