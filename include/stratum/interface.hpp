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
// - Where the exact BRDF/BTDF exceeds Real's range (it diverges like 1 / cos at some grazing directions: a
//   masking-only BRDF as wo.z -> 0) it saturates at the largest finite value. A grazing pair whose half
//   vector underflows (|wi + wo|^2 = 0 in Real) is degenerate input, too: 0.
//
// Microfacet model (Stam 2001 Section 4, corrected as in docs/physics.md sections 4 and 11; Walter et al. 2007 form):
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
// straight-through direction flagged as delta, hemispherical_totals returns {0, 1}. For eta_above != eta_below the BTDF is a
// proper function however close the indices are; its lobe narrows like |eta - 1| sigma and its peak grows
// like 1/(eta - 1)^2 (finite; 0 is returned only where the Jacobian denominator is exactly 0). Note that with
// shadowing the energy of that lobe tends, as eta -> 1, to E[G2 / G1(i)] < 1 (the single-scattering model
// still counts light striking a second facet as lost, although at eta = 1 that facet is invisible), so the
// exact-matching identity is the limit only for masking_only. Measured (sigma = 0.3, height-correlated):
// T(eta = 1 + 1e-9) = 0.99999992 at mu_i = 0.77, 0.80 at mu_i = 0.2, against 1 at eta = 1 exactly.
//
// Smooth limit (sigma < RoughDielectric::smooth_sigma = 1e-7, sigma = 0 included; see there for the choice):
// the interface is the smooth dielectric (SmoothDielectric). As for index matching, brdf, btdf and pdf return
// 0, sample returns the mirror or Snell direction as a delta sample chosen with probability F or 1 - F, and
// hemispherical_totals returns {F, 1 - F}. Every value is finite for every sigma >= 0 (tests/test_interface_smooth_limit.cpp).
//
// Energy (tests/test_interface_energy.cpp): with masking_only, R + T equals 1 minus the facet-scattered light
// sent into the wrong hemisphere, as measured by a facet-level Monte Carlo (e.g. 0.63% at sigma = 0.3,
// eta = 1.4, 40 deg; 2.9% at sigma = 1, 60 deg). The default shadowing loses 1 - (R + T) = 0.89% (sigma = 0.3,
// eta = 1.4, 40 deg, from above), 8.3% (same, from the dense side), 23% and 48% (sigma = 1, 60 deg, from above
// and from below). Height-correlated transmission shadows more than separable (Chebyshev's inequality:
// B(1 + a, 1 + b) <= 1 / ((1 + a)(1 + b))), reflection less.
//
// Cost: eval, brdf, btdf and pdf are a few dozen flops and one exp/erfc each; sample adds two CDF inversions
// by Newton; hemispherical_totals is a 2-D integral (see there). Measured figures: README and docs/accuracy.md.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#include "detail/config.hpp"
#include "detail/math.hpp"
#include "detail/rough_hemispherical.hpp"
#include "detail/validate.hpp"
#include "fresnel.hpp"
#include "microfacet.hpp"
#include "quadrature.hpp"
#include "vec3.hpp"

