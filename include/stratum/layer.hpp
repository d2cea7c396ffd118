// stratum/layer.hpp -- a scattering layer bounded by dielectric interfaces, solved by the discrete-
// ordinate method (Stam 2001, "An Illumination Model for a Skin Layer Bounded by Rough Surfaces"),
// evaluated at arbitrary directions.
//
// Geometry. Medium 1 (index n1) above, the layer (n2) in the middle, medium 3 (n3) below. The top
// boundary separates 1 | 2, the bottom one 2 | 3; each is a RoughDielectric, a SmoothDielectric or index
// matched. Directions follow vec3.hpp: wi towards the light, wo towards the viewer, both pointing away
// from the surface; light arrives from above (wi.z > 0).
//
// Method (physics-notes sections 5-6). Per Fourier mode k and on M half-range ordinates, every component
// is a set of M x M operators mapping incoming to outgoing radiance coefficients (adding.hpp): the
// interfaces' R_12, T_12, R_21, T_21 (interface_operators.hpp) and the bare slab's R, T (slab.hpp). With
// S the reflection of everything below the top interface seen from inside the layer (slab + bottom
// interface, by the adding equations), the field inside the layer driven by radiance coefficients c
// transmitted through the top is
//     a = (I - R_21 S)^{-1} c          (down-going, just below the top interface)
//     b = S a                          (up-going, just below the top interface)
//     e = (I - R_s R_23)^{-1} T_s a    (down-going, arriving at the bottom interface)
// so per mode the solver keeps Q_b = S (I - R_21 S)^{-1} and Q_e = (I - R_s R_23)^{-1} T_s (I - R_21 S)^{-1}.
// Only the internal field lives on ordinates. For a rough top the incident direction enters through
// the top's transmission coefficients evaluated at the true mu_0 and the outgoing one through t_21 at the
// true mu (no interpolation; physics-notes section 6):
//     c_{k,m}   = (2 - delta_k0) / (2 pi) I^{t12}_k(mu_0 -> mu_m)
//     f_s(wi, wo) = sum_k cos(k dphi) sum_m w_m mu_m I^{t21}_k(mu_m -> mu) (Q_b c_k)_m,
// with dphi the azimuth between the incident and outgoing PROPAGATION directions (-wi and wo).
// Both Gauss sums over the ordinates (the flux entering, sum_m w_m mu_m I^{t12}_0, and the exit weights) are
// rescaled to their exact values, T_12(mu_0) and (n_out/n_in)^2 T(mu) by reciprocity, so that a lobe the
// ordinates do not resolve neither creates nor loses energy; the interface operators are renormalized to
// the hemispherical totals in the same way (LayerOptions::renormalization).
// A specular (smooth or index-matched) boundary has no BTDF to carry the true angle. Between two specular
// faces the unscattered beam is kept out of the discrete fields and computed exactly at the true angle
// (direct_transmittance, direct_reflectance: Fresnel factors, e^{-tau/mu'}, the bounces between the faces).
// The light it scatters starts from the beam spread over the ordinates inside the escape cone (Lagrange
// weights that conserve its flux, 4 points from 8 ordinates on, linear below; mode k scaled by
// (sin theta' / sin theta_m)^k so that a beam along the normal has no k > 0 modes), scaled to the energy the
// true beam loses; radiance leaves a smooth face by 4-point interpolation between the ordinates inside its
// escape cone. That interpolation is the documented approximation of this path: tests/test_layer.cpp and
// tests/test_layer_monte_carlo.cpp measure it (up to 0.01 near a critical angle). The exact treatment,
// DISORT's beam source with intensities at user angles, is not done yet.
//
// Units: BRDF/BTDF per steradian (cosine not included), reflectance and transmittance as fractions of the
// incident flux, ambient as reflected radiance per unit incident sky radiance.
#pragma once

#include <cmath>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "adding.hpp"
#include "detail/linalg.hpp"
#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "henyey_greenstein.hpp"
#include "interface.hpp"
#include "interface_operators.hpp"
#include "quadrature.hpp"
#include "slab.hpp"
#include "vec3.hpp"

namespace stratum {

/// The outputs a scene asks for; combine with |. The solver skips the work of the others.
enum class LayerOutput : unsigned {
    surface_reflection = 1u << 0,     ///< r_12: reflection by the top interface alone (needs no solve)
    subsurface_reflection = 1u << 1,  ///< r_s: light that entered the layer and came back out of the top
    transmission = 1u << 2,           ///< t_s: light leaving through the bottom
    ambient = 1u << 3,                ///< r_a: subsurface reflection of a uniform sky (Fourier mode 0 only)
    operators = 1u << 4,              ///< the whole layer's per-mode operators on the ordinates (for stacking)
    all = (1u << 5) - 1,
};
constexpr LayerOutput operator|(LayerOutput a, LayerOutput b) noexcept {
    return static_cast<LayerOutput>(static_cast<unsigned>(a) | static_cast<unsigned>(b));
}
constexpr bool includes(LayerOutput set, LayerOutput o) noexcept {
    return (static_cast<unsigned>(set) & static_cast<unsigned>(o)) != 0;
}

/// Discretization knobs.
struct LayerOptions {
    int ordinates = 16;   ///< M half-range ordinates per hemisphere (gauss_legendre_half), >= 1
    int modes = 0;        ///< K azimuthal modes; 0 = 2M (as many as 2M Legendre moments support)
    bool delta_m = true;  ///< delta-M scaling (Wiscombe 1977) with 2M moments, for g > 0 (forward peaks)
    /// Rough boundaries: rescale each operator column to the exact hemispherical totals (interface_operators.hpp).
    Renormalization renormalization = Renormalization::hemispherical_totals;
    /// Smooth boundaries: how the Snell-mapped transmission is put on the ordinates (interface_operators.hpp).
    /// automatic: as there for the top and bottom faces, flux_conserving for the interior faces of a stack
    /// (solve_stack), where only it keeps energy; pointwise there can create energy (README, known limitations).
    SpecularTransmission specular_transmission = SpecularTransmission::automatic;
};

/// What a scene needs (see LayerOutput); the solver computes nothing else.
template <class Real = double>
struct LayerRequest {
    LayerOutput outputs = LayerOutput::all;
    /// Incidence cosines mu_0 in (0, 1] at which brdf/btdf/reflectance/transmittance will be evaluated; their internal fields
    /// are precomputed, so evaluation there skips the top interface's coefficients and the per-mode solve.
    /// Other incidences still work (computed on the fly).
    std::vector<Real> incidence;
    /// Modes beyond this are not solved (0 = no cap beyond LayerOptions::modes).
    int max_modes = 0;
    /// 0: everything exact to the discretization. > 0: (a) modes are solved in order and the loop stops
    /// after two consecutive modes whose operators are below tolerance relative to mode 0; (b) a slab with
    /// e^{-tau} < tolerance is solved as semi-infinite when transmission is not requested.
    Real tolerance = 0;
};

/// A boundary of a layer: rough (Beckmann microfacets) or specular (smooth or index-matched).
/// Converts implicitly from RoughDielectric and SmoothDielectric.
template <class Real = double>
class Boundary {
public:
    Boundary(const RoughDielectric<Real>& rough) : rough_(rough), smooth_(rough.eta_above(), rough.eta_below()) {}  // NOLINT
    Boundary(const SmoothDielectric<Real>& smooth) : smooth_(smooth) {}                                            // NOLINT
    /// Both sides of index eta: light crosses unchanged.
    static Boundary index_matched(Real eta = Real(1)) { return Boundary(SmoothDielectric<Real>(eta, eta)); }

