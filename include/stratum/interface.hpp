// stratum/interface.hpp -- rough and smooth dielectric interfaces between two media.
//
// Geometry and conventions (used by every function below):
// - Local frame: z is the macro-surface normal, pointing into the medium ABOVE (index eta_above); the medium
//   below has index eta_below. Only the ratio of the indices matters.
// - Renderer-facing functions take unit vectors wi (towards the light) and wo (towards the viewer), both
//   pointing AWAY from the surface (pbrt's convention). Light travels from wi's side to wo's side: wi and wo
//   in the same hemisphere (above or below) is reflection, in opposite hemispheres transmission.
//   eta_i, eta_o below denote the indices on wi's and wo's sides.
// - All values are BSDF values per steradian, without the cosine: outgoing radiance
//   L(wo) = int f(wi, wo) L(wi) |wi.z| dwi; the hemispherical reflectance/transmittance for incidence wi are
//   int f(wi, wo) |wo.z| dwo over wo's hemisphere (power fractions; the BTDF carries the radiance factor
//   eta_o^2 / eta_i^2 of Walter et al. 2007, so no further factor appears in these integrals).
// - Degenerate input (a direction on the horizon, a refraction configuration no facet can produce) gives 0.
//
// Microfacet model (Stam 2001 Section 4, corrected as in the project's physics notes; Walter et al. 2007 form):
//   brdf  r(i, o) = F(i.h, eta_t/eta_i) D(h) G2(i, o) / (4 |i.z| |o.z|),                  h = normalize(i + o)
//   btdf  t(i, o) = |i.h| |o.h| / (|i.z| |o.z|) eta_o^2 (1 - F(i.h, eta_o/eta_i)) D(h) G2(i, o)
//                   / (eta_i (i.h) + eta_o (o.h))^2,                                     h = +-normalize(eta_i i + eta_o o)
// with D the Beckmann distribution (microfacet.hpp), normalized over projected area. Stam's paper writes the
// slope density P = D cos(theta_h) in place of D, which loses ~7% of the transmitted energy at sigma = 0.3;
// this code uses D. The denominator is Stam's refraction Jacobian (cos th'_0 - mu_t)^2 with
// mu_t = sqrt(cos^2 th'_0 + eta^2 - 1) (the paper drops both squares). The half vector h is taken on the
// side of wi (facet normals of the height field point into wi's medium as seen from wi); back-facing facets
// contribute nothing: reflection needs (i.h) > 0 and (o.h) > 0, transmission (i.h) > 0 and (o.h) < 0.
//
// Shadowing (Smith, Gaussian surface, Lambda from van Ginneken et al. 1998), chosen by `Shadowing`:
// - height_correlated (DEFAULT): reflection G2 = 1 / (1 + Lambda(i) + Lambda(o)); transmission, where masking
//   and shadowing are on opposite sides of the microsurface, G2 = B(1 + Lambda(i), 1 + Lambda(o)) with B the
//   Beta function (Heitz 2014, "Understanding the masking-shadowing function in microfacet-based BRDFs",
//   Sec. 6: a point at height-CDF value C is visible from above with probability C^Lambda(i) and from below
//   with probability (1 - C)^Lambda(o); integrating over C gives B; the same integral with C^Lambda(o) gives
//   the reflection form).
// - separable: G2 = G1(i) G1(o) for both.
// - masking_only: G2 = G1(i) (no outgoing shadowing). Not a rendering model: it is the form whose total
//   reflected + transmitted energy equals exactly the facet-scattered energy minus the part sent into the
//   wrong hemisphere; the tests use it to check the BRDF/BTDF against a facet-level Monte Carlo.
//
// Index matching (eta_above == eta_below exactly): nothing is reflected and the transmission is the identity,
// a delta in the direction -wi. brdf and btdf return 0 (a delta cannot be evaluated), sample returns the
// straight-through direction flagged as delta, albedo returns {0, 1}. For eta_above != eta_below the BTDF is a
// proper function however close the indices are; its lobe narrows like |eta - 1| sigma and its peak grows
// like 1/(eta - 1)^2 (finite; 0 is returned only where the Jacobian denominator is exactly 0). Note that with
// shadowing the energy of that lobe tends, as eta -> 1, to E[G2 / G1(i)] < 1 (the single-scattering model
// still counts light striking a second facet as lost, although at eta = 1 that facet is invisible), so the
// exact-matching identity is the limit only for masking_only. Measured (sigma = 0.3, height-correlated):
// T(eta = 1 + 1e-9) = 0.99999992 at mu_i = 0.77, 0.80 at mu_i = 0.2, against 1 at eta = 1 exactly.
//
// Energy (tests/test_interface_energy.cpp): with masking_only, R + T equals 1 minus the facet-scattered light
// sent into the wrong hemisphere, as measured by a facet-level Monte Carlo (e.g. 0.63% at sigma = 0.3,
// eta = 1.4, 40 deg; 2.9% at sigma = 1, 60 deg). The default shadowing loses 1 - (R + T) = 0.89% (sigma = 0.3,
// eta = 1.4, 40 deg, from above), 8.3% (same, from the dense side), 23% and 48% (sigma = 1, 60 deg, from above
// and from below). Height-correlated transmission shadows more than separable (Chebyshev's inequality:
// B(1 + a, 1 + b) <= 1 / ((1 + a)(1 + b))), reflection less.
//
// Cost (double, one core, tests' machine): eval ~65 ns, brdf ~100 ns, sample ~0.5-1.5 us (two CDF inversions
// by Newton), albedo 2-5 ms.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include "detail/validate.hpp"
#include "fresnel.hpp"
#include "microfacet.hpp"
#include "quadrature.hpp"
#include "vec3.hpp"