namespace stratum {

// Shadowing and HemisphericalTotals are declared in microfacet.hpp.

/// Which way a path tracer follows light through eval and sample (pbrt's TransportMode, with this library's
/// argument order):
/// - importance: wi points to where the light (or a light-traced particle) comes from, wo to where it goes; the
///   value is f(wi -> wo). The library's own convention, and the default.
/// - radiance: wi points to the viewer (the direction a camera path already knows), wo to the light; the value is
///   f(wo -> wi), the BSDF with its arguments exchanged: the BTDF times (eta_wi / eta_wo)^2 by generalized
///   reciprocity (and the masking-only BRDF, the one non-symmetric form, evaluated the other way round).
/// The sampling density of wo given wi is the same in both modes; only the value (and so the weight) changes.
enum class TransportMode { importance, radiance };

/// The kinds of scattering (pbrt's BxDFType): a direction, reflection or transmission, and a kind, glossy (a
/// density) or specular (a delta). Combine with |. Passed to sample and pdf, a mask restricts sampling to the lobes
/// whose direction and kind it both holds (the density then is that of the restricted sampler); BsdfSample::lobe()
/// says what a sample is.
enum class Lobe : unsigned {
    reflection = 1u << 0,
    transmission = 1u << 1,
    glossy = 1u << 2,
    specular = 1u << 3,
    all = (1u << 4) - 1,
};
STRATUM_HOST_DEVICE constexpr Lobe operator|(Lobe a, Lobe b) noexcept {
    return static_cast<Lobe>(static_cast<unsigned>(a) | static_cast<unsigned>(b));
}
/// Whether `mask` holds the lobe of the given direction (reflected or not) and kind (delta: specular, else glossy).
STRATUM_HOST_DEVICE constexpr bool allows(Lobe mask, bool reflected, bool delta) noexcept {
    return (static_cast<unsigned>(mask) & static_cast<unsigned>(reflected ? Lobe::reflection : Lobe::transmission)) != 0 &&
           (static_cast<unsigned>(mask) & static_cast<unsigned>(delta ? Lobe::specular : Lobe::glossy)) != 0;
}

/// Result of RoughDielectric::sample. value = f(wi, wo) (no cosine) and pdf its solid-angle density, so the
/// Monte Carlo weight is value |wo.z| / pdf. A failed sample (direction into the wrong hemisphere, wi on the
/// horizon) has pdf = 0 and value = 0 and must be discarded. A delta sample (index-matched or smooth interface)
/// has delta = true, pdf = the probability of choosing that lobe and value = its power fraction / |wo.z| (the
/// coefficient of the solid-angle delta in wo), so the weight value |wo.z| / pdf is the lobe's power fraction per
/// selection probability, 1 when every lobe may be sampled:
/// - index matched: wo = -wi, pdf = 1;
/// - smooth (RoughDielectric::smooth()): mirror direction with pdf = F, or Snell direction with pdf = 1 - F
///   (F = fresnel_dielectric(|wi.z|, eta_t / eta_i); under total internal reflection the mirror, pdf = 1).
/// The weight is a power (flux) ratio, as for the rough lobes, whose weight G2 / G1(wi) tends to 1 as
/// sigma -> 0: sample() estimates int f(wi, wo) |wo.z| dwo over wo. A camera path tracer, which passes the
/// viewer's direction as wi, asks for TransportMode::radiance: a transmission's weight then carries
/// (n_viewer / n_light)^2 (generalized reciprocity btdf(wi, wo) / eta_o^2 = btdf(wo, wi) / eta_i^2), the
/// radiance factor of SmoothDielectric::radiance_transmittance.
template <class Real = double>
struct BsdfSample {
    Vec3<Real> wo{};
    Real value = 0;
    Real pdf = 0;
    bool reflected = false;
    bool delta = false;
    STRATUM_HOST_DEVICE bool valid() const noexcept { return pdf > 0; }
    /// The sample's lobe: reflection or transmission, and specular (a delta) or glossy.
    STRATUM_HOST_DEVICE Lobe lobe() const noexcept {
        return (reflected ? Lobe::reflection : Lobe::transmission) | (delta ? Lobe::specular : Lobe::glossy);
    }
};

namespace detail {

/// Joint masking-shadowing for the Smith Lambdas li (incident) and lo (outgoing), as a function of the
/// form and of whether the two directions are on opposite sides (transmission).
template <class W>
STRATUM_HOST_DEVICE W smith_g2(W li, W lo, Shadowing form, bool transmission) noexcept {
    const W inf = std::numeric_limits<W>::infinity();
    switch (form) {
        case Shadowing::masking_only: return 1 / (1 + li);
        case Shadowing::separable: return 1 / ((1 + li) * (1 + lo));
        case Shadowing::height_correlated:
        default:
            if (!transmission) return 1 / (1 + li + lo);
            if (li == inf || lo == inf) return W(0);
            // B(1 + li, 1 + lo) = Gamma(1 + li) Gamma(1 + lo) / Gamma(2 + li + lo) (thread-safe log-gammas,
            // detail/math.hpp). B <= B(1 + m, 1 + m) < 4^{-m}, m = min(li, lo): 0 in every type for m > 1e15,
            // where the log-gammas would overflow (inf - inf).
            if (!(std::fmin(li, lo) <= W(1e15))) return W(0);
            return std::exp(log_beta1(li, lo));
    }
}

}  // namespace detail

/// Rough dielectric interface: a Gaussian microsurface of RMS slope sigma between media of indices
/// eta_above (z > 0) and eta_below. All evaluation functions are noexcept and allocation-free.
/// sigma = 0 (and any sigma below smooth_sigma) is the smooth limit: see smooth().
template <class Real = double>
class RoughDielectric {
public:
    /// Below this RMS slope the interface is treated as exactly smooth (smooth()). The same value for every
    /// type, chosen above every arithmetic limit and below anything physical:
    /// - arithmetic: D's peak 1 / (2 pi sigma^2) and the BTDF and pdf peaks, which grow like
    ///   eta_o^2 / ((eta_o - eta_i)^2 sigma^2) (eta_o, eta_i adjacent floating-point numbers at worst), are
    ///   Real values (D, pdf and the visible-normal sampling are computed in Real, and Lambda and G2 too where both
    ///   cosines are at least 1e-4; the brdf/btdf products, albedo and G2 at grazing cosines in detail::wide_t).
    ///   They overflow for sigma below ~8.5e-139 in double (3e-155 for D alone) and ~1.8e-13 in float (2.2e-20 for
    ///   D alone). Meaning is lost earlier in float: a unit vector resolves
    ///   ~2^-24 = 6e-8 rad, so a lobe narrower than ~1e-7 lies within an ulp or two of its centre and its
    ///   values at representable directions are noise.
    /// - physical: a geometric-optics lobe narrower than the diffraction limit lambda / L means nothing; at
    ///   lambda = 0.5 um that is 1e-7 rad for a 5 m patch. Polished surfaces have RMS slopes >= ~1e-4, and no
    ///   renderer resolves 1e-7 rad (a 4K image of a 1 degree field has 4e-6 rad pixels).
    /// Continuity (tests/test_interface_smooth_limit.cpp): at sigma = smooth_sigma the rough albedo equals the
    /// Fresnel values within 1.9e-9 (the quadrature's error; the model's own difference is O(sigma^2) = 1e-14)
    /// at cosines 1e-3 or more from grazing and from a critical angle; within 1e-3 of a critical cosine the
    /// square-root onset of F is smeared by O(sqrt(sigma)) (1.1e-3 at n 1 | 1.5, 6e-3 at 1 | 1.0001).
    static constexpr Real smooth_sigma = Real(1) / Real(10000000);  // 1e-7 correctly rounded in every type
    /// The largest RMS slope accepted, 1e10 (facets within 1e-10 rad of vertical): hemispherical_totals() keeps its 1e-8
    /// accuracy up to it (measured 1e-11 at 1e10), not beyond (3e-6 at sigma = 1e140, found by fuzz_pointwise).
    static constexpr Real max_sigma = Real(1e10);