    bool rough() const noexcept { return rough_.has_value() && !rough_->index_matched() && !rough_->smooth(); }
    Real eta_above() const noexcept { return smooth_.eta_above(); }
    Real eta_below() const noexcept { return smooth_.eta_below(); }
    const std::optional<RoughDielectric<Real>>& rough_interface() const noexcept { return rough_; }
    const SmoothDielectric<Real>& smooth_interface() const noexcept { return smooth_; }

    InterfaceOperators<Real> operators(const Quadrature<Real>& q, int modes, const LayerOptions& o) const {
        return rough() ? InterfaceOperators<Real>(*rough_, q, modes, AzimuthalQuadrature<Real>(), o.renormalization)
                       : InterfaceOperators<Real>(smooth_, q, modes, o.specular_transmission);
    }
    /// Directional-hemispherical transmittance for light arriving with cosine mu (> 0 from above): an
    /// integral for a rough face, the Fresnel value for a smooth one.
    Real hemispherical_transmittance(Real mu) const {
        return rough() ? rough_->hemispherical_transmittance(mu) : smooth_.transmittance(mu);
    }
    /// Directional-hemispherical reflectance for light arriving with cosine mu (> 0 from above), likewise.
    Real hemispherical_reflectance(Real mu) const {
        return rough() ? rough_->hemispherical_reflectance(mu) : smooth_.reflectance(mu);
    }

private:
    std::optional<RoughDielectric<Real>> rough_;
    SmoothDielectric<Real> smooth_;  // the indices; the specular model when not rough
};

template <class Real>
class LayeredSurface;

/// Solves a stack: `top` boundary, then slabs[0], interior[0], slabs[1], ..., slabs[N-1], then `bottom`
/// (interior.size() == slabs.size() - 1). Adjacent indices must agree (top.eta_below() ==
/// interior[0].eta_above(), ...). Throws std::invalid_argument for inconsistent input or bad options.
/// The boundaries are not deduced, so a RoughDielectric or SmoothDielectric converts to a Boundary.
template <class Real>
LayeredSurface<Real> solve_stack(const detail::non_deduced_t<Boundary<Real>>& top, const std::vector<Slab<Real>>& slabs,
                                 const std::vector<Boundary<Real>>& interior,
                                 const detail::non_deduced_t<Boundary<Real>>& bottom, const LayerOptions& options = {},
                                 const detail::non_deduced_t<LayerRequest<Real>>& request = {});

namespace detail {

template <class Real>
ComponentOperators<Real> interface_component(const InterfaceOperators<Real>& ops, int k) {
    ComponentOperators<Real> c;
    c.size = static_cast<std::size_t>(ops.size());
    const std::size_t n = c.size * c.size;
    auto copy = [&](const FourierOperators<Real>& f) { return std::vector<Real>(f.mode(k), f.mode(k) + n); };
    c.reflection_down = copy(ops.R12());
    c.transmission_down = copy(ops.T12());
    c.reflection_up = copy(ops.R21());
    c.transmission_up = copy(ops.T21());
    return c;
}

/// The slab's per-mode operators, with delta-M scaling and the Henyey-Greenstein phase matrices.
template <class Real>
struct SlabModes {
    Slab<Real> slab;  // possibly delta-M scaled
    PhaseFourierMatrices<Real> phase;
};

template <class Real>
SlabModes<Real> prepare_slab(const Slab<Real>& s, const Quadrature<Real>& q, int modes, bool delta_m, Real tau_override) {
    const int moments = 2 * static_cast<int>(q.size());
    const Real tau = tau_override;
    // Delta-M folds a FORWARD peak into the unscattered beam; for g < 0 (a backward peak) its moments
    // (g^l - f) / (1 - f) would be far outside [-1, 1], so backward-scattering media are truncated plainly.
    if (delta_m && s.g() > Real(0)) {
        const DeltaMScaled<Real> dm = delta_m_scaling(s.albedo(), tau, s.g(), moments);
        // 1 - Omega' = (1 - Omega) / (1 - f Omega), with 1 - f Omega = (1 - f) + f (1 - Omega): no cancellation.
        const Real one_minus_f_omega = (Real(1) - dm.f) + dm.f * s.one_minus_albedo();
        const Slab<Real> scaled = Slab<Real>::from_one_minus_albedo(s.one_minus_albedo() / one_minus_f_omega, s.g(),
                                                                    one_minus_f_omega * tau);
        return {scaled, phase_fourier_matrices(dm.moments, q.nodes, modes)};
    }
    const HenyeyGreenstein<Real> hg(s.g());
    return {Slab<Real>::from_one_minus_albedo(s.one_minus_albedo(), s.g(), tau),
            phase_fourier_matrices(hg.legendre_moments(moments), q.nodes, modes)};
}

/// A function of mu in (0, 1] tabulated at N + 1 points equispaced in t = sqrt(mu) and interpolated by cubic
/// Lagrange polynomials in t on the 4 nearest points: the hemispherical transmittance of a rough boundary,
/// which costs a 2-D integral per value and changes fastest near grazing (its limit at mu -> 0+ differs from
/// its value at mu = 0, which is the point t = 0 is given instead). Error: tests/test_layer.cpp measures it.
template <class Real>
struct MuTable {
    std::vector<Real> values;  // f((j / N)^2), j = 0..N (j = 0: the limit mu -> 0+)
    template <class F>
    void build(int intervals, F f) {
        values.resize(static_cast<std::size_t>(intervals) + 1);
        for (int j = 0; j <= intervals; ++j) {
            const Real t = Real(j) / Real(intervals);
            values[static_cast<std::size_t>(j)] = f(j == 0 ? Real(1e-12) : t * t);
        }
    }
    Real operator()(Real mu) const noexcept {
        const int n = static_cast<int>(values.size()) - 1;
        const Real x = std::sqrt(std::fmin(std::fmax(mu, Real(0)), Real(1))) * Real(n);
        const int first = std::min(std::max(static_cast<int>(x) - 1, 0), n - 3);
        Real sum = 0;
        for (int a = 0; a < 4; ++a) {
            Real l = 1;
            for (int b = 0; b < 4; ++b)
                if (b != a) l *= (x - Real(first + b)) / Real(a - b);
            sum += l * values[static_cast<std::size_t>(first + a)];
        }
        return sum;
    }
};

/// Largest entry of a slab's diffuse operators: R, and T without its unscattered diagonal e^{-tau/mu}.
template <class Real>
Real diffuse_size(const ComponentOperators<Real>& c, const std::vector<Real>& mu, Real tau) noexcept {
    const std::size_t m = c.size;
    Real x = 0;
    for (std::size_t i = 0; i < m; ++i)
        for (std::size_t j = 0; j < m; ++j) {
            const Real direct = (i == j && std::isfinite(tau)) ? std::exp(-tau / mu[i]) : Real(0);
            x = std::fmax(x, std::fmax(std::fabs(c.reflection_down[i * m + j]),
                                       std::fabs(c.transmission_down[i * m + j] - direct)));
        }
    return x;
}

}  // namespace detail

/// The solved layer: evaluate its BRDF, BTDF, reflectance, transmittance and ambient term at any direction.
/// Built by solve_layer / solve_stack. Evaluation functions take an optional Workspace so that repeated
/// calls allocate nothing; they are const and thread-safe with one Workspace per thread.
/// Degenerate arguments give 0, as in pbrt (never NaN, never an exception): a direction with a NaN or infinite
/// component, on the horizon (z = 0) or in the wrong hemisphere, and a cosine outside (0, 1] (NaN included).
/// Directions are expected to be unit vectors and are not normalized; a finite non-unit vector gives a finite
/// value >= 0 (its |z| clamped to 1, its azimuth taken from its x and y) that means nothing in particular.
/// (tests/test_layer_inputs.cpp checks all of this.)
template <class Real = double>
class LayeredSurface {
public:
    /// Scratch memory for evaluation (sized on first use).
    struct Workspace {
        std::vector<Real> in, out, c, field, shape;
    };

