// stratum/dipole.hpp -- the diffusion dipole of Jensen et al. 2001 as production uses it (Hery,
// "Implementing a skin BSSRDF"): the radial profile R_d(r), the total diffuse reflectance R_d(alpha')
// and its inverse, the parameter conversions, and radial importance sampling.
//
// Units. Lengths and coefficients use any one length unit, consistently: sigma_a and sigma_s' in 1/unit,
// r, z_r, z_v and the diffuse mean free path in units, R_d(r) in 1/unit^2 (a density over the surface).
// Jensen's measured coefficients are in 1/mm, so r is then in mm.
//
// Refractive index. eta = n_medium / n_outside (> 1 for skin in air; 1.3 in Jensen and Hery), the same
// eta as fresnel_diffuse_reflectance. Renderers disagree on this side: Mitsuba passes 1/eta to its F_dr.
//
// The model (docs/physics.md section 8):
//   sigma_t' = sigma_a + sigma_s',  alpha' = sigma_s' / sigma_t',  sigma_tr = sqrt(3 sigma_a sigma_t'),
//   z_r = 1 / sigma_t',  z_v = z_r (1 + 4A/3),  A = (1 + F_dr) / (1 - F_dr),
//   d_r = sqrt(r^2 + z_r^2),  d_v = sqrt(r^2 + z_v^2),
//   R_d(r) = alpha' / (4 pi) [z_r (sigma_tr d_r + 1) e^{-sigma_tr d_r} / d_r^3
//                            + z_v (sigma_tr d_v + 1) e^{-sigma_tr d_v} / d_v^3],
//   R_d    = int_0^inf R_d(r) 2 pi r dr = (alpha' / 2) (1 + e^{-(4/3) A s}) e^{-s},  s = sqrt(3 (1 - alpha')).
// (Each term integrates in closed form: with d = sqrt(r^2 + z^2), r dr = d dd and
// int_z^inf z (sigma d + 1) e^{-sigma d} / d^2 dd = e^{-sigma z}; and sigma_tr z_r = s.)
// s = sigma_tr / sigma_t' is the natural variable of the inversion: R_d is analytic in s on [0, sqrt(3)]
// with a nonzero slope at both ends, while 1 - alpha' = s^2 / 3 vanishes quadratically as R_d -> 1.
//
// F_dr and its default. A needs the internal diffuse Fresnel reflectance F_dr (fresnel.hpp). Two choices:
//   DiffuseFresnel::jensen_fit (the default): the Egan-Hilgeman fit, as Jensen 2001 and Hery's shader use it;
//     cheap, so the (alpha', eta) functions below cost a few flops for it; meant for eta >= 1 only (below 1 the
//     fit is negative and A meaningless: rejected). A = 2.602064 at eta = 1.3.
//   DiffuseFresnel::exact: the exact hemispherical integral; valid for any eta > 0 (A = 1 at eta = 1);
//     costs ~10^3 Fresnel evaluations per call, so build a DipoleBoundary once and reuse it.
// The default follows the published model, so that published values (and renders) are reproduced. The
// difference is small for skin-like indices (tests/test_dipole.cpp checks these figures):
//   eta = 1.3: A = 2.602064 (fit) vs 2.600079 (exact); R_d(alpha') differs by <= 1.1e-4 absolute, 2.1e-4 relative;
//   eta = 1.5: A = 3.959497 vs 3.954736; <= 1.9e-4 absolute, 3.4e-4 relative;
//   eta = 1:   A = 1.003205 vs 1 (the fit's F_dr(1) = 0.0016); <= 3.2e-4 absolute, 8.9e-4 relative;
//   eta = 2.5: A = 15.75 vs 15.06; <= 7.8e-3 absolute, 1.2e-2 relative (prefer exact for high indices).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include "detail/config.hpp"
#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "fresnel.hpp"
#include "lambert_w.hpp"

namespace stratum {

/// Which internal diffuse Fresnel reflectance F_dr enters A = (1 + F_dr) / (1 - F_dr).
enum class DiffuseFresnel {
    jensen_fit,  ///< Egan-Hilgeman fit (Jensen 2001, Hery); eta in [1, 3] only. The default.
    exact,       ///< exact hemispherical average (fresnel_diffuse_reflectance); eta in [1e-4, 1e4].
};

/// The boundary of a semi-infinite diffusing medium: its relative index eta = n_medium / n_outside and the
/// dipole's boundary coefficient A = (1 + F_dr(eta)) / (1 - F_dr(eta)). Build it once (the exact F_dr is
/// an integral); the noexcept overloads below take it.
template <class Real = double>
struct DipoleBoundary {
    Real eta = 1;
    Real A = 1;