namespace stratum {

/// Joint masking-shadowing form; see the header comment. height_correlated is the default.
enum class Shadowing { height_correlated, separable, masking_only };

/// Result of RoughDielectric::sample. value = f(wi, wo) (no cosine) and pdf its solid-angle density, so the
/// Monte Carlo weight is value |wo.z| / pdf. A failed sample (direction into the wrong hemisphere, wi on the
/// horizon) has pdf = 0 and value = 0 and must be discarded. A delta sample (index-matched interface) has
/// delta = true, pdf = 1 and value = 1 / |wo.z| (weight 1).
template <class Real>
struct BsdfSample {
    Vec3<Real> wo{};
    Real value = 0;
    Real pdf = 0;
    bool reflected = false;
    bool delta = false;
    bool valid() const noexcept { return pdf > 0; }
};

/// Hemispherical reflectance and transmittance (power fractions) for one incident direction.
template <class Real>
struct Albedo {
    Real reflectance = 0;
    Real transmittance = 0;
};

namespace detail {

/// Joint masking-shadowing for the Smith Lambdas li (incident) and lo (outgoing), as a function of the
/// form and of whether the two directions are on opposite sides (transmission).
template <class W>
W smith_g2(W li, W lo, Shadowing form, bool transmission) noexcept {
    const W inf = std::numeric_limits<W>::infinity();
    switch (form) {
        case Shadowing::masking_only: return 1 / (1 + li);
        case Shadowing::separable: return 1 / ((1 + li) * (1 + lo));
        case Shadowing::height_correlated:
        default:
            if (!transmission) return 1 / (1 + li + lo);
            if (li == inf || lo == inf) return W(0);
            // B(1 + li, 1 + lo) = Gamma(1 + li) Gamma(1 + lo) / Gamma(2 + li + lo)
            return std::exp(std::lgamma(1 + li) + std::lgamma(1 + lo) - std::lgamma(2 + li + lo));
    }
}

/// G2 / G1(i) with G1(i) = 1 / (1 + li), finite also at li = inf (grazing incidence); used where the visible
/// normal distribution (which contains G1(i)) is the integration measure.
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
            return std::exp(std::lgamma(1 + li) + std::lgamma(1 + lo) - std::lgamma(2 + li + lo) + std::log1p(li));
    }
}

