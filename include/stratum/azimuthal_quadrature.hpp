// stratum/azimuthal_quadrature.hpp -- azimuthal Fourier coefficients and Fourier-mode operators of a
// scattering kernel on discrete ordinates (docs/physics.md section 5; Stam 2001 Appendix D with its missing
// factor w_m mu_m restored). Generic numerics: any kernel rho(mu_in -> mu_out, phi); interface_operators.hpp
// applies it to dielectric interfaces.
//
// Conventions (shared with the layer solver).
//  * Ordinates mu_1..mu_M with weights w_m come from gauss_legendre_half (sum w_m = 1); mu is the
//    absolute cosine of a direction with the macro normal, in the hemisphere it travels in.
//  * Radiance is expanded over PROPAGATION directions, L(mu, phi) = sum_k u_k(mu) cos(k phi).
//  * A kernel rho(mu_in -> mu_out, phi) is a BRDF or BTDF written in propagation terms (cosine not
//    included): phi is the azimuth of the outgoing propagation direction minus that of the incident
//    propagation direction, so specular reflection and refraction peak at phi = 0. rho is even in phi.
//  * Raw Fourier coefficients of the kernel:
//        I_k(mu_in, mu_out) = int_0^{2pi} rho(mu_in -> mu_out, phi) cos(k phi) dphi
//                           = 2 int_0^{pi} rho cos(k phi) dphi,
//    so rho(phi) = sum_k (2 - delta_k0) / (2 pi) I_k cos(k phi).
//  * The mode-k operator (an M x M row-major matrix; row n = outgoing ordinate, column m = incoming):
//        (L_k)_{n,m} = w_m mu_m I_k(mu_m, mu_n),
//    so that the mode-k outgoing radiance is L_k u_k for every k, including k = 0:
//        L_out(mu_n, phi) = int rho L_in mu_in dw_in = sum_k cos(k phi) sum_m w_m mu_m I_k(mu_m, mu_n) u_k(mu_m).
//  * Energy: the flux carried by ordinate m is 2 pi w_m mu_m u_m (mode 0), so
//        sum_n w_n mu_n (L_0)_{n,m} / (w_m mu_m) = sum_n w_n mu_n I_0(mu_m, mu_n)
//    is the Gauss-rule estimate of the hemispherical total int rho mu_out dw_out for incidence mu_m.
//    (Flux-weighted column sums; this is exact only as far as the ordinates resolve the lobe in mu.)
//  * Reciprocity shows as symmetry of L_k D^{-1}, D = diag(w_m mu_m), for a reciprocal kernel
//    (a BRDF); for a BTDF pair, T12_k D^{-1} / n_2^2 = (T21_k D^{-1})^T / n_1^2.
//
// The phi integral. rho is even in phi and, for microfacet kernels, peaked at phi = 0 with a width
// that shrinks with the roughness (a Beckmann lobe is exactly exp(kappa cos phi) times a slowly
// varying factor, see the dielectric-interface section below). The integral over [0, pi] uses a composite
// Gauss-Legendre rule of n points per panel (AzimuthalQuadrature):
//  * geometrically graded panels [0, s], [s, 2s], [2s, 4s], ... where s is the lobe width (the scale
//    on which rho changes near phi = 0), so a lobe of any width is resolved with O(n log(pi / s)) points;
//  * once a panel reaches the length h = n / (K - 1) (K modes), uniform panels of length <= h up to pi,
//    so cos((K - 1) phi) is sampled at >= 2 pi points per period (n-point Gauss-Legendre integrates
//    cos(w x) on [-1, 1] to ~1e-16 for w <= n/2, measured);
//  * panels are also split at the points where rho is not smooth (AzimuthalFeatures: for an interface,
//    the azimuth where the connecting facet reaches total internal reflection or stops refracting),
//    and integrated there in a variable t with phi - phi_b ~ t^2, which removes a square-root onset.
// The error falls exponentially in n for kernels analytic in phi; measured figures are in
// tests/test_interface_operators.cpp (the "accuracy vs phi samples" case prints a table).
// Where rho is known to be analytic in a strip around the real axis (AzimuthalFeatures::analytic_strip, no
// breakpoints), the trapezoid rule on [0, pi] takes the panels' place when it needs fewer samples: for a periodic
// analytic integrand it is exact up to aliasing, about 2 points per period of the highest mode plus the lobe's own
// bandwidth instead of 2 pi (AzimuthalQuadrature::trapezoid_intervals).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>
#include <vector>