    /// Throws std::invalid_argument unless eta is in [1, 3] (jensen_fit: the range where its error is stated;
    /// beyond ~3.8 the fit exceeds 1 and A turns negative, which made R_d negative) or in [1e-4, 1e4] (exact).
    static DipoleBoundary from_eta(Real eta, DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
        if (model == DiffuseFresnel::jensen_fit) {
            if (!(eta >= 1 && eta <= 3))
                detail::throw_out_of_range("eta", eta, "[1, 3] for the Jensen F_dr fit (DiffuseFresnel::exact "
                                                       "accepts [0.0001, 10000])");
            const Real f = fresnel_diffuse_reflectance_fit(eta);
            return {eta, (1 + f) / (1 - f)};
        }
        detail::require_refractive_index("eta", eta);
        // In the wide type: for float, 1 - F_dr (~1e-6 at eta = 1000) rounded to 0 and A to +inf, whose profile
        // and inversion were NaN (found by review); A itself fits (at most ~1e9, at eta = 1e4).
        using W = detail::wide_t<Real>;
        const W f = fresnel_diffuse_reflectance(static_cast<W>(eta));
        return {eta, static_cast<Real>((1 + f) / (1 - f))};
    }
};

namespace detail {
/// A boundary given as it is (DipoleBoundary is an aggregate): eta a refractive index ratio and A = (1 + F_dr) /
/// (1 - F_dr) >= 1 and finite (F_dr in [0, 1)). A = -5 gave a total reflectance of 9.04 and A = NaN NaN (found by a
/// review sweep); A = +inf (F_dr = 1), which from_eta gave for float at eta = 1000 before it computed in double,
/// makes R_d jump from 1 at alpha' = 1 to 1/2 just below it (no inversion), and NaN profiles and inversions (found
/// by review). Throws std::invalid_argument naming the field.
template <class Real>
const DipoleBoundary<Real>& require_dipole_boundary(const DipoleBoundary<Real>& b) {
    require_refractive_index("boundary.eta", b.eta);
    if (!(b.A >= 1 && b.A <= std::numeric_limits<Real>::max())) throw_out_of_range("boundary.A", b.A, "[1, inf)");
    return b;
}
}  // namespace detail

/// A = (1 + F_dr) / (1 - F_dr) for eta = n_medium / n_outside. Throws as DipoleBoundary::from_eta.
template <class Real>
Real dipole_A(Real eta, DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
    return DipoleBoundary<Real>::from_eta(eta, model).A;
}

namespace detail {

/// The total diffuse reflectance as a function of s = sqrt(3 (1 - alpha')), and 1 - R_d, each accurate
/// in a relative sense (1 - R_d through expm1, without cancellation, for R_d near 1), with the first two
/// s-derivatives of R_d. k = 4A/3.
///   R_d = P(s) E(s),  P = 1 - s^2/3,  E = (e^{-s} + e^{-(k+1)s}) / 2,
///   1 - R_d = (1 - E) + (s^2/3) E,  1 - E = -(expm1(-s) + expm1(-(k+1)s)) / 2.
template <class Real>
struct ReflectanceInS {
    Real R, one_minus_R, dR, d2R;
    Real E, dE, d2E;
};

template <class Real>
STRATUM_HOST_DEVICE ReflectanceInS<Real> reflectance_in_s(Real s, Real k) noexcept {
    // expm1 only where 1 - e^{-x} needs relative accuracy (small x); elsewhere exp is cheaper and e - 1 loses
    // nothing (exact for e >= 1/2, Sterbenz).
    Real e1, e2, m1, m2;
    if ((k + 1) * s < Real(0.5)) {
        m1 = std::expm1(-s), m2 = std::expm1(-(k + 1) * s);
        e1 = 1 + m1, e2 = 1 + m2;
    } else {
        e1 = std::exp(-s), e2 = std::exp(-(k + 1) * s);
        m1 = e1 - 1, m2 = e2 - 1;
    }
    const Real E = (e1 + e2) / 2, one_minus_E = -(m1 + m2) / 2;
    const Real ke2 = (k + 1) * e2;  // (then times k + 1 again: (k + 1)^2 alone overflows float from A ~ 1e19)
    const Real dE = -(e1 + ke2) / 2, d2E = (e1 + (k + 1) * ke2) / 2;
    const Real s2_3 = s * s / 3, P = (1 - s2_3);
    return {P * E, one_minus_E + s2_3 * E, -Real(2) / 3 * s * E + P * dE,
            -Real(2) / 3 * E - Real(4) / 3 * s * dE + P * d2E, E, dE, d2E};
}

/// R_d = (alpha'/2) (1 + e^{-(4/3) A s}) e^{-s} with s = sqrt(3 (1 - alpha')) given: where s is known from the
/// coefficients (s^2 = 3 sigma_a / sigma_t'), 1 - alpha' need not be resolved (in float it is not near alpha' = 1).
template <class Real>
STRATUM_HOST_DEVICE Real total_reflectance_in_s(Real alpha_prime, Real s, Real A) noexcept {
    return alpha_prime / 2 * (1 + std::exp(-Real(4) / 3 * A * s)) * std::exp(-s);
}

}  // namespace detail

/// Total diffuse reflectance R_d(alpha') = (alpha'/2) (1 + e^{-(4/3) A s}) e^{-s}, s = sqrt(3 (1 - alpha')),
/// for the given boundary. alpha' is clamped to [0, 1] (NaN gives 0). Monotone from R_d(0) = 0 to R_d(1) = 1.
template <class Real>
STRATUM_HOST_DEVICE Real total_diffuse_reflectance(Real alpha_prime, const DipoleBoundary<Real>& boundary) noexcept {
    if (!(alpha_prime > 0)) return Real(0);
    if (!(alpha_prime < 1)) return Real(1);
    return detail::total_reflectance_in_s(alpha_prime, std::sqrt(3 * (1 - alpha_prime)), boundary.A);
}

/// Total diffuse reflectance for alpha' in [0, 1] and eta = n_medium / n_outside (see DiffuseFresnel).
/// Throws std::invalid_argument for alpha' outside [0, 1] (or NaN) and for an invalid eta.
template <class Real>
Real total_diffuse_reflectance(Real alpha_prime, Real eta, DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
    detail::require_closed("alpha_prime", alpha_prime, Real(0), Real(1));
    return total_diffuse_reflectance(alpha_prime, DipoleBoundary<Real>::from_eta(eta, model));
}

namespace detail {

/// The inversion proper: s = sqrt(3 (1 - alpha')) (with its own relative accuracy, which alpha' near 1 cannot
/// carry) and alpha'. See alpha_prime_from_reflectance.
template <class Real>
struct InverseReflectance {
    Real s, alpha_prime;
};

template <class Real>
STRATUM_HOST_DEVICE InverseReflectance<Real> invert_reflectance(Real Rd, const DipoleBoundary<Real>& boundary) noexcept {
    if (!(Rd > 0)) return {std::sqrt(Real(3)), Real(0)};
    if (!(Rd < 1)) return {Real(0), Real(1)};
    constexpr Real eps = std::numeric_limits<Real>::epsilon();
    const Real sqrt3 = std::sqrt(Real(3));
    const Real k = Real(4) / 3 * boundary.A;
    const Real t = 1 - Rd;  // exact for Rd >= 1/2
    const bool upper = Rd >= Real(0.5);
    // Bounds (R_d is convex): tangent at s = 0, R_d >= 1 - (k + 2) s / 2; tangent at s = sqrt(3),
    // R_d >= m (sqrt(3) - s) with m = -R_d'(sqrt(3)) = (2 / sqrt(3)) E(sqrt(3)); chord, R_d <= 1 - s / sqrt(3).
    const Real e_sqrt3 = std::exp(-sqrt3);  // a constant
    const Real m = e_sqrt3 * (1 + std::exp(-k * sqrt3)) / sqrt3;
    const Real a = 2 / (k + 2);
    const Real lo = std::fmax(a * t, sqrt3 - Rd / m);
    const Real hi = std::fmin(sqrt3 * t, sqrt3);
    // Start: the rational s ~ t (a + b t) / (1 + c t), t = 1 - R_d, with the exact values and slopes at both
    // ends (s = 0, ds/dt = a at t = 0; s = sqrt(3), ds/dt = 1/m at t = 1): within ~0.05-0.08 of the root
    // in s for A in [1, 16], ten times closer than the tangents.
    const Real c = (1 / m - 2 * sqrt3 + a) / (sqrt3 - 1 / m), b = sqrt3 * (1 + c) - a;
    Real s = std::fmin(std::fmax(t * (a + b * t) / (1 + c * t), lo), hi);
    // Halley converges cubically: after a step of size d the error is ~ d^3, so stop once (d / s)^3 < eps / 4096.
    // Far from the root its correction h = newton R'' / (2 R') can be huge: with k s >> 1 the start lies far right
    // of a root near s ~ t / k, where e^{-(k+1) s} is negligible in R but (k + 1)^2 e^{-(k+1) s} dominates R'', and
    // Halley's steps shrank s by ~10% each, 12 of them leaving R_d 0.37 off at A = 3.8e11 (double, eta 1e4) and 0.13
    // at A = 3.8e5 (float, eta 300; found by review). Newton's step is taken there instead: from the right of the
    // convex R it lands left of the root (clamped to lo at worst), from where it climbs monotonically.
    constexpr Real tol3 = eps / 4096;
    Real E = 1;  // E at the final s by a Taylor step from the last evaluation (error ~ E''' d^3 / 6 < eps)
    for (int iter = 0; iter < 64; ++iter) {
        const auto r = detail::reflectance_in_s(s, k);
        const Real f = upper ? t - r.one_minus_R : r.R - Rd;
        const Real newton = f / r.dR, h = newton * r.d2R / (2 * r.dR);
        const bool halley = std::fabs(h) < Real(0.5);
        Real next = s - (halley ? newton / (1 - h) : newton);
        if (!(next >= lo && next <= hi)) next = s - newton;  // Newton from a convex function's left stays inside
        next = std::fmin(std::fmax(next, lo), hi);
        const Real delta = next - s, d = std::fabs(delta);
        E = r.E + delta * (r.dE + delta / 2 * r.d2E);
        s = next;
        if ((halley && d * d * d <= tol3 * s * s * s) || d <= eps * s) break;
    }
    if (s * s < Real(1.5)) return {s, 1 - s * s / 3};  // alpha' > 1/2
    // alpha' <= 1/2: alpha' = Rd / E(s) keeps relative accuracy as Rd -> 0 (s is then near sqrt(3)).
    return {s, std::fmin(Rd / E, Real(1))};
}

}  // namespace detail

/// The inverse of total_diffuse_reflectance: the alpha' in [0, 1] with R_d(alpha') = Rd, for the given
/// boundary. Rd is clamped to [0, 1] (NaN gives 0).
///
/// Method: solve R_d(s) = Rd for s = sqrt(3 (1 - alpha')) in [0, sqrt(3)], where R_d is convex and
/// decreasing with a nonzero slope at both ends, so the problem is well conditioned everywhere. A rational
/// start matching the values and slopes at both ends, kept inside the bracket of the tangent and chord
/// bounds; Halley's iteration (cubic) then takes 2-3 steps (2 exponentials each). The residual is formed as
/// (1 - Rd) - (1 - R_d(s)) for Rd >= 1/2, where both are exact or accurate, so s keeps its relative
/// accuracy as Rd -> 1 (where 1 - alpha' = s^2/3 ~ (1 - Rd)^2 falls below the resolution of alpha' near 1;
/// Dipole::from_reflectance builds sigma_a = sigma_t' s^2 / 3 from s, not from 1 - alpha'); alpha' itself
/// comes from Rd / E(s) for alpha' < 1/2, so it keeps relative accuracy as Rd -> 0.
/// Accuracy (tests): within 3e-16 absolute of the mpmath root over [0, 1] in double (1e-15 asserted), and
/// within 8 eps relative for alpha' < 1/2. Cost: 2-3 Halley steps, 2 exponentials each, plus one exp.
template <class Real>
STRATUM_HOST_DEVICE Real alpha_prime_from_reflectance(Real Rd, const DipoleBoundary<Real>& boundary) noexcept {
    return detail::invert_reflectance(Rd, boundary).alpha_prime;
}

/// The inverse for Rd in [0, 1] and eta = n_medium / n_outside (see DiffuseFresnel). Throws
/// std::invalid_argument for Rd outside [0, 1] (or NaN) and for an invalid eta.
template <class Real>
Real alpha_prime_from_reflectance(Real Rd, Real eta, DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
    detail::require_closed("Rd", Rd, Real(0), Real(1));
    return alpha_prime_from_reflectance(Rd, DipoleBoundary<Real>::from_eta(eta, model));
}

/// The fast path of the inversion: alpha' tabulated for one boundary at construction and interpolated by
/// cubic Hermite polynomials with the exact derivative at every node.
///
/// The grid is uniform in y = sqrt(R_d), not in R_d: alpha'(R_d) is analytic on [0, 1] but has a complex
/// singularity where dR_d/dalpha' = 0 (alpha' = -2.0, R_d = -0.050 at eta = 1.3), close to R_d = 0, so a
/// grid uniform in R_d converges slowly (measured 6.8e-11 with 2001 nodes at eta = 1.3). In y that
/// singularity sits 0.22 away (on the imaginary axis) and the Hermite error, ~ h^4, is far smaller; the
/// lookup costs one sqrt.
/// Maximum absolute error in double, stated and tested (tests/test_dipole.cpp: 2e5 points; eta in
/// {1, 1.3, 1.5, 2.5}, both F_dr models): 2001 nodes (the default, Hery's table size) <= 7e-13 (measured
/// 4.3e-13 at eta = 1.3, 6.1e-13 at 2.5); 513 nodes <= 1.6e-10; 129 nodes <= 4e-8. The same 2001 nodes
/// uniform in R_d would give 6.8e-11.
/// max_error() returns the error measured at construction at every interval's midpoint, where the Hermite
/// error peaks. In float the error is that of float rounding (<= 1e-6, measured 2.3e-7).
template <class Real = double>
class AlphaPrimeTable {
public:
    /// Throws std::invalid_argument for an invalid eta or size < 2.
    explicit AlphaPrimeTable(Real eta, DiffuseFresnel model = DiffuseFresnel::jensen_fit, int size = 2001)
        : AlphaPrimeTable(DipoleBoundary<Real>::from_eta(eta, model), size) {}