/// Hemispherical reflectance and transmittance of a rough dielectric for incidence from above with cosine
/// mu in [0, 1], relative index eta = eta_t / eta_i. With wi = (s, 0, mu), facet slopes X = alpha x,
/// Y = alpha y (alpha = 1 units x, y) and m = (-X, -Y, 1):
///   R = int int e^{-x^2-y^2} / (pi A(mu)) (mu - s X)_+ F(c) [G2/G1(i)](o_r) [o_r.z > 0] dx dy,
///   T = the same with (1 - F(c)) and the refracted direction o_t, [o_t.z < 0],
/// c = (mu - s X)/|m|, A(mu) = mu (1 + Lambda(mu)) the visible projected area (Beckmann::projected_area).
/// The integrand is analytic except on a few curves, all conics in (X, Y):
///   reflected direction on the horizon    mu X^2 + 2 s X + mu (Y^2 - 1) = 0,
///   refracted direction on the horizon    mu^2 X^2 + 2 mu s X + mu^2 (Y^2 - 1) - (eta^2 - 1) = 0,
///   critical angle (eta < 1, c_c^2 = 1 - eta^2)   (s^2 - c_c^2) X^2 - 2 mu s X + mu^2 - c_c^2 (1 + Y^2) = 0,
/// and the back-facing edge X = mu / s. For each y the x range [-L, x_max] is split at the roots of these
/// quadratics, and the y range [0, L] (the integrand is even in y) at the y where two roots merge or a root
/// crosses x_max; L = sqrt(ln(1/eps)) + 1 truncates the Gaussian below eps. Every panel gets an n-point
/// Gauss-Legendre rule through the map t -> 3t^2 - 2t^3, which turns the square-root onsets (total internal
/// reflection, merging roots) at panel ends into smooth behaviour, so convergence is spectral in n.
template <class W>
Albedo<W> rough_albedo(W sigma, W mu, W eta, Shadowing form, int n) {
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
    const Quadrature<W> rule = gauss_legendre_half<W>(n);

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
        const W F = fresnel_dielectric(c, eta);
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

}  // namespace detail

/// Rough dielectric interface: a Gaussian microsurface of RMS slope sigma between media of indices
/// eta_above (z > 0) and eta_below. All evaluation functions are noexcept and allocation-free.
template <class Real>
class RoughDielectric {
public:
    /// sigma: RMS slope in (0, inf); eta_above, eta_below: refractive indices in (0, inf).
    /// Throws std::invalid_argument naming the offending parameter.
    RoughDielectric(Real sigma, Real eta_above, Real eta_below, Shadowing shadowing = Shadowing::height_correlated)
        : distribution_(sigma),
          eta_above_(detail::require_positive("eta_above", eta_above)),
          eta_below_(detail::require_positive("eta_below", eta_below)),
          shadowing_(shadowing) {}

    const Beckmann<Real>& distribution() const noexcept { return distribution_; }
    Real sigma() const noexcept { return distribution_.sigma(); }
    Real eta_above() const noexcept { return eta_above_; }
    Real eta_below() const noexcept { return eta_below_; }
    Shadowing shadowing() const noexcept { return shadowing_; }
    /// True when eta_above == eta_below exactly: the interface is invisible (see the header comment).
    bool index_matched() const noexcept { return eta_above_ == eta_below_; }