    /// sigma: RMS slope in [0, max_sigma] (0: the smooth limit); eta_above, eta_below: refractive indices in
    /// [1e-4, 1e4]. Throws std::invalid_argument naming the offending parameter.
    RoughDielectric(Real sigma, Real eta_above, Real eta_below, Shadowing shadowing = Shadowing::height_correlated)
        : sigma_(detail::require_closed("sigma", sigma, Real(0), max_sigma)),
          distribution_(sigma_ < smooth_sigma ? smooth_sigma : sigma_),
          eta_above_(detail::require_refractive_index("eta_above", eta_above)),
          eta_below_(detail::require_refractive_index("eta_below", eta_below)),
          shadowing_(shadowing) {}

    /// The Beckmann distribution of the facets. For a smooth interface (smooth()) a placeholder of RMS slope
    /// smooth_sigma, which this class never evaluates (Beckmann needs sigma > 0).
    STRATUM_HOST_DEVICE const Beckmann<Real>& distribution() const noexcept { return distribution_; }
    /// The RMS slope as constructed (0 allowed).
    STRATUM_HOST_DEVICE Real sigma() const noexcept { return sigma_; }
    STRATUM_HOST_DEVICE Real eta_above() const noexcept { return eta_above_; }
    STRATUM_HOST_DEVICE Real eta_below() const noexcept { return eta_below_; }
    STRATUM_HOST_DEVICE Shadowing shadowing() const noexcept { return shadowing_; }
    /// True when eta_above == eta_below exactly: the interface is invisible (see the header comment).
    STRATUM_HOST_DEVICE bool index_matched() const noexcept { return eta_above_ == eta_below_; }
    /// True when sigma < smooth_sigma (sigma = 0 included): the interface is the smooth dielectric, a specular
    /// reflector and refractor. brdf, btdf, eval and pdf return 0 (a delta cannot be evaluated); sample returns
    /// the mirror or Snell direction as a delta sample (see BsdfSample); hemispherical_totals returns the Fresnel values
    /// {F, 1 - F}, exactly SmoothDielectric's. Index matching takes precedence (identity transmission).
    STRATUM_HOST_DEVICE bool smooth() const noexcept { return sigma_ < smooth_sigma; }

    /// BRDF r(wi, wo) for wi, wo in the same hemisphere (either one); 0 otherwise, for index matching and
    /// for a smooth interface.
    /// Symmetric, brdf(wi, wo) == brdf(wo, wi), for every shadowing model but Shadowing::masking_only.
    STRATUM_HOST_DEVICE Real brdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        const detail::wide_t<Real> f = facet_brdf(wi, wo);
        if (!(f > 0)) return Real(0);
        return detail::saturate_to<Real>(times_g2_over_cosines(f, std::fabs(wi.z), std::fabs(wo.z), false));
    }