    explicit AlphaPrimeTable(const DipoleBoundary<Real>& boundary, int size = 2001)
        : boundary_(detail::require_dipole_boundary(boundary)) {
        detail::require_count("size", size, 2);
        const auto n = static_cast<std::size_t>(size);
        scale_ = static_cast<Real>(n - 1);
        value_.resize(n);
        slope_.resize(n);
        const Real k = Real(4) / 3 * boundary.A, h = 1 / scale_;
        for (std::size_t i = 0; i < n; ++i) {
            const Real y = static_cast<Real>(i) * h;
            const Real a = i + 1 == n ? Real(1) : alpha_prime_from_reflectance(y * y, boundary);
            // d alpha' / dy = 2y (d alpha'/ds) / (dR_d/ds) = 2y (-2s/3) / R_d'(s); 0 at both ends.
            const Real s = std::sqrt(3 * (1 - a));
            value_[i] = a;
            slope_[i] = h * 2 * y * (-Real(2) / 3 * s) / detail::reflectance_in_s(s, k).dR;
        }
        max_error_ = 0;
        for (std::size_t i = 0; i + 1 < n; ++i) {
            const Real y = (static_cast<Real>(i) + Real(0.5)) * h;
            const Real exact = alpha_prime_from_reflectance(y * y, boundary);
            max_error_ = std::fmax(max_error_, std::fabs((*this)(y * y) - exact));
        }
    }