    /// BRDF r(wi, wo) for wi, wo in the same hemisphere (either one); 0 otherwise and for index matching.
    /// Symmetric: brdf(wi, wo) == brdf(wo, wi).
    Real brdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z * wo.z > 0) || index_matched()) return Real(0);
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        const Vec3<Real> sum = wi + wo;
        const Real len2 = dot(sum, sum);
        if (!(len2 > 0)) return Real(0);
        const Vec3<Real> h = (Real(1) / std::sqrt(len2)) * sum;
        const Real c = dot(wi, h);
        if (!(c > 0) || !(dot(wo, h) > 0)) return Real(0);
        const Real F = fresnel_dielectric(c, eta_t / eta_i);
        const Real G = g2(wi.z, wo.z, false);
        return F * distribution_.D(h) * G / (4 * wi.z * wo.z);
    }

    /// BTDF t(wi, wo) for wi, wo in opposite hemispheres (light from wi's medium into wo's medium); 0 for
    /// the same hemisphere, for configurations no facet refracts, and for index matching (a delta).
    /// Generalized reciprocity: btdf(wi, wo) / eta_o^2 == btdf(wo, wi) / eta_i^2.
    Real btdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z * wo.z < 0) || index_matched()) return Real(0);
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_o = below ? eta_above_ : eta_below_;
        Vec3<Real> v = eta_i * wi + eta_o * wo;
        const Real len2 = dot(v, v);
        if (!(len2 > 0)) return Real(0);
        Vec3<Real> h = (Real(1) / std::sqrt(len2)) * v;
        if (h.z < 0) h = -h;
        const Real ci = dot(wi, h), co = dot(wo, h);
        if (!(ci > 0) || !(co < 0)) return Real(0);
        const Real F = fresnel_dielectric(ci, eta_o / eta_i);
        const Real G = g2(wi.z, -wo.z, true);
        // (eta_i (i.h) + eta_o (o.h))^2 == |v|^2, since h = +-v / |v|.
        return ci * (-co) / (wi.z * (-wo.z)) * eta_o * eta_o * (1 - F) * distribution_.D(h) * G / len2;
    }

    /// brdf or btdf, whichever the hemispheres of wi and wo call for.
    Real eval(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        return wi.z * wo.z > 0 ? brdf(wi, wo) : btdf(wi, wo);
    }

    /// The BSDF for directions given as PROPAGATION directions, the form a radiative-transfer solver uses.
    ///   mu_in:    cosine (to +z) of the incident propagation direction; mu_in < 0 is light travelling down,
    ///             i.e. arriving from above (wi = -incident propagation direction).
    ///   mu_out:   cosine of the outgoing propagation direction (mu_out > 0: leaving upwards).
    ///   cos_dphi: cosine of the azimuth difference between the two propagation directions, so specular
    ///             reflection and refraction lie at dphi = 0.
    /// Returns f (per steradian, cosine NOT included); mu_in * mu_out > 0 is transmission, < 0 reflection.
    Real eval_propagation(Real mu_in, Real mu_out, Real cos_dphi) const noexcept {
        const Real s_in = std::sqrt(std::fmax(Real(0), (1 - mu_in) * (1 + mu_in)));
        const Real s_out = std::sqrt(std::fmax(Real(0), (1 - mu_out) * (1 + mu_out)));
        const Real c = std::fmin(std::fmax(cos_dphi, Real(-1)), Real(1));
        const Real s = std::sqrt((1 - c) * (1 + c));
        const Vec3<Real> wi{-s_in, Real(0), -mu_in};
        const Vec3<Real> wo{s_out * c, s_out * s, mu_out};
        return eval(wi, wo);
    }

    /// Samples wo given wi: a facet normal from the visible-normal distribution of wi (three uniforms
    /// u_lobe, u1, u2 in [0, 1)), then reflection with probability F and refraction otherwise. See
    /// BsdfSample for the meaning of the result; value and pdf are those of eval and pdf at (wi, wo).
    BsdfSample<Real> sample(Vec3<Real> wi, Real u_lobe, Real u1, Real u2) const noexcept {
        BsdfSample<Real> out;
        if (!(wi.z != 0)) return out;
        if (index_matched()) {
            out.wo = -wi;
            out.delta = true;
            out.pdf = Real(1);
            out.value = Real(1) / std::fabs(wi.z);
            return out;
        }
        const bool below = wi.z < 0;
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        Vec3<Real> w = wi;
        if (below) w.z = -w.z;
        const Vec3<Real> h = distribution_.sample_visible_normal(w, u1, u2);
        const Real c = dot(w, h);
        if (!(c > 0)) return out;
        const Real eta = eta_t / eta_i;
        const Real F = fresnel_dielectric(c, eta);
        Vec3<Real> wo;
        if (u_lobe < F) {
            wo = 2 * c * h - w;
            if (!(wo.z > 0)) return out;
            out.reflected = true;
        } else {
            const Real sin2_t = (1 - c * c) / (eta * eta);
            if (!(sin2_t < 1)) return out;
            const Real cos_t = std::sqrt(1 - sin2_t);
            wo = normalize((c / eta - cos_t) * h - (Real(1) / eta) * w);
            if (!(wo.z < 0)) return out;
        }
        if (below) wo.z = -wo.z;
        out.wo = wo;
        out.pdf = pdf(wi, wo);
        if (!(out.pdf > 0)) {
            out.pdf = 0;
            return out;
        }
        out.value = eval(wi, wo);
        return out;
    }

    /// Solid-angle density of sample(wi, ...) at wo: visible-normal density times the selection
    /// probability (F or 1 - F) times the Jacobian dh/dwo (1 / (4 (wo.h)) for reflection,
    /// eta_o^2 |wo.h| / (eta_i (wi.h) + eta_o (wo.h))^2 for refraction). 0 for index matching (delta).
    Real pdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z != 0) || !(wo.z != 0) || index_matched()) return Real(0);
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        if (wo.z > 0) {
            const Vec3<Real> h = normalize(wi + wo);
            const Real c = dot(wi, h);
            if (!(c > 0) || !(h.z > 0)) return Real(0);
            return distribution_.visible_normal_pdf(wi, h) * fresnel_dielectric(c, eta_t / eta_i) / (4 * c);
        }
        const Vec3<Real> v = eta_i * wi + eta_t * wo;
        const Real len2 = dot(v, v);
        if (!(len2 > 0)) return Real(0);
        Vec3<Real> h = (Real(1) / std::sqrt(len2)) * v;
        if (h.z < 0) h = -h;
        const Real ci = dot(wi, h), co = dot(wo, h);
        if (!(ci > 0) || !(co < 0)) return Real(0);
        const Real T = 1 - fresnel_dielectric(ci, eta_t / eta_i);
        return distribution_.visible_normal_pdf(wi, h) * T * eta_t * eta_t * (-co) / len2;
    }

    /// Hemispherical reflectance and transmittance for light arriving from a direction with cosine mu_i
    /// (mu_i > 0: from above, wi.z = mu_i; mu_i < 0: from below): R = int brdf |wo.z| dwo over wi's
    /// hemisphere, T = int btdf |wo.z| dwo over the other one. Computed over facet slopes, where no Jacobian
    /// appears (so it stays smooth as eta -> 1); see detail::rough_albedo for the method. Accuracy, measured
    /// in tests/test_interface_energy.cpp (16 against 32 nodes per panel, over sigma in [1e-4, 2], eta in
    /// {1/1.4, 1.0001, 1.4}, mu_i in [-0.5, 1] including 0 and 1e-4): absolute error <= 2e-9 with the default
    /// 16 nodes (<= 3e-7 for masking_only, whose integrand jumps at the horizon); agreement with the direct
    /// integral of brdf/btdf over wo within that integral's own error (<= 5e-7), and with adaptive
    /// scipy dblquad to 1e-9 (spot checks). Values of `nodes` above 32 are treated as 32 (no accuracy left to
    /// gain in double). Not a hot-path function: 10^4 - 10^5 facet evaluations, 2-5 ms.
    /// Throws std::invalid_argument for nodes < 2.
    Albedo<Real> albedo(Real mu_i, int nodes = 16) const {
        detail::require_count("nodes", nodes, 2);
        nodes = nodes < 32 ? nodes : 32;
        using W = detail::wide_t<Real>;
        if (index_matched()) return {Real(0), Real(1)};
        const bool below = mu_i < 0;
        const W eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        const W m = std::fmin(std::fabs(static_cast<W>(mu_i)), W(1));
        const auto a = detail::rough_albedo<W>(distribution_.sigma(), m, eta_t / eta_i, shadowing_, nodes);
        return {static_cast<Real>(a.reflectance), static_cast<Real>(a.transmittance)};
    }

    /// albedo(mu_i).reflectance
    Real reflectance(Real mu_i) const { return albedo(mu_i).reflectance; }
    /// albedo(mu_i).transmittance
    Real transmittance(Real mu_i) const { return albedo(mu_i).transmittance; }