    int ordinates() const noexcept { return static_cast<int>(q_.size()); }
    /// The number of Fourier modes actually solved (after the request's tolerance and cap).
    int modes() const noexcept { return modes_; }
    const Quadrature<Real>& quadrature() const noexcept { return q_; }
    LayerOutput outputs() const noexcept { return outputs_; }
    /// Per-mode operators of the whole layer on the ordinates, light arriving from above or below
    /// (empty unless LayerOutput::operators was requested). Compose with add_components().
    const std::vector<ComponentOperators<Real>>& mode_operators() const noexcept { return whole_; }

    /// Total BRDF above the layer, r_12 + r_s (the specular reflection of a smooth top is a delta and
    /// is not included: use the top's SmoothDielectric for it, and direct_reflectance() below).
    /// Outputs that were not requested (LayerRequest::outputs) evaluate to 0.
    Real brdf(Vec3<Real> wi, Vec3<Real> wo, Workspace& ws) const {
        if (!finite(wi) || !finite(wo)) return Real(0);  // degenerate input (see the class comment)
        const Real surface = (top_.rough() && includes(outputs_, LayerOutput::surface_reflection))
                                 ? top_.rough_interface()->brdf(wi, wo) : Real(0);
        return surface + subsurface_brdf(wi, wo, ws);
    }
    Real brdf(Vec3<Real> wi, Vec3<Real> wo) const { Workspace ws; return brdf(wi, wo, ws); }

    /// r_s: light refracted into the layer, scattered, and refracted back out of the top. Negative values of
    /// the truncated azimuthal series (Gibbs ringing with few modes) are returned as 0; a NaN computed from valid
    /// arguments is never hidden (degenerate arguments give 0: see the class comment).
    Real subsurface_brdf(Vec3<Real> wi, Vec3<Real> wo, Workspace& ws) const {
        if (!includes(outputs_, LayerOutput::subsurface_reflection) || !(wi.z > 0) || !(wo.z > 0) || !finite(wi) ||
            !finite(wo))
            return Real(0);
        const Real mu_i = std::fmin(wi.z, Real(1));
        const Real scale = scattering_scale(mu_i, ws);
        return scale * exit_sum(wi, wo, *top_ops_, top_, false, field(mu_i, false, ws), ws);
    }
    Real subsurface_brdf(Vec3<Real> wi, Vec3<Real> wo) const { Workspace ws; return subsurface_brdf(wi, wo, ws); }

    /// t_s: BTDF from above (wi.z > 0) to below (wo.z < 0) through the whole layer. Between two specular
    /// boundaries the unscattered beam is a delta, not part of t_s: see direct_transmittance().
    Real btdf(Vec3<Real> wi, Vec3<Real> wo, Workspace& ws) const {
        if (!includes(outputs_, LayerOutput::transmission) || !(wi.z > 0) || !(wo.z < 0) || !finite(wi) || !finite(wo))
            return Real(0);
        const Real mu_i = std::fmin(wi.z, Real(1));
        const Real scale = scattering_scale(mu_i, ws);
        return scale * exit_sum(wi, wo, *bottom_ops_, bottom_, true, field(mu_i, true, ws), ws);
    }
    Real btdf(Vec3<Real> wi, Vec3<Real> wo) const { Workspace ws; return btdf(wi, wo, ws); }

    /// Directional-hemispherical reflectance for incidence cosine mu_i in (0, 1]: {surface, subsurface}
    /// (0 outside (0, 1]). The subsurface part includes the unscattered beam (see direct_reflectance).
    struct Reflectance {
        Real surface, subsurface;
        Real total() const noexcept { return surface + subsurface; }
    };
    Reflectance reflectance(Real mu_i) const {
        if (!(mu_i > 0 && mu_i <= 1)) return {Real(0), Real(0)};
        Workspace ws;
        Reflectance a{top_.hemispherical_reflectance(mu_i), Real(0)};
        if (includes(outputs_, LayerOutput::subsurface_reflection))
            a.subsurface = non_negative(scattering_scale(mu_i, ws) * flux_out(field(mu_i, false, ws), exit_top_)) +
                           direct(mu_i, false);
        return a;
    }

    /// Fraction of the incident flux (cosine mu_i in (0, 1] from above) leaving through the bottom, including
    /// the unscattered beam; 0 outside (0, 1] or if transmission was not requested.
    Real transmittance(Real mu_i) const {
        if (!includes(outputs_, LayerOutput::transmission) || !(mu_i > 0 && mu_i <= 1)) return Real(0);
        Workspace ws;
        return non_negative(scattering_scale(mu_i, ws) * flux_out(field(mu_i, true, ws), exit_bottom_)) + direct(mu_i, true);
    }

    /// Between two specular (smooth or index-matched) boundaries the unscattered beam leaves as a delta:
    /// through the bottom in the Snell direction of wi (direct_transmittance) and, after a specular
    /// reflection at the bottom, through the top in the mirror direction (direct_reflectance). These are the
    /// fractions of the incident flux they carry, computed exactly at the true angle (Fresnel factors, the
    /// attenuation e^{-tau/mu'} and the geometric series of bounces between the faces); 0 otherwise.
    /// reflectance() and transmittance() include them; the scattered light is scaled so that it receives exactly the
    /// energy the true beam loses, which keeps a non-absorbing layer exactly energy-conserving.
    /// Like transmittance() and reflectance(), they are 0 when their output (LayerOutput::transmission,
    /// subsurface_reflection) was not requested.
    Real direct_transmittance(Real mu_i) const {
        return includes(outputs_, LayerOutput::transmission) && mu_i > 0 && mu_i <= 1 ? direct(mu_i, true) : Real(0);
    }
    Real direct_reflectance(Real mu_i) const {
        return includes(outputs_, LayerOutput::subsurface_reflection) && mu_i > 0 && mu_i <= 1 ? direct(mu_i, false)
                                                                                              : Real(0);
    }

    /// r_a(wo): subsurface radiance leaving towards wo (wo.z > 0) under a uniform sky of unit radiance
    /// (Stam's ambient term; the top's own reflection of the sky is its reflectance(wo.z) by reciprocity).
    Real ambient(Vec3<Real> wo, Workspace& ws) const {
        if (!includes(outputs_, LayerOutput::ambient) || !(wo.z > 0) || !finite(wo)) return Real(0);
        const std::size_t m = q_.size();
        ws.c.assign(m, Real(0));
        for (std::size_t i = 0; i < m; ++i) ws.c[i] = ambient_field_[i];
        return exit_value(std::fmin(wo.z, Real(1)), *top_ops_, top_, false, 0, ws.c.data(), ws);
    }
    Real ambient(Vec3<Real> wo) const { Workspace ws; return ambient(wo, ws); }

private:
    // The solver behind solve_stack and solve_layer, the public entry points.
    static LayeredSurface solve(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                                const LayerOptions& options, const LayerRequest<Real>& request);
    template <class R>
    friend LayeredSurface<R> solve_stack(const detail::non_deduced_t<Boundary<R>>&, const std::vector<Slab<R>>&,
                                         const std::vector<Boundary<R>>&, const detail::non_deduced_t<Boundary<R>>&,
                                         const LayerOptions&, const detail::non_deduced_t<LayerRequest<R>>&);