#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "quadrature.hpp"

namespace stratum {

/// What the azimuthal rule needs to know about rho(phi) for one (mu_in, mu_out) pair: the width of its
/// peak at phi = 0 (pi or more for a kernel without one), and up to 4 points in (0, pi) where rho is not
/// smooth (a kink, or a square-root onset such as total internal reflection at the facets). Converts
/// implicitly from a width alone. `analytic_strip`, where known, lets the rule use the trapezoid rule (see
/// AzimuthalQuadrature::trapezoid_intervals): rho continued to complex phi is analytic in |Im phi| < analytic_strip
/// (0: unknown, the default). Its peak at phi = 0 is taken to be no sharper than exp(kappa cos phi) with
/// kappa = 1 / lobe_width^2 (as a Beckmann lobe is, interface_operators.hpp).
template <class Real = double>
struct AzimuthalFeatures {
    Real lobe_width = detail::pi_v<Real>;
    int break_count = 0;
    Real breaks[4] = {};
    Real analytic_strip = 0;

    AzimuthalFeatures() = default;
    AzimuthalFeatures(Real width) noexcept : lobe_width(width) {}  // NOLINT: implicit on purpose

    /// Adds a breakpoint if it lies inside (0, pi) and there is room; keeps them ascending.
    void add_break(Real phi) noexcept {
        const Real pi = detail::pi_v<Real>;
        if (!(phi > 0 && phi < pi) || break_count == 4) return;
        int i = break_count++;
        while (i > 0 && breaks[i - 1] > phi) {
            breaks[i] = breaks[i - 1];
            --i;
        }
        breaks[i] = phi;
    }
};

/// The composite Gauss-Legendre rule on [0, pi] used for every azimuthal integral (see the header
/// comment): n points per panel; panels graded geometrically from the lobe width s near phi = 0, then
/// uniform of length <= 2 pi n / (p (K - 1)) so that cos((K - 1) phi) gets >= p points per period
/// (p = points_per_period, default 2 pi). Panels are split at the breakpoints of AzimuthalFeatures, and a panel
/// ending at a breakpoint is integrated in t with phi - phi_b ~ t^2 (both ends: the cubic t^2 (3 - 2t)),
/// which turns a square-root singularity there into a smooth integrand (exponential convergence again).
/// Construction validates and tabulates the reference rule; iteration over the nodes allocates nothing.
template <class Real = double>
class AzimuthalQuadrature {
public:
    /// points_per_panel >= 2 (default 24: measured <= 1e-12 relative on the rough-interface kernels at 48 modes,
    /// up to 1e-7 with one mode, whose rule has one panel; ~1e-15 on analytic lobes; 16 gives ~1e-8 with ~10%
    /// fewer samples);
    /// points_per_period in [2, 1e6]: sampling density of cos((K - 1) phi) in the uniform panels; the default
    /// 2 pi gives panels of length n / (K - 1), on which n-point Gauss integrates cos((K - 1) phi) to ~1e-16
    /// (it is exact to degree 2n - 1; measured: 1e-16 at (K - 1) h / 2 = n / 2, 3e-11 at 3n / 4).
    explicit AzimuthalQuadrature(int points_per_panel = 24,
                                 Real points_per_period = detail::two_pi_v<Real>)
        : points_per_period_(detail::require_closed("points_per_period", points_per_period, Real(2), Real(1e6))) {
        detail::require_count("points_per_panel", points_per_panel, 2);
        const Quadrature<long double> q = gauss_legendre<long double>(points_per_panel);
        for (std::size_t i = 0; i < q.size(); ++i) {
            nodes_.push_back(static_cast<Real>((1 + q.nodes[i]) / 2));
            weights_.push_back(static_cast<Real>(q.weights[i] / 2));
        }
    }

    int points_per_panel() const noexcept { return static_cast<int>(nodes_.size()); }
    Real points_per_period() const noexcept { return points_per_period_; }

    /// Smallest lobe width honoured; narrower widths are clamped to it (phi resolution ~1e-10 rad).
    static constexpr Real min_width() noexcept { return Real(1e-10); }