private:
    // G2 for cosines mu_i, mu_o (both > 0, already on their own sides).
    Real g2(Real mu_i, Real mu_o, bool transmission) const noexcept {
        using W = detail::wide_t<Real>;
        const W li = distribution_.Lambda(mu_i), lo = distribution_.Lambda(mu_o);
        return static_cast<Real>(detail::smith_g2<W>(li, lo, shadowing_, transmission));
    }

    Beckmann<Real> distribution_;
    Real eta_above_;
    Real eta_below_;
    Shadowing shadowing_;
};

/// Result of SmoothDielectric::scatter for one incident direction wi.
template <class Real>
struct SpecularScattering {
    Vec3<Real> reflected{};          ///< mirror direction (-wi.x, -wi.y, wi.z), on wi's side
    Vec3<Real> transmitted{};        ///< Snell direction on the other side, pointing away; zero vector under TIR
    Real reflectance = 0;            ///< F: reflected fraction of power (and of radiance)
    Real transmittance = 0;          ///< 1 - F: transmitted fraction of power
    Real radiance_transmittance = 0; ///< (eta_t / eta_i)^2 (1 - F): transmitted radiance per incident radiance
    bool total_internal_reflection = false;
};

/// Smooth dielectric interface: the sigma -> 0 limit of RoughDielectric, as an exact specular interface
/// (no delta is ever evaluated). mu_i is the cosine of wi (towards the light, pointing away from the
/// surface): mu_i > 0 means light arriving from above. Index matching gives F = 0 and identity transmission.
template <class Real>
class SmoothDielectric {
public:
    /// eta_above, eta_below in (0, inf); throws std::invalid_argument otherwise.
    SmoothDielectric(Real eta_above, Real eta_below)
        : eta_above_(detail::require_positive("eta_above", eta_above)),
          eta_below_(detail::require_positive("eta_below", eta_below)) {}