    LayeredSurface(Boundary<Real> top, Boundary<Real> bottom) : top_(std::move(top)), bottom_(std::move(bottom)) {}

    static constexpr Real pi() noexcept { return Real(3.141592653589793238462643383279502884L); }

    // The internal field (K blocks of M) for incidence mu_i: Q_b c_k (reflection) or Q_e c_k (transmission).
    const Real* field(Real mu_i, bool transmitted, Workspace& ws) const {
        const std::vector<std::vector<Real>>& cache = transmitted ? cached_e_ : cached_b_;
        for (std::size_t j = 0; j < incidence_.size(); ++j)
            if (incidence_[j] == mu_i && !cache[j].empty()) return cache[j].data();
        entry(mu_i, ws);
        const std::size_t m = q_.size();
        ws.field.assign(static_cast<std::size_t>(modes_) * m, Real(0));
        const std::vector<detail::Matrix<Real>>& q = transmitted ? qe_ : qb_;
        for (int k = 0; k < modes_; ++k) {
            const detail::Matrix<Real>& a = q[static_cast<std::size_t>(k)];
            const Real* c = ws.c.data() + static_cast<std::size_t>(k) * m;
            Real* f = ws.field.data() + static_cast<std::size_t>(k) * m;
            for (std::size_t n = 0; n < m; ++n) {
                Real s = 0;
                for (std::size_t i = 0; i < m; ++i) s += a(n, i) * c[i];
                f[n] = s;
            }
        }
        return ws.field.data();
    }

    // c_{k,m}: mode-k radiance coefficients just below the top for a unit-irradiance beam at cosine mu_i.
    // Rough top: c_{k,m} = (2 - delta_k0)/(2 pi) I^{t12}_k(mu_i -> mu_m), rescaled so that the flux it carries,
    // 2 pi sum_m w_m mu_m c_{0,m} (a Gauss sum over a lobe the ordinates may not resolve), equals the exact
    // transmittance T_12(mu_i). Specular top (or a lobe that falls between the ordinates): the refracted
    // beam at the Snell cosine, spread over the nearest ordinates inside the top's escape cone with
    // Lagrange weights (they sum to 1, so the flux is conserved; exact when the Snell cosine is an ordinate).
    void entry(Real mu_i, Workspace& ws) const {
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes_);
        ws.c.assign(kk * m, Real(0));
        const Real flux = !top_.rough() || mu_i < tables().grazing ? top_.hemispherical_transmittance(mu_i)
                                                                    : non_negative(tables().top_in(mu_i));
        if (!(flux > 0)) return;
        Real specular_share = 1;
        if (top_.rough()) {
            ws.in.resize(static_cast<std::size_t>(top_ops_->modes()));
            Real gauss = 0;
            for (std::size_t i = 0; i < m; ++i) {
                top_ops_->t12_coefficients(mu_i, q_.nodes[i], ws.in.data());
                gauss += q_.weights[i] * q_.nodes[i] * ws.in[0];
                for (std::size_t k = 0; k < kk; ++k) ws.c[k * m + i] = ws.in[k] * (k == 0 ? Real(1) : Real(2)) / (2 * pi());
            }
            // Blend: alpha = min(r, 1/r), r = gauss / flux, of the rescaled lobe (alpha flux / gauss = min(1,
            // (flux/gauss)^2)) and 1 - alpha of the specular spread: both carry the exact flux, the lobe wins
            // where the ordinates resolve it, and the result is continuous in every parameter.
            const Real r = gauss / flux;
            const Real lobe = r >= 1 ? Real(1) / (r * r) : Real(1);
            for (Real& x : ws.c) x *= lobe;
            specular_share = r >= 1 ? Real(1) - Real(1) / r : Real(1) - r;
            if (!(specular_share > 0)) return;
        }
        const Real mu_t = std::fabs(top_.smooth_interface().transmitted_cosine(mu_i));
        if (!(mu_t > 0)) return;
        // Azimuthal shape: a delta in phi for a specular top; a rough top's lobe keeps its own shape I_k / I_0
        // at the image (so that higher modes decay as the lobe's do).
        shape(mu_i, mu_t, top_.rough() ? &*top_ops_ : nullptr, Incidence::from_above, ws);
        // 4 points from 8 ordinates on (accurate: the photon Monte Carlo prefers it to a linear spread by 0.002
        // at 16 ordinates); with fewer ordinates the stencil spans most of [0, 1] and its negative weights can
        // create energy, so the spread is linear there, clamped to the stencil: non-negative weights.
        const bool few = q_.size() < 8;
        lagrange(few ? std::fmin(mu_t, q_.nodes.back()) : mu_t, critical_cosine(top_, false), few ? 2 : 4, ws);
        for (std::size_t i = 0; i < m; ++i) {
            const Real base = specular_share * flux * ws.in[i] / (q_.weights[i] * q_.nodes[i]);
            Real pole = 1;  // pole_factor(mu_t, mu_m)^k
            const Real step = pole_factor(mu_t, q_.nodes[i]);
            for (std::size_t k = 0; k < kk; ++k, pole *= step)
                ws.c[k * m + i] += base * pole * ws.shape[k] * (k == 0 ? Real(1) : Real(2)) / (2 * pi());
        }
    }

    // ws.in[0..M-1] = weights of p-point Lagrange interpolation at x from the ordinates >= lo nearest to x (lo:
    // the critical cosine of the boundary the light crosses; ordinates below it are totally reflected and hold
    // trapped light that must not leak into the interpolation). The weights sum to 1.
    void lagrange(Real x, Real lo, int p, Workspace& ws) const {
        const int m = static_cast<int>(q_.size());
        ws.in.assign(q_.size(), Real(0));
        int first_valid = 0;
        while (first_valid < m - 1 && q_.nodes[static_cast<std::size_t>(first_valid)] < lo) ++first_valid;
        const int count = m - first_valid;
        p = std::min(p, count);
        int j = first_valid;  // first node > x
        while (j < m && q_.nodes[static_cast<std::size_t>(j)] <= x) ++j;
        int first = std::max(first_valid, std::min(j - p / 2, m - p));
        auto node = [&](int i) { return q_.nodes[static_cast<std::size_t>(i)]; };
        for (int a = 0; a < p; ++a) {
            Real l = 1;
            for (int b = 0; b < p; ++b)
                if (b != a) l *= (x - node(first + b)) / (node(first + a) - node(first + b));
            ws.in[static_cast<std::size_t>(first + a)] = l;
        }
    }

