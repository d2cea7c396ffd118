// stratum/microfacet.hpp -- the Beckmann (Gaussian) microfacet distribution with Smith shadowing.
//
// The microsurface is an isotropic Gaussian height field whose slopes (x~, y~) are independent normal
// variables with standard deviation sigma (the RMS slope, Stam's parameter; Beckmann's alpha = sqrt(2) sigma).
// A facet with slopes (x~, y~) has the unit normal h = normalize(-x~, -y~, 1), so every facet normal lies in
// the upper hemisphere (h.z > 0) of the local frame, whose z axis is the macro-surface normal.
//
// Normalization: D is normalized over PROJECTED area, int D(h) cos(theta_h) dw_h = 1, so D(h) dw_h is the
// facet area per unit macro area with normals in dw_h. Stam (2001) writes the slope density P = D cos(theta_h)
// (his Eq. 17) and then uses P where D belongs; see interface.hpp.
//
// Directions: unit vectors in the local frame. Lambda and G1 depend on a direction only through |cos theta|:
// the Gaussian surface looks the same from below as from above (seen from below its facet normals are -h).
// sample_visible_normal and visible_normal_pdf work on the side of the given direction: for wi.z < 0 the
// returned normal lies in the lower hemisphere (it is the mirror image of the normal sampled for the mirrored
// direction).
#pragma once

#include <cmath>
#include <limits>
#include <type_traits>

#include "detail/config.hpp"
#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "vec3.hpp"