    Real eta_above() const noexcept { return eta_above_; }
    Real eta_below() const noexcept { return eta_below_; }

    /// Relative index eta_t / eta_i for light arriving with cosine mu_i.
    Real relative_eta(Real mu_i) const noexcept { return mu_i >= 0 ? eta_below_ / eta_above_ : eta_above_ / eta_below_; }

    /// Fresnel reflectance F(|mu_i|, eta_t / eta_i); 1 under total internal reflection.
    Real reflectance(Real mu_i) const noexcept { return fresnel_dielectric(std::fabs(mu_i), relative_eta(mu_i)); }

    /// Transmitted power fraction 1 - F.
    Real transmittance(Real mu_i) const noexcept { return 1 - reflectance(mu_i); }

    /// Transmitted radiance per incident radiance, (eta_t / eta_i)^2 (1 - F) (radiance / n^2 is invariant).
    Real radiance_transmittance(Real mu_i) const noexcept {
        const Real e = relative_eta(mu_i);
        return e * e * transmittance(mu_i);
    }

    /// Cosine of the transmitted direction (pointing away from the surface, so of the opposite sign to
    /// mu_i): |mu_t| = sqrt(mu_i^2 + eta^2 - 1) / eta, eta = eta_t / eta_i; 0 under total internal reflection.
    Real transmitted_cosine(Real mu_i) const noexcept {
        const Real e = relative_eta(mu_i);
        const Real m2 = mu_i * mu_i + (e - 1) * (e + 1);
        if (!(m2 > 0)) return Real(0);
        const Real mt = std::fmin(std::sqrt(m2) / e, Real(1));
        return mu_i >= 0 ? -mt : mt;
    }

    /// Both scattered directions and their weights for a unit vector wi.
    SpecularScattering<Real> scatter(Vec3<Real> wi) const noexcept {
        SpecularScattering<Real> out;
        out.reflected = {-wi.x, -wi.y, wi.z};
        const Real e = relative_eta(wi.z);
        out.reflectance = reflectance(wi.z);
        out.transmittance = 1 - out.reflectance;
        out.radiance_transmittance = e * e * out.transmittance;
        const Real mt = transmitted_cosine(wi.z);
        if (mt == 0) {
            out.total_internal_reflection = e != Real(1) || wi.z != 0;
            return out;
        }
        // Tangential component scales by 1/eta (Snell), normal component is mt on the other side.
        out.transmitted = {-wi.x / e, -wi.y / e, mt};
        out.transmitted = normalize(out.transmitted);
        return out;
    }

private:
    Real eta_above_;
    Real eta_below_;
};

}  // namespace stratum