    /// Calls f(a, b, singular_a, singular_b) for each panel [a, b] of the rule, in order. The breakpoints cut
    /// [0, pi] into segments; in each, the panel starting at phi has length clamp(phi, s, h) (geometric
    /// grading towards phi = 0 down to the lobe width s, capped at h), and the last one or two panels of a
    /// segment share its remainder equally, so no panel ends closer to a breakpoint than its own length.
    template <class F>
    void for_each_panel(const AzimuthalFeatures<Real>& features, int modes, F&& f) const
        noexcept(noexcept(f(Real(0), Real(1), false, false))) {
        const Real pi = detail::pi_v<Real>;
        const Real n = static_cast<Real>(nodes_.size());
        const Real h = modes > 1 ? std::fmin(pi, 2 * pi * n / (points_per_period_ * static_cast<Real>(modes - 1))) : pi;
        Real s = features.lobe_width;
        if (!(s > min_width())) s = min_width();  // also catches NaN
        Real c = 0;
        for (int segment = 0; segment <= features.break_count; ++segment) {
            const bool break_at_end = segment < features.break_count;
            const Real d = break_at_end ? features.breaks[segment] : pi;
            if (!(d > c)) continue;  // a repeated breakpoint
            const bool break_at_start = c > 0;
            Real a = c;
            bool first = true;
            for (;;) {
                const Real len = std::fmin(std::fmax(a, s), h);
                if (a + 2 * len < d) {
                    f(a, a + len, first && break_at_start, false);
                    a += len;
                    first = false;
                    continue;
                }
                const Real rest = d - a;
                const int count = std::max(1, static_cast<int>(std::ceil(rest / h - Real(1e-6))));
                const Real step = rest / static_cast<Real>(count);
                for (int j = 0; j < count; ++j)
                    f(a + step * static_cast<Real>(j), j + 1 == count ? d : a + step * static_cast<Real>(j + 1),
                      first && j == 0 && break_at_start, j + 1 == count && break_at_end);
                break;
            }
            c = d;
        }
    }

    /// The number of intervals N of the trapezoid rule on [0, pi] (nodes j pi / N, j = 0..N, the ends at half
    /// weight) when it serves these features and K modes with fewer samples than the panels, else 0. For a rho that
    /// is even, 2 pi-periodic and analytic in a strip (no breakpoints, analytic_strip = a > 0), the rule returns
    /// a_k + a_{2N-k} + a_{2N+k} + ... for the coefficient a_k: it is exact but for the aliased coefficients of
    /// modes 2N - K + 1 and up. Those fall like e^{-a j} (the strip) and, for the peak exp(kappa cos phi) (width
    /// w = 1/sqrt(kappa)), like I_j(kappa) / I_0(kappa) <= exp(kappa (cosh b - 1) - j b) for any b > 0 (its bound on
    /// the line Im phi = b), least at b = asinh(j / kappa): e^{-j^2 / (2 kappa)} for j << kappa, (e kappa / 2j)^j
    /// for j >> kappa (peak_bandwidth). Both below e^{-D} beyond J = J_peak + D / a, so N = ceil((K - 1 + J) / 2).
    /// D = min(36, 1.5 n) for n points per panel
    /// (e^{-36} ~ 2e-16; the panels' own accuracy falls with n likewise). Measured on the rough-interface kernels
    /// against the panels at 32 points (sigma 0.01 to 10, n 1 | 1.0001 to 1 | 4 and 1.33 | 1, every shadowing form,
    /// M 3 to 40): within 1.8e-13 of the largest coefficient, where the panels at 24 points are within 4e-12
    /// (tests/test_interface_operators.cpp). A narrow peak or a strip narrower than ~1 (grazing pairs) needs more
    /// samples than the graded panels: those stay on the panels.
    int trapezoid_intervals(const AzimuthalFeatures<Real>& features, int modes) const noexcept {
        const Real a = features.analytic_strip, w = features.lobe_width;
        if (features.break_count > 0 || !(a > 0) || !(w > 0)) return 0;
        const Real digits = std::fmin(Real(36), Real(1.5) * static_cast<Real>(nodes_.size()));
        const Real bandwidth = peak_bandwidth(1 / (w * w), digits) + digits / a;
        const Real n = std::ceil((static_cast<Real>(std::max(modes, 1) - 1) + bandwidth) / 2);
        int panels = 0;
        for_each_panel(features, modes, [&](Real, Real, bool, bool) noexcept { ++panels; });
        const Real graded = static_cast<Real>(panels) * static_cast<Real>(nodes_.size());
        return n + 1 < graded ? std::max(1, static_cast<int>(n)) : 0;
    }