namespace stratum {

/// Joint masking-shadowing form of the microsurface (Smith, Gaussian surface), used by RoughDielectric;
/// interface.hpp's header comment defines the three. height_correlated is the default.
enum class Shadowing { height_correlated, separable, masking_only };

/// Directional-hemispherical reflectance and transmittance (power fractions) of a microsurface for one
/// incident direction (RoughDielectric::hemispherical_totals).
template <class Real = double>
struct HemisphericalTotals {
    Real reflectance = 0;
    Real transmittance = 0;
};

namespace detail {

/// Smith's Lambda of a Gaussian surface as a function of a = cot(theta) / alpha (a >= 0):
///   Lambda(a) = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2          (van Ginneken et al. 1998)
/// For a < 5 the two terms are evaluated directly; they cancel, losing ~2a^2 ulp of Lambda (at most
/// 50 ulp, near a = 5 where Lambda ~ 1e-14 and G1 = 1/(1 + Lambda) is unaffected). For a >= 5 the
/// difference is taken analytically from the continued fraction
///   sqrt(pi) exp(a^2) erfc(a) = 1/(a + t),  t = (1/2)/(a + (2/2)/(a + (3/2)/(a + ...))),
/// so 1/a - 1/(a + t) = t / (a (a + t)) without cancellation; 16 levels give relative error < 3e-15 at
/// a = 5, falling fast beyond (measured with mpmath; this bounds long double too, where Lambda < 1.5e-14
/// there). Exact otherwise: no rational fit. a = 0 gives +inf, a = inf gives 0.
template <class W>
STRATUM_HOST_DEVICE W smith_lambda_gaussian(W a) noexcept {
    if (!(a > 0)) return std::numeric_limits<W>::infinity();
    if (a < W(5)) return (std::exp(-a * a) / (a * sqrt_pi_v<W>) - std::erfc(a)) / 2;
    if (!(a < std::numeric_limits<W>::max())) return W(0);
    W t = 0;
    for (int k = 16; k >= 1; --k) t = (W(k) / 2) / (a + t);
    return std::exp(-a * a) / (2 * sqrt_pi_v<W>) * t / (a * (a + t));
}

/// Winitzki's approximation of the inverse of erfc on (0, 2) (relative error ~2e-3): the starting value of
/// erfc_inverse, and of sample_visible_slope for a nearly Gaussian slope distribution. q is clamped away from 0.
template <class W>
STRATUM_HOST_DEVICE W erfc_inverse_estimate(W q) noexcept {
    const W tiny = std::numeric_limits<W>::min() / std::numeric_limits<W>::epsilon();
    const W sign = q > 1 ? W(-1) : W(1);
    if (q > 1) q = 2 - q;
    if (!(q > tiny)) q = tiny;
    // erf^{-1}(z) ~ sqrt(sqrt(b^2 - L/c) - b), b = 2/(pi c) + L/2, L = ln(1 - z^2), c = 0.147.
    const W L = std::log(q) + std::log(2 - q);  // ln(1 - z^2) with z = 1 - q, without cancellation
    const W c = W(0.147);
    const W b = 2 / (pi_v<W> * c) + L / 2;
    return sign * std::sqrt(std::fmax(W(0), std::sqrt(b * b - L / c) - b));
}

/// Inverse of erfc on (0, 2): Winitzki's starting value refined by Halley steps on erfc itself, so the result is
/// as accurate as std::erfc. q is clamped away from 0 and 2 (results stay finite). For f = erfc(x) - q,
/// f''/f' = -2x and f'''/f' = 4x^2 - 2, so a Halley step s leaves an error of about (1 + x^2) s^3 / 3: the
/// iteration stops once that is below rounding, without evaluating erfc again to confirm it (tested against
/// long double references in tests/test_microfacet.cpp).
template <class W>
STRATUM_HOST_DEVICE W erfc_inverse(W q) noexcept {
    const W tiny = std::numeric_limits<W>::min() / std::numeric_limits<W>::epsilon();
    W sign = 1;
    if (q > 1) {
        q = 2 - q;
        sign = -1;
    }
    if (!(q > tiny)) q = tiny;
    if (q == 1) return W(0);
    W x = erfc_inverse_estimate(q);
    for (int it = 0; it < 4; ++it) {
        // f = erfc(x) - q, f' = -(2/sqrt(pi)) e^{-x^2}: Halley step x -= r / (1 + x r), r = f/f'.
        const W r = -(std::erfc(x) - q) * (sqrt_pi_v<W> / 2) * std::exp(x * x);
        const W step = r / (1 + x * r);
        x -= step;
        if (std::fabs(step) * step * step * (1 + x * x) <= std::numeric_limits<W>::epsilon() * std::fmax(W(1), x)) break;
    }
    return sign * x;
}

/// Samples the slope x (alpha = 1 units, along the azimuth of the incident direction) of a facet visible
/// from a direction with a = cot(theta) / alpha. Its density is proportional to (a - x) exp(-x^2) on x < a
/// (projected facet area times the slope density), with CDF proportional to
///   g(x) = (sqrt(pi)/2) a erfc(-x) + exp(-x^2) / 2,
/// inverted by Halley's (or Newton's) method safeguarded by bisection, stopped when the residual is at rounding level.
/// g is scaled by 1/a when a >= 1 (a = inf is the Gaussian). The search interval is [-27, min(a, 27)]:
/// beyond 27 the density is below 1e-316.
template <class W>
STRATUM_HOST_DEVICE W sample_visible_slope(W a, W u) noexcept {
    const W A = a >= 1 ? W(1) : a;
    const W B = a >= 1 ? 1 / a : W(1);
    W lo = -27, hi = std::fmin(a, W(27));
    const W total = A * (sqrt_pi_v<W> / 2) * std::erfc(-hi) + B * std::exp(-hi * hi) / 2, target = u * total;
    // Starting value: for a >= 1 the Gaussian quantile (Winitzki's estimate of it) shifted by -1 / (2a), since
    // (a - x) exp(-x^2) ~ a exp(-(x + 1/(2a))^2) for large a (closer, so fewer steps, than the unshifted quantile);
    // below, the a = 0 solution x = -sqrt(-ln u) (density -x exp(-x^2)).
    const W x0 = a >= 1 ? -erfc_inverse_estimate(2 * u) - 1 / (2 * a)
                        : -std::sqrt(-std::log(std::fmax(u, std::numeric_limits<W>::min())));
    W x = std::fmin(std::fmax(x0, lo), hi);
    for (int it = 0; it < 100; ++it) {
        const W e = std::exp(-x * x);  // (once: g and its derivatives share it)
        const W f = A * (sqrt_pi_v<W> / 2) * std::erfc(-x) + B * e / 2 - target;
        // Rounding level relative to the target: in the lower tail u total falls below eps total (from u ~ 1e-7 in
        // float), where a stop at eps total accepted any slope.
        if (std::fabs(f) <= 4 * std::numeric_limits<W>::epsilon() * std::fmin(total, std::fmax(target, std::numeric_limits<W>::min())))
            break;
        if (f < 0)
            lo = x;
        else
            hi = x;
        // f' = e (A - B x), f'' = -e (2 x (A - B x) + B): Halley's step where its correction to Newton's is
        // moderate (far from the root, in the tails, Halley's step creeps), else Newton's.
        const W d1 = e * (A - B * x), d2 = -e * (2 * x * (A - B * x) + B);
        W next = (lo + hi) / 2;
        if (d1 > 0) {
            const W newton = f / d1, t = newton * d2 / (2 * d1);
            next = x - (std::fabs(t) < W(0.5) ? newton / (1 - t) : newton);
        }
        if (!(next >= lo && next <= hi)) next = (lo + hi) / 2;  // left the bracket: bisect
        const W step = std::fabs(next - x);
        x = next;
        if (step <= 2 * std::numeric_limits<W>::epsilon() * std::fmax(W(1), std::fabs(x)) || !(lo < hi)) break;
    }
    return x;
}

}  // namespace detail

/// Beckmann distribution of facet normals for a Gaussian surface of RMS slope sigma.
template <class Real = double>
class Beckmann {
public:
    /// sigma: RMS slope, 0 < sigma < inf (alpha = sqrt(2) sigma). Throws std::invalid_argument otherwise.
    explicit Beckmann(Real sigma) : sigma_(detail::require_positive("sigma", sigma)) {
        alpha_ = std::sqrt(Real(2)) * sigma_;
    }