    /// BTDF t(wi, wo) for wi, wo in opposite hemispheres (light from wi's medium into wo's medium); 0 for
    /// the same hemisphere, for configurations no facet refracts, for index matching and for a smooth
    /// interface (deltas).
    /// Generalized reciprocity: btdf(wi, wo) / eta_o^2 == btdf(wo, wi) / eta_i^2.
    STRATUM_HOST_DEVICE Real btdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        const detail::wide_t<Real> f = facet_btdf(wi, wo);
        if (!(f > 0)) return Real(0);
        return detail::saturate_to<Real>(times_g2_over_cosines(f, std::fabs(wi.z), std::fabs(wo.z), true));
    }

    /// brdf and btdf as (facet term) x (shadowing term), the second depending on the two cosines alone:
    ///   brdf(wi, wo) = facet_brdf(wi, wo) shadowing_over_cosines(|wi.z|, |wo.z|, false),
    ///   btdf(wi, wo) = facet_btdf(wi, wo) shadowing_over_cosines(|wi.z|, |wo.z|, true),
    /// equal to brdf and btdf within a few ulp (the order of the products differs), for callers that evaluate
    /// many directions sharing two cosines (the azimuthal integrals of InterfaceOperators) and compute the
    /// shadowing, the costly part, once. Returned in the wide type (double for float); for float the shadowing is
    /// computed in float where both cosines are at least 1e-4 (see times_g2_over_cosines).
    /// facet_brdf = F(i.h) D(h) / 4, facet_btdf = |i.h| |o.h| eta_o^2 (1 - F) D(h) / (eta_i i.h + eta_o o.h)^2, and 0
    /// wherever brdf or btdf is 0 for any other reason than shadowing.
    STRATUM_HOST_DEVICE detail::wide_t<Real> facet_brdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z * wo.z > 0) || index_matched() || smooth()) return 0;
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        const Vec3<Real> sum = wi + wo;
        const Real len2 = dot(sum, sum);
        if (!(len2 > 0)) return 0;
        const Vec3<Real> h = (Real(1) / std::sqrt(len2)) * sum;
        const Real c = dot(wi, h);
        if (!(c > 0) || !(dot(wo, h) > 0)) return 0;
        const Real D = distribution_.D(h);
        if (!(D > 0)) return 0;  // (spares the Lambdas, and 0 * inf at grazing directions)
        const Real F = fresnel_dielectric(c, eta_t / eta_i);
        if (!(F > 0)) return 0;  // (and 0 * inf where the cosines are subnormal)
        using W = detail::wide_t<Real>;
        return static_cast<W>(F) * static_cast<W>(D) / 4;
    }
    STRATUM_HOST_DEVICE detail::wide_t<Real> facet_btdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z * wo.z < 0) || index_matched() || smooth()) return 0;
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_o = below ? eta_above_ : eta_below_;
        Vec3<Real> v = eta_i * wi + eta_o * wo;
        const Real len2 = dot(v, v);
        if (!(len2 > 0)) return 0;
        Vec3<Real> h = (Real(1) / std::sqrt(len2)) * v;
        if (h.z < 0) h = -h;
        const Real ci = dot(wi, h), co = dot(wo, h);
        if (!(ci > 0) || !(co < 0)) return 0;
        const Real D = distribution_.D(h);
        if (!(D > 0)) return 0;  // (spares the Lambdas, and 0 * inf at grazing directions)
        const Real F = fresnel_dielectric(ci, eta_o / eta_i);
        if (!(F < 1)) return 0;  // facet total internal reflection (and 0 * inf at subnormal cosines)
        // (eta_i (i.h) + eta_o (o.h))^2 == |v|^2, since h = +-v / |v|. The product in the wide type: for float
        // its factors can leave float's range at grazing directions although the value does not.
        using W = detail::wide_t<Real>;
        const W eo = eta_o;
        return static_cast<W>(ci) * static_cast<W>(-co) * eo * eo * static_cast<W>(1 - F) * static_cast<W>(D) /
               static_cast<W>(len2);
    }
    /// G2(mu_i, mu_o) / (mu_i mu_o) for cosines in (0, 1] (the shadowing form of the interface; transmission
    /// selects the height-correlated form's transmission variant). +inf or NaN where a cosine is subnormal or 0:
    /// use brdf or btdf there.
    STRATUM_HOST_DEVICE detail::wide_t<Real> shadowing_over_cosines(Real mu_i, Real mu_o, bool transmission) const noexcept {
        return times_g2_over_cosines(detail::wide_t<Real>(1), mu_i, mu_o, transmission);
    }

    /// brdf or btdf, whichever the hemispheres of wi and wo call for; in TransportMode::radiance with the
    /// arguments exchanged (see TransportMode).
    STRATUM_HOST_DEVICE Real eval(Vec3<Real> wi, Vec3<Real> wo, TransportMode mode = TransportMode::importance) const noexcept {
        if (mode == TransportMode::radiance) return eval(wo, wi);
        return wi.z * wo.z > 0 ? brdf(wi, wo) : btdf(wi, wo);
    }

    /// The BSDF for directions given as PROPAGATION directions, the form a radiative-transfer solver uses.
    ///   mu_in:    cosine (to +z) of the incident propagation direction; mu_in < 0 is light travelling down,
    ///             i.e. arriving from above (wi = -incident propagation direction).
    ///   mu_out:   cosine of the outgoing propagation direction (mu_out > 0: leaving upwards).
    ///   cos_dphi: cosine of the azimuth difference between the two propagation directions, so specular
    ///             reflection and refraction lie at dphi = 0.
    /// Returns f (per steradian, cosine NOT included); mu_in * mu_out > 0 is transmission, < 0 reflection.
    STRATUM_HOST_DEVICE Real eval_propagation(Real mu_in, Real mu_out, Real cos_dphi) const noexcept {
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
    /// Smooth interface (smooth()): the mirror direction if u_lobe < F(|wi.z|) (always under total internal
    /// reflection), else the Snell direction, as a delta sample (u1, u2 unused).
    /// In TransportMode::radiance wi is the viewer's direction and the value is eval(wi, wo, radiance) (see
    /// TransportMode): a refracted sample's weight is then (eta_wi / eta_wo)^2 times the importance weight.
    /// `allowed` restricts the lobes (Lobe): with reflection or transmission alone the other is never chosen (its
    /// selection probability F or 1 - F becomes 1 for the one allowed); a lobe of the wrong kind (glossy for a
    /// smooth interface, specular for a rough one) gives a failed sample.
    STRATUM_HOST_DEVICE BsdfSample<Real> sample(Vec3<Real> wi, Real u_lobe, Real u1, Real u2,
                                                TransportMode mode = TransportMode::importance,
                                                Lobe allowed = Lobe::all) const noexcept {
        BsdfSample<Real> out = sample_importance(wi, u_lobe, u1, u2, allowed);
        if (mode == TransportMode::radiance && out.valid()) {
            if (out.delta) {
                // The delta's coefficient scales as the BTDF: (eta_wi / eta_wo)^2 for a refraction.
                const Real eta_wi = wi.z > 0 ? eta_above_ : eta_below_, eta_wo = out.wo.z > 0 ? eta_above_ : eta_below_;
                if (!out.reflected) out.value *= (eta_wi / eta_wo) * (eta_wi / eta_wo);
            } else {
                out.value = eval(wi, out.wo, mode);
            }
        }
        return out;
    }

private:
    STRATUM_HOST_DEVICE BsdfSample<Real> sample_importance(Vec3<Real> wi, Real u_lobe, Real u1, Real u2,
                                                           Lobe allowed) const noexcept {
        BsdfSample<Real> out;
        // The horizon, and subnormal cosines: a delta sample's value 1 / |wo.z| would overflow (found by
        // fuzz_pointwise at wi.z = 2e-315); such directions carry no energy.
        if (!(std::fabs(wi.z) >= std::numeric_limits<Real>::min())) return out;
        // (a NaN or infinite wi.x or wi.y: the delta branches below returned a valid sample with a NaN direction;
        // found by a review sweep)
        if (!all_finite(wi)) return out;
        const bool delta = index_matched() || smooth();
        const bool may_reflect = allows(allowed, true, delta), may_transmit = allows(allowed, false, delta);
        if (!may_reflect && !may_transmit) return out;
        if (index_matched()) {
            if (!may_transmit) return out;
            out.wo = -wi;
            out.delta = true;
            out.pdf = Real(1);
            out.value = Real(1) / std::fabs(wi.z);
            return out;
        }
        const bool below = wi.z < 0;
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        if (smooth()) return sample_smooth(wi, eta_t / eta_i, u_lobe, may_reflect, may_transmit);
        Vec3<Real> w = wi;
        if (below) w.z = -w.z;
        const Vec3<Real> h = distribution_.sample_visible_normal(w, u1, u2);
        const Real c = dot(w, h);
        if (!(c > 0)) return out;
        const Real eta = eta_t / eta_i;
        const Real F = fresnel_dielectric(c, eta);
        Vec3<Real> wo;
        if (may_reflect && (u_lobe < F || !may_transmit)) {
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
        out.pdf = pdf(wi, wo, allowed);
        if (!(out.pdf > 0)) {
            out.pdf = 0;
            return out;
        }
        out.value = eval(wi, wo);
        return out;
    }

public:
    /// Solid-angle density of sample(wi, ...) at wo: visible-normal density times the selection
    /// probability (F or 1 - F; 1 when `allowed` holds that lobe alone, 0 when it does not hold it) times the
    /// Jacobian dh/dwo (1 / (4 (wo.h)) for reflection, eta_o^2 |wo.h| / (eta_i (wi.h) + eta_o (wo.h))^2 for
    /// refraction). 0 for index matching and smooth (deltas).
    STRATUM_HOST_DEVICE Real pdf(Vec3<Real> wi, Vec3<Real> wo, Lobe allowed = Lobe::all) const noexcept {
        if (!(wi.z != 0) || !(wo.z != 0) || index_matched() || smooth()) return Real(0);
        const bool may_reflect = allows(allowed, true, false), may_transmit = allows(allowed, false, false);
        if (!(wi.z * wo.z > 0 ? may_reflect : may_transmit)) return Real(0);
        const bool both = may_reflect && may_transmit;
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
            return distribution_.visible_normal_pdf(wi, h) * (both ? fresnel_dielectric(c, eta_t / eta_i) : Real(1)) / (4 * c);
        }
        const Vec3<Real> v = eta_i * wi + eta_t * wo;
        const Real len2 = dot(v, v);
        if (!(len2 > 0)) return Real(0);
        Vec3<Real> h = (Real(1) / std::sqrt(len2)) * v;
        if (h.z < 0) h = -h;
        const Real ci = dot(wi, h), co = dot(wo, h);
        if (!(ci > 0) || !(co < 0)) return Real(0);
        const Real T = both ? 1 - fresnel_dielectric(ci, eta_t / eta_i) : Real(1);
        return distribution_.visible_normal_pdf(wi, h) * T * eta_t * eta_t * (-co) / len2;
    }

    /// Hemispherical reflectance and transmittance for light arriving from a direction with cosine mu_i
    /// (mu_i > 0: from above, wi.z = mu_i; mu_i < 0: from below): R = int brdf |wo.z| dwo over wi's
    /// hemisphere, T = int btdf |wo.z| dwo over the other one. Computed over facet slopes, where no Jacobian
    /// appears (so it stays smooth as eta -> 1); see detail/rough_hemispherical.hpp for the method. `nodes` is the
    /// Gauss-Legendre count per x panel (3/4 of it per y panel). Accuracy, measured against the previous
    /// implementation at 56 nodes per panel (tests/test_interface_albedo.cpp and a 1944-case grid: sigma in
    /// [1e-4, 2], eta_t / eta_i in {1/2.5, 1/1.4, 1/1.0001, 1 -+ 1e-9, 1.0001, 1.1, 1.4, 2.5}, |mu_i| in [0, 1],
    /// all three Shadowing forms): absolute error <= 1e-8 with the default 16 nodes (largest 9.9e-9, at
    /// sigma = 0.3, eta = 0.4, mu = 0.766, separable; typically < 1e-10), <= 3e-9 with 32 (the reference's own
    /// error). Agreement with the
    /// direct integral of brdf/btdf over wo within that integral's own error (<= 5e-7, test_interface_energy).
    /// Values of `nodes` above 32 are treated as 32. Height-correlated transmission at mu_i = 0 exactly
    /// (Lambda(wi) = inf) is 0, the limit (1 + li)^{-lo} -> 0 for every lo > 0. Smooth interface (smooth()):
    /// exactly {F, 1 - F}, F = fresnel_dielectric(|mu_i|, eta_t / eta_i) (SmoothDielectric's values).
    /// Cost: a two-dimensional integral of 3 000 - 20 000 facet evaluations (more for large sigma and for
    /// eta < 1, where more curves cross): microseconds to a millisecond (BM_interface_hemispherical_totals;
    /// figures in docs/accuracy.md). Throws std::invalid_argument for nodes < 2.
    HemisphericalTotals<Real> hemispherical_totals(Real mu_i, int nodes = 16) const {
        detail::require_count("nodes", nodes, 2);
        nodes = nodes < 32 ? nodes : 32;
        using W = detail::wide_t<Real>;
        if (index_matched()) return {Real(0), Real(1)};
        if (smooth()) {  // the Fresnel values, bit for bit SmoothDielectric's
            const Real F = fresnel_dielectric(std::fmin(std::fabs(mu_i), Real(1)),
                                              mu_i < 0 ? eta_above_ / eta_below_ : eta_below_ / eta_above_);
            return {F, 1 - F};
        }
        const bool below = mu_i < 0;
        const W eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        // Cosines below 1e-150 are raised to it: the totals have converged to their grazing limit long before
        // (to all digits from 1e-20 on), and near the smallest normal double Lambda's 1/a overflowed into NaN
        // (found by fuzz_pointwise at mu = 2.25e-308). 0 itself is the limit, handled exactly.
        W m = std::fmin(std::fabs(static_cast<W>(mu_i)), W(1));
        if (m > 0 && m < W(1e-150)) m = W(1e-150);
        const auto a = detail::rough_hemispherical_totals<W>(distribution_.sigma(), m, eta_t / eta_i, shadowing_, nodes);
        return {static_cast<Real>(a.reflectance), static_cast<Real>(a.transmittance)};
    }

    /// hemispherical_totals(mu_i).reflectance (the same integral: cache the pair where both are needed)
    Real hemispherical_reflectance(Real mu_i) const { return hemispherical_totals(mu_i).reflectance; }
    /// hemispherical_totals(mu_i).transmittance
    Real hemispherical_transmittance(Real mu_i) const { return hemispherical_totals(mu_i).transmittance; }

private:
    // The smooth interface's delta sample for wi (wi.z != 0) and eta = eta_t / eta_i: the mirror direction with
    // probability F (1 under total internal reflection), else the Snell direction (tangential component / eta,
    // normal cosine sqrt(mu^2 + eta^2 - 1) / eta on the other side, as SmoothDielectric::scatter). pdf is the
    // selection probability and value = the power fraction / |wo.z|, so the weight value |wo.z| / pdf is 1
    // (BsdfSample); with one direction allowed alone its probability is 1 (and the weight its power fraction).
    STRATUM_HOST_DEVICE static BsdfSample<Real> sample_smooth(Vec3<Real> wi, Real eta, Real u_lobe, bool may_reflect,
                                                              bool may_transmit) noexcept {
        BsdfSample<Real> out;
        out.delta = true;
        const Real mu = std::fmin(std::fabs(wi.z), Real(1));
        const Real F = fresnel_dielectric(mu, eta);
        if (may_reflect && (u_lobe < F || !(F < 1) || !may_transmit)) {
            if (!(F > 0)) return {};
            out.wo = {-wi.x, -wi.y, wi.z};
            out.reflected = true;
            out.pdf = may_transmit ? F : Real(1);
            out.value = F / std::fabs(wi.z);
            return out;
        }
        if (!(F < 1)) return {};  // total internal reflection, and only transmission allowed
        // F < 1: no total internal reflection, so m2 > 0 (fresnel_dielectric returns 1 for m2 <= 0, eta != 1).
        const Real m2 = mu * mu + (eta - 1) * (eta + 1);
        const Real mt = std::fmin(std::sqrt(m2) / eta, Real(1));
        out.wo = normalize(Vec3<Real>{-wi.x / eta, -wi.y / eta, wi.z > 0 ? -mt : mt});
        if (!(std::fabs(out.wo.z) >= std::numeric_limits<Real>::min())) return {};  // refracted onto the horizon
        out.pdf = may_reflect ? 1 - F : Real(1);
        out.value = (1 - F) / std::fabs(out.wo.z);
        return out;
    }

    // factor G2 / (mu_i mu_o) for cosines mu_i, mu_o (both > 0, already on their own sides), in the wide type.
    // G2 vanishes like the cosines at grazing directions, so G2 / mu_i stays bounded; the factor multiplies
    // before the last division so that a small factor keeps the value finite where 1 / mu_o alone would not
    // be (a subnormal mu_o), and mu_i mu_o (or its reciprocal) is never formed (it leaves float's range).
    STRATUM_HOST_DEVICE detail::wide_t<Real> times_g2_over_cosines(detail::wide_t<Real> factor, Real mu_i, Real mu_o,
                                                                   bool transmission) const noexcept {
        using W = detail::wide_t<Real>;
        if constexpr (!std::is_same_v<Real, W>) {
            if (mu_i >= narrow_cosine_min && mu_o >= narrow_cosine_min) {
                const Real g2 = detail::smith_g2<Real>(shadowing_lambda<Real>(mu_i), shadowing_lambda<Real>(mu_o),
                                                       shadowing_, transmission);
                return factor * static_cast<W>(g2 / mu_i) / static_cast<W>(mu_o);
            }
        }
        const W li = shadowing_lambda<W>(mu_i), lo = shadowing_lambda<W>(mu_o);
        const W g2_over_mu_i = detail::smith_g2<W>(li, lo, shadowing_, transmission) / static_cast<W>(mu_i);
        return factor * g2_over_mu_i / static_cast<W>(mu_o);
    }

    // The shadowing of a type narrower than double (float) is computed in that type where both cosines are at
    // least narrow_cosine_min: every factor then stays inside float's range (a = mu / (alpha s) >= 7e-15, Lambda
    // <= 4e13); below, in the wide type.
    static constexpr Real narrow_cosine_min = Real(1e-4);
    // Where a = cot(theta) / alpha reaches this, Lambda < eps(C) / 4 (float: Lambda(4) = 2.3e-10; double and long
    // double: Lambda(6.25) = 6.0e-21; wider: Lambda(9.5) = 1.0e-43): it enters the shadowing only as 1 + Lambda (log_beta1
    // included), where C cannot tell it from 0, so it is returned as 0 without smith_lambda_gaussian's continued
    // fraction (a fifth of a float brdf's time; in double the results are unchanged, bit for bit).
    template <class C>
    static constexpr C negligible_lambda_a() noexcept {
        return std::numeric_limits<C>::digits <= 24 ? C(4) : std::numeric_limits<C>::digits <= 64 ? C(6.25) : C(9.5);
    }
    // Smith's Lambda of the cosine mu (only |mu| matters) for the shadowing, computed in C: a as Beckmann::Lambda
    // forms it.
    template <class C>
    STRATUM_HOST_DEVICE C shadowing_lambda(Real mu) const noexcept {
        const C m = std::fmin(std::fabs(static_cast<C>(mu)), C(1));
        const C alpha_s = static_cast<C>(distribution_.alpha()) * std::sqrt((1 - m) * (1 + m));
        if (!(m < negligible_lambda_a<C>() * alpha_s)) return C(0);  // (also at m = 1, where s = 0, and for NaN)
        return detail::smith_lambda_gaussian<C>(m / alpha_s);
    }

    Real sigma_;
    Beckmann<Real> distribution_;  // a placeholder of RMS slope smooth_sigma when smooth()
    Real eta_above_;
    Real eta_below_;
    Shadowing shadowing_;
};