    /// Calls f(phi, weight) for every node of the rule on [0, pi] (weights sum to pi).
    template <class F>
    void for_each_node(const AzimuthalFeatures<Real>& features, int modes, F&& f) const noexcept(noexcept(f(Real(0), Real(1)))) {
        if (const int intervals = trapezoid_intervals(features, modes)) {
            const Real pi = detail::pi_v<Real>, h = pi / static_cast<Real>(intervals);
            for (int j = 0; j <= intervals; ++j)
                f(j == intervals ? pi : h * static_cast<Real>(j), (j == 0 || j == intervals) ? h / 2 : h);
            return;
        }
        for_each_panel(features, modes, [&](Real a, Real b, bool singular_a, bool singular_b) {
            const Real len = b - a;
            for (std::size_t i = 0; i < nodes_.size(); ++i) {
                const Real t = nodes_[i], w = len * weights_[i];
                if (singular_a && singular_b)  // phi = a + len t^2 (3 - 2t)
                    f(a + len * t * t * (3 - 2 * t), w * 6 * t * (1 - t));
                else if (singular_a)  // phi = a + len t^2
                    f(a + len * t * t, w * 2 * t);
                else if (singular_b)  // phi = b - len (1 - t)^2
                    f(b - len * (1 - t) * (1 - t), w * 2 * (1 - t));
                else
                    f(a + len * t, w);
            }
        });
    }

    /// Number of phi samples the rule uses for these features and K modes.
    int sample_count(const AzimuthalFeatures<Real>& features, int modes) const noexcept {
        if (const int intervals = trapezoid_intervals(features, modes)) return intervals + 1;
        int panels = 0;
        for_each_panel(features, modes, [&](Real, Real, bool, bool) noexcept { ++panels; });
        return panels * points_per_panel();
    }

private:
    // The J at which the bound above on I_j(kappa) / I_0(kappa), e^{-g(J)} with g(J) = J asinh(J / kappa) -
    // kappa (sqrt(1 + (J / kappa)^2) - 1) (increasing and convex in J, g' = asinh(J / kappa)), reaches e^{-D}: Newton's
    // method from max(sqrt(2 D kappa), D), the roots of the two asymptotes. g being convex, an iterate below the root
    // (the start, for kappa above ~14) is followed by one above it, and from there the iterates decrease to the root:
    // the last one is never below it (stopped at a step of 1e-3 J).
    static Real peak_bandwidth(Real kappa, Real digits) noexcept {
        if (!(kappa > 0)) return Real(0);
        Real j = std::fmax(std::sqrt(2 * digits * kappa), digits);
        for (int it = 0; it < 16; ++it) {
            const Real x = j / kappa, g = j * std::asinh(x) - kappa * (std::sqrt(1 + x * x) - 1);
            const Real step = (g - digits) / std::asinh(x);
            j -= step;
            if (step >= 0 && !(step > Real(1e-3) * j)) break;
        }
        return j;
    }