    STRATUM_HOST_DEVICE Real sigma() const noexcept { return sigma_; }
    STRATUM_HOST_DEVICE Real alpha() const noexcept { return alpha_; }

    /// Facet-normal density over solid angle, normalized over projected area (int D cos(theta_h) dw_h = 1):
    ///   D(h) = exp(-tan^2(theta_h) / (2 sigma^2)) / (2 pi sigma^2 cos^4(theta_h)),   h.z > 0; 0 otherwise.
    /// Units 1/sr. h must be a unit vector. Never NaN for any sigma the constructor accepts: where the Gaussian
    /// factor underflows to 0 the result is 0 (also when the denominator underflows too, e.g. h.z ~ 1e-13 with
    /// sigma ~ 1e-137, or h.z^4 below float's range at any sigma: 0/0 otherwise). The peak 1 / (2 pi sigma^2)
    /// overflows to +inf for sigma below ~3e-155 (double) or ~2e-20 (float): a legitimate, if useless, value of a
    /// density that narrow (RoughDielectric never evaluates D below RoughDielectric::smooth_sigma).
    STRATUM_HOST_DEVICE Real D(Vec3<Real> h) const noexcept {
        if (!(h.z > 0)) return Real(0);
        const Real c2 = h.z * h.z;
        const Real tan2 = (h.x * h.x + h.y * h.y) / c2;
        const Real s2 = sigma_ * sigma_;
        // tan2 = 0: the peak, also where sigma^2 underflows to 0 (0 / 0 otherwise).
        const Real g = tan2 > 0 ? std::exp(-tan2 / (2 * s2)) : Real(1);
        if (!(g > 0)) return Real(0);
        return g / (2 * detail::pi_v<Real> * s2 * c2 * c2);
    }