    /// alpha'(Rd); Rd clamped to [0, 1] (NaN gives 0).
    Real operator()(Real Rd) const noexcept {
        const Real x = std::sqrt(Rd > 0 ? (Rd < 1 ? Rd : Real(1)) : Real(0)) * scale_;
        std::size_t i = static_cast<std::size_t>(x);
        if (i + 1 >= value_.size()) i = value_.size() - 2;
        const Real u = x - static_cast<Real>(i), v = 1 - u;
        // Cubic Hermite: y0 (1 + 2u) v^2 + m0 u v^2 + y1 u^2 (3 - 2u) - m1 u^2 v (slopes pre-scaled by h).
        return (value_[i] * (1 + 2 * u) + slope_[i] * u) * v * v +
               (value_[i + 1] * (3 - 2 * u) - slope_[i + 1] * v) * u * u;
    }

    /// Largest |table - exact| found at the interval midpoints at construction.
    Real max_error() const noexcept { return max_error_; }
    int size() const noexcept { return static_cast<int>(value_.size()); }
    STRATUM_HOST_DEVICE const DipoleBoundary<Real>& boundary() const noexcept { return boundary_; }
    /// The tabulated alpha' at R_d = (i / (size - 1))^2.
    const std::vector<Real>& values() const noexcept { return value_; }

private:
    DipoleBoundary<Real> boundary_;
    Real scale_ = 1, max_error_ = 0;
    std::vector<Real> value_, slope_;
};

/// The dipole diffusion model of a semi-infinite homogeneous medium with a smooth boundary.
template <class Real = double>
class Dipole {
public:
    /// From the absorption and reduced scattering coefficients sigma_a, sigma_s' >= 0 (1/length, finite,
    /// not both 0) and eta = n_medium / n_outside. Throws std::invalid_argument naming the bad value.
    Dipole(Real sigma_a, Real sigma_s_prime, Real eta, DiffuseFresnel model = DiffuseFresnel::jensen_fit)
        : Dipole(sigma_a, sigma_s_prime, DipoleBoundary<Real>::from_eta(eta, model)) {}