    Real points_per_period_;
    std::vector<Real> nodes_, weights_;  // n-point Gauss-Legendre on [0, 1]
};

namespace detail {

// Calls a kernel with (mu_in, mu_out, cos_phi, sin_phi) when it accepts four arguments, else with
// (mu_in, mu_out, cos_phi). The sine lets a kernel form 1 - cos(phi) = sin^2 / (1 + cos) without
// cancellation (needed for lobes narrower than ~1e-4 rad).
template <class Real, class Kernel>
Real call_kernel(const Kernel& rho, Real mu_in, Real mu_out, Real c, Real s) {
    if constexpr (std::is_invocable_v<const Kernel&, Real, Real, Real, Real>)
        return static_cast<Real>(rho(mu_in, mu_out, c, s));
    else
        return static_cast<Real>(rho(mu_in, mu_out, c));
}

// Accumulates out[k] += sum_j f_j cos(k phi_j), k = 0..modes-1, over the samples of an azimuthal rule, a block of
// kLanes samples at a time: the blocks' recurrences are independent (the sum over k of a single sample is a chain
// of dependent multiplications, which bounded the old loop by latency, not by arithmetic).
// cos(k phi) comes from Reinsch's form of the Chebyshev recurrence, stable where the plain one
// (T_k+1 = 2x T_k - T_k-1, x = cos phi) loses ~k^2 ulp near x = +-1: with S_k = sigma^k T_k, sigma = sign(x),
//   S_k+1 = S_k + D_k+1,   D_k+1 = D_k + mu S_k,   S_0 = 1, D_1 = mu / 2,   mu = 2 (|x| - 1) = -2 sin^2 phi / (1 + |x|),
// the last form free of cancellation (measured: within 1.2 k ulp of cos(k phi) for k < 1024, phi random and within
// 1e-12 of 0 and pi; the plain recurrence loses up to 285 k ulp there). The samples are
// kept in two blocks by the sign of x, so the lanes of a block share sigma.
template <class Real>
class CosineMoments {
public:
    static constexpr int kLanes = 8;

    CosineMoments(int modes, Real* out) noexcept : modes_(modes), out_(out) {
        for (int k = 0; k < modes; ++k) out[k] = Real(0);
    }
    ~CosineMoments() { flush_all(); }
    CosineMoments(const CosineMoments&) = delete;
    CosineMoments& operator=(const CosineMoments&) = delete;

    // Adds f cos(k phi) for the sample with c = cos(phi), s = sin(phi). An infinite (or NaN) f is added at once by
    // the rotation recurrence, as f cos(k phi) (the blocks would turn inf into NaN: inf x 0, inf - inf).
    void add(Real f, Real c, Real s) noexcept {
        if (!(std::fabs(f) <= std::numeric_limits<Real>::max())) {
            Real ck = 1, sk = 0;
            for (int k = 0; k < modes_; ++k) {
                out_[k] += f * ck;
                const Real next = ck * c - sk * s;
                sk = sk * c + ck * s;
                ck = next;
            }
            return;
        }
        const int side = c < 0 ? 1 : 0;
        Block& b = blocks_[side];
        b.f[b.count] = f;
        b.mu[b.count] = -2 * s * s / (1 + std::fabs(c));
        if (++b.count == kLanes) flush(side);
    }

    // Adds the pending samples to out (the destructor does it too).
    void flush_all() noexcept {
        flush(0);
        flush(1);
    }

private:
    struct Block {
        Real f[kLanes] = {}, mu[kLanes] = {};
        int count = 0;
    };

    void flush(int side) noexcept {
        Block& b = blocks_[side];
        if (b.count == 0 || modes_ < 1) {  // (modes < 1: nothing to write)
            b.count = 0;
            return;
        }
        for (int l = b.count; l < kLanes; ++l) b.f[l] = b.mu[l] = Real(0);
        Real S[kLanes], D[kLanes];
        Real sum = 0;
        for (int l = 0; l < kLanes; ++l) {
            S[l] = b.f[l];
            D[l] = b.f[l] * b.mu[l] / 2;
            sum += S[l];
        }
        out_[0] += sum;
        for (int k = 1; k < modes_; ++k) {
            for (int l = 0; l < kLanes; ++l) S[l] += D[l];
            Real t = 0;
            for (int l = 0; l < kLanes; ++l) t += S[l];
            out_[k] += (side == 1 && (k & 1)) ? -t : t;
            for (int l = 0; l < kLanes; ++l) D[l] += b.mu[l] * S[l];
        }
        b.count = 0;
    }