    /// Density of the slopes (x~, y~) = (-h.x / h.z, -h.y / h.z) per unit slope area:
    ///   P22(x~, y~) = exp(-(x~^2 + y~^2) / (2 sigma^2)) / (2 pi sigma^2)   (= D(h) cos^4(theta_h)).
    /// Never NaN; +inf at slope 0 where 2 pi sigma^2 underflows (see D).
    STRATUM_HOST_DEVICE Real slope_pdf(Real slope_x, Real slope_y) const noexcept {
        const Real s2 = sigma_ * sigma_;
        const Real r2 = slope_x * slope_x + slope_y * slope_y;
        const Real g = r2 > 0 ? std::exp(-r2 / (2 * s2)) : Real(1);
        if (!(g > 0)) return Real(0);
        return g / (2 * detail::pi_v<Real> * s2);
    }

    /// Smith's Lambda for a direction with cosine mu to the macro normal (only |mu| matters):
    ///   Lambda = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2,  a = |mu| / (sqrt(2) sigma sqrt(1 - mu^2)).
    /// Exact (erfc-based; no rational fit). Lambda(0) = +inf (grazing), Lambda(+-1) = 0.
    STRATUM_HOST_DEVICE Real Lambda(Real mu) const noexcept {
        using W = detail::wide_t<Real>;
        return static_cast<Real>(detail::smith_lambda_gaussian<W>(cot_over_alpha(std::fabs(mu))));
    }

    /// Projected area of the visible microsurface per unit macro area, seen from |mu|:
    ///   A(mu) = int max(0, w.h) D(h) dw_h = |mu| (1 + Lambda(mu)),   A(0) = sigma / sqrt(2 pi) > 0.
    /// Evaluated without the 0 * inf of the product form at grazing incidence.
    STRATUM_HOST_DEVICE Real projected_area(Real mu) const noexcept {
        using W = detail::wide_t<Real>;
        const W m = std::fmin(std::fabs(static_cast<W>(mu)), W(1));
        const W a = cot_over_alpha(static_cast<Real>(m));
        W mu_lambda;
        if (a < W(5)) {
            // mu Lambda = (s exp(-a^2) / sqrt(pi) - mu erfc(a)) / 2 with s = mu / a = alpha sqrt(1 - mu^2).
            const W s = static_cast<W>(alpha_) * std::sqrt((1 - m) * (1 + m));
            mu_lambda = (s * std::exp(-a * a) / detail::sqrt_pi_v<W> - m * std::erfc(a)) / 2;
        } else {
            mu_lambda = m * detail::smith_lambda_gaussian<W>(a);
        }
        return static_cast<Real>(m + mu_lambda);
    }

    /// Smith masking of the whole microsurface seen from |mu|: G1(mu) = 1 / (1 + Lambda(mu)), in [0, 1];
    /// G1(0) = 0 (explicitly: A(0) = sigma / sqrt(2 pi) underflows to 0 for denormal sigma).
    STRATUM_HOST_DEVICE Real G1(Real mu) const noexcept {
        const Real m = std::fmin(std::fabs(mu), Real(1));
        if (!(m > 0)) return Real(0);
        return m / projected_area(m);
    }

    /// Smith masking of facet h seen from direction w: G1(|w.z|) if the facet faces w on w's side of the
    /// surface ((w.h) (w.z) > 0), else 0 (back-facing facets are never visible).
    STRATUM_HOST_DEVICE Real G1(Vec3<Real> w, Vec3<Real> h) const noexcept {
        if (!(dot(w, h) * w.z > 0)) return Real(0);
        return G1(w.z);
    }