/// Result of SmoothDielectric::scatter for one incident direction wi.
template <class Real = double>
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
template <class Real = double>
class SmoothDielectric {
public:
    /// eta_above, eta_below: refractive indices in [1e-4, 1e4]; throws std::invalid_argument otherwise.
    SmoothDielectric(Real eta_above, Real eta_below)
        : eta_above_(detail::require_refractive_index("eta_above", eta_above)),
          eta_below_(detail::require_refractive_index("eta_below", eta_below)) {}

    STRATUM_HOST_DEVICE Real eta_above() const noexcept { return eta_above_; }
    STRATUM_HOST_DEVICE Real eta_below() const noexcept { return eta_below_; }

    /// Relative index eta_t / eta_i for light arriving with cosine mu_i.
    STRATUM_HOST_DEVICE Real relative_eta(Real mu_i) const noexcept { return mu_i >= 0 ? eta_below_ / eta_above_ : eta_above_ / eta_below_; }

    /// Fresnel reflectance F(|mu_i|, eta_t / eta_i); 1 under total internal reflection; 0 (exactly, as F) when
    /// the indices match, without computing F (the layer solver asks at every ordinate of index-matched faces).
    STRATUM_HOST_DEVICE Real reflectance(Real mu_i) const noexcept {
        return eta_above_ == eta_below_ ? Real(0) : fresnel_dielectric(std::fabs(mu_i), relative_eta(mu_i));
    }