    int modes_;
    Real* out_;
    Block blocks_[2];
};

}  // namespace detail

/// Raw Fourier coefficients I_k(mu_in, mu_out) = int_0^{2pi} rho(mu_in -> mu_out, phi) cos(k phi) dphi
/// for k = 0..modes-1, written to out[0..modes-1], at ANY pair of cosines (true incidence/viewing
/// angles, not only ordinates). rho is called as rho(mu_in, mu_out, cos_phi[, sin_phi]) with phi in
/// [0, pi]; features gives the phi scale of its peak at phi = 0 (pi, or anything larger, for a kernel
/// without a peak) and its non-smooth points, if any. Allocation-free; cos(k phi) from Reinsch's recurrence
/// (detail::CosineMoments; error ~ k ulp).
template <class Real, class Kernel>
void azimuthal_coefficients(const Kernel& rho, Real mu_in, Real mu_out,
                            const AzimuthalFeatures<detail::non_deduced_t<Real>>& features,
                            int modes, Real* out, const AzimuthalQuadrature<detail::non_deduced_t<Real>>& rule) {
    detail::CosineMoments<Real> moments(modes, out);
    rule.for_each_node(features, modes, [&](Real phi, Real weight) {
        const Real c = std::cos(phi), s = std::sin(phi);
        const Real f = 2 * weight * detail::call_kernel(rho, mu_in, mu_out, c, s);
        if (f != Real(0)) moments.add(f, c, s);
    });
}

/// K Fourier-mode operators on M ordinates: mode k is an M x M row-major matrix,
/// (L_k)_{n,m} = w_m mu_m I_k(mu_m, mu_n) (row n = outgoing ordinate, column m = incoming).
template <class Real = double>
struct FourierOperators {
    int size = 0;             ///< M, the number of ordinates
    int modes = 0;            ///< K, the number of azimuthal modes (k = 0..K-1)
    std::vector<Real> data;   ///< K blocks of M * M, mode-major

    FourierOperators() = default;
    FourierOperators(int m, int k)
        : size(m), modes(k), data(static_cast<std::size_t>(m) * static_cast<std::size_t>(m) * static_cast<std::size_t>(k), Real(0)) {}

    /// Pointer to the row-major M x M block of mode k.
    Real* mode(int k) noexcept { return data.data() + block(k); }
    const Real* mode(int k) const noexcept { return data.data() + block(k); }
    /// (L_k)_{n,m}.
    Real& operator()(int k, int n, int m) noexcept { return data[index(k, n, m)]; }
    Real operator()(int k, int n, int m) const noexcept { return data[index(k, n, m)]; }

    /// The identity in every mode (an index-matched, non-scattering boundary).
    static FourierOperators identity(int m, int k) {
        FourierOperators op(m, k);
        for (int q = 0; q < k; ++q)
            for (int i = 0; i < m; ++i) op(q, i, i) = Real(1);
        return op;
    }

private:
    std::size_t block(int k) const noexcept {
        return static_cast<std::size_t>(k) * static_cast<std::size_t>(size) * static_cast<std::size_t>(size);
    }
    std::size_t index(int k, int n, int m) const noexcept {
        return block(k) + static_cast<std::size_t>(n) * static_cast<std::size_t>(size) + static_cast<std::size_t>(m);
    }
};

/// Builds the K mode operators of a kernel on the given ordinates (a gauss_legendre_half rule).
/// features(mu_in, mu_out) returns the AzimuthalFeatures of each pair, or just the phi width of the
/// kernel's peak (pi or more for a kernel without one). Cost: M^2 pairs x (samples x K) multiply-adds.
/// Throws std::invalid_argument for modes < 1 or an empty rule.
template <class Real, class Kernel, class Features>
FourierOperators<Real> fourier_operators(const Kernel& rho, const Features& features, const Quadrature<Real>& ordinates,
                                         int modes, const AzimuthalQuadrature<Real>& rule = AzimuthalQuadrature<Real>()) {
    detail::require_count("modes", modes, 1);
    detail::require_count("ordinates", static_cast<int>(ordinates.size()), 1);
    const int m_count = static_cast<int>(ordinates.size());
    FourierOperators<Real> op(m_count, modes);
    std::vector<Real> coefficients(static_cast<std::size_t>(modes));
    for (int m = 0; m < m_count; ++m) {
        const Real mu_in = ordinates.nodes[static_cast<std::size_t>(m)];
        const Real column_weight = ordinates.weights[static_cast<std::size_t>(m)] * mu_in;
        for (int n = 0; n < m_count; ++n) {
            const Real mu_out = ordinates.nodes[static_cast<std::size_t>(n)];
            const AzimuthalFeatures<Real> f = features(mu_in, mu_out);
            azimuthal_coefficients(rho, mu_in, mu_out, f, modes, coefficients.data(), rule);
            for (int k = 0; k < modes; ++k) op(k, n, m) = column_weight * coefficients[static_cast<std::size_t>(k)];
        }
    }
    return op;
}

}  // namespace stratum