    // ws.shape[k] = I_k / I_0 of a rough boundary's transmission lobe from mu_in to mu_out for light arriving
    // from `side` (ops == nullptr: specular, a delta in phi, shape 1 for every k).
    void shape(Real mu_in, Real mu_out, const InterfaceOperators<Real>* ops, Incidence side, Workspace& ws) const {
        const std::size_t kk = static_cast<std::size_t>(modes_);
        ws.shape.assign(kk, Real(1));
        if (ops == nullptr) return;
        ws.in.resize(static_cast<std::size_t>(ops->modes()));
        ops->coefficients(side, true, mu_in, mu_out, ws.in.data());
        const Real i0 = ws.in[0];
        for (std::size_t k = 0; k < kk; ++k) ws.shape[k] = i0 > 0 ? ws.in[k] / i0 : Real(k == 0);
    }

    // The critical cosine inside the layer for light leaving through `boundary` (0 if none).
    static Real critical_cosine(const Boundary<Real>& boundary, bool bottom) noexcept {
        const Real n_in = bottom ? boundary.eta_above() : boundary.eta_below();
        const Real n_out = bottom ? boundary.eta_below() : boundary.eta_above();
        if (!(n_out < n_in)) return Real(0);
        const Real r = n_out / n_in;
        return std::sqrt((Real(1) - r) * (Real(1) + r));
    }

    // Radiance leaving through `boundary` towards wo from the internal field, summed over modes.
    Real exit_sum(Vec3<Real> wi, Vec3<Real> wo, const InterfaceOperators<Real>& ops, const Boundary<Real>& boundary,
                  bool bottom, const Real* fld, Workspace& ws) const {
        // Azimuth between the propagation directions -wi and wo: cos(dphi) = -(wi_t . wo_t) / (|wi_t| |wo_t|),
        // from the normalized tangential parts (hypot: no overflow or underflow for finite non-unit vectors, whose
        // squares would give inf / inf or 0 / 0) and clamped to [-1, 1] so that the Chebyshev recurrence stays bounded.
        const Real ri = std::hypot(wi.x, wi.y), ro = std::hypot(wo.x, wo.y);
        const bool pole = !(ri > 0) || !(ro > 0);
        const Real cos_dphi =
            pole ? Real(1)
                 : std::fmin(std::fmax(-((wi.x / ri) * (wo.x / ro) + (wi.y / ri) * (wo.y / ro)), Real(-1)), Real(1));
        const Real mu_o = std::fmin(std::fabs(wo.z), Real(1));
        exit_weights(mu_o, ops, boundary, bottom, ws);
        const std::size_t m = q_.size();
        Real sum = 0, c_prev = 1, c_k = 1;  // cos(k dphi) by the Chebyshev recurrence
        // At the pole (wi or wo along the normal) the azimuth is undefined and only mode 0 survives.
        const int modes = pole ? std::min(modes_, 1) : modes_;
        for (int k = 0; k < modes; ++k) {
            const Real* f = fld + static_cast<std::size_t>(k) * m;
            Real s = 0;
            for (std::size_t i = 0; i < m; ++i) s += ws.out[static_cast<std::size_t>(k) * m + i] * f[i];
            sum += c_k * s;
            const Real c_next = k == 0 ? cos_dphi : 2 * cos_dphi * c_k - c_prev;
            c_prev = c_k;
            c_k = c_next;
        }
        return non_negative(sum);
    }

    // The value of one mode at outgoing cosine mu_o (used for the mode-0 ambient term).
    Real exit_value(Real mu_o, const InterfaceOperators<Real>& ops, const Boundary<Real>& boundary, bool bottom, int k,
                    const Real* fld, Workspace& ws) const {
        exit_weights(mu_o, ops, boundary, bottom, ws);
        const std::size_t m = q_.size();
        Real s = 0;
        for (std::size_t i = 0; i < m; ++i) s += ws.out[static_cast<std::size_t>(k) * m + i] * fld[i];
        return non_negative(s);
    }