    Dipole(Real sigma_a, Real sigma_s_prime, const DipoleBoundary<Real>& boundary)
        : sigma_a_(detail::require_nonnegative("sigma_a", sigma_a)),
          sigma_s_prime_(detail::require_nonnegative("sigma_s_prime", sigma_s_prime)),
          boundary_(detail::require_dipole_boundary(boundary)) {
        const Real st = sigma_a + sigma_s_prime;
        if (!(st > 0 && std::isfinite(st))) detail::throw_out_of_range("sigma_a + sigma_s_prime", st, "(0, inf)");
        alpha_prime_ = sigma_s_prime / st;
        // sigma_tr = sigma_t' s with s = sqrt(3 sigma_a / sigma_t') = sqrt(3 (1 - alpha')) (exact for sigma_a = 0).
        const Real s = std::sqrt(3 * (sigma_a / st));
        finish(st, s);
    }

    /// Hery's parameters: the reduced albedo alpha' in [0, 1) and the diffuse mean free path
    /// ld = 1 / sigma_tr > 0 (length). Then s = sqrt(3 (1 - alpha')), sigma_t' = 1 / (ld s),
    /// sigma_s' = alpha' sigma_t', sigma_a = sigma_t' - sigma_s'. alpha' = 1 would need ld = inf (no
    /// absorption): use the (sigma_a, sigma_s') constructor with sigma_a = 0 for that.
    static Dipole from_albedo(Real alpha_prime, Real diffuse_mean_free_path, Real eta,
                              DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
        return from_albedo(alpha_prime, diffuse_mean_free_path, DipoleBoundary<Real>::from_eta(eta, model));
    }