    /// Transmitted power fraction 1 - F.
    STRATUM_HOST_DEVICE Real transmittance(Real mu_i) const noexcept { return 1 - reflectance(mu_i); }

    /// Transmitted radiance per incident radiance, (eta_t / eta_i)^2 (1 - F) (radiance / n^2 is invariant).
    STRATUM_HOST_DEVICE Real radiance_transmittance(Real mu_i) const noexcept {
        const Real e = relative_eta(mu_i);
        return e * e * transmittance(mu_i);
    }

    /// Cosine of the transmitted direction (pointing away from the surface, so of the opposite sign to
    /// mu_i): |mu_t| = sqrt(mu_i^2 + eta^2 - 1) / eta, eta = eta_t / eta_i; 0 under total internal reflection.
    STRATUM_HOST_DEVICE Real transmitted_cosine(Real mu_i) const noexcept {
        const Real e = relative_eta(mu_i);
        const Real m2 = mu_i * mu_i + (e - 1) * (e + 1);
        if (!(m2 > 0)) return Real(0);
        const Real mt = std::fmin(std::sqrt(m2) / e, Real(1));
        return mu_i >= 0 ? -mt : mt;
    }

    /// Both scattered directions and their weights for a unit vector wi.
    STRATUM_HOST_DEVICE SpecularScattering<Real> scatter(Vec3<Real> wi) const noexcept {
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