    // ws.out[k M + m]: weight of internal ordinate m, mode k, in the radiance leaving at mu_o.
    // Rough: w_m mu_m I^{t}_k(mu_m -> mu_o), rescaled so that the weights of mode 0 sum to their exact value:
    // by reciprocity (t_ij / n_j^2 = t_ji / n_i^2 with the arguments swapped), sum_m w_m mu_m I^t_0(mu_m -> mu_o)
    // -> (n_out / n_in)^2 T(mu_o), with T the transmittance of light arriving from outside at mu_o.
    // Specular: (radiance transmittance) x local Lagrange weights at the internal Snell cosine mu'.
    void exit_weights(Real mu_o, const InterfaceOperators<Real>& ops, const Boundary<Real>& boundary, bool bottom,
                      Workspace& ws) const {
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes_);
        ws.out.assign(kk * m, Real(0));
        const SmoothDielectric<Real>& s = boundary.smooth_interface();
        const Real outside = bottom ? -mu_o : mu_o;  // cosine of the outgoing ray seen from its own side
        const Real mu_t = std::fabs(s.transmitted_cosine(outside));  // the internal direction, ray reversed
        Real specular = mu_t > 0 ? s.radiance_transmittance(bottom ? mu_t : -mu_t) : Real(0);
        if (boundary.rough()) {
            const Real n_in = bottom ? boundary.eta_above() : boundary.eta_below();
            const Real n_out = bottom ? boundary.eta_below() : boundary.eta_above();
            const Real t_outside = mu_o < tables().grazing ? boundary.hemispherical_transmittance(outside)
                                   : non_negative(bottom ? tables().bottom_in(mu_o) : tables().top_in(mu_o));
            const Real expected = (n_out / n_in) * (n_out / n_in) * t_outside;
            if (!(expected > 0)) return;
            // The reciprocity behind `expected` needs a reciprocal BTDF: with masking-only shadowing the exit
            // weights are used as they are (tests/test_layer_monte_carlo.cpp measured both against a photon
            // Monte Carlo).
            const bool reciprocal = boundary.rough_interface()->shadowing() != Shadowing::masking_only;
            ws.in.resize(static_cast<std::size_t>(ops.modes()));
            Real gauss = 0;
            for (std::size_t i = 0; i < m; ++i) {
                if (bottom) ops.t12_coefficients(q_.nodes[i], mu_o, ws.in.data());  // layer (above the bottom) -> medium 3
                else ops.t21_coefficients(q_.nodes[i], mu_o, ws.in.data());         // layer (below the top) -> medium 1
                const Real wm = q_.weights[i] * q_.nodes[i];
                gauss += wm * ws.in[0];
                for (std::size_t k = 0; k < kk; ++k) ws.out[k * m + i] = wm * ws.in[k];
            }
            // The same continuous blend as in entry(): the rescaled lobe where the ordinates resolve it,
            // otherwise the interpolated internal radiance at the Snell direction times `expected`.
            if (!reciprocal) return;
            const Real r = gauss / expected;
            const Real lobe = r >= 1 ? Real(1) / (r * r) : Real(1);
            for (Real& x : ws.out) x *= lobe;
            specular = expected * (r >= 1 ? Real(1) - Real(1) / r : Real(1) - r);
        }
        if (!(specular > 0) || !(mu_t > 0)) return;
        shape(mu_t, mu_o, boundary.rough() ? &ops : nullptr, bottom ? Incidence::from_above : Incidence::from_below, ws);
        lagrange(mu_t, critical_cosine(boundary, bottom), 4, ws);
        for (std::size_t i = 0; i < m; ++i) {
            Real pole = 1;
            const Real step = pole_factor(mu_t, q_.nodes[i]);
            for (std::size_t k = 0; k < kk; ++k, pole *= step) ws.out[k * m + i] += specular * ws.in[i] * pole * ws.shape[k];
        }
    }

    // Mode k of a field near the pole varies as sin^k(theta) (it is (1 - mu^2)^{k/2} times a smooth function):
    // moving a beam (or reading a radiance) between the internal cosine mu_t and an ordinate mu_m scales mode k
    // by (sin theta_t / sin theta_m)^k. This returns that ratio, capped at 1 so that nothing is amplified; it
    // makes every k > 0 mode vanish for a beam along the normal, as it must.
    static Real pole_factor(Real mu_t, Real mu_m) noexcept {
        const Real st2 = (Real(1) - mu_t) * (Real(1) + mu_t), sm2 = (Real(1) - mu_m) * (Real(1) + mu_m);
        return st2 >= sm2 ? Real(1) : std::sqrt(st2 / sm2);
    }

    // x < 0 -> 0 (rounding or the interpolation's overshoot); NaN passes through so that tests see it.
    static Real non_negative(Real x) noexcept { return x < 0 ? Real(0) : x; }

    // No NaN or infinite component (the evaluation functions return 0 for such a direction).
    static bool finite(Vec3<Real> v) noexcept { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

    // The unscattered beam between two specular boundaries (see direct_transmittance), exactly at mu_i.
    Real direct(Real mu_i, bool transmitted) const {
        if (!direct_separated_) return Real(0);
        const SmoothDielectric<Real>& t = top_.smooth_interface();
        const SmoothDielectric<Real>& b = bottom_.smooth_interface();
        const Real mu_t = std::fabs(t.transmitted_cosine(mu_i));
        if (!(mu_t > 0)) return Real(0);
        const Real d = std::isinf(direct_tau_) ? Real(0) : std::exp(-direct_tau_ / mu_t);
        // 0 when the beam is trapped: total internal reflection at both faces with d = 1 (tau = 0), which rounding
        // produces for grazing incidence (mu_i^2 below the rounding of eta^2 - 1 puts mu_t exactly on the critical
        // cosine): the true value there is O(T_12(mu_i)) = O(mu_i) < 1e-7, while 1 / 0 times 0 would be NaN.
        const Real denominator = Real(1) - t.reflectance(-mu_t) * b.reflectance(mu_t) * d * d;
        if (!(denominator > 0)) return Real(0);
        const Real bounce = Real(1) / denominator;
        const Real into = t.transmittance(mu_i) * d * bounce;
        return transmitted ? into * b.transmittance(mu_t) : into * b.reflectance(mu_t) * d * t.transmittance(-mu_t);
    }

    // Between specular faces the scattered light is driven by the beam spread over the ordinates, whose
    // extinction differs from the true beam's. Energy taken from a beam of unit flux entering at internal
    // cosine x, over all its passes: E(x) = (1 - d)(1 + r23 d) / (1 - r21 r23 d^2), d = e^{-tau/x}. The scattered
    // field is scaled by E(mu_t) / sum_m s_m E(mu_m), s_m the spread's flux shares, so that it receives exactly
    // the energy the true beam loses (energy is then conserved exactly with the exact direct beam).
    Real scattering_scale(Real mu_i, Workspace& ws) const {
        if (!direct_separated_ || modes_ == 0) return Real(1);
        const SmoothDielectric<Real>& t = top_.smooth_interface();
        const SmoothDielectric<Real>& b = bottom_.smooth_interface();
        auto extracted = [&](Real x) {
            const Real d = std::isinf(direct_tau_) ? Real(0) : std::exp(-direct_tau_ / x);
            if (!(d < 1)) return Real(0);  // nothing taken (and 0 / 0 under total internal reflection at both faces)
            const Real r21 = t.reflectance(-x), r23 = b.reflectance(x);
            return (Real(1) - d) * (Real(1) + r23 * d) / (Real(1) - r21 * r23 * d * d);
        };
        const Real mu_t = std::fabs(t.transmitted_cosine(mu_i));
        if (!(mu_t > 0)) return Real(1);
        entry(mu_i, ws);
        Real spread = 0, total = 0;
        for (std::size_t n = 0; n < q_.size(); ++n) {
            const Real share = q_.weights[n] * q_.nodes[n] * ws.c[n];  // mode-0 flux share (up to 1 / 2 pi)
            spread += share * extracted(q_.nodes[n]);
            total += share;
        }
        // The shares are Lagrange weights and may be negative; where the spread extracts less than half the
        // true beam's energy the scale is capped at 2, so that the spread's overshoot is not amplified.
        if (!(spread > 0)) return Real(1);
        return std::fmin(total * extracted(mu_t) / spread, Real(2));
    }

    // Flux leaving through a boundary from the mode-0 internal field: 2 pi sum_n w_n mu_n f_n tau(mu_n).
    Real flux_out(const Real* fld, const std::vector<Real>& exit) const {
        Real s = 0;
        for (std::size_t n = 0; n < q_.size(); ++n) s += q_.weights[n] * q_.nodes[n] * fld[n] * exit[n];
        return 2 * pi() * s;
    }

    Boundary<Real> top_, bottom_;
    std::optional<InterfaceOperators<Real>> top_ops_, bottom_ops_;  // empty when nothing was solved
    Quadrature<Real> q_;
    int modes_ = 0;
    LayerOutput outputs_ = LayerOutput::all;
    std::vector<detail::Matrix<Real>> qb_, qe_;           // per mode
    std::vector<ComponentOperators<Real>> whole_;         // per mode, if requested
    std::vector<Real> incidence_;
    std::vector<std::vector<Real>> cached_b_, cached_e_;  // per requested incidence: K blocks of M
    std::vector<Real> exit_top_, exit_bottom_;            // hemispherical transmittance out of the layer per ordinate
    bool direct_separated_ = false;                       // specular top and bottom: unscattered beam kept apart
    Real direct_tau_ = 0;                                 // its optical thickness (delta-M scaled)
    // Rough boundaries: the transmittance of light arriving from outside, tabulated on first use (64 hemispherical
    // integrals each, so a solve for fluxes alone does not pay for them); std::call_once keeps it thread-safe.
    struct Tables {
        std::once_flag once;
        detail::MuTable<Real> top_in, bottom_in;
        Real grazing = 0;  // below the first table interval the transmittance is computed exactly
    };
    std::shared_ptr<Tables> tables_ = std::make_shared<Tables>();
    const Tables& tables() const {
        std::call_once(tables_->once, [this] {
            constexpr int intervals = 64;
            if (top_.rough()) tables_->top_in.build(intervals, [this](Real mu) { return top_.hemispherical_transmittance(mu); });
            if (bottom_.rough()) tables_->bottom_in.build(intervals, [this](Real mu) { return bottom_.hemispherical_transmittance(-mu); });
            tables_->grazing = Real(1) / Real(intervals * intervals);
        });
        return *tables_;
    }
    std::vector<Real> ambient_field_;                     // mode-0 up-going field under a uniform sky
};

template <class Real>
LayeredSurface<Real> solve_stack(const detail::non_deduced_t<Boundary<Real>>& top, const std::vector<Slab<Real>>& slabs,
                                 const std::vector<Boundary<Real>>& interior,
                                 const detail::non_deduced_t<Boundary<Real>>& bottom, const LayerOptions& options,
                                 const detail::non_deduced_t<LayerRequest<Real>>& request) {
    return LayeredSurface<Real>::solve(top, slabs, interior, bottom, options, request);
}