    static Dipole from_albedo(Real alpha_prime, Real diffuse_mean_free_path, const DipoleBoundary<Real>& boundary) {
        if (!(alpha_prime >= 0 && alpha_prime < 1))
            detail::throw_out_of_range("alpha_prime", alpha_prime, "[0, 1) (with a finite diffuse mean free path)");
        detail::require_dipole_boundary(boundary);
        const Real s = std::sqrt(3 * (1 - alpha_prime));
        const Real st = extinction(diffuse_mean_free_path, s);
        return Dipole(st * (1 - alpha_prime), st * alpha_prime, st, s, alpha_prime, boundary);
    }

    /// Hery's workflow: the artist's diffuse colour (total diffuse reflectance Rd in [0, 1)) and the
    /// diffuse mean free path ld > 0; alpha' = alpha_prime_from_reflectance(Rd), sigma_t' = 1 / (ld s).
    static Dipole from_reflectance(Real Rd, Real diffuse_mean_free_path, Real eta,
                                   DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
        if (!(Rd >= 0 && Rd < 1))
            detail::throw_out_of_range("Rd", Rd, "[0, 1) (with a finite diffuse mean free path)");
        const auto boundary = DipoleBoundary<Real>::from_eta(eta, model);
        // From s rather than alpha': as Rd -> 1, 1 - alpha' ~ (1 - Rd)^2 is not resolved by alpha' but s is.
        const auto inv = detail::invert_reflectance(Rd, boundary);
        const Real st = extinction(diffuse_mean_free_path, inv.s);
        return Dipole(st * inv.s * inv.s / 3, st * inv.alpha_prime, st, inv.s, inv.alpha_prime, boundary);
    }