    /// Samples a facet normal from the distribution of normals visible from wi (Heitz and d'Eon 2014):
    ///   D_wi(h) = G1(wi) max(0, wi.h) D(h) / |wi.z|,
    /// by stretching to alpha = 1, sampling the slope along wi's azimuth from (a - x) exp(-x^2) (exact CDF
    /// inversion) and the perpendicular slope from exp(-y^2) / sqrt(pi), then unstretching. u1, u2 in [0, 1);
    /// the result is a finite unit vector for every such u (u = 0 gives the bracket's end, slope -27: density 1e-316). For
    /// wi.z < 0 the normal is on the lower side (h.z < 0), the mirror image of the wi.z > 0 case.
    STRATUM_HOST_DEVICE Vec3<Real> sample_visible_normal(Vec3<Real> wi, Real u1, Real u2) const noexcept {
        // In Real, float included: within 5.1e-6 of the double sampler's normal at the same inputs for 99.9% of
        // uniforms (5e-8 typical), 8.1e-4 at u1 = 1 - 2^-24, where float's u resolves the CDF's last 6e-8 only
        // (tests/test_microfacet.cpp); RoughDielectric<float>::sample 12% faster than in double (README).
        using W = Real;
        const W al = alpha_;
        // Azimuth and a = cot(theta) / alpha from wi itself (alpha is isotropic), so that neither a tiny alpha
        // (alpha wi.x underflowing) nor a huge one ((alpha wi.x)^2 overflowing) changes them.
        const W wx = static_cast<W>(wi.x), wy = static_cast<W>(wi.y);
        const W st = std::sqrt(wx * wx + wy * wy);
        const W wz = std::fabs(static_cast<W>(wi.z));
        const W a = st > 0 ? wz / (al * st) : std::numeric_limits<W>::infinity();
        const W cphi = st > 0 ? wx / st : W(1), sphi = st > 0 ? wy / st : W(0);
        const W x = detail::sample_visible_slope<W>(a, static_cast<W>(u1));
        const W y = -detail::erfc_inverse<W>(2 * static_cast<W>(u2));
        if (al > 1) {
            // h ~ (-px, -py, 1) / alpha, the slopes divided by alpha (px^2 would overflow for sigma > ~1e153),
            // then by the largest component (1 / alpha^2 underflows for sigma > ~1e154).
            const W px = cphi * x - sphi * y, py = sphi * x + cphi * y, pz = 1 / al;
            const W m = std::fmax(std::fmax(std::fabs(px), std::fabs(py)), pz);
            const W qx = px / m, qy = py / m, qz = pz / m;
            const W inv = 1 / std::sqrt(qx * qx + qy * qy + qz * qz);
            const W hz = wi.z < 0 ? -qz * inv : qz * inv;
            return {static_cast<Real>(-qx * inv), static_cast<Real>(-qy * inv), static_cast<Real>(hz)};
        }
        const W px = al * (cphi * x - sphi * y), py = al * (sphi * x + cphi * y);
        const W inv = 1 / std::sqrt(px * px + py * py + 1);
        const W hz = wi.z < 0 ? -inv : inv;
        return {static_cast<Real>(-px * inv), static_cast<Real>(-py * inv), static_cast<Real>(hz)};
    }

    /// Density (per steradian of h) of sample_visible_normal: max(0, wi.h) D(h) / (|wi.z| (1 + Lambda)),
    /// with both vectors mirrored to the upper side when wi.z < 0; 0 for h on the other side of wi. Never NaN
    /// (0 where D is 0; +inf where D overflows, see D, or where A(wi.z) underflows, grazing wi with denormal sigma).
    STRATUM_HOST_DEVICE Real visible_normal_pdf(Vec3<Real> wi, Vec3<Real> h) const noexcept {
        if (wi.z < 0) {
            wi.z = -wi.z;
            h.z = -h.z;
        }
        const Real c = dot(wi, h);
        if (!(c > 0) || !(h.z > 0)) return Real(0);
        const Real d = D(h);
        if (!(d > 0)) return Real(0);
        return c * d / projected_area(wi.z);
    }

private:
    // a = mu / (alpha sqrt(1 - mu^2)), mu in [0, 1]; +inf at mu = 1.
    STRATUM_HOST_DEVICE detail::wide_t<Real> cot_over_alpha(Real mu) const noexcept {
        using W = detail::wide_t<Real>;
        const W m = std::fmin(static_cast<W>(mu), W(1));
        const W s = std::sqrt((1 - m) * (1 + m));
        if (!(s > 0)) return std::numeric_limits<W>::infinity();
        return m / (static_cast<W>(alpha_) * s);
    }

    Real sigma_;
    Real alpha_;
};

}  // namespace stratum