template <class Real>
LayeredSurface<Real> LayeredSurface<Real>::solve(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                                 const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                                                 const LayerOptions& options, const LayerRequest<Real>& request) {
    detail::require_count("options.ordinates", options.ordinates, 1);
    detail::require_count("options.modes", options.modes, 0);
    detail::require_count("request.max_modes", request.max_modes, 0);
    detail::require_count("slabs.size()", static_cast<int>(slabs.size()), 1);
    if (!(request.tolerance >= 0 && request.tolerance < 1))
        detail::throw_out_of_range("request.tolerance", request.tolerance, "[0, 1)");
    if (interior.size() + 1 != slabs.size())
        detail::fail_invalid_argument("stratum: solve_stack needs interior.size() == slabs.size() - 1, got " +
                                    std::to_string(interior.size()) + " and " + std::to_string(slabs.size()));
    {
        Real above = top.eta_below();
        for (std::size_t i = 0; i <= interior.size(); ++i) {
            const Real below = i < interior.size() ? interior[i].eta_above() : bottom.eta_above();
            if (below != above)
                detail::fail_invalid_argument("stratum: boundary indices disagree around slab " + std::to_string(i) + ": " +
                                            detail::format_value(above) + " above it, " + detail::format_value(below) +
                                            " below it");
            if (i < interior.size()) above = interior[i].eta_below();
        }
    }
    for (std::size_t j = 0; j < request.incidence.size(); ++j)
        detail::require_closed(("request.incidence[" + std::to_string(j) + "]").c_str(), request.incidence[j],
                               std::nextafter(Real(0), Real(1)), Real(1));

    LayeredSurface s(top, bottom);
    s.outputs_ = request.outputs;
    s.q_ = gauss_legendre_half<Real>(options.ordinates);
    const Quadrature<Real>& q = s.q_;
    const std::size_t m = q.size();
    const bool want_r = includes(request.outputs, LayerOutput::subsurface_reflection);
    const bool want_t = includes(request.outputs, LayerOutput::transmission);
    const bool want_a = includes(request.outputs, LayerOutput::ambient);
    const bool want_ops = includes(request.outputs, LayerOutput::operators);
    int modes = options.modes > 0 ? options.modes : 2 * options.ordinates;
    if (request.max_modes > 0) modes = std::min(modes, request.max_modes);
    if (!want_r && !want_t && !want_ops) modes = want_a ? 1 : 0;  // ambient: mode 0 only; surface only: no solve
    s.incidence_ = request.incidence;
    if (modes == 0) {
        s.modes_ = 0;
        return s;
    }

    s.top_ops_.emplace(top.operators(q, modes, options));
    s.bottom_ops_.emplace(bottom.operators(q, modes, options));
    // Interior faces of a stack: the adding equations multiply a face's energy error by the bounces between
    // the faces around it, so under SpecularTransmission::automatic a smooth interior face is flux_conserving
    // both ways (exact energy per ordinate). Pointwise out of the denser medium created up to 26% of the
    // incident energy at M = 4 and 2% at M = 16 (thin slabs between smooth faces; tests/test_layer_inputs.cpp).
    // An explicit choice is kept (README, known limitations).
    LayerOptions interior_options = options;
    if (interior_options.specular_transmission == SpecularTransmission::automatic)
        interior_options.specular_transmission = SpecularTransmission::flux_conserving;
    std::vector<InterfaceOperators<Real>> interior_ops;
    for (const Boundary<Real>& b : interior) interior_ops.push_back(b.operators(q, modes, interior_options));
    std::vector<detail::SlabModes<Real>> prepared;
    for (const Slab<Real>& slab : slabs) {
        prepared.push_back(detail::prepare_slab(slab, q, modes, options.delta_m, slab.optical_thickness()));
        detail::SlabModes<Real>& p = prepared.back();
        // Semi-infinite shortcut: the diffuse field decays into the slab no faster than e^{-lambda_min tau}
        // (lambda_min: the smallest mode-0 eigenvalue), which is slower than the beam's e^{-tau}; so the
        // criterion is e^{-lambda_min tau} < tolerance, not e^{-tau} < tolerance.
        const Real tau = p.slab.optical_thickness();
        if (request.tolerance > 0 && !want_t && !want_ops && slabs.size() == 1 && std::isfinite(tau) &&
            p.slab.one_minus_albedo() > 0) {
            const auto es = detail::slab_eigensystem(p.slab.one_minus_albedo(), q.nodes, q.weights, p.phase.same_k(0),
                                                     p.phase.opposite_k(0), 0);
            Real lambda_min = std::numeric_limits<Real>::infinity();
            for (Real l : es.lambda) lambda_min = std::fmin(lambda_min, l);
            if (std::exp(-lambda_min * tau) < request.tolerance)
                p.slab = Slab<Real>::from_one_minus_albedo(p.slab.one_minus_albedo(), p.slab.g(),
                                                           std::numeric_limits<Real>::infinity());
        }
    }
    // The slab modes. A phase function too peaked for the ordinates (|g| near 1 without delta-M, or any g < 0
    // near -1, whose backward peak delta-M cannot remove) has a truncated expansion that is not admissible on
    // them: the slab solver then regularizes its aliased part (regularize_aliased_phase = true; slab.hpp), which
    // keeps the results finite and energy-conserving. Admissible phase functions are solved as without it.
    auto slab_mode = [&](const detail::SlabModes<Real>& p, int k) {
        return slab_component(solve_slab_mode(p.slab, q, p.phase.same_k(k), p.phase.opposite_k(k), k, true));
    };
    // Hemispherical transmittance out of the layer at each ordinate (for the reflectance/transmittance fluxes).
    s.exit_top_.resize(m);
    s.exit_bottom_.resize(m);
    // (the renormalized rough operators computed these totals already)
    const auto& top_totals = s.top_ops_->ordinate_totals(Incidence::from_below);
    const auto& bottom_totals = s.bottom_ops_->ordinate_totals(Incidence::from_above);
    for (std::size_t i = 0; i < m; ++i) {
        s.exit_top_[i] = top_totals.size() == m ? top_totals[i].transmittance : top.hemispherical_transmittance(-q.nodes[i]);
        s.exit_bottom_[i] = bottom_totals.size() == m ? bottom_totals[i].transmittance : bottom.hemispherical_transmittance(q.nodes[i]);
    }

    using detail::Matrix;
    bool any_rough = top.rough() || bottom.rough();
    for (const Boundary<Real>& b : interior) any_rough = any_rough || b.rough();
    Real norm0 = 0;
    int below_tolerance = 0;
    int solved = 0;
    for (int k = 0; k < modes; ++k) {
        // middle = slabs and interior interfaces; lower = middle + bottom interface.
        ComponentOperators<Real> middle = slab_mode(prepared[0], k);
        Real slab_size = detail::diffuse_size(middle, q.nodes, prepared[0].slab.optical_thickness());
        for (std::size_t i = 0; i < interior.size(); ++i) {
            middle = add_components(middle, detail::interface_component(interior_ops[i], k));
            const ComponentOperators<Real> next = slab_mode(prepared[i + 1], k);
            slab_size = std::fmax(slab_size, detail::diffuse_size(next, q.nodes, prepared[i + 1].slab.optical_thickness()));
            middle = add_components(middle, next);
        }
        const ComponentOperators<Real> bottom_c = detail::interface_component(*s.bottom_ops_, k);
        const ComponentOperators<Real> lower = add_components(middle, bottom_c);
        const Matrix<Real> S = detail::as_matrix(m, lower.reflection_down);
        const Matrix<Real> r21 = detail::as_matrix(m, std::vector<Real>(s.top_ops_->R21().mode(k), s.top_ops_->R21().mode(k) + m * m));
        // A = (I - R21 S)^{-1};  Q_b = S A;  Q_e = (I - R_mid_up R23)^{-1} T_mid_down A.
        const detail::LU<Real> lu_a = detail::lu_factor(detail::one_minus_product(r21, S));
        Matrix<Real> qb = S;  // Q_b = S A = (I - S R21)^{-1} S, solved from the right via the transpose form
        {
            // S A: solve A^T-free form: (I - R21 S) X = I gives A; then Q_b = S A.
            Matrix<Real> a = Matrix<Real>::identity(m);
            detail::lu_solve(lu_a, a);
            qb = detail::multiply(S, a);
            if (want_t) {
                const Matrix<Real> r_mid_up = detail::as_matrix(m, middle.reflection_up);
                const Matrix<Real> r23 = detail::as_matrix(m, bottom_c.reflection_down);
                Matrix<Real> x = detail::multiply(detail::as_matrix(m, middle.transmission_down), a);
                detail::lu_solve(detail::lu_factor(detail::one_minus_product(r_mid_up, r23)), x);
                s.qe_.push_back(std::move(x));
            }
        }
        if (want_ops) s.whole_.push_back(add_components(detail::interface_component(*s.top_ops_, k), lower));
        s.qb_.push_back(std::move(qb));
        solved = k + 1;
        // Adaptive mode count: mode k is negligible when the BRDF/BTDF Fourier coefficients it adds at the
        // ordinate pairs, (2 - delta_k0)/(2 pi) (T21 Q_b T12)_nj / (w_j mu_j) (and T23 Q_e T12), are below
        // tolerance relative to the largest mode-0 coefficient. Through specular boundaries only, the
        // unscattered beam is a delta that no number of modes represents: there the slabs' diffuse operators
        // are measured instead. Stop after two consecutive negligible modes.
        if (request.tolerance > 0) {
            Real size_k = 0;
            if (any_rough) {
                const Matrix<Real> t12 = detail::as_matrix(m, std::vector<Real>(s.top_ops_->T12().mode(k), s.top_ops_->T12().mode(k) + m * m));
                auto coefficient_size = [&](const Matrix<Real>& exit, const Matrix<Real>& inner) {
                    const Matrix<Real> x = detail::multiply(exit, detail::multiply(inner, t12));
                    Real big = 0;
                    for (std::size_t n = 0; n < m; ++n)
                        for (std::size_t j = 0; j < m; ++j)
                            big = std::fmax(big, std::fabs(x(n, j)) / (q.weights[j] * q.nodes[j]));
                    return big * (k == 0 ? Real(1) : Real(2));
                };
                if (want_r || want_a)
                    size_k = coefficient_size(detail::as_matrix(m, std::vector<Real>(s.top_ops_->T21().mode(k), s.top_ops_->T21().mode(k) + m * m)), s.qb_.back());
                if (want_t)
                    size_k = std::fmax(size_k, coefficient_size(detail::as_matrix(m, bottom_c.transmission_down), s.qe_.back()));
            } else {
                size_k = slab_size;
            }
            if (k == 0) norm0 = size_k;
            below_tolerance = (k > 0 && size_k <= request.tolerance * norm0) ? below_tolerance + 1 : 0;
            if (below_tolerance == 2) break;
        }
    }
    s.modes_ = solved;

    if (want_a) {
        // (computed before the unscattered beam is taken out of Q_b: under a diffuse sky it is diffuse too)
        // Uniform unit sky: radiance transmitted to internal ordinate m is (n2/n1)^2 tau_21(mu_m) by
        // reciprocity of the top's BTDF (t_12 / n_2^2 = t_21 / n_1^2 with arguments swapped).
        const Real ratio = top.eta_below() / top.eta_above();
        std::vector<Real> c(m);
        for (std::size_t i = 0; i < m; ++i) c[i] = ratio * ratio * s.exit_top_[i];
        s.ambient_field_.assign(m, Real(0));
        for (std::size_t n = 0; n < m; ++n)
            for (std::size_t i = 0; i < m; ++i) s.ambient_field_[n] += s.qb_[0](n, i) * c[i];
    }
    // Between two specular boundaries the unscattered beam stays on its own ordinate (every operator on its
    // path is diagonal): take it out of Q_b and Q_e, per ordinate
    //   Q_e^dir = d / (1 - r21 r23 d^2),   Q_b^dir = d^2 r23 / (1 - r21 r23 d^2),   d = e^{-tau/mu_m},
    // so that brdf/btdf hold scattered light only, and add it back exactly at the true angle (direct()).
    if (!top.rough() && !bottom.rough() && slabs.size() == 1) {
        s.direct_separated_ = true;
        s.direct_tau_ = prepared[0].slab.optical_thickness();
        for (std::size_t i = 0; i < m; ++i) {
            const Real mu = q.nodes[i];
            const Real d = std::isinf(s.direct_tau_) ? Real(0) : std::exp(-s.direct_tau_ / mu);
            const Real r21 = top.smooth_interface().reflectance(-mu), r23 = bottom.smooth_interface().reflectance(mu);
            // 1 - r21 r23 d^2 = 0: total internal reflection at both faces and nothing taken from the beam
            // (d = 1: tau = 0, or tau / mu below rounding). No beam from outside reaches such an ordinate, and
            // the series would be 1 / 0 (inf - inf = NaN in Q_b): there is nothing to take out.
            const Real denominator = Real(1) - r21 * r23 * d * d;
            if (!(denominator > 0)) continue;
            const Real bounce = Real(1) / denominator;
            for (int k = 0; k < s.modes_; ++k) {
                s.qb_[static_cast<std::size_t>(k)](i, i) -= d * d * r23 * bounce;
                if (want_t) s.qe_[static_cast<std::size_t>(k)](i, i) -= d * bounce;
            }
        }
    }

    // Precompute the fields of the requested incidences.
    Workspace ws;
    s.cached_b_.assign(s.incidence_.size(), {});
    s.cached_e_.assign(s.incidence_.size(), {});
    for (std::size_t j = 0; j < s.incidence_.size(); ++j) {
        if (want_r) {
            const Real* f = s.field(s.incidence_[j], false, ws);
            s.cached_b_[j].assign(f, f + static_cast<std::size_t>(s.modes_) * m);
        }
        if (want_t) {
            const Real* f = s.field(s.incidence_[j], true, ws);
            s.cached_e_[j].assign(f, f + static_cast<std::size_t>(s.modes_) * m);
        }
    }
    return s;
}

/// Solves one layer: `slab` between `top` (media 1 | 2) and `bottom` (2 | 3). See solve_stack.
template <class Real>
LayeredSurface<Real> solve_layer(const Slab<Real>& slab, const detail::non_deduced_t<Boundary<Real>>& top,
                                 const detail::non_deduced_t<Boundary<Real>>& bottom, const LayerOptions& options = {},
                                 const detail::non_deduced_t<LayerRequest<Real>>& request = {}) {
    return solve_stack(top, std::vector<Slab<Real>>{slab}, std::vector<Boundary<Real>>{}, bottom, options, request);
}

}  // namespace stratum