    STRATUM_HOST_DEVICE Real sigma_a() const noexcept { return sigma_a_; }
    STRATUM_HOST_DEVICE Real sigma_s_prime() const noexcept { return sigma_s_prime_; }
    STRATUM_HOST_DEVICE Real sigma_t_prime() const noexcept { return sigma_t_prime_; }
    STRATUM_HOST_DEVICE Real alpha_prime() const noexcept { return alpha_prime_; }
    STRATUM_HOST_DEVICE Real sigma_tr() const noexcept { return sigma_tr_; }
    /// 1 / sigma_tr (infinite when sigma_a = 0).
    STRATUM_HOST_DEVICE Real diffuse_mean_free_path() const noexcept {
        return sigma_tr_ > 0 ? 1 / sigma_tr_ : std::numeric_limits<Real>::infinity();
    }
    STRATUM_HOST_DEVICE Real z_r() const noexcept { return z_r_; }
    STRATUM_HOST_DEVICE Real z_v() const noexcept { return z_v_; }
    STRATUM_HOST_DEVICE Real A() const noexcept { return boundary_.A; }
    STRATUM_HOST_DEVICE Real eta() const noexcept { return boundary_.eta; }
    STRATUM_HOST_DEVICE const DipoleBoundary<Real>& boundary() const noexcept { return boundary_; }

    /// The radial profile R_d(r) (1/length^2): the diffuse exitance at distance r from a unit-power point
    /// of entry. Finite at r = 0, -> 0 as r -> inf (0 for r = inf); even in r.
    STRATUM_HOST_DEVICE Real Rd(Real r) const noexcept {
        const Real r2 = r * r;
        if (!(r2 < std::numeric_limits<Real>::infinity())) return Real(0);
        return pole(r, r2, z_r_) + pole(r, r2, z_v_);
    }

    /// int_0^inf R_d(r) 2 pi r dr = total_diffuse_reflectance(alpha', boundary).
    STRATUM_HOST_DEVICE Real total_reflectance() const noexcept { return total_; }

    /// A radius with pdf sigma_tr^2 r e^{-sigma_tr r} on [0, inf) (per unit radius; the density over the
    /// plane is that over 2 pi r), by the exact inverse of P(u) = 1 - e^{-u} (1 + u), u = sigma_tr r:
    /// u = -1 - W_{-1}((xi - 1) / e). xi is clamped to [0, 1 - eps/2] (xi = 1 gives a finite ~40 / sigma_tr
    /// in double); xi = 0 gives 0. Without absorption (sigma_tr = 0) the pdf does not exist: returns 0.
    STRATUM_HOST_DEVICE Real sample_radius(Real xi) const noexcept {
        if (!(sigma_tr_ > 0)) return Real(0);
        xi = detail::clamp_uniform(xi);
        // x = (xi - 1) / e with 1 - xi exact for xi >= 1/2; q = e x + 1 = xi exactly.
        const Real x = -(1 - xi) * detail::InvE<Real>::hi;
        return -detail::lambert_wm1_plus_one(x, xi) / sigma_tr_;
    }

    /// The pdf of sample_radius per unit radius: sigma_tr^2 r e^{-sigma_tr r} for r >= 0, else 0
    /// (0 everywhere when sigma_tr = 0).
    STRATUM_HOST_DEVICE Real pdf_radius(Real r) const noexcept {
        if (!(r >= 0) || !(r < std::numeric_limits<Real>::infinity())) return Real(0);
        const Real u = sigma_tr_ * r;  // sigma_tr (u e^{-u}): sigma_tr^2 alone overflows for sigma_tr > 1e154
        if (!(u < std::numeric_limits<Real>::infinity())) return Real(0);  // u e^{-u} -> 0 (inf * 0 is NaN)
        return sigma_tr_ * (u * std::exp(-u));
    }

private:
    // sigma_t' = 1 / (ld s) for Hery's parameters, required finite: a subnormal ld (1e-310) was accepted with
    // sigma_t' = inf, which the coefficients' constructor refuses, and R_d(r) was 0 everywhere while the total was 0.3
    // (found by a review sweep).
    static Real extinction(Real diffuse_mean_free_path, Real s) {
        detail::require_positive("diffuse_mean_free_path", diffuse_mean_free_path);
        const Real st = 1 / (diffuse_mean_free_path * s);
        if (!(st < std::numeric_limits<Real>::infinity()))
            detail::throw_out_of_range("diffuse_mean_free_path", diffuse_mean_free_path,
                                       "(0, inf) with sigma_t' = 1 / (ld sqrt(3 (1 - alpha'))) finite");
        return st;
    }

    Dipole(Real sigma_a, Real sigma_s_prime, Real st, Real s, Real alpha_prime, const DipoleBoundary<Real>& boundary)
        : sigma_a_(sigma_a), sigma_s_prime_(sigma_s_prime), alpha_prime_(alpha_prime), boundary_(boundary) {
        finish(st, s);
    }

    void finish(Real st, Real s) {
        sigma_t_prime_ = st;
        sigma_tr_ = st * s;
        z_r_ = 1 / st;
        z_v_ = z_r_ * (1 + Real(4) / 3 * boundary_.A);
        prefactor_ = alpha_prime_ * detail::inv_four_pi_v<Real>;
        // From s itself, as sigma_tr: through alpha' (1 - alpha' unresolved in float near 1) the total missed the
        // profile's own integral by 1.4e-4 at sigma_a / sigma_s' = 1e-7 in float, 10% of 1 - R_d (found by review).
        total_ = detail::total_reflectance_in_s(alpha_prime_, s, boundary_.A);
    }

    /// One pole's term of R_d, prefactor z (x + 1) e^{-x} / d^3 with d = sqrt(r^2 + z^2), x = sigma_tr d, formed so
    /// that no partial product overflows unless the result does: the prefactor and z / d (<= 1) first, then 1 / d
    /// twice, so a huge d underflows to 0 and the tiny z of a huge sigma_t' gives a finite value (1 / d^3 alone
    /// overflowed: inf for float sigma_t' 1e20, NaN times alpha' = 0; found by review); d by hypot where r^2 + z^2 is
    /// below the normal range (z^2 underflows first).
    STRATUM_HOST_DEVICE Real pole(Real r, Real r2, Real z) const noexcept {
        const Real d2 = r2 + z * z;
        const Real d = d2 >= std::numeric_limits<Real>::min() ? std::sqrt(d2) : std::hypot(r, z), inv = 1 / d;
        const Real x = sigma_tr_ * d;
        if (!(x < std::numeric_limits<Real>::infinity())) return Real(0);  // (x + 1) e^{-x} -> 0, not inf * 0
        return (x + 1) * std::exp(-x) * (prefactor_ * (z * inv)) * inv * inv;
    }

    Real sigma_a_ = 0, sigma_s_prime_ = 0, sigma_t_prime_ = 0, alpha_prime_ = 0, sigma_tr_ = 0;
    Real z_r_ = 0, z_v_ = 0, prefactor_ = 0, total_ = 0;
    DipoleBoundary<Real> boundary_;
};

namespace detail {
template <class Real, std::size_t N, std::size_t... I>
std::array<Dipole<Real>, N> make_dipoles(const std::array<Real, N>& sigma_a, const std::array<Real, N>& sigma_s_prime,
                                         const DipoleBoundary<Real>& boundary, std::index_sequence<I...>) {
    return {Dipole<Real>(sigma_a[I], sigma_s_prime[I], boundary)...};
}
}  // namespace detail

/// One Dipole per spectral channel (e.g. RGB) from per-channel coefficients and one shared boundary:
///   auto skin = make_dipoles<float, 3>({0.032f, 0.17f, 0.48f}, {0.74f, 0.88f, 1.01f}, 1.3f);
template <class Real, std::size_t N>
std::array<Dipole<Real>, N> make_dipoles(const std::array<Real, N>& sigma_a, const std::array<Real, N>& sigma_s_prime,
                                         Real eta, DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
    return detail::make_dipoles(sigma_a, sigma_s_prime, DipoleBoundary<Real>::from_eta(eta, model),
                                std::make_index_sequence<N>{});
}

}  // namespace stratum
