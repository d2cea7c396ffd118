// stratum/layer.hpp -- a scattering layer (or a stack of them) bounded by dielectric interfaces, solved by the
// discrete-ordinate method after Stam (2001) and evaluated at arbitrary directions: solve_layer, solve_stack and
// the LayeredSurface they return.
//
// Geometry. Medium 1 (index n1) above, the layer (n2), medium 3 (n3) below; each face is a RoughDielectric, a
// SmoothDielectric or index matched (Boundary). Directions follow vec3.hpp: wi towards the light, wo towards the
// viewer, both pointing away from the surface; light arrives from above (wi.z > 0).
//
// Method (docs/physics.md sections 5-6). Per Fourier mode, everything below the top face is combined by the
// adding equations (adding.hpp) from the faces' operators (interface_operators.hpp) and the slab's
// (slab.hpp); the solver keeps the operators that map light entering through the top to the internal field
// (Q_b, Q_e; see add_field_operators). Only that field lives on the ordinates: a rough face couples it to the
// true incident and outgoing angles through its Fourier coefficients there (entry, exit_sum), and the fluxes
// are rescaled to the faces' exact hemispherical totals. Between two specular faces (one slab, or slabs joined by
// faces that do not change the index) the unscattered beam is kept apart and computed exactly (DirectBeam),
// with delta-M's forward peak reported beside it; the light it scatters leaves a smooth face by interpolation
// between ordinates, the documented approximation of this path (README, known limitations).
//
// Units: BRDF/BTDF per steradian (cosine not included), reflectance and transmittance as fractions of the
// incident flux, ambient as reflected radiance per unit incident sky radiance.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "adding.hpp"
#include "detail/beam_source.hpp"
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

/// The outputs a scene asks for; combine with |. The solver skips the work of the others. "Reflection" and
/// "transmission" are the angular distributions (BRDF, BTDF: all Fourier modes); "reflectance" and
/// "transmittance" the fractions of an incident beam's flux (reflectance(mu), transmittance(mu)), which need
/// Fourier mode 0 alone: a request with no angular output solves that mode only.
enum class LayerOutput : unsigned {
    surface_reflection = 1u << 0,     ///< r_12: reflection by the top interface alone (needs no solve)
    subsurface_reflection = 1u << 1,  ///< r_s: light that entered the layer and came back out of the top (includes reflectance)
    transmission = 1u << 2,           ///< t_s: light leaving through the bottom (includes transmittance)
    ambient = 1u << 3,                ///< r_a: subsurface reflection of a uniform sky (Fourier mode 0 only)
    operators = 1u << 4,              ///< the whole layer's per-mode operators on the ordinates (for stacking)
    reflectance = 1u << 5,            ///< reflectance(mu).subsurface, direct_ and forward_peak_reflectance alone (mode 0)
    transmittance = 1u << 6,          ///< transmittance(mu), direct_ and forward_peak_transmittance alone (mode 0)
    all = (1u << 7) - 1,
};
constexpr LayerOutput operator|(LayerOutput a, LayerOutput b) noexcept {
    return static_cast<LayerOutput>(static_cast<unsigned>(a) | static_cast<unsigned>(b));
}
constexpr bool includes(LayerOutput set, LayerOutput o) noexcept {
    return (static_cast<unsigned>(set) & static_cast<unsigned>(o)) != 0;
}

namespace detail {
// Whether the internal field of reflected (Q_b) or transmitted (Q_e) light is needed: for the angular output or
// for its flux alone.
constexpr bool needs_reflected(LayerOutput set) noexcept {
    return includes(set, LayerOutput::subsurface_reflection | LayerOutput::reflectance);
}
constexpr bool needs_transmitted(LayerOutput set) noexcept {
    return includes(set, LayerOutput::transmission | LayerOutput::transmittance);
}
}  // namespace detail

/// Discretization knobs.
struct LayerOptions {
    int ordinates = 16;   ///< M half-range ordinates per hemisphere (gauss_legendre_half), 1 to 4096 (>= 2 under a
                          ///< smooth face whose critical cosine exceeds 0.5: detail::require_escape; >= 5, and more
                          ///< than the distinct critical cosines, for scattering slabs joined by a refracting smooth
                          ///< face: detail::minimum_ordinates)
    int modes = 0;        ///< K azimuthal modes; 0 = 2M (as many as 2M Legendre moments support)
    bool delta_m = true;  ///< delta-M scaling (Wiscombe 1977) with 2M moments, for g > 0 (forward peaks)
    /// Rough boundaries: rescale each operator column to the exact hemispherical totals (interface_operators.hpp).
    Renormalization renormalization = Renormalization::hemispherical_totals;
    /// Rough boundaries: Gauss nodes per panel of those hemispherical integrals (RoughDielectric::hemispherical_totals,
    /// 2 to 32). Measured at sigma 0.3, n 1 | 1.4: 16 within 1e-9, 12 1.3e-7, 10 5.8e-7 in 0.45 of 16's time, 8 2.7e-5;
    /// Stam's layer at M = 24 solves in 0.79 of the time at 10 (docs/accuracy.md, "the rough faces' integrals").
    /// A request with a tolerance caps it, and azimuthal_points, at what the tolerance needs (integrals_for_tolerance).
    int hemispherical_nodes = 16;
    /// Rough boundaries: Gauss points per panel of the azimuthal rule of their operators (AzimuthalQuadrature, >= 2):
    /// 24 within ~1e-13 of converged, 12 ~5e-7 of an entry (docs/accuracy.md, "azimuthal rule"). The panels that
    /// resolve the highest mode set the sample count from M ~ 16 on, so fewer points save little there (same file,
    /// "the rough faces' integrals").
    int azimuthal_points = 24;
    /// Smooth boundaries: how the Snell-mapped transmission is put on the ordinates (interface_operators.hpp).
    /// automatic: as there for the top and bottom faces, flux_conserving for the interior faces of a stack
    /// (solve_stack), where only it keeps energy; pointwise there can create energy (README, known limitations).
    SpecularTransmission specular_transmission = SpecularTransmission::automatic;
    /// A slab (or slabs joined by smooth or index-matched faces) under a specular top (smooth or index-matched) and
    /// over any face or a Lambertian floor, or under a rough top over a specular face, where a face leads into a less
    /// dense medium: the ordinates are split at the faces' critical cosines inside (every slab's, joints included;
    /// docs/physics.md section 6), a Gauss rule on each panel (see detail::layer_quadrature for how the points are
    /// shared and which rough tops qualify), so that light that can leave and light that is trapped are integrated
    /// apart. Off, or otherwise: one half-range rule (also where the split rule aliases a refracting stack's phase
    /// function: solve_stack falls back to it).
    bool critical_split = true;
    /// Between specular faces (where the beam is a source: docs/physics.md section 6), brdf and btdf add the exact
    /// single scattering of the untruncated phase function in place of the truncated one, and the truncated peak's
    /// second scattering around the transmitted beam (Nakajima and Tanaka 1988's TMS and IMS corrections, as
    /// DISORT's intensities; the IMS at every angle, not only within DISORT's 10 degrees): near the beam's
    /// directions, where delta-M's truncated phase function cannot follow a forward peak, the radiance is then right
    /// at 16 ordinates (tests/test_layer_intensity.cpp). The IMS is an approximation and not reciprocal.
    /// The forward peak's single scattering, which reflectance() and transmittance() count in the delta-M beam
    /// (forward_peak_*), is then in brdf and btdf as well: their integrals exceed the fluxes by it. Off: brdf and
    /// btdf integrate to the fluxes (and fourier_coefficients, which never include it, give them) to the
    /// discretization's error: one slab between smooth faces on the split rule 1.75e-3 at M = 8, 2e-6 at 16; on one
    /// half-range rule there (critical_split = false) far less well, 6% at M = 16 and 33% at 4, whose exit at a true
    /// angle meets the Fresnel factor's kink between the ordinates (found by review).
    bool single_scattering_correction = false;
};

/// What a scene needs (see LayerOutput); the solver computes nothing else.
template <class Real = double>
struct LayerRequest {
    LayerOutput outputs = LayerOutput::all;
    /// Incidence cosines mu_0 in (0, 1] at which brdf/btdf/reflectance/transmittance will be evaluated; their internal fields
    /// (and, when surface_reflection is requested, the top face's hemispherical reflectance) are precomputed, so
    /// evaluation there skips the top interface's coefficients, its reflectance integral and the per-mode solve.
    /// Other incidences still work (computed on the fly).
    std::vector<Real> incidence;
    /// Optical depths in [0, tau], measured from the top of the layer (true, not delta-M scaled; through a stack,
    /// the sum of the slabs' thicknesses above plus the depth into the slab), at which depth_profile() will give
    /// the fluence rate and the net flux (their fields are prepared here: two slab solves of mode 0 per depth, and
    /// in a stack under a rough top the adding of the slabs above and below). A depth on a joint is taken in the
    /// slab above it.
    std::vector<Real> depths;
    /// Modes beyond this are not solved (0 = no cap beyond LayerOptions::modes).
    int max_modes = 0;
    /// 0: everything exact to the discretization. > 0: (a) modes are solved in order and the loop stops
    /// after two consecutive modes whose operators are below tolerance relative to mode 0 (the subsurface BRDF's and
    /// the BTDF's coefficients at the ordinates, for the outputs requested, the layer's operators counting as both;
    /// between specular faces the slabs' diffuse operators; rough faces not prepared are built for the modes it is
    /// expected to need, and for all where the loop goes on: docs/physics.md section 6); (b) a slab with
    /// e^{-lambda_min tau} < tolerance (lambda_min: the slowest diffuse mode) is solved as semi-infinite when neither
    /// transmission, transmittance nor depths are requested; (c) rough faces built for the solve
    /// (not prepared ones) take their integrals no finer than the tolerance needs: LayerOptions::hemispherical_nodes
    /// and ::azimuthal_points capped at 9 and 12 from 1e-2, 12 and 12 from 1e-3 (integrals_for_tolerance: their
    /// errors stay 35 times or more inside the tolerance).
    Real tolerance = 0;
    /// Tabulate, at the solve, the rough faces' couplings between every outside cosine and the ordinates (the
    /// azimuthal integrals of their BTDF that brdf, btdf, reflectance and transmittance compute at an incidence or exit
    /// not listed in `incidence`), and the top face's hemispherical reflectance (where its table holds it:
    /// detail::EntryTransmittance) and the faces' transmittance (else tabulated point by point as evaluations need
    /// them: 4 integrals where an evaluation's mu is new), so that evaluation at any angle costs microseconds and no
    /// evaluation computes a table's points (README, speed table). The
    /// couplings are interpolated by cubic polynomials in
    /// (2 / pi) asin(sqrt(mu)) (detail::MuTable, 128 intervals; the first two keep the integrals); each table is
    /// checked at the solve against the integrals at 16 points between its nodes, and a face whose lobe is too narrow
    /// for it (sigma 0.05 at n 1 | 1.4; a nearly index-matched face, whose BTDF nears a delta) keeps the integrals, as
    /// does light from a denser medium (an onset at the critical cosine): see detail::CouplingTable and
    /// tabulated_couplings(). What the kept tables change in the outputs is measured in tests/test_layer_tabulated.cpp.
    /// Cost at the solve: for Stam's skin layer one table (its bottom is its top turned over, and the BTDF is
    /// reciprocal) and the entry tables, checked, about as much as 90 reflectance(mu) evaluations on the fly (README,
    /// speed table). PreparedBoundary faces keep their tables (detail::CouplingCache): from them only the first
    /// tabulated solve pays, the next cost a prepared solve. A TabulatedBSDF built from the layer then takes a
    /// seventh of the time (tabulated_bsdf.hpp).
    bool tabulate_faces = false;
};

/// `options` with the rough faces' integrals no finer than a tolerance needs: LayerOptions::hemispherical_nodes
/// capped at 9 from 1e-2 and 12 from 1e-3, ::azimuthal_points at 12 from 1e-3, so that their worst errors stay 35
/// times or more inside the tolerance, relative to the largest of the outputs (the subsurface BRDF and BTDF
/// together; an output far below the others, such as a subsurface BRDF 50 times below the BTDF, may change by up to
/// 0.3 t of its own peak: docs/physics.md section 6); none capped below 1e-3. A solve with LayerRequest::tolerance builds its
/// rough faces so (and the planner its levels); faces prepared with these options give that solve's result bit for
/// bit (PreparedBoundary), faces prepared with `options` the same within the integrals' error. Measured: the
/// hemispherical totals' worst absolute difference from 32 nodes over sigma 0.003 to 20, n 1 | 1.001 to 1 | 4
/// either way up, both sides, every shadowing form, at the ordinates of 8, 24 and 48-point rules: 1.6e-4 / 4.7e-5 /
/// 7.3e-6 at 9 / 10 / 12 nodes (16: 2.8e-7, at sigma 20; ~1e-11 at sigma 0.1 to 0.3; docs/accuracy.md, "the
/// hemispherical integrals' Gauss nodes over a sweep", repeats it at 24 ordinates); the azimuthal rule's worst entry
/// relative to its column's peak at 12 points 2.5e-6 (sigma 0.005 to 5; 4.7e-7 within 0.02 to 1, docs/accuracy.md,
/// "azimuthal rule"). The same rule gives the faces' couplings at true angles (brdf, btdf, reflectance(mu)).
/// The options unchanged without a tolerance.
template <class Real>
LayerOptions integrals_for_tolerance(LayerOptions options, Real tolerance) noexcept {
    // (compared in Real, the thresholds rounded from long double: a float 1e-3f or a long double 1e-3L is 1e-3 here)
    if (!(tolerance >= static_cast<Real>(1e-3L))) return options;
    options.hemispherical_nodes = std::min(options.hemispherical_nodes, tolerance >= static_cast<Real>(1e-2L) ? 9 : 12);
    options.azimuthal_points = std::min(options.azimuthal_points, 12);
    return options;
}

/// A boundary of a layer: rough (Beckmann microfacets), specular (smooth or index-matched), or an opaque
/// Lambertian floor (the bottom of a layer only). Converts implicitly from RoughDielectric and SmoothDielectric.
template <class Real = double>
class Boundary {
public:
    Boundary(const RoughDielectric<Real>& rough) : rough_(rough), smooth_(rough.eta_above(), rough.eta_below()) {}  // NOLINT
    Boundary(const SmoothDielectric<Real>& smooth) : smooth_(smooth) {}                                            // NOLINT
    /// Both sides of index eta: light crosses unchanged.
    static Boundary index_matched(Real eta = Real(1)) { return Boundary(SmoothDielectric<Real>(eta, eta)); }
    /// An opaque diffuse floor under a medium of index eta: light from above is reflected with radiance
    /// albedo / pi times its irradiance (bone under tissue, soil under a leaf, a white ground under paint);
    /// nothing is transmitted. Only the bottom of a layer or stack. Throws std::invalid_argument for albedo outside
    /// [0, 1] or eta outside [1e-4, 1e4].
    static Boundary lambertian(Real albedo, Real eta = Real(1)) {
        detail::require_refractive_index("eta", eta);  // (named as here: the face's check said eta_above)
        Boundary b(SmoothDielectric<Real>(eta, eta));
        b.floor_albedo_ = detail::require_closed("albedo", albedo, Real(0), Real(1));
        return b;
    }

    bool rough() const noexcept { return rough_.has_value() && !rough_->index_matched() && !rough_->smooth(); }
    bool lambertian() const noexcept { return floor_albedo_.has_value(); }
    /// The albedo of a Lambertian floor (0 for any other boundary).
    Real floor_albedo() const noexcept { return floor_albedo_.value_or(Real(0)); }
    Real eta_above() const noexcept { return smooth_.eta_above(); }
    Real eta_below() const noexcept { return smooth_.eta_below(); }
    const std::optional<RoughDielectric<Real>>& rough_interface() const noexcept { return rough_; }
    const SmoothDielectric<Real>& smooth_interface() const noexcept { return smooth_; }

    InterfaceOperators<Real> operators(const Quadrature<Real>& q, int modes, const LayerOptions& o) const {
        if (lambertian()) return InterfaceOperators<Real>::lambertian_floor(*floor_albedo_, q, modes);
        return rough() ? InterfaceOperators<Real>(*rough_, q, modes, AzimuthalQuadrature<Real>(o.azimuthal_points),
                                                  o.renormalization, o.hemispherical_nodes)
                       : InterfaceOperators<Real>(smooth_, q, modes, o.specular_transmission);
    }
    /// Directional-hemispherical transmittance for light arriving with cosine mu (> 0 from above): an
    /// integral for a rough face, the Fresnel value for a smooth one, 0 for a Lambertian floor.
    Real hemispherical_transmittance(Real mu) const {
        if (lambertian()) return Real(0);
        return rough() ? rough_->hemispherical_transmittance(mu) : smooth_.transmittance(mu);
    }
    /// Directional-hemispherical reflectance for light arriving with cosine mu (> 0 from above), likewise (a
    /// Lambertian floor: its albedo from above, 0 from below).
    Real hemispherical_reflectance(Real mu) const {
        if (lambertian()) return mu > 0 ? *floor_albedo_ : Real(0);
        return rough() ? rough_->hemispherical_reflectance(mu) : smooth_.reflectance(mu);
    }

private:
    std::optional<RoughDielectric<Real>> rough_;
    std::optional<Real> floor_albedo_;  // a Lambertian floor
    SmoothDielectric<Real> smooth_;  // the indices; the specular model when not rough
};

namespace detail {

/// LayerOptions in range: ordinates in [1, 4096], modes in [0, 8192], hemispherical_nodes in [2, 32],
/// azimuthal_points in [2, 1024], the enumerations' values known.
inline void require_options(const LayerOptions& options) {
    // At most 4096 ordinates, beyond any discretization solved in practice (a rough face's operators alone take
    // 32 M^3 bytes, 4.3 GB at 512, which may still fail to allocate below the bound); 2^30 threw std::length_error
    // from an allocation (found by a review sweep).
    if (options.ordinates < 1 || options.ordinates > 4096) throw_out_of_range("options.ordinates", options.ordinates, "[1, 4096]");
    // modes and azimuthal_points likewise (2^30 threw std::bad_alloc; found by review): 2 x 4096 modes at most, and
    // 1024 points per panel (24 are within ~1e-13 of converged).
    if (options.modes < 0 || options.modes > 8192) throw_out_of_range("options.modes", options.modes, "[0, 8192]");
    if (options.hemispherical_nodes < 2 || options.hemispherical_nodes > 32)
        throw_out_of_range("options.hemispherical_nodes", options.hemispherical_nodes, "[2, 32]");
    if (options.azimuthal_points < 2 || options.azimuthal_points > 1024)
        throw_out_of_range("options.azimuthal_points", options.azimuthal_points, "[2, 1024]");
    // Enumerations converted from out-of-range integers were used silently (Renormalization(99) changed R).
    if (options.renormalization != Renormalization::none && options.renormalization != Renormalization::hemispherical_totals)
        throw_out_of_range("options.renormalization", static_cast<int>(options.renormalization), "{0, 1} (Renormalization)");
    if (options.specular_transmission != SpecularTransmission::pointwise &&
        options.specular_transmission != SpecularTransmission::flux_conserving &&
        options.specular_transmission != SpecularTransmission::automatic)
        throw_out_of_range("options.specular_transmission", static_cast<int>(options.specular_transmission),
                           "{0, 1, 2} (SpecularTransmission)");
}

/// The spacing of ascending ordinates around x: between the first ordinate at or above x and the one before it
/// (the first two where x lies below them all; 1 for a single ordinate).
template <class Real>
Real spacing_at(const std::vector<Real>& nodes, Real x) noexcept {
    std::size_t j = 0;
    while (j + 1 < nodes.size() && nodes[j] < x) ++j;
    return j > 0 ? nodes[j] - nodes[j - 1] : nodes.size() > 1 ? nodes[1] - nodes[0] : Real(1);
}

/// A function of mu in (0, 1], or `width` of them, tabulated at N + 1 points equispaced in t = sqrt(mu) and
/// interpolated by cubic Lagrange polynomials in t on the 4 nearest points: the hemispherical transmittance and
/// reflectance of a rough boundary, which cost a 2-D integral per value, and a rough face's coupling to the ordinates
/// (CouplingTable); they change fastest near grazing (the limit at mu -> 0+ differs from the value at mu = 0, which
/// is the point t = 0 is given instead). Error: tests/test_layer.cpp and tests/test_layer_tabulated.cpp measure it.
template <class Real>
struct MuTable {
    // The table's variable: t = sqrt(mu), or t = (2 / pi) asin(sqrt(mu)) (`arcsine`: also smooth where a function
    // of mu behaves like sin^k(theta) = (1 - mu^2)^{k/2} at the normal, as the k-th azimuthal mode of a BSDF does).
    bool arcsine = false;
    int width = 1;
    std::vector<Real> values;  // f(mu(j / N))[v] at j width + v, j = 0..N (j = 0: the limit mu -> 0+)
    // f(mu, out) writes the width values at mu.
    template <class F>
    void build(int intervals, int values_per_point, F f) {
        allocate(intervals, values_per_point);
        for (int j = 0; j <= intervals; ++j) fill(j, f);
    }
    // Or point by point (EntryTransmittance): the storage first, then each point j as needed (the 4 from first_point(mu)).
    void allocate(int intervals, int values_per_point) {
        width = values_per_point;
        values.assign(static_cast<std::size_t>(intervals + 1) * static_cast<std::size_t>(width), Real(0));
    }
    template <class F>
    void fill(int j, F f) {
        f(j == 0 ? Real(1e-12) : cosine(Real(j) / Real(intervals())),
          values.data() + static_cast<std::size_t>(j) * static_cast<std::size_t>(width));
    }
    // The first of the 4 points that interpolate at mu.
    int first_point(Real mu) const noexcept {
        Real w[4];
        return lagrange_weights(Points{}, intervals() + 1, parameter(mu) * Real(intervals()), 4, w).first;
    }
    Real cosine(Real t) const noexcept {
        if (!arcsine) return t * t;
        const Real s = std::sin(pi_v<Real> / 2 * t);
        return t >= 1 ? Real(1) : s * s;
    }
    Real parameter(Real mu) const noexcept {
        const Real m = std::fmin(std::fmax(mu, Real(0)), Real(1));
        return arcsine ? Real(2) / pi_v<Real> * std::asin(std::sqrt(m)) : std::sqrt(m);
    }
    int intervals() const noexcept { return static_cast<int>(values.size()) / width - 1; }
    // The first `count` values at mu into out.
    void interpolate(Real mu, Real* out, int count) const noexcept {
        Real w[4];
        const Real* row = window(mu, w);
        const std::size_t stride = static_cast<std::size_t>(width);
        for (std::size_t v = 0; v < static_cast<std::size_t>(count); ++v)
            out[v] = w[0] * row[v] + w[1] * row[stride + v] + w[2] * row[2 * stride + v] + w[3] * row[3 * stride + v];
    }
    // Value v at mu.
    Real operator()(Real mu, int v = 0) const noexcept {
        Real w[4];
        const Real* row = window(mu, w) + v;
        const std::size_t stride = static_cast<std::size_t>(width);
        return w[0] * row[0] + w[1] * row[stride] + w[2] * row[2 * stride] + w[3] * row[3 * stride];
    }

private:
    // The Lagrange weights at mu into w, and the first of their 4 points' rows.
    const Real* window(Real mu, Real* w) const noexcept {
        const int n = intervals();
        const Real x = parameter(mu) * Real(n);  // in units of 1 / N
        const LagrangeWindow lw = lagrange_weights(Points{}, n + 1, x, 4, w);
        return values.data() + static_cast<std::size_t>(lw.first) * static_cast<std::size_t>(width);
    }
    struct Points {  // the table's points t_j = j / N, in units of 1 / N
        Real operator[](std::size_t j) const noexcept { return static_cast<Real>(j); }
    };
};

/// Whether `bottom` is the rough face `top` turned over (same roughness and shadowing, indices exchanged): Stam's
/// skin layer, a slab of one material in one medium. Its operators are then top's flipped (InterfaceOperators::
/// flipped), and its entry from below top's entry from above: the solve builds the face once.
template <class Real>
bool turned_over(const Boundary<Real>& top, const Boundary<Real>& bottom) noexcept {
    if (!top.rough() || !bottom.rough()) return false;
    const RoughDielectric<Real>& t = *top.rough_interface();
    const RoughDielectric<Real>& b = *bottom.rough_interface();
    return t.sigma() == b.sigma() && t.shadowing() == b.shadowing() && t.eta_above() == b.eta_below() &&
           t.eta_below() == b.eta_above();
}

/// The directional-hemispherical transmittance of a boundary for light arriving at |cosine| mu from one side (the
/// outside of a layer: above a top face, below a bottom face), and its reflectance. A rough face's 2-D integral
/// (which gives both) is tabulated (MuTable, 64 intervals) point by point as evaluations need them: the 4 points
/// that interpolate at mu, each computed once (std::call_once per point keeps it thread-safe), shared by every layer
/// solved with one PreparedBoundary. (The whole table at the first evaluation, as before, cost 65 integrals there,
/// about 9 ms at M = 16 for sigma 0.3, where the evaluation itself takes 0.3 ms.) Exact below the
/// first table interval, for a specular face, and for light from a denser medium: there T(mu) has an onset at the
/// critical cosine, as steep as sigma is small, which no polynomial table resolves (found by fuzz_layer: n 1.88 | 0.50,
/// sigma 7e-5, mu 0.996 gave a transmittance 12% above the entering flux). The layer uses the tabulated
/// transmittance always (to scale the light it lets in), the reflectance only with LayerRequest::tabulate_faces and
/// where the table holds it (check_reflectance; else the integral at each mu).
template <class Real>
class EntryTransmittance {
public:
    EntryTransmittance(const Boundary<Real>& boundary, Incidence side) : boundary_(boundary), side_(side) {
        if (tabulated(Real(1))) table_.allocate(intervals, 2);
    }

    Real operator()(Real mu) const { return value(mu, false); }
    // From the table where it was checked to hold R (check_reflectance), else the integral.
    Real reflectance(Real mu) const {
        const Real signed_mu = side_ == Incidence::from_above ? mu : -mu;
        if (!tabulated(mu)) return boundary_.hemispherical_reflectance(signed_mu);
        check_reflectance();  // (call_once: reflectance_held_ is written before it returns)
        return reflectance_held_ ? value(mu, true) : boundary_.hemispherical_reflectance(signed_mu);
    }
    // Builds the table now (where one serves), and checks its reflectance if asked, so that no later evaluation pays
    // for them.
    void prepare(bool reflectance) const {
        if (!tabulated(Real(1))) return;
        if (reflectance) check_reflectance();
        else build();
    }
    // How many of the table's points have been computed (each a 2-D integral; tests).
    int points_computed() const noexcept { return computed_.load(); }

private:
    bool tabulated(Real mu) const noexcept {
        const bool from_above = side_ == Incidence::from_above;
        const Real eta_outside = from_above ? boundary_.eta_above() : boundary_.eta_below();
        const Real eta_inside = from_above ? boundary_.eta_below() : boundary_.eta_above();
        return boundary_.rough() && !(eta_outside > eta_inside) && !(mu < grazing);
    }
    // Point j of the table, computed once. The integrals with 12 Gauss nodes per panel instead of 16: within 4.4e-7
    // of the default's (measured at the table's points, sigma 0.005 to 2, n 1 | 1.1, 1.4, 2.5), 25 times below the
    // table's own interpolation error (1.1e-5, tests/test_layer.cpp), in about 0.6 of the time (10 nodes: 1.1e-5 at
    // sigma 0.1, n 2.5).
    void point(int j) const {
        std::call_once(point_once_[static_cast<std::size_t>(j)], [this, j] {
            const RoughDielectric<Real>& face = *boundary_.rough_interface();
            const bool from_above = side_ == Incidence::from_above;
            table_.fill(j, [&](Real x, Real* out) {
                const HemisphericalTotals<Real> a = face.hemispherical_totals(from_above ? x : -x, 12);
                out[0] = a.transmittance;
                out[1] = a.reflectance;
            });
            ++computed_;
        });
    }
    void build() const {
        for (int j = 0; j <= intervals; ++j) point(j);
    }
    // R has a shadowing feature near mu ~ sigma that the nodes miss for small sigma (1e-2 at sigma 5e-4, 4.2e-5 at
    // 1e-2; found by review): the table's R is used only where it is within reflectance_limit of the integrals
    // (at 12 nodes, as the table's) at the midpoints of every interval below t = 1/4 (mu < 1/16, where mu ~ sigma
    // for the narrow lobes) and of every fourth above (27 points).
    static constexpr Real reflectance_limit = Real(2e-6);
    void check_reflectance() const {
        build();
        std::call_once(checked_, [this] {
            const RoughDielectric<Real>& face = *boundary_.rough_interface();
            const bool from_above = side_ == Incidence::from_above;
            Real worst = 0;
            for (int j = 1; j < intervals; j += j < intervals / 4 ? 1 : 4) {
                const Real t = (Real(j) + Real(0.5)) / Real(intervals), mu = t * t;
                const Real exact = face.hemispherical_totals(from_above ? mu : -mu, 12).reflectance;
                worst = std::fmax(worst, std::fabs(table_(mu, 1) - exact));
            }
            reflectance_held_ = worst <= reflectance_limit;
        });
    }
    Real value(Real mu, bool reflected) const {
        const Real signed_mu = side_ == Incidence::from_above ? mu : -mu;
        if (!tabulated(mu))
            return reflected ? boundary_.hemispherical_reflectance(signed_mu) : boundary_.hemispherical_transmittance(signed_mu);
        const int first = table_.first_point(mu);
        for (int a = 0; a < 4; ++a) point(first + a);
        const Real t = table_(mu, reflected ? 1 : 0);
        return t < 0 ? Real(0) : t;
    }

    static constexpr int intervals = 64;
    static constexpr Real grazing = Real(1) / Real(intervals * intervals);  // below the first table interval
    Boundary<Real> boundary_;
    Incidence side_;
    mutable std::array<std::once_flag, intervals + 1> point_once_;
    mutable std::once_flag checked_;
    mutable std::atomic<int> computed_{0};
    mutable MuTable<Real> table_;  // (allocated at construction: point() writes only its own point's values)
    mutable bool reflectance_held_ = false;  // (written once, under checked_)
};

/// A rough face's couplings to a layer's ordinates, tabulated over the outside cosine (LayerRequest::tabulate_faces):
/// for light crossing the face one way at |cosine| mu outside, I_k(mu <-> mu_m) for each ordinate m and mode k < K
/// at [m K + k], then I_k(mu <-> mu_t) at mu's Snell cosine inside at [M K + k] ((M + 1) K values per point, MuTable
/// in (2 / pi) asin(sqrt(mu)): mode k behaves like sin^k(theta) at the normal), times `scale`: one table serves
/// both ways across a face whose BTDF is reciprocal, I^{t21}(mu_m -> mu) = (n_1 / n_2)^2 I^{t12}(mu -> mu_m)
/// (interface_operators.hpp), and a bottom face that is the top turned over. Below `grazing` (the first two
/// intervals, whose stencils would reach the point given the limit mu -> 0+) the integrals are computed.
template <class Real>
struct CouplingTable {
    std::shared_ptr<const MuTable<Real>> table;  // null: not tabulated
    Real scale = 1;
    int modes = 0;  // K (at least the solve's: a table kept with a prepared face holds all its operators' modes)
    // (A multiple of TabulatedBSDF's grid intervals, 8 to 128: its cosines fall on these nodes; the midpoints where
    // its finest grid measures its error, 256 intervals, do not.)
    static constexpr int intervals = 128;
    Real grazing = 1;
    // The largest difference from the integrals at the check points, every mode's summed, relative to the flux
    // the ordinates carry: sum_m w_m mu_m sum_k |Delta I_k(mu, mu_m)| / sum_m w_m mu_m I_0(mu, mu_m). Beyond `limit`
    // the face keeps its integrals: a lobe too narrow for the table's nodes (sigma 0.05 at n 1 | 1.4: 43; every
    // sigma at n 1 | 1.05, where the BTDF nears a delta: 1.1 at sigma 1, up to 1e140 at 0.02), against 1.1e-3 to
    // 3.6e-3 for sigma 0.2 to 1 at n 1 | 1.4 and 1 | 2.5 (M = 16; tests/test_layer_tabulated.cpp measures what
    // the kept tables change in the layer's outputs).
    Real error = 0;
    static constexpr Real limit = Real(5e-3);
    bool holds(Real mu) const noexcept { return table && mu >= grazing; }
};

/// The coupling tables of a prepared face on one rule (PreparedBoundary), built by the first solve that asks for them
/// (LayerRequest::tabulate_faces) and reused by the next (a new albedo, g, thickness or wavelength): as the top for
/// light entering and leaving, as the bottom for light leaving. Thread-safe (std::call_once).
template <class Real>
struct CouplingCache {
    std::once_flag once[3];
    CouplingTable<Real> table[3];
};

}  // namespace detail

/// A boundary with its operators built for one discretization: LayerOptions::ordinates, ::modes (0: 2M),
/// ::renormalization, ::hemispherical_nodes and ::azimuthal_points. They depend on the face alone, never on the slab, and are most of a rough-faced solve's cost:
/// prepare the faces once and pass them to solve_layer / solve_stack for every slab (an edit of albedo, g or
/// thickness, another wavelength), which then pays for the slab alone. The result is identical to a solve from
/// the plain Boundary, bit for bit, when the request solves all the prepared modes (with a tolerance, from faces
/// prepared with integrals_for_tolerance(options, tolerance), as the plain solve builds them); a request for fewer
/// (LayerRequest::max_modes, or no angular output: fluxes and the ambient term need mode 0 alone) uses the
/// prepared operators, whose azimuthal rule resolves more modes than it needs: equal within that rule's error
/// (1e-12 at the default 24 points; ~5e-7 at 12). A specular (smooth or index-matched) face has cheap operators and keeps none: they are built
/// at each solve. Immutable; copies share the operators; usable from several threads at once.
template <class Real>
class LayeredSurface;

template <class Real = double>
class PreparedBoundary {
public:
    /// Throws std::invalid_argument for options out of range (detail::require_options), naming the option.
    explicit PreparedBoundary(const Boundary<Real>& boundary, const LayerOptions& options = {})
        : boundary_(boundary), options_(options),
          from_above_(std::make_shared<const detail::EntryTransmittance<Real>>(boundary, Incidence::from_above)),
          from_below_(std::make_shared<const detail::EntryTransmittance<Real>>(boundary, Incidence::from_below)) {
        detail::require_options(options);
        if (!boundary.rough()) return;
        plain_ = build(gauss_legendre_half<Real>(options.ordinates));
    }
    /// The same face prepared for other options, sharing what does not depend on them: the entry transmittances
    /// (tabulated as evaluations need them, 65 points of about 0.14 ms each for a rough face), which a convergence
    /// study over the ordinates or the
    /// planner (planner.hpp) then builds once. Equal bit for bit to preparing other.boundary() afresh. Throws as the
    /// constructor.
    explicit PreparedBoundary(const PreparedBoundary& other, const LayerOptions& options)
        : boundary_(other.boundary_), options_(options), from_above_(other.from_above_), from_below_(other.from_below_) {
        detail::require_options(options);
        if (!boundary_.rough()) return;
        plain_ = build(gauss_legendre_half<Real>(options.ordinates));
    }

    const Boundary<Real>& boundary() const noexcept { return boundary_; }
    /// The options the operators were built for (all the faces of one solve must share them).
    const LayerOptions& options() const noexcept { return options_; }
    /// The number of Fourier modes prepared: options().modes, or 2M for 0.
    int modes() const noexcept { return options_.modes > 0 ? options_.modes : 2 * options_.ordinates; }
    /// The prepared operators on the half-range rule of options().ordinates; null for a specular face.
    const std::shared_ptr<const InterfaceOperators<Real>>& operators() const noexcept { return plain_.operators; }

    /// This rough face turned over (its indices exchanged: a layer's bottom face when this is its top, as in Stam's
    /// skin layer), prepared from this one at the cost of a copy (InterfaceOperators::flipped; the entry tables are
    /// shared, each side's being the other side's of the turned face): equal bit for bit to preparing the turned face.
    /// A specular face is returned as prepared afresh (its preparation costs nothing); a Lambertian floor has no
    /// other side (std::invalid_argument).
    PreparedBoundary turned_over() const {
        if (boundary_.lambertian())
            detail::fail_invalid_argument("stratum: PreparedBoundary::turned_over: a Lambertian floor has no other side");
        const Boundary<Real> turned = boundary_.rough_interface()  // (kept a RoughDielectric even when smooth())
            ? Boundary<Real>(RoughDielectric<Real>(boundary_.rough_interface()->sigma(), boundary_.eta_below(),
                                                   boundary_.eta_above(), boundary_.rough_interface()->shadowing()))
            : Boundary<Real>(SmoothDielectric<Real>(boundary_.eta_below(), boundary_.eta_above()));
        if (!plain_.operators) return PreparedBoundary(turned, options_);
        PreparedBoundary out(*this);
        out.boundary_ = turned;
        out.plain_.operators = std::make_shared<const InterfaceOperators<Real>>(plain_.operators->flipped());
        out.plain_.couplings = std::make_shared<detail::CouplingCache<Real>>();  // (not this face's tables)
        std::swap(out.from_above_, out.from_below_);
        std::swap(out.plain_.above, out.plain_.below);
        out.split_ = std::make_shared<SplitRules>();  // (this face's rules are not the turned face's)
        return out;
    }

private:
    template <class R>
    friend LayeredSurface<R> solve_stack(const PreparedBoundary<R>&, const std::vector<Slab<R>>&,
                                         const std::vector<PreparedBoundary<R>>&, const PreparedBoundary<R>&,
                                         const detail::non_deduced_t<LayerRequest<R>>&);
    // For the solver: the transmittance of light arriving from `side`, tabulated as evaluations need it for a rough
    // face and shared by the layers solved with this face; and its values at the ordinates (empty: specular face).
    const std::shared_ptr<const detail::EntryTransmittance<Real>>& entry_transmittance(Incidence side) const noexcept {
        return side == Incidence::from_above ? from_above_ : from_below_;
    }
    // The operators on a rule, and the hemispherical transmittance at each of its ordinates from either side (what
    // leaves a layer through the face: the renormalized operators hold it already, otherwise 2M integrals, here and
    // not at every solve).
    struct OnRule {
        std::vector<Real> nodes;
        std::shared_ptr<const InterfaceOperators<Real>> operators;
        std::vector<Real> above, below;
        std::shared_ptr<detail::CouplingCache<Real>> couplings = std::make_shared<detail::CouplingCache<Real>>();
        const std::vector<Real>& transmittance(Incidence side) const noexcept {
            return side == Incidence::from_above ? above : below;
        }
    };
    OnRule build(const Quadrature<Real>& q) const {
        OnRule out;
        out.nodes = q.nodes;
        out.operators = std::make_shared<const InterfaceOperators<Real>>(boundary_.operators(q, modes(), options_));
        for (const Incidence side : {Incidence::from_above, Incidence::from_below}) {
            std::vector<Real>& t = side == Incidence::from_above ? out.above : out.below;
            const auto& totals = out.operators->ordinate_totals(side);
            for (std::size_t i = 0; i < q.size(); ++i)
                t.push_back(totals.size() == q.size() ? totals[i].transmittance
                                                      : boundary_.hemispherical_transmittance(
                                                            side == Incidence::from_above ? q.nodes[i] : -q.nodes[i]));
        }
        return out;
    }
    // The face on the layer's rule q: the half-range rule prepared at construction, or a rule split at the critical
    // cosines of the layer it bounds (a rough top over a smooth bottom: detail::layer_quadrature), built on first use
    // and kept for the next solves (thread-safe; copies share them).
    const OnRule& on_rule(const Quadrature<Real>& q) const {
        if (!plain_.operators || q.nodes == plain_.nodes) return plain_;  // (a specular face keeps no operators)
        const std::lock_guard<std::mutex> lock(split_->mutex);
        for (const std::shared_ptr<const OnRule>& r : split_->rules)
            if (r->nodes == q.nodes) return *r;
        split_->rules.push_back(std::make_shared<const OnRule>(build(q)));
        return *split_->rules.back();
    }
    struct SplitRules {
        std::mutex mutex;
        std::vector<std::shared_ptr<const OnRule>> rules;
    };

    Boundary<Real> boundary_;
    LayerOptions options_;
    OnRule plain_;  // operators null for a specular face
    std::shared_ptr<SplitRules> split_ = std::make_shared<SplitRules>();
    std::shared_ptr<const detail::EntryTransmittance<Real>> from_above_, from_below_;
};

/// Solves a stack: `top` boundary, then slabs[0], interior[0], slabs[1], ..., slabs[N-1], then `bottom`
/// (interior.size() == slabs.size() - 1). Adjacent indices must agree (top.eta_below() ==
/// interior[0].eta_above(), ...). Throws std::invalid_argument for inconsistent input or bad options.
/// The boundaries are not deduced, so a RoughDielectric or SmoothDielectric converts to a Boundary.
template <class Real>
LayeredSurface<Real> solve_stack(const detail::non_deduced_t<Boundary<Real>>& top, const std::vector<Slab<Real>>& slabs,
                                 const std::vector<Boundary<Real>>& interior,
                                 const detail::non_deduced_t<Boundary<Real>>& bottom, const LayerOptions& options = {},
                                 const detail::non_deduced_t<LayerRequest<Real>>& request = {});

/// The same solve from prepared boundaries (PreparedBoundary): their operators are reused, and the discretization
/// is theirs (they must all have been prepared with the same LayerOptions; std::invalid_argument otherwise).
template <class Real>
LayeredSurface<Real> solve_stack(const PreparedBoundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                 const std::vector<PreparedBoundary<Real>>& interior, const PreparedBoundary<Real>& bottom,
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

/// The slab prepared for its per-mode operators: delta-M scaled (or not), with its phase matrices.
template <class Real>
struct SlabModes {
    Slab<Real> slab;  // possibly delta-M scaled
    PhaseFourierMatrices<Real> phase;
    std::vector<Real> moments;  // the Legendre moments behind `phase` (scaled and truncated as it is)
    Real truncation = 0;        // delta-M's f (0 without)
};

/// Scattering conserves energy on the ordinates: sum_m w_m (P+ + P-)_nm = 2 for mode 0 (Stam's normalization). The
/// half-range Gauss rule integrates the truncated phase function exactly (to rounding); a rule split at critical
/// cosines (layer_quadrature) does not, and at albedo 1 the slab would then lose energy. Where a row's defect
/// exceeds rounding it is moved onto the diagonal (forward scattering into the same direction), which keeps the
/// matrix symmetric: P+_nn += (2 - sum) / w_n. The defect is small for delta-M scaled media (<= 1% at 4 ordinates);
/// for a peaked phase function without delta-M (g = 0.99, delta_m off, 32 ordinates) it reaches 40% and the
/// diagonal takes large corrections (README, known limitations). Rescaling the rows in proportion to the scattering
/// instead (symmetrically) was tried: it keeps the shape of a peak but costs accuracy in the usual case (worst error
/// against adding-doubling at M = 48: 7.6e-6 instead of 8.6e-7).
template <class Real>
void make_discretely_conservative(PhaseFourierMatrices<Real>& p, const Quadrature<Real>& q) {
    if (p.modes < 1) return;
    const std::size_t m = q.size();
    const Real tolerance = Real(64) * Real(m) * std::numeric_limits<Real>::epsilon();
    Real* same = p.same.data();  // mode 0: the first block
    const Real* opposite = p.opposite.data();
    for (std::size_t n = 0; n < m; ++n) {
        Real sum = 0;
        for (std::size_t j = 0; j < m; ++j) sum += q.weights[j] * (same[n * m + j] + opposite[n * m + j]);
        if (std::fabs(sum / 2 - 1) > tolerance) same[n * m + n] += (2 - sum) / q.weights[n];
    }
}

/// prepare_slab for a phase function given by its Legendre moments (Slab::with_phase_moments): the first
/// L = 2M, delta-M scaled with f = chi_L when the medium scatters forwards (g > 0) and chi_L is given, positive and
/// below 1, with every scaled moment in [-1, 1] (a forward peak beyond what the ordinates resolve), plainly
/// truncated otherwise (moments beyond those given are 0: nothing to truncate).
template <class Real>
SlabModes<Real> prepare_slab_from_moments(const Slab<Real>& s, const Quadrature<Real>& q, int modes, bool delta_m,
                                          Real tau) {
    const std::size_t count = 2 * q.size();
    const std::vector<Real>& given = s.phase_moments();
    std::vector<Real> chi(count, Real(0));
    for (std::size_t l = 0; l < count && l < given.size(); ++l) chi[l] = given[l];
    // As for Henyey-Greenstein (prepare_slab): delta-M only for a forward-scattering medium (g = chi_1 > 0), and
    // only where it leaves a phase function: f < 1 and every scaled moment (chi_l - f) / (1 - f) in [-1, 1]. (Moments
    // {1, 0.5, 1}, a forward and a backward delta, have f = chi_2 = 1 at M = 1: the scaling divided by 0, and the
    // slab was refused with "chi[1] = -inf"; found by review.) The switch is a jump in the moments where a scaled
    // moment reaches -1 (R of {1, 0.5, 1 - d} at M = 1 by 28% across d = 1/4; found by the next review); lowering f
    // to min_l (1 + chi_l) / 2 instead, which is continuous, lost 13% of the light at grazing incidence there (the
    // scaled moments at -1 are a phase function negative over half the sphere). Neither affects Henyey-Greenstein.
    Real f = delta_m && s.g() > Real(0) && given.size() > count ? given[count] : Real(0);
    for (std::size_t l = 1; l < count && f > 0; ++l)
        if (!(f < 1) || !(std::fabs(chi[l] - f) <= Real(1) - f)) f = 0;
    if (!(f > 0)) {
        SlabModes<Real> out{Slab<Real>::from_one_minus_albedo(s.one_minus_albedo(), s.g(), tau),
                            phase_fourier_matrices(chi, q.nodes, modes), chi};
        make_discretely_conservative(out.phase, q);
        return out;
    }
    // Wiscombe 1977 (docs/physics.md section 2): chi'_l = (chi_l - f) / (1 - f), 1 - Omega' = (1 - Omega) / (1 - f
    // Omega), tau' = (1 - f Omega) tau; 1 - f Omega = (1 - f) + f (1 - Omega) without cancellation.
    for (std::size_t l = 1; l < count; ++l) chi[l] = (chi[l] - f) / (Real(1) - f);
    const Real one_minus_f_omega = (Real(1) - f) + f * s.one_minus_albedo();
    SlabModes<Real> out{Slab<Real>::from_one_minus_albedo(s.one_minus_albedo() / one_minus_f_omega, s.g(), one_minus_f_omega * tau),
                        phase_fourier_matrices(chi, q.nodes, modes), chi, f};
    make_discretely_conservative(out.phase, q);
    return out;
}

template <class Real>
SlabModes<Real> prepare_slab(const Slab<Real>& s, const Quadrature<Real>& q, int modes, bool delta_m, Real tau_override) {
    const int moments = 2 * static_cast<int>(q.size());
    const Real tau = tau_override;
    if (!s.henyey_greenstein()) return prepare_slab_from_moments(s, q, modes, delta_m, tau);
    // Delta-M folds a FORWARD peak into the unscattered beam; for g < 0 (a backward peak) its moments
    // (g^l - f) / (1 - f) would be far outside [-1, 1], so backward-scattering media are truncated plainly.
    if (delta_m && s.g() > Real(0)) {
        const DeltaMScaled<Real> dm = delta_m_scaling(s.albedo(), tau, s.g(), moments);
        // 1 - Omega' = (1 - Omega) / (1 - f Omega), with 1 - f Omega = (1 - f) + f (1 - Omega): no cancellation.
        const Real one_minus_f_omega = (Real(1) - dm.f) + dm.f * s.one_minus_albedo();
        const Slab<Real> scaled = Slab<Real>::from_one_minus_albedo(s.one_minus_albedo() / one_minus_f_omega, s.g(),
                                                                    one_minus_f_omega * tau);
        SlabModes<Real> out{scaled, phase_fourier_matrices(dm.moments, q.nodes, modes), dm.moments, dm.f};
        make_discretely_conservative(out.phase, q);
        return out;
    }
    const HenyeyGreenstein<Real> hg(s.g());
    std::vector<Real> chi = hg.legendre_moments(moments);
    SlabModes<Real> out{Slab<Real>::from_one_minus_albedo(s.one_minus_albedo(), s.g(), tau),
                        phase_fourier_matrices(chi, q.nodes, modes), chi};
    make_discretely_conservative(out.phase, q);
    return out;
}

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

// ---- The steps of LayeredSurface::solve that need nothing of the solved layer ----

/// Whether the beam can be a source exact at its angle (LayeredSurface::beam_field): slabs joined by smooth or
/// index-matched faces under a specular top, over a specular face or a Lambertian floor.
template <class Real>
bool beam_is_a_source(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior,
                      const Boundary<Real>& bottom) noexcept {
    if (top.rough() || top.lambertian() || bottom.rough()) return false;
    for (const Boundary<Real>& b : interior)
        if (b.rough() || b.lambertian()) return false;
    return true;
}

/// Rejects inconsistent input (solve_stack's contract) through fail_invalid_argument: counts, the tolerance, the
/// number of interior faces, indices that disagree across a slab, incidence cosines outside (0, 1], depths outside
/// the layer.
template <class Real>
void validate_stack(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                    const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                    const LayerOptions& options, const LayerRequest<Real>& request) {
    require_options(options);
    require_count("request.max_modes", request.max_modes, 0);
    require_count("slabs.size()", static_cast<int>(slabs.size()), 1);
    if (top.lambertian()) fail_invalid_argument("stratum: a Lambertian floor can only be the bottom boundary, not the top");
    for (std::size_t i = 0; i < interior.size(); ++i)
        if (interior[i].lambertian())
            fail_invalid_argument("stratum: a Lambertian floor can only be the bottom boundary, not interior[" +
                                  std::to_string(i) + "]");
    if (!(request.tolerance >= 0 && request.tolerance < 1))
        throw_out_of_range("request.tolerance", request.tolerance, "[0, 1)");
    if (interior.size() + 1 != slabs.size())
        fail_invalid_argument("stratum: solve_stack needs interior.size() == slabs.size() - 1, got " +
                              std::to_string(interior.size()) + " and " + std::to_string(slabs.size()));
    Real above = top.eta_below();
    for (std::size_t i = 0; i <= interior.size(); ++i) {
        const Real below = i < interior.size() ? interior[i].eta_above() : bottom.eta_above();
        if (below != above)
            fail_invalid_argument("stratum: boundary indices disagree around slab " + std::to_string(i) + ": " +
                                  format_value(above) + " above it, " + format_value(below) + " below it");
        if (i < interior.size()) above = interior[i].eta_below();
    }
    // (bits beyond LayerOutput::all were accepted and meant nothing; found by review)
    if ((static_cast<unsigned>(request.outputs) & ~static_cast<unsigned>(LayerOutput::all)) != 0)
        throw_out_of_range("request.outputs", static_cast<long long>(static_cast<unsigned>(request.outputs)),
                           "combinations of LayerOutput's flags, [0, 127]");
    for (std::size_t j = 0; j < request.incidence.size(); ++j)
        require_closed(("request.incidence[" + std::to_string(j) + "]").c_str(), request.incidence[j],
                       std::nextafter(Real(0), Real(1)), Real(1));
    Real total = 0;
    for (const Slab<Real>& slab : slabs) total += slab.optical_thickness();
    for (std::size_t j = 0; j < request.depths.size(); ++j) {
        const std::string name = "request.depths[" + std::to_string(j) + "]";
        require_closed(name.c_str(), request.depths[j], Real(0), total);
        // (a semi-infinite stack's depth inf passed the range and failed later naming an internal thickness, NaN)
        if (!std::isfinite(request.depths[j])) throw_out_of_range(name.c_str(), request.depths[j], "[0, inf)");
    }
}

/// The Fourier modes to solve: LayerOptions::modes (0: 2M, as many as 2M Legendre moments support) capped by
/// LayerRequest::max_modes; mode 0 alone when no angular output is requested (reflectance, transmittance, the
/// ambient term and the fields at depth need no other); none for the surface reflection alone (with depths
/// requested beside it, none left them unsolved: an empty profile; found by review).
template <class Real>
int mode_count(const LayerOptions& options, const LayerRequest<Real>& request) noexcept {
    int modes = options.modes > 0 ? options.modes : 2 * options.ordinates;
    if (request.max_modes > 0) modes = std::min(modes, request.max_modes);
    const bool angular = includes(request.outputs, LayerOutput::subsurface_reflection | LayerOutput::transmission |
                                                       LayerOutput::operators);
    const bool fluxes = includes(request.outputs, LayerOutput::reflectance | LayerOutput::transmittance |
                                                      LayerOutput::ambient) ||
                        !request.depths.empty();
    if (!angular) modes = fluxes ? 1 : 0;
    return modes;
}

/// The modes a rough top or bottom face's operators are first built for, from plain faces, when the request has a
/// tolerance: solve_modes stops where the modes' coefficients fall below it (after 8 to 31 modes for Stam's layer at
/// tolerances 1e-2 to 1e-6; reflection alone 8 to 22), so 8 + 4 per decade of the tolerance (12 at least: with fewer
/// the azimuthal rule resolves too few panels, 2e-8 of an entry at 8 modes and sigma 1 against 2e-10 at 12 or more);
/// more are built when the loop reaches them (LayeredSurface::extend_faces). `modes` without a tolerance.
template <class Real>
int first_face_modes(Real tolerance, int modes) noexcept {
    if (!(tolerance > 0)) return modes;
    // (in double, clamped: a long double tolerance below double's range would make the logarithm infinite)
    const double decades = std::ceil(-std::log10(std::fmax(static_cast<double>(tolerance), 1e-300)));
    return std::min(modes, std::max(12, 8 + 4 * static_cast<int>(decades)));
}

/// Mode k of an operator family as a matrix.
template <class Real>
Matrix<Real> mode_matrix(const FourierOperators<Real>& f, int k) {
    const std::size_t m = static_cast<std::size_t>(f.size);
    Matrix<Real> a(m, m);
    std::copy(f.mode(k), f.mode(k) + m * m, a.data.begin());
    return a;
}

/// Semi-infinite shortcut (LayerRequest::tolerance, when neither transmission nor transmittance is requested): the diffuse field decays
/// into the slab no faster than e^{-lambda_min tau} (lambda_min: the smallest mode-0 eigenvalue), which is slower
/// than the beam's e^{-tau}; so a slab with e^{-lambda_min tau} < tolerance (not e^{-tau} < tolerance) is solved
/// as semi-infinite.
template <class Real>
void make_semi_infinite_if_opaque(SlabModes<Real>& p, const Quadrature<Real>& q, Real tolerance) {
    const Real tau = p.slab.optical_thickness();
    if (!std::isfinite(tau) || !(p.slab.one_minus_albedo() > 0)) return;
    const auto es = slab_eigensystem(p.slab.one_minus_albedo(), q.nodes, q.weights, p.phase.same_k(0),
                                     p.phase.opposite_k(0), 0);
    Real lambda_min = std::numeric_limits<Real>::infinity();
    for (Real l : es.lambda) lambda_min = std::fmin(lambda_min, l);
    if (std::exp(-lambda_min * tau) < tolerance)
        p.slab = Slab<Real>::from_one_minus_albedo(p.slab.one_minus_albedo(), p.slab.g(),
                                                   std::numeric_limits<Real>::infinity());
}

/// A face's operators on the ordinates, shared between solves (PreparedBoundary) or owned by one.
template <class Real>
using SharedOperators = std::shared_ptr<const InterfaceOperators<Real>>;

/// The operators a caller prepared (PreparedBoundary), for the faces of one solve; null: built by the solve.
template <class Real>
struct PreparedOperators {
    SharedOperators<Real> top, bottom;
    std::vector<SharedOperators<Real>> interior;  // empty, or one per interior face
    std::shared_ptr<const EntryTransmittance<Real>> top_entry, bottom_entry;  // light from outside the layer
    std::vector<Real> top_exit, bottom_exit;  // transmittance out of the layer at the ordinates (empty: compute)
    std::shared_ptr<CouplingCache<Real>> top_couplings, bottom_couplings;  // (null: tables built by the solve)
};

/// Everything below the top face, ready for the per-mode adding (stack_mode).
template <class Real>
struct PreparedStack {
    std::vector<SlabModes<Real>> slabs;              // delta-M scaled, with their phase matrices (prepare_slab)
    std::vector<SharedOperators<Real>> interior;     // the interior faces' operators on the ordinates
    bool any_rough = false;                          // a rough boundary anywhere, top and bottom included
};

/// The optical thickness (delta-M scaled) below which a slab scatters as a film (tau = 0; prepare_stack): 1e5 eps
/// times the smallest ordinate, where the losses of light trapped by total internal reflection, O(tau / mu), are
/// 1e3 times the rounding of the slab's eigen-solution (~100 eps, measured: the trapped fluence 1.4% off at
/// 8.5e3 eps), at most sqrt(eps) times it (float), the most that a film drops of R and T.
template <class Real>
Real film_limit(const Quadrature<Real>& q) noexcept {
    const Real eps = std::numeric_limits<Real>::epsilon();
    return std::fmin(Real(1e5) * eps, std::sqrt(eps)) * q.nodes.front();
}

/// Prepares the slabs (delta-M, phase matrices, the semi-infinite shortcut) and the interior faces' operators.
/// Interior faces of a stack: the adding equations multiply a face's energy error by the bounces between the faces
/// around it, so under SpecularTransmission::automatic a smooth interior face is flux_conserving both ways (exact
/// energy per ordinate). Pointwise out of the denser medium created up to 26% of the incident energy at M = 4 and
/// 2% at M = 16 (thin slabs between smooth faces; tests/test_layer_inputs.cpp). An explicit choice is kept
/// (README, known limitations).
template <class Real>
PreparedStack<Real> prepare_stack(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                  const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                                  const Quadrature<Real>& q, int modes, const LayerOptions& options,
                                  const LayerRequest<Real>& request, const std::vector<SharedOperators<Real>>& prepared) {
    PreparedStack<Real> stack;
    LayerOptions interior_options = integrals_for_tolerance(options, request.tolerance);
    if (interior_options.specular_transmission == SpecularTransmission::automatic)
        interior_options.specular_transmission = SpecularTransmission::flux_conserving;
    stack.any_rough = top.rough() || bottom.rough();
    for (std::size_t i = 0; i < interior.size(); ++i) {
        const Boundary<Real>& b = interior[i];
        stack.interior.push_back(i < prepared.size() && prepared[i]
                                     ? prepared[i]
                                     : std::make_shared<const InterfaceOperators<Real>>(b.operators(q, modes, interior_options)));
        stack.any_rough = stack.any_rough || b.rough();
    }
    // (Not with depths: the profile reaches the floor or bottom face the shortcut drops; over a white floor the net
    // flux there was 2e-5 where it is 0, the fluence 11 times low at tolerance 1e-3: found by review.)
    const bool shortcut = request.tolerance > 0 && slabs.size() == 1 && !needs_transmitted(request.outputs) &&
                          !includes(request.outputs, LayerOutput::operators) && request.depths.empty();
    for (const Slab<Real>& slab : slabs) {
        // With a tolerance the solve may stop after a few modes: the phase matrices of mode 0 now, the others as the
        // solve reaches them (extend_phase_modes; for Stam's layer at M = 24 they were 17% of a prepared solve).
        stack.slabs.push_back(prepare_slab(slab, q, request.tolerance > 0 ? 1 : modes, options.delta_m, slab.optical_thickness()));
        // A slab whose (delta-M scaled) thickness is below film_limit scatters for the ordinates as a film (tau = 0):
        // its eigen-solution carries absolute errors ~eps against O(tau / mu) losses, and between two faces that trap
        // light at some ordinates (total internal reflection at both) the adding divides by those losses, which
        // rounding can make 0 or negative: R + T = 5.4 at tau = 1e-20 (4 ordinates, split), and up to 4e17 at
        // tau = 1e-14, g = 0.999999 (delta-M scales it to 3e-19; 16 ordinates; NaN on one rule) or 1.42 at 5.6e-18,
        // g = 0, where the limit was eps mu_min on the unscaled thickness (found by review,
        // tests/test_layer_inputs.cpp). What the film drops is O(tau / mu_min) of R and T, the light a beam within
        // tau of grazing loses, and the fluence of the light such a slab traps (O(1) as tau -> 0); the unscattered
        // beam keeps the true thickness.
        SlabModes<Real>& p = stack.slabs.back();
        if (p.slab.optical_thickness() < film_limit(q))
            p.slab = Slab<Real>::from_one_minus_albedo(p.slab.one_minus_albedo(), p.slab.g(), Real(0));
        if (shortcut) make_semi_infinite_if_opaque(p, q, request.tolerance);
    }
    return stack;
}

/// Gives every slab's phase matrices (at least) `modes` modes.
template <class Real>
void extend_phase_modes(PreparedStack<Real>& stack, const Quadrature<Real>& q, int modes) {
    for (SlabModes<Real>& p : stack.slabs)
        if (p.phase.modes < modes) append_phase_fourier_modes(p.moments, q.nodes, modes, p.phase);
}

/// Whether a solve between specular faces needs the beam as a source, exact at its true angle (docs/physics.md section
/// 6), in every slab (one thinner than film_limit is a film, tau = 0 in prepare_stack, whose response to the beam is
/// exactly none; above it a slab's errors ~eps are small against its O(tau / mu) scattering; the beam was spread over
/// the ordinates below sqrt(eps) mu_min, and a refracting stack's R jumped by 4.6e-3 at mu = 0.1 where a slab crossed
/// that limit; found by review): for reflected or transmitted light, the ambient term (the subsurface reflectance at
/// the exit cosine) and depths (without it a request for depths with ambient or operators alone spread the beam over
/// the ordinates, and the net flux at albedo 1 wandered by 4e-4 where it is constant to 1e-13; found by review). Where
/// the phase function is aliased on the ordinates (solve_modes) the beam is spread over them instead, its energy made
/// exact (scattering_scale).
template <class Real>
bool needs_beam_source(const LayerRequest<Real>& request) noexcept {
    return needs_reflected(request.outputs) || needs_transmitted(request.outputs) ||
           includes(request.outputs, LayerOutput::ambient) || !request.depths.empty();
}

/// Whether the unscattered beam stays on its ordinate through the whole stack, so that the solver can keep it apart
/// (LayeredSurface::separate_direct_beam): specular top and bottom faces, and interior faces that do not change
/// the index (identity operators). An interior face that refracts maps an ordinate onto a cosine between
/// ordinates, and the beam is then spread over them (README, known limitations).
template <class Real>
bool beam_stays_on_its_ordinate(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior,
                                const Boundary<Real>& bottom) noexcept {
    if (top.rough() || bottom.rough() || bottom.lambertian()) return false;
    for (const Boundary<Real>& b : interior)
        if (b.rough() || b.eta_above() != b.eta_below()) return false;
    return true;
}

/// Whether light reflected by the joints of a stack comes back out of the top as a delta that the solver must keep
/// apart (LayeredSurface::separate_joint_mirror): a specular top over specular interior faces of which one at least
/// refracts (and so reflects), above a rough bottom. (Over a specular bottom or a Lambertian floor the beam is a
/// source, and the stack's specular reflection is direct_reflectance already; under a rough top no delta leaves, and
/// a rough joint's reflection is a lobe: taken for a mirror it moved the BRDF by 10%; found by review.)
template <class Real>
bool joints_mirror_the_beam(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior,
                            const Boundary<Real>& bottom) noexcept {
    if (top.rough() || top.lambertian() || !bottom.rough()) return false;
    bool refracting = false;
    for (const Boundary<Real>& b : interior) {
        if (b.rough() || b.lambertian()) return false;  // (a rough joint's reflection is a lobe, not a delta)
        refracting = refracting || b.eta_above() != b.eta_below();
    }
    return refracting;
}

/// Mode k of a prepared slab (slab.hpp). A phase function too peaked for the ordinates (|g| near 1 without delta-M,
/// or any g < 0 near -1, whose backward peak delta-M cannot remove) has a truncated expansion that is not admissible
/// on them: the slab solver then regularizes its aliased part (regularize_aliased_phase = true), which keeps the
/// results finite and energy-conserving. Admissible phase functions are solved as without it.
template <class Real>
ComponentOperators<Real> slab_mode(const SlabModes<Real>& p, const Quadrature<Real>& q, int k) {
    return slab_component(solve_slab_mode(p.slab, q, p.phase.same_k(k), p.phase.opposite_k(k), k, true));
}

/// Mode k of everything below the top face, by the adding equations (adding.hpp).
template <class Real>
struct StackMode {
    ComponentOperators<Real> middle;  // the slabs and the interior faces
    ComponentOperators<Real> bottom;  // the bottom face
    ComponentOperators<Real> lower;   // middle + bottom: S = lower.reflection_down (the transmission down and the
                                      // upward half only if asked)
    Matrix<Real> x;                   // (I - R_mid,up R_23)^{-1} T_mid,down: down-going light above the bottom face
    Real slab_size = 0;               // the largest diffuse_size of the slabs (the mode cutoff between specular faces)
};

// solved: where not null, every slab's mode as solved (with its eigen-solution) is kept there; upward: whether the
// lower part's operators for light from below and its transmission down are needed (the whole layer's operators,
// unless the layer is the same seen from below).
template <class Real>
StackMode<Real> stack_mode(const PreparedStack<Real>& stack, const InterfaceOperators<Real>& bottom,
                           const Quadrature<Real>& q, int k, std::vector<SlabModeSolution<Real>>* solved = nullptr,
                           bool upward = false) {
    auto slab = [&](std::size_t i) {
        const SlabModes<Real>& p = stack.slabs[i];
        if (!solved) return slab_mode(p, q, k);
        solved->push_back(slab_mode_solution(p.slab, q, p.phase.same_k(k), p.phase.opposite_k(k), k, true));
        return slab_component(slab_mode_operators(solved->back(), q, p.slab.optical_thickness()));
    };
    StackMode<Real> s;
    s.middle = slab(0);
    s.slab_size = diffuse_size(s.middle, q.nodes, stack.slabs[0].slab.optical_thickness());
    for (std::size_t i = 0; i < stack.interior.size(); ++i) {
        s.middle = add_components(s.middle, interface_component(*stack.interior[i], k));
        const ComponentOperators<Real> next = slab(i + 1);
        s.slab_size = std::fmax(s.slab_size, diffuse_size(next, q.nodes, stack.slabs[i + 1].slab.optical_thickness()));
        s.middle = add_components(s.middle, next);
    }
    s.bottom = interface_component(bottom, k);
    add_from_above(s.middle, s.bottom, s.x, s.lower, upward);
    if (upward) add_from_below(s.middle, s.bottom, s.lower);
    return s;
}

}  // namespace detail

namespace detail {

// Serial numbers for BeamSolution and LayeredSurface: a Workspace keys what it caches by them (the slab responses,
// keyed by the address, were taken by a layer solved where a freed one had been: BRDF 0 where it is 0.0035; found
// by review).
inline std::uint64_t next_beam_serial() noexcept {
    static std::atomic<std::uint64_t> serial{0};
    return ++serial;
}

/// Between specular faces around slabs joined by index-matched faces, the beam as a source (detail/beam_source.hpp):
/// each slab's beam source (top to bottom) and, per mode, the LU factors of the diffuse field's system
/// (LayeredSurface::beam_field), with the faces' reflectances from inside at the ordinates; and a serial number no
/// other BeamSolution of the program has had (next_beam_serial).
template <class Real>
struct BeamSolution {
    std::uint64_t serial = next_beam_serial();
    std::vector<SlabBeam<Real>> slabs;
    std::vector<LU<Real>> lu;  // per mode; no factors where nothing makes a diffuse field
    std::vector<Real> r21, r23;
    // One slab between faces that reflect nothing back into it (index matched, black or no floor): the diffuse
    // field's system is the identity, the field is the slab's response itself, and no factors are kept.
    bool identity_system = false;
    Real floor = -1;           // a Lambertian floor's albedo (< 0: the bottom is specular)
    bool single_scattering = false;  // LayerOptions::single_scattering_correction
    std::vector<Real> eta, true_tau;                  // per slab: its index, its true optical thickness
    std::vector<SmoothDielectric<Real>> joints;       // the faces between slabs (L - 1), top to bottom
    bool refracting = false;                          // a joint changes the index
    // per mode and joint, on the ordinates (unscaled): T_12, R_21, T_21, R_12 of the joint
    std::vector<std::vector<Matrix<Real>>> joint_t_down, joint_r_up, joint_t_up, joint_r_down;
};

/// The diffuse field of one incidence mu_i between specular faces: per slab the beam's flux entering it going down
/// and going up (all passes), and its response to a beam; per mode and slab (index (k L + j) M + n) the radiance
/// leaving slab j up through its top (u) and down through its bottom (v) at the ordinates: u of the first slab
/// arrives at the top face, v of the last at the bottom face.
template <class Real>
struct BeamField {
    Real mu_i = -1;
    int modes = 0;
    std::vector<Real> x, flux_down, flux_up;  // per slab: the beam's cosine (0: it does not reach the slab), fluxes
    Real floor_radiance = 0;  // over a Lambertian floor: its radiance (mode 0, the same in every direction)
    std::vector<BeamResponse<Real>> response;  // per slab
    std::vector<Real> u, v, d, w;  // per mode and slab: leaving up (u) and down (v), entering from above (d) and below (w)
    bool lit() const noexcept { return !flux_down.empty() && flux_down[0] > 0; }
};

}  // namespace detail

/// The solved layer: evaluate its BRDF, BTDF, reflectance, transmittance and ambient term at any direction.
/// Built by solve_layer / solve_stack. Evaluation functions take an optional Workspace so that repeated
/// calls allocate nothing; they are const and thread-safe with one Workspace per thread.
/// Degenerate arguments give 0, as in pbrt (never NaN, never an exception): a direction with a NaN or infinite
/// component, on the horizon (z = 0) or in the wrong hemisphere, and a cosine outside (0, 1] (NaN included).
/// Directions are expected to be unit vectors and are not normalized; a finite non-unit vector gives a finite
/// value >= 0 (its |z| clamped to 1, its azimuth taken from its x and y) that means nothing in particular.
/// (tests/test_layer_inputs.cpp checks all of this.)
/// One-sided: light arrives from above (wi.z > 0). Light from below (wi.z < 0) is outside the domain and gives 0
/// from every function; for it, solve the layer turned over (bottom face first, its indices swapped).
template <class Real = double>
class LayeredSurface {
public:
    /// Scratch memory for evaluation (sized on first use). It also keeps what the last incidence computed on the fly
    /// let into the layer (the entry; between specular faces its field) and, between specular faces, the last exit
    /// cosine's response, so that calls at one incidence (or one exit) reuse them.
    struct Workspace {
        std::vector<Real> in, out, c, field, shape, row, row_all, spread, first;
        // the last entry (ws.c) entry() computed, and for which layer (its serial number: 0 while none), incidence
        // and number of modes (a prefix of it serves fewer)
        std::vector<Real> entry_kept;
        struct {
            std::uint64_t owner = 0;
            Real mu_i = -1;
            int modes = 0;
        } entry_key;
        // between specular faces (the beam as a source): the field of an incidence computed on the fly (and the
        // serial number of the beam source it belongs to: 0 while none), the slab's response to a beam at the exit
        // cosine, scratch
        detail::BeamField<Real> beam;
        std::uint64_t beam_owner = 0;
        std::vector<detail::BeamResponse<Real>> beam_y[2];  // per side (reflection, transmission), per slab
        std::vector<Real> beam_y_leave[2];  // per side: leave()'s weights of up_j and down_j (P, Q of bounce) at the exit
        struct {  // what beam_y[side] and beam_y_leave[side] hold: the layer's beam source (its serial number), the exit cosine, the modes
            std::uint64_t owner = 0;
            Real mu_o = -1;
            int modes = 0;
        } beam_y_key[2];
        std::vector<Real> small, small_rhs, small_e, path_c, path_e, path_up, path_down, path_exits, faces;
        std::vector<Real> scratch;
        detail::Matrix<Real> rhs;
    };

    int ordinates() const noexcept { return static_cast<int>(q_.size()); }
    /// The number of Fourier modes actually solved (after the request's tolerance and cap).
    int modes() const noexcept { return modes_; }
    /// With LayerRequest::tabulate_faces, how many couplings are tabulated (0 to 3: the top's for light entering and
    /// leaving, the bottom's for light leaving); the others are integrated at each evaluation (a smooth face, light
    /// from a denser medium, an output not requested, or a table that failed its check: detail::CouplingTable).
    int tabulated_couplings() const noexcept {
        int n = 0;
        for (int i = 0; i < 3; ++i) n += couplings_[i].table ? 1 : 0;
        return n;
    }
    const Quadrature<Real>& quadrature() const noexcept { return q_; }
    LayerOutput outputs() const noexcept { return outputs_; }
    /// Per-mode operators of the whole layer on the ordinates, light arriving from above or below
    /// (empty unless LayerOutput::operators was requested). Compose with add_components().
    const std::vector<ComponentOperators<Real>>& mode_operators() const noexcept { return whole_; }

    /// Total BRDF above the layer, r_12 + r_s (the specular reflection of a smooth top is a delta and
    /// is not included: use the top's SmoothDielectric for it, and direct_reflectance() and
    /// forward_peak_reflectance() below).
    /// Outputs that were not requested (LayerRequest::outputs) evaluate to 0.
    Real brdf(Vec3<Real> wi, Vec3<Real> wo, Workspace& ws) const {
        // degenerate input and light from below (see the class comment)
        if (!all_finite(wi) || !all_finite(wo) || !(wi.z > 0) || !(wo.z > 0)) return Real(0);
        const Real surface = (top_.rough() && includes(outputs_, LayerOutput::surface_reflection))
                                 ? top_.rough_interface()->brdf(wi, wo) : Real(0);
        return surface + subsurface_brdf(wi, wo, ws);
    }
    Real brdf(Vec3<Real> wi, Vec3<Real> wo) const { Workspace ws; return brdf(wi, wo, ws); }

    /// r_s: light refracted into the layer, scattered, and refracted back out of the top. Negative values of
    /// the truncated azimuthal series (Gibbs ringing with few modes) are returned as 0; a NaN computed from valid
    /// arguments is never hidden (degenerate arguments give 0: see the class comment).
    Real subsurface_brdf(Vec3<Real> wi, Vec3<Real> wo, Workspace& ws) const {
        if (!includes(outputs_, LayerOutput::subsurface_reflection) || !(wi.z > 0) || !(wo.z > 0) || !all_finite(wi) ||
            !all_finite(wo))
            return Real(0);
        if (beam_) return beam_radiance(wi, wo, false, ws);
        if (first_reflection_exact_) return non_negative(with_exact_pass(wi, wo, false, ws));
        const Real mu_i = std::fmin(wi.z, Real(1));
        const Real scale = scattering_scale(mu_i, ws);  // (before the field: it computes its own entry)
        return scale * exit_sum(wi, wo, top_face(), field(mu_i, false, ws), ws);
    }
    Real subsurface_brdf(Vec3<Real> wi, Vec3<Real> wo) const { Workspace ws; return subsurface_brdf(wi, wo, ws); }

    /// t_s: BTDF from above (wi.z > 0) to below (wo.z < 0) through the whole layer. Between two specular
    /// boundaries the unscattered beam is a delta, not part of t_s: see direct_transmittance() and
    /// forward_peak_transmittance().
    Real btdf(Vec3<Real> wi, Vec3<Real> wo, Workspace& ws) const {
        if (!includes(outputs_, LayerOutput::transmission) || bottom_.lambertian() || !(wi.z > 0) || !(wo.z < 0) ||
            !all_finite(wi) || !all_finite(wo))
            return Real(0);
        if (beam_) return beam_radiance(wi, wo, true, ws);
        if (first_pass_exact_) return non_negative(with_exact_pass(wi, wo, true, ws));
        const Real mu_i = std::fmin(wi.z, Real(1));
        const Real scale = scattering_scale(mu_i, ws);  // (before the field: it computes its own entry)
        return scale * exit_sum(wi, wo, bottom_face(), field(mu_i, true, ws), ws);
    }
    Real btdf(Vec3<Real> wi, Vec3<Real> wo) const { Workspace ws; return btdf(wi, wo, ws); }

    /// Directional-hemispherical reflectance for incidence cosine mu_i in (0, 1]: {surface, subsurface}
    /// (0 outside (0, 1]). The subsurface part includes the unscattered beam (see direct_reflectance); it is 0
    /// unless LayerOutput::subsurface_reflection or LayerOutput::reflectance was requested.
    struct Reflectance {
        Real surface, subsurface;
        Real total() const noexcept { return surface + subsurface; }
    };
    Reflectance reflectance(Real mu_i) const {
        if (!(mu_i > 0 && mu_i <= 1)) return {Real(0), Real(0)};
        Workspace ws;
        Reflectance a{surface_reflectance(mu_i), Real(0)};
        if (detail::needs_reflected(outputs_)) a.subsurface = subsurface_reflectance(mu_i, ws);
        return a;
    }

    /// Fraction of the incident flux (cosine mu_i in (0, 1] from above) leaving through the bottom, including
    /// the unscattered beam; 0 outside (0, 1] or unless LayerOutput::transmission or ::transmittance was requested.
    Real transmittance(Real mu_i) const {
        if (!detail::needs_transmitted(outputs_) || !(mu_i > 0 && mu_i <= 1)) return Real(0);
        Workspace ws;
        if (beam_)
            return non_negative(flux_out(beam_field(mu_i, 1, ws).v.data() + (beam_->slabs.size() - 1) * q_.size(), exit_bottom_)) +
                   direct(mu_i, true, direct_tau_);
        const Real scale = scattering_scale(mu_i, ws);  // (before the field: it computes its own entry)
        return non_negative(scale * flux_out(field(mu_i, true, ws, 1), exit_bottom_)) + direct(mu_i, true, direct_tau_);
    }

    /// Between two specular (smooth or index-matched) boundaries the unscattered beam leaves as a delta:
    /// through the bottom in the Snell direction of wi (direct_transmittance) and, after a specular
    /// reflection at the bottom, through the top in the mirror direction (direct_reflectance); under a specular top
    /// over refracting joints and a rough bottom, the joints' specular reflection (direct_reflectance). These are the
    /// fractions of the incident flux they carry, computed exactly at the true angle (Fresnel factors, the
    /// attenuation e^{-tau/mu'} with the slab's true optical thickness, and the geometric series of bounces
    /// between the faces); 0 otherwise.
    /// Delta-M (LayerOptions::delta_m) treats scattering into the truncated forward peak, a fraction f of all
    /// scattering, as no scattering: that light travels on with the beam, which the solver attenuates by the
    /// scaled thickness (1 - f albedo) tau instead. The difference, light scattered into the forward peak that
    /// leaves within a narrow cone around the beam's directions, is forward_peak_transmittance and
    /// forward_peak_reflectance (0 without delta-M or for g <= 0); a renderer may add it to the delta.
    /// reflectance() and transmittance() include both; the scattered light is scaled so that it receives exactly
    /// the energy the beam loses, which keeps a non-absorbing layer exactly energy-conserving.
    /// Like transmittance() and reflectance(), they are 0 when their outputs (LayerOutput::transmission or
    /// ::transmittance; ::subsurface_reflection or ::reflectance) were not requested.
    Real direct_transmittance(Real mu_i) const {
        return detail::needs_transmitted(outputs_) && mu_i > 0 && mu_i <= 1 ? direct(mu_i, true, beam_tau_) : Real(0);
    }
    Real direct_reflectance(Real mu_i) const {
        return detail::needs_reflected(outputs_) && mu_i > 0 && mu_i <= 1 ? direct(mu_i, false, beam_tau_) : Real(0);
    }
    Real forward_peak_transmittance(Real mu_i) const {
        return detail::needs_transmitted(outputs_) && mu_i > 0 && mu_i <= 1 ? forward_peak(mu_i, true) : Real(0);
    }
    Real forward_peak_reflectance(Real mu_i) const {
        return detail::needs_reflected(outputs_) && mu_i > 0 && mu_i <= 1 ? forward_peak(mu_i, false) : Real(0);
    }

    /// r_a(wo): subsurface radiance leaving towards wo (wo.z > 0) under a uniform sky of unit radiance
    /// (Stam's ambient term; the top's own reflection of the sky is its reflectance(wo.z) by reciprocity), the sky's
    /// light that crossed the layer unscattered between specular faces included: by reciprocity it equals
    /// reflectance(wo.z).subsurface (docs/physics.md section 6). Between specular faces it is computed so, with the
    /// beam a source at wo.z: read from the ordinates' field, the exit at a grazing wo (its Snell cosine beside the
    /// critical cosine, where the field varies steeply) was 26% off at 16 ordinates and 1.6% at 64 (found by review).
    /// So too under a specular top over joints that refract and a rough bottom (where the joints' specular
    /// reflection is a delta, direct_reflectance): read from the field at the normal, where the
    /// joints' operators crowd the light onto the last ordinate, it was 0.17 where reflectance(1).subsurface is 0.119
    /// (1 | 1.5 | 1.4 over a rough 0.3 bottom, M = 16; found by review).
    Real ambient(Vec3<Real> wo, Workspace& ws) const {
        if (!includes(outputs_, LayerOutput::ambient) || !(wo.z > 0) || !all_finite(wo)) return Real(0);
        if (beam_ || joint_mirror_) return subsurface_reflectance(std::fmin(wo.z, Real(1)), ws);
        const std::size_t m = q_.size();
        ws.c.assign(m, Real(0));
        for (std::size_t i = 0; i < m; ++i) ws.c[i] = ambient_field_[i];
        return exit_value(std::fmin(wo.z, Real(1)), top_face(), 0, ws.c.data(), ws);
    }
    Real ambient(Vec3<Real> wo) const { Workspace ws; return ambient(wo, ws); }

    /// The azimuthal Fourier series behind subsurface_brdf (which = LayerOutput::subsurface_reflection) or btdf
    /// (which = LayerOutput::transmission), cosine-weighted, for every pair of an incidence cosine mu_i[a] and an
    /// exit cosine mu_o[b] (|wo.z|, for the BTDF too), all in [0, 1]:
    ///   f(wi, wo) |wo.z| = sum_{k < modes()} a_k cos(k dphi),   a_k = result[(a mu_o.size() + b) modes() + k],
    /// with dphi the azimuth between -wi and wo (0: on in the direction of travel) as in those functions, which
    /// sum this series (and return 0 where it is negative). A cosine 0 gives 0; an output that was not requested
    /// gives zeros. The cost is one internal field per mu_i and one set of exit weights per mu_o, then
    /// M modes() multiply-adds per pair (tabulated_bsdf.hpp builds its table from this).
    /// Throws std::invalid_argument for another `which` or a cosine outside [0, 1] (NaN included).
    std::vector<Real> fourier_coefficients(LayerOutput which, const std::vector<Real>& mu_i,
                                           const std::vector<Real>& mu_o) const;

    /// The faces as solved: light arrives through top() from above and leaves below through bottom().
    const Boundary<Real>& top() const noexcept { return top_; }
    const Boundary<Real>& bottom() const noexcept { return bottom_; }
    /// The refractive index of each slab, top to bottom (top().eta_below(), then each joint's index below it).
    const std::vector<Real>& slab_indices() const noexcept { return indices_; }

    /// Inside the layer at a requested depth (LayerRequest::depths; through a stack, in the slab holding it), for a
    /// beam of unit irradiance arriving with cosine mu_i in (0, 1]: the fluence rate phi = int L dw over all
    /// directions (4 pi times the mean radiance; for a beam alone, its flux over its cosine; >= 0) and the net flux
    /// downwards, both per unit incident flux.
    /// Conservation: where nothing is absorbed the net flux is the same at every depth, and d(net flux)/dtau =
    /// -(1 - albedo) phi. Between specular faces the beam (with delta-M's forward peak) is exact at the true angle,
    /// as in the fluxes (the law then holds to 1e-10); elsewhere it is part of the discrete field, and where it is
    /// spread over the ordinates (no delta-M, a peak the ordinates alias) the law holds to the spread's accuracy
    /// (6.7e-3 at 8 ordinates, g 0.99, mu 0.6; tests/test_layer_depth.cpp). Empty for mu_i outside (0, 1].
    struct DepthPoint {
        Real depth, fluence, net_flux;
    };
    std::vector<DepthPoint> depth_profile(Real mu_i) const;

private:
    // The solver behind solve_stack and solve_layer, the public entry points.
    static LayeredSurface solve(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                                const LayerOptions& options, const LayerRequest<Real>& request,
                                const detail::PreparedOperators<Real>& prepared);
    // solve() of an equivalent simpler problem where there is one (an empty slab dropped, a floor under opaque slabs
    // made black); nothing otherwise.
    static std::optional<LayeredSurface> solve_simpler(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                                       const std::vector<Boundary<Real>>& interior,
                                                       const Boundary<Real>& bottom, const LayerOptions& options,
                                                       const LayerRequest<Real>& request,
                                                       const detail::PreparedOperators<Real>& prepared);
    template <class R>
    friend LayeredSurface<R> solve_stack(const detail::non_deduced_t<Boundary<R>>&, const std::vector<Slab<R>>&,
                                         const std::vector<Boundary<R>>&, const detail::non_deduced_t<Boundary<R>>&,
                                         const LayerOptions&, const detail::non_deduced_t<LayerRequest<R>>&);
    template <class R>
    friend LayeredSurface<R> solve_stack(const PreparedBoundary<R>&, const std::vector<Slab<R>>&,
                                         const std::vector<PreparedBoundary<R>>&, const PreparedBoundary<R>&,
                                         const detail::non_deduced_t<LayerRequest<R>>&);

    LayeredSurface(Boundary<Real> top, Boundary<Real> bottom) : top_(std::move(top)), bottom_(std::move(bottom)) {}

    // The steps of solve() that fill the layer (defined after it, at the end of this file).
    void set_up_beam(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs, const std::vector<Boundary<Real>>& interior,
                     const Boundary<Real>& bottom, const detail::PreparedStack<Real>& stack, int modes, const LayerOptions& options);
    void solve_modes(detail::PreparedStack<Real>& stack, int modes, Real tolerance);
    void extend_faces(int modes);
    void add_beam_mode(int k, std::vector<detail::SlabModeSolution<Real>>&& slabs, const detail::PreparedStack<Real>& stack);
    void add_field_operators(int k, const detail::StackMode<Real>& below);
    std::array<Real, 2> coefficient_size(int k, const ComponentOperators<Real>& bottom, const std::array<Real, 2>& exceeds,
                                         std::array<std::size_t, 2>& column) const;
    void solve_ambient();
    void solve_depths(const detail::PreparedStack<Real>& stack, const std::vector<Slab<Real>>& slabs,
                      const LayerOptions& options, const std::vector<Real>& depths);
    void separate_direct_beam(Real scaled_tau, Real true_tau);
    void separate_joint_mirror(const std::vector<Boundary<Real>>& interior, const std::vector<Slab<Real>>& slabs,
                               const detail::PreparedStack<Real>& stack);
    void compose_passes();
    void set_up_exact_passes(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior,
                             const Boundary<Real>& bottom, const detail::PreparedStack<Real>& stack, LayerOutput outputs);
    struct BeamDepth;
    BeamDepth beam_depth(const Slab<Real>& slab, const LayerOptions& options, Real t) const;
    std::vector<DepthPoint> beam_depth_profile(Real mu_i) const;
    void precompute_incidences();
    void tabulate_faces();


    // The top face's hemispherical reflectance (an integral for a rough face), precomputed at the requested incidences
    // when LayerOutput::surface_reflection was requested, tabulated with LayerRequest::tabulate_faces.
    Real surface_reflectance(Real mu_i) const {
        for (std::size_t j = 0; j < cached_surface_.size(); ++j)
            if (incidence_[j] == mu_i) return cached_surface_[j];
        return faces_tabulated_ ? top_entry_->reflectance(mu_i) : top_.hemispherical_reflectance(mu_i);
    }

    // Which way light crosses a face: into the layer from outside, or out of it.
    enum class Crossing { entering, leaving };

    // One boundary seen from inside the layer: what depends on the face that light crosses. Outside is medium 1
    // above the top and medium 3 below the bottom; signed cosines follow interface.hpp (> 0: arriving from above).
    struct Face {
        const LayeredSurface& layer;
        bool bottom;  // false: the top (1 | 2); true: the bottom (2 | 3)

        const Boundary<Real>& boundary() const noexcept { return bottom ? layer.bottom_ : layer.top_; }
        const InterfaceOperators<Real>& ops() const noexcept { return bottom ? *layer.bottom_ops_ : *layer.top_ops_; }
        bool rough() const noexcept { return boundary().rough(); }
        Real eta_inside() const noexcept { return bottom ? boundary().eta_above() : boundary().eta_below(); }
        Real eta_outside() const noexcept { return bottom ? boundary().eta_below() : boundary().eta_above(); }
        // The side that light crossing this way arrives from (the operators' Incidence).
        Incidence incidence(Crossing c) const noexcept {
            return (c == Crossing::entering) != bottom ? Incidence::from_above : Incidence::from_below;
        }
        // The signed cosine of light arriving at the face with |cosine| mu from outside, or from inside.
        Real from_outside(Real mu) const noexcept { return bottom ? -mu : mu; }
        Real from_inside(Real mu) const noexcept { return bottom ? mu : -mu; }
        // Snell: the |cosine| inside the layer of the ray crossing with |cosine| mu outside (0 if none does).
        Real internal_cosine(Real mu) const noexcept {
            return std::fabs(boundary().smooth_interface().transmitted_cosine(from_outside(mu)));
        }
        // The critical cosine inside the layer (0 if none): ordinates below it are totally reflected.
        Real critical_cosine() const noexcept {
            const Real n_in = eta_inside(), n_out = eta_outside();
            if (!(n_out < n_in)) return Real(0);
            const Real r = n_out / n_in;
            return std::sqrt((Real(1) - r) * (Real(1) + r));
        }
        // Directional-hemispherical transmittance into the layer of light from outside at |cosine| mu
        // (detail::EntryTransmittance: tabulated for a rough face, where that serves).
        Real transmittance_from_outside(Real mu) const { return bottom ? (*layer.bottom_entry_)(mu) : (*layer.top_entry_)(mu); }
        // tau(mu_m): the transmittance out of the layer of light from inside at each ordinate (the renormalized
        // rough operators computed these totals already).
        std::vector<Real> transmittance_at_ordinates() const {
            const std::vector<Real>& nodes = layer.q_.nodes;
            const auto& totals = ops().ordinate_totals(incidence(Crossing::leaving));
            std::vector<Real> t(nodes.size());
            for (std::size_t i = 0; i < nodes.size(); ++i)
                t[i] = totals.size() == nodes.size() ? totals[i].transmittance
                                                     : boundary().hemispherical_transmittance(from_inside(nodes[i]));
            return t;
        }
        // I_k, k < modes (at most the layer's modes(): the operators may hold more, prepared for another request),
        // of a rough face's transmission between |cosine| mu outside and mu_inside inside, for light crossing the
        // given way; fewer modes need fewer azimuthal samples (mode 0 alone far fewer).
        void transmission(Crossing c, Real mu, Real mu_inside, Real* out, int modes) const noexcept {
            if (c == Crossing::entering) ops().coefficients(incidence(c), true, mu, mu_inside, out, modes);
            else ops().coefficients(incidence(c), true, mu_inside, mu, out, modes);
        }
    };
    Face top_face() const noexcept { return Face{*this, false}; }
    Face bottom_face() const noexcept { return Face{*this, true}; }
    detail::CouplingTable<Real> tabulate_couplings(const Face& face, Crossing c, int modes) const;
    detail::CouplingTable<Real> coupling_table_for(const Face& face, Crossing c) const;

    // The internal field (K blocks of M) for incidence mu_i: Q_b c_k (reflection) or Q_e c_k (transmission).
    // The first `modes` modes only (fluxes need mode 0; its azimuthal integrals then take far fewer samples, and
    // agree with the full call's to 2.3e-13 for the transmission used here, measured); a cached field holds all modes.
    const Real* field(Real mu_i, bool transmitted, Workspace& ws, int modes = -1) const {
        if (modes < 0) modes = modes_;
        if (const Real* cached = cached_field(mu_i, transmitted)) return cached;
        entry(mu_i, ws, modes);
        return field_of_entry(transmitted, ws, modes);
    }
    // The field of a requested incidence, kept from the solve (all modes), or null.
    const Real* cached_field(Real mu_i, bool transmitted) const noexcept {
        const std::vector<std::vector<Real>>& cache = transmitted ? cached_e_ : cached_b_;
        for (std::size_t j = 0; j < incidence_.size(); ++j)
            if (incidence_[j] == mu_i && !cache[j].empty()) return cache[j].data();
        return nullptr;
    }
    // The field of the entry in ws.c (entry()), first `modes` modes.
    const Real* field_of_entry(bool transmitted, Workspace& ws, int modes) const {
        const std::size_t m = q_.size();
        ws.field.assign(static_cast<std::size_t>(modes) * m, Real(0));
        const std::vector<detail::Matrix<Real>>& q = transmitted ? qe_ : qb_;
        for (int k = 0; k < modes; ++k) {
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
    // (The first `modes` modes; all by default.) The Workspace keeps the last one computed: calls at one incidence
    // (exits, the BRDF and the BTDF) share it.
    void entry(Real mu_i, Workspace& ws, int modes = -1) const {
        if (modes < 0) modes = modes_;
        const auto& key = ws.entry_key;
        if (key.owner == serial_ && key.mu_i == mu_i && key.modes >= modes) {
            ws.c.assign(ws.entry_kept.begin(), ws.entry_kept.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(modes) * q_.size()));
            return;
        }
        compute_entry(mu_i, ws, modes);
        ws.entry_key.owner = 0;
        ws.entry_kept = ws.c;
        ws.entry_key = {serial_, mu_i, modes};
    }
    void compute_entry(Real mu_i, Workspace& ws, int modes) const {
        const Face top = top_face();
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes);
        ws.c.assign(kk * m, Real(0));
        const Real flux = top.transmittance_from_outside(mu_i);
        if (!(flux > 0)) return;
        Real specular_share = 1;
        const Real mu_t = top.internal_cosine(mu_i);
        if (top.rough()) {
            couplings(top, Crossing::entering, mu_i, mu_t, modes, ws);
            Real gauss = 0;
            for (std::size_t i = 0; i < m; ++i) {
                const Real* in = ws.row.data() + i * kk;
                gauss += q_.weights[i] * q_.nodes[i] * in[0];
                for (std::size_t k = 0; k < kk; ++k) ws.c[k * m + i] = in[k] * (k == 0 ? Real(1) : Real(2)) / (2 * detail::pi_v<Real>);
            }
            specular_share = blend(gauss, flux, ws.c);
            if (!(specular_share > 0)) return;
        }
        if (!(mu_t > 0)) return;
        const bool extrapolate = extrapolates(mu_t, top);
        specular_spread(top, mu_t, 2, ws, modes, !extrapolate);
        if (top.rough() && mu_t > q_.nodes.back() && q_.size() >= 8) {  // (see extrapolates)
            std::swap(ws.in, ws.spread);  // the stencil at the pole's end (linear to the last ordinate at mu = 1), kept
            specular_spread(top, mu_t, 4, ws, modes);
            for (std::size_t i = 0; i < m; ++i) ws.in[i] = (1 - specular_share) * ws.in[i] + specular_share * ws.spread[i];
        }
        for (std::size_t i = 0; i < m; ++i) {
            const Real base = specular_share * flux * ws.in[i] / (q_.weights[i] * q_.nodes[i]);
            Real pole = 1;  // pole_factor(mu_t, mu_m)^k
            const Real step = pole_factor(mu_t, q_.nodes[i]);
            for (std::size_t k = 0; k < kk; ++k, pole *= step)
                ws.c[k * m + i] += base * pole * ws.shape[k] * (k == 0 ? Real(1) : Real(2)) / (2 * detail::pi_v<Real>);
        }
    }

    // The specular spread's stencil (entry, exit_weights) at the internal cosine x: linear between the ordinates
    // (non-negative weights). A 4-point stencil between the ordinates (used before) put negative shares on ordinates
    // whose light, nearly trapped between the faces, leaves only in part after many bounces (shadowing losses), and
    // the layer created energy: R + T up to 1.024 in the random sweep of docs/accuracy.md, 1.108 on ordinates split
    // under a rough top; linear, none above 1 + 1e-3 there. (The photon Monte Carlo preferred 4 points between the
    // ordinates by 0.002 at 16 ordinates when the lobe's blend was min(r, 1/r); the smooth blend gives the spread a
    // far smaller share where the ordinates resolve the lobe.)
    // Beyond the last ordinate (towards mu = 1, where a beam at normal incidence lies) a beam entering through a
    // specular top is extrapolated to linearly from the last two ordinates (from 8 ordinates on): put on the last
    // ordinate, the fluxes of an index-matched top over a rough bottom at normal incidence were off by 4.4e-3 at 8
    // ordinates and 3.7e-4 at 16 (found by review). Extrapolated from 4 points (as until the sweep below), the stencil
    // reached ordinates 54 degrees from the normal at 8 ordinates, where the other face's reflectance climbs towards
    // its critical angle: a 1 | 1.1 top over a rough 1.1 | 1 bottom of RMS slope 0.03 around an empty slab reflected
    // -2.3e-3 (returned as 0: R + T = 1.0017, found by a review sweep), and over 16 layers of n 1.4 (RMS slope 0.03 to
    // 0.5, matched or smooth top) the worst flux error at 8 ordinates was 1.7e-3 against 6.5e-4 linearly
    // (tests/test_layer_inputs.cpp); at n 1.1 and slopes 0.3 and 0.5 four points were the better (5.4e-4 and 1.1e-3
    // against 1.1e-3 and 1.4e-3; found by review). Neither conserves energy exactly where the bottom's losses to
    // shadowing grow fast away from the normal, which the extrapolation carries to the pole: over 800 non-absorbing
    // layers at normal incidence (n 1.05 to 1.6, RMS slope 0.03 to 0.5, tau 0 and 1, 8 to 16 ordinates) R + T exceeds
    // 1 in 31 linearly (at most 1.0e-3, at 8 ordinates; 3.8e-6 from 9 on; none at 16) and in 111 from 4 points (5.1e-3).
    // Above the last ordinate but one the spread, entering (beyond the last ordinate, where it does not extrapolate)
    // and leaving alike, is linear from it to the last ordinate's value at mu = 1 (`pole`): the last ordinate read flat
    // from itself to mu = 1 made its cell 21% larger in flux than its Gauss weight (at 16 ordinates; it does not shrink
    // with M), and the BTDF of faces of RMS slope 0.05 lit at the normal, whose beam the last ordinate holds,
    // integrated to 7.0% more than the transmittance at 16 ordinates and 3.2% at 32 (now 1.7% and 1.4%; at the exit
    // alone reciprocity failed by 3.8e-2). The fluxes of 6 layers with rough tops (slope 0.05 to 0.3 over rough or
    // smooth bottoms, 8 to 24 ordinates, six incidences from the normal to 26 degrees) moved by at most 1e-4 away from
    // 64 ordinates' and up to 2e-3 closer (7.1e-3 -> 6.4e-3 at 8, slope 0.05). Under a rough top the
    // spread's two stencils are blended by the lobe's share: the last ordinate's by the specular share s (the share of a
    // lobe the ordinates do not resolve), the extrapolation (there from 4 points: the spread carries s of the flux, so
    // the extrapolation's weight is s (1 - s) <= 1/4; 2 points left the flux errors of 6 layers with rough tops of RMS
    // slope 0.05 to 0.3, at 8 to 24 ordinates, unchanged to 2 digits) by 1 - s. Extrapolated whole, its negative shares made the
    // field below the last ordinate negative for a beam through a nearly specular rough top (RMS slope 0.05, s ~ 1) at
    // normal incidence; the BTDF read it back negative between 8 and 12 degrees, returned 0 there (non_negative), and
    // integrated to 0.92 (16 ordinates) and 0.91 (32) where the transmittance is 0.743 (then 0.793 and 0.766; found by
    // the renderer sweep); in the random sweep of docs/accuracy.md (rough tops) R + T now stays below 1 + 1e-5 (1 and
    // 3 layers above 1 + 1e-3 before). The last ordinate alone (no blend) cost Stam's layer at 8 ordinates 1.2e-2 in
    // T at normal incidence (6.1e-3 extrapolated, 8.0e-3 blended) and made its TabulatedBSDF need 129 nodes at 1e-2
    // instead of 65 (the stencil's kink at the last ordinate's image; found when reviewing the change).
    bool extrapolates(Real x, const Face& face) const noexcept {
        return !face.rough() && x > q_.nodes.back() && q_.size() >= 8;
    }

    // The blend of a rough face's lobe with the specular spread, used where the lobe meets the ordinates (entry,
    // exit_weights). `lobe` holds the lobe on the ordinates, whose Gauss sum is `gauss`; `exact` is its true value.
    // With r = gauss / exact and q = min(r, 1/r), the share alpha = 2q / (1 + q^2) = 1 / cosh(ln r) goes to the lobe
    // rescaled to the exact value (a factor alpha exact / gauss = alpha / r, applied to `lobe` here) and
    // 1 - alpha = (1 - q)^2 / (1 + q^2), returned, to the specular spread: both carry the exact value, the lobe
    // wins where the ordinates resolve it, and the result is smooth in every parameter. (The share min(r, 1/r)
    // had a kink wherever r crossed 1: r, a Gauss sum of a lobe that moves across the ordinates, oscillates about
    // 1 as mu changes, at some 20 cosines for Stam's layer at 16 ordinates, and those kinks held
    // TabulatedBSDF's spline error to O(h^2). Here alpha is flat at r = 1, the specular share O((r - 1)^2).)
    static Real blend(Real gauss, Real exact, std::vector<Real>& lobe) noexcept {
        const Real r = gauss / exact;
        const bool above = r > 1;
        const Real q = above ? Real(1) / r : r, d = Real(1) + q * q;
        const Real scale = above ? 2 * q * q / d : Real(2) / d;  // alpha / r
        for (Real& x : lobe) x *= scale;
        return (Real(1) - q) * (Real(1) - q) / d;
    }

    // The specular part of a face's coupling between the internal cosine mu_t and the ordinates, for light crossing
    // the given way at |cosine| mu outside (the caller scales it and applies pole_factor):
    //  - ws.in[m]: the weights of p-point Lagrange interpolation (p <= 4) at x from the ordinates inside the face's
    //    escape cone, 0 elsewhere (below its critical cosine the ordinates are totally reflected and hold trapped
    //    light that must not leak into the interpolation); they sum to 1;
    //  - ws.shape[k]: the azimuthal shape, I_k / I_0 of a rough face's lobe between mu and mu_t (so that its higher
    //    modes decay as the lobe's do: couplings() left its I_k in the last row of ws.row), or 1 for every k through
    //    a specular face (a delta in phi).
    void specular_spread(const Face& face, Real x, int p, Workspace& ws, int modes, bool pole = false) const {
        const std::size_t kk = static_cast<std::size_t>(modes);
        ws.shape.assign(kk, Real(1));
        if (face.rough()) {
            const Real* lobe = ws.row.data() + q_.size() * kk;
            const Real i0 = lobe[0];
            // |I_k| <= I_0 for a non-negative lobe: a tabulated I_0 near grazing, small and relatively less exact
            // than the I_k, must not amplify them.
            for (std::size_t k = 0; k < kk; ++k)
                ws.shape[k] = i0 > 0 ? std::fmin(std::fmax(lobe[k] / i0, Real(-1)), Real(1)) : Real(k == 0);
        }
        const int m = static_cast<int>(q_.size());
        // The stencil stays inside the face's escape cone and on x's side of the other face's critical cosine where
        // that is sharp (sharp_critical_cosine): light at those ordinates meets the other face as light at x does,
        // totally reflected or not. A stencil across it put part of a nearly specular face's beam on ordinates the
        // other face transmits, with a negative share on ordinates it traps, whose bounces turned that into energy
        // (R + T = 2.1 at 16 ordinates, tests/test_layer_inputs.cpp).
        const Real other = sharp_critical_cosine(face.bottom ? top_face() : bottom_face());
        const Real low_cut = other > 0 && other <= x ? std::fmax(face.critical_cosine(), other) : face.critical_cosine();
        int lowest = 0;  // the first ordinate of the stencil's range (the last one at least)
        while (lowest < m - 1 && q_.nodes[static_cast<std::size_t>(lowest)] < low_cut) ++lowest;
        int end = lowest + 1;  // one past its last ordinate
        while (end < m && !(other > x && q_.nodes[static_cast<std::size_t>(end)] >= other)) ++end;
        // Below the range's first ordinate (towards a critical cosine or grazing) and above its last one when a cut
        // bounds it there, extrapolation would weigh the ordinates beyond 1 and below 0 (2.19 and -1.19 at 7
        // ordinates in a sweep, R + T = 1.30; 1.85 and -0.85 next to the face's own critical cosine, 1.19): the
        // nearest ordinate takes the beam there. Towards mu = 1 a beam entering through a specular top is extrapolated
        // to (entry); elsewhere above the last ordinate but one, with `pole`, linear to the last one's value at mu = 1.
        Real w[4] = {Real(1)};
        detail::LagrangeWindow window{lowest, 1};
        if (other > x && x >= q_.nodes[static_cast<std::size_t>(end - 1)]) window.first = end - 1;
        else if (pole && p == 2 && end == m && m >= 2 && lowest <= m - 2 && x > q_.nodes[static_cast<std::size_t>(m - 2)]) {
            const Real a = q_.nodes[static_cast<std::size_t>(m - 2)], t = std::fmin((x - a) / (1 - a), Real(1));
            window = {m - 2, 2};
            w[0] = 1 - t;
            w[1] = t;
        } else if (x > q_.nodes[static_cast<std::size_t>(lowest)]) {  // (with `pole`, never beyond the last ordinate)
            window = detail::lagrange_weights(q_.nodes.data(), end, pole ? std::fmin(x, q_.nodes.back()) : x, p, w, lowest);
        }
        ws.in.assign(q_.size(), Real(0));
        for (int a = 0; a < window.points; ++a) ws.in[static_cast<std::size_t>(window.first + a)] = w[a];
    }

    // A rough face's integrals I_k, k < modes, between |cosine| mu outside and each ordinate inside, into
    // ws.row[m K + k] (K = modes), and between mu and mu_t, its Snell cosine inside, into ws.row[M K + k] (for the
    // specular spread's azimuthal shape; left 0 where mu_t = 0, K = 1 (the shape is 1) or no spread follows), for light crossing the
    // given way: from the face's table where it holds mu (LayerRequest::tabulate_faces), else by their integrals.
    void couplings(const Face& face, Crossing c, Real mu, Real mu_t, int modes, Workspace& ws) const {
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes);
        ws.row.assign((m + 1) * kk, Real(0));
        const detail::CouplingTable<Real>* table = coupling_table(face, c);
        if (!table || !table->holds(mu)) {
            for (std::size_t i = 0; i < m; ++i) face.transmission(c, mu, q_.nodes[i], ws.row.data() + i * kk, modes);
            // (exit_weights spreads nothing with masking-only shadowing)
            const bool spread = c == Crossing::entering || face.boundary().rough_interface()->shadowing() != Shadowing::masking_only;
            if (mu_t > 0 && kk > 1 && spread) face.transmission(c, mu, mu_t, ws.row.data() + m * kk, modes);
            return;
        }
        const std::size_t all = static_cast<std::size_t>(table->modes);
        ws.row_all.resize((m + 1) * all);
        table->table->interpolate(mu, ws.row_all.data(), static_cast<int>((m + 1) * all));
        for (std::size_t i = 0; i <= m; ++i)
            for (std::size_t k = 0; k < kk; ++k) ws.row[i * kk + k] = table->scale * ws.row_all[i * all + k];
    }
    const detail::CouplingTable<Real>* coupling_table(const Face& face, Crossing c) const noexcept {
        if (face.bottom && c == Crossing::entering) return nullptr;  // (light enters from above)
        const detail::CouplingTable<Real>& t = couplings_[face.bottom ? 2 : c == Crossing::entering ? 0 : 1];
        return t.table ? &t : nullptr;
    }

    // A face's critical cosine inside, where it is sharp at the ordinates' resolution (0 where it is not, or there
    // is none): always for a specular face; for a rough one when its facets spread the directions there, about
    // sigma sin(theta_c) in cosine, over less than half the spacing of the ordinates around it. (A wide lobe blurs
    // the cut: restricting a stencil at it there cost 2% against the photon Monte Carlo, tests/test_layer_monte_carlo.)
    Real sharp_critical_cosine(const Face& f) const noexcept {
        const Real cut = f.critical_cosine();
        if (!(cut > 0) || !f.rough()) return cut;
        const Real spread = f.boundary().rough_interface()->sigma() * std::sqrt((Real(1) - cut) * (Real(1) + cut));
        return spread < detail::spacing_at(q_.nodes, cut) / 2 ? cut : Real(0);
    }

    // The azimuth between the propagation directions -wi and wo: cos(dphi) = -(wi_t . wo_t) / (|wi_t| |wo_t|), from
    // the normalized tangential parts (hypot: no overflow or underflow for finite non-unit vectors, whose squares
    // would give inf / inf or 0 / 0), clamped to [-1, 1] so that the Chebyshev recurrence stays bounded. At the pole
    // (wi or wo along the normal) it is undefined (1 is returned): only mode 0 survives there.
    static Real azimuth_cosine(Vec3<Real> wi, Vec3<Real> wo, bool& pole) noexcept {
        const Real ri = std::hypot(wi.x, wi.y), ro = std::hypot(wo.x, wo.y);
        pole = !(ri > 0) || !(ro > 0);
        return pole ? Real(1)
                    : std::fmin(std::fmax(-((wi.x / ri) * (wo.x / ro) + (wi.y / ri) * (wo.y / ro)), Real(-1)), Real(1));
    }

    // sum_k a_k cos(k dphi), dphi the azimuth between -wi and wo (at the pole, wi or wo along the normal, the azimuth is
    // undefined and only mode 0 survives).
    Real mode_sum(Vec3<Real> wi, Vec3<Real> wo, const Real* a) const {
        bool pole = false;
        const Real cos_dphi = azimuth_cosine(wi, wo, pole);
        Real sum = 0, c_prev = 1, c_k = 1;  // cos(k dphi) by the Chebyshev recurrence
        const int modes = pole ? std::min(modes_, 1) : modes_;
        for (int k = 0; k < modes; ++k) {
            sum += c_k * a[k];
            const Real c_next = k == 0 ? cos_dphi : 2 * cos_dphi * c_k - c_prev;
            c_prev = c_k;
            c_k = c_next;
        }
        return sum;
    }

    // One face rough and the other specular (first_pass_exact_, first_reflection_exact_): the light let in that crosses
    // the slabs unscattered and leaves through the bottom (under either top) or, reflected once by a rough bottom,
    // through a specular top. The solution on the ordinates holds it as D c (D the slabs' e^{-tau'/mu_m}, c the entry;
    // across joints that refract, D_1 T_12 D_2 ... with the joints' operators) or D R_23 D c (R_23 the bottom's
    // reflection operator) and the exit reads it out between the ordinates: a lobe
    // narrower than their spacing near the normal came out inflated (lit at the normal under a rough 0.3 top over a
    // smooth bottom, the BTDF integrated to 1.25 times the transmittance at 16 ordinates, 1.81 for slope 0.1; a
    // smooth top over a rough 0.05 bottom 1.61, and its BRDF 18% off the BRDF at 96 ordinates; found by review).
    // brdf and btdf take that pass out of the solution's modes and add it exactly at (wi, wo) (exact_pass), as a
    // value, not a Fourier series: a lobe narrow in azimuth needs more modes than the solve has, and cut to them it
    // rang (at 1 | 1.05, slope 0.1, 88 degrees off the lobe 4.3 where the truth is 0.25; found by the next review).
    // fourier_coefficients has no choice but the series (add_exact_pass_modes): there such a lobe rings.
    Real with_exact_pass(Vec3<Real> wi, Vec3<Real> wo, bool transmitted, Workspace& ws) const {
        const Real mu_i = std::fmin(wi.z, Real(1)), mu_o = std::fmin(std::fabs(wo.z), Real(1));
        const Real scale = scattering_scale(mu_i, ws);  // (as fourier_coefficients: 1 but under joints' mirror)
        const Real* fld = nullptr;
        const Real* c = entry_and_field(mu_i, transmitted, ws, fld);
        exit_weights(mu_o, transmitted ? bottom_face() : top_face(), ws);
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes_);
        ws.small.assign(kk, Real(0));
        subtract_discrete_pass(transmitted, ws.out.data(), c, ws, ws.small.data());
        for (std::size_t k = 0; k < kk; ++k)
            for (std::size_t i = 0; i < m; ++i) ws.small[k] += ws.out[k * m + i] * fld[k * m + i];
        return scale * (mode_sum(wi, wo, ws.small.data()) + exact_pass(wi, wo, transmitted));
    }

    // The entry at mu_i (returned) and the field (into fld), both kept from the solve for a requested incidence, else
    // computed (the entry into ws.c, from the Workspace's own copy where it holds this layer's at mu_i: entry()). (A
    // key naming ws.c's content, withdrawn, went stale after ambient() or another layer's call; found by review.)
    const Real* entry_and_field(Real mu_i, bool transmitted, Workspace& ws, const Real*& fld) const {
        fld = cached_field(mu_i, transmitted);
        for (std::size_t j = 0; j < incidence_.size() && fld; ++j)
            if (incidence_[j] == mu_i && j < cached_c_.size() && !cached_c_[j].empty()) return cached_c_[j].data();
        entry(mu_i, ws);
        if (!fld) fld = field_of_entry(transmitted, ws, modes_);
        return ws.c.data();
    }

    // delta[k] -= the pass as the solution holds it, read out by the exit weights exit_w, from the entry c_in (entry()):
    // D c, or D R_23 D c for reflection (one column), else the operators compose_passes made.
    void subtract_discrete_pass(bool transmitted, const Real* exit_w, const Real* c_in, Workspace& ws, Real* delta) const {
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes_);
        ws.first.assign(m, Real(0));
        for (std::size_t k = 0; k < kk; ++k) {
            const Real* c = c_in + k * m;
            const Real* d = pass_d_[0].data();
            if (pass_d_.size() > 1) {
                const detail::Matrix<Real>& a = (transmitted ? pass_down_ : pass_reflected_)[k];
                for (std::size_t n = 0; n < m; ++n) {
                    Real sum = 0;
                    for (std::size_t i = 0; i < m; ++i) sum += a(n, i) * c[i];
                    ws.first[n] = sum;
                }
            } else if (transmitted) {
                for (std::size_t n = 0; n < m; ++n) ws.first[n] = d[n] * c[n];
            } else {
                const Real* r = bottom_ops_->R12().mode(static_cast<int>(k));  // (row n out, column i in)
                for (std::size_t n = 0; n < m; ++n) {
                    Real sum = 0;
                    for (std::size_t i = 0; i < m; ++i) sum += r[n * m + i] * d[i] * c[i];
                    ws.first[n] = d[n] * sum;
                }
            }
            for (std::size_t n = 0; n < m; ++n) delta[k] -= exit_w[k * m + n] * ws.first[n];
        }
    }

    // The pass's geometry: `through`, the factors besides the rough face's BRDF or BTDF (the light let in, T_12(mu_i),
    // under a specular top; the attenuations; the specular face's radiance transmittance on the way out), and the
    // cosines inside, mu_t of wi's Snell direction (specular top) and mu_e of wo's (specular exit face); 0 where either
    // cannot be reached.
    struct PassGeometry {
        Real through = 0, mu_t = 0, mu_e = 0;
    };
    // Across the columns (pass_tau_) the cosines follow Snell's law at the refracting joints between them: crossing
    // down, the light let in keeps its flux T (specular top: an irradiance) and a radiance its radiance transmittance
    // (rough top); crossing up, a radiance its radiance transmittance from below.
    enum class Crossings { flux_down, radiance_down, radiance_up };
    PassGeometry pass_geometry(Real mu_i, Real mu_o, bool transmitted) const {
        const Face top = top_face(), bottom = bottom_face();
        const std::size_t last = pass_tau_.size() - 1;
        // The path with cosine c in column 0, traced down: the factor of its crossings into `factor` and its
        // attenuations' exponent into `sum`; the cosine in the last column (0 where a joint reflects it totally).
        const auto trace = [&](Real c, Crossings how, Real& factor, Real& sum) {
            for (std::size_t g = 0; g <= last && c > 0; ++g) {
                sum += pass_tau_[g] / c;
                if (g == last) break;
                const SmoothDielectric<Real>& joint = pass_joints_[g];
                const Real below = std::fabs(joint.transmitted_cosine(c));
                factor *= how == Crossings::flux_down       ? joint.transmittance(c)
                          : how == Crossings::radiance_down ? joint.radiance_transmittance(c)
                                                            : (below > 0 ? joint.radiance_transmittance(-below) : Real(0));
                c = below;
            }
            return c;
        };
        PassGeometry p;
        Real factor = 1, sum = 0;
        if (transmitted && top.rough()) {  // wo's direction traced back up to column 0, then the pass down from there
            Real c = bottom.internal_cosine(mu_o);
            for (std::size_t g = last; g > 0 && c > 0; --g) c = std::fabs(pass_joints_[g - 1].transmitted_cosine(-c));
            if (!(c > 0)) return {};
            p.mu_e = c;
            const Real c_last = trace(c, Crossings::radiance_down, factor, sum);
            p.through = factor * bottom.boundary().smooth_interface().radiance_transmittance(bottom.from_inside(c_last)) *
                        std::exp(-sum);
            return p;
        }
        const Real mu_t = top.internal_cosine(mu_i);
        p.mu_t = mu_t > 0 ? trace(mu_t, Crossings::flux_down, factor, sum) : Real(0);
        if (!(p.mu_t > 0)) return {};
        p.through = top.transmittance_from_outside(mu_i) * factor;
        if (!transmitted) {  // and back up to wo
            const Real mu_e = top.internal_cosine(mu_o);
            factor = 1;
            p.mu_e = mu_e > 0 ? trace(mu_e, Crossings::radiance_up, factor, sum) : Real(0);
            if (!(p.mu_e > 0)) return {};
            p.through *= factor * top.boundary().smooth_interface().radiance_transmittance(top.from_inside(mu_e));
        }
        p.through *= std::exp(-sum);
        return p;
    }

    // The exact pass at (wi, wo): under a rough top its BTDF towards wo's Snell direction inside, times that
    // direction's attenuation and the bottom's radiance transmittance; under a specular top T_12(mu_i) e^{-tau'/mu_t}
    // times the bottom's BTDF from wi's Snell direction inside to wo, or for reflection its BRDF from there to wo's
    // Snell direction inside, times e^{-tau'/mu_e} and the top's radiance transmittance (tau' the delta-M scaled
    // thickness: the solution's own unscattered light, whose fluxes stay as solved).
    Real exact_pass(Vec3<Real> wi, Vec3<Real> wo, bool transmitted) const {
        const Real mu_i = std::fmin(wi.z, Real(1)), mu_o = std::fmin(std::fabs(wo.z), Real(1));
        const PassGeometry p = pass_geometry(mu_i, mu_o, transmitted);
        if (!(p.through > 0)) return Real(0);
        // the direction inside with cosine c (its sign z) and the azimuth of v's horizontal part (x when v has none)
        const auto inside = [](Vec3<Real> v, Real c, Real z) {
            const Real h = std::sqrt(v.x * v.x + v.y * v.y), s = std::sqrt(std::fmax(Real(0), (1 - c) * (1 + c)));
            return h > 0 ? Vec3<Real>{v.x / h * s, v.y / h * s, z} : Vec3<Real>{s, Real(0), z};
        };
        if (transmitted && top_.rough())  // wo's direction of travel inside, continued
            return p.through * top_.rough_interface()->btdf(wi, inside(wo, p.mu_e, -p.mu_e));
        const Vec3<Real> from = inside(wi, p.mu_t, p.mu_t);  // towards the light, above the bottom face
        if (transmitted) return p.through * bottom_.rough_interface()->btdf(from, wo);
        return p.through * bottom_.rough_interface()->brdf(from, inside(wo, p.mu_e, p.mu_e));
    }

    // delta[k] += the exact pass's Fourier coefficients at (mu_i, mu_o): (2 - delta_k0) / (2 pi) times the rough face's
    // azimuthal integrals I_k (section 5 of docs/physics.md) times the pass's geometry, cut to the solve's modes.
    void add_exact_pass_modes(Real mu_i, Real mu_o, bool transmitted, Workspace& ws, Real* delta) const {
        const std::size_t kk = static_cast<std::size_t>(modes_);
        const PassGeometry p = pass_geometry(mu_i, mu_o, transmitted);
        if (!(p.through > 0)) return;
        ws.first.assign(kk, Real(0));
        if (transmitted && top_face().rough()) top_face().transmission(Crossing::entering, mu_i, p.mu_e, ws.first.data(), modes_);
        else if (transmitted) bottom_face().transmission(Crossing::leaving, mu_o, p.mu_t, ws.first.data(), modes_);
        else bottom_ops_->coefficients(Incidence::from_above, false, p.mu_t, p.mu_e, ws.first.data(), modes_);
        for (std::size_t k = 0; k < kk; ++k)
            delta[k] += p.through * ws.first[k] * (k == 0 ? Real(1) : Real(2)) / (2 * detail::pi_v<Real>);
    }

    // Radiance leaving through `face` towards wo from the internal field, summed over modes.
    Real exit_sum(Vec3<Real> wi, Vec3<Real> wo, const Face& face, const Real* fld, Workspace& ws) const {
        exit_weights(std::fmin(std::fabs(wo.z), Real(1)), face, ws);
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes_);
        ws.small.assign(kk, Real(0));
        for (std::size_t k = 0; k < kk; ++k)
            for (std::size_t i = 0; i < m; ++i) ws.small[k] += ws.out[k * m + i] * fld[k * m + i];
        return non_negative(mode_sum(wi, wo, ws.small.data()));
    }

    // ---- Between specular faces (beam_): the beam as a source (docs/physics.md section 6) ----
    // Slab j (of L, top to bottom) has index n_j; joint j (j = 1 .. L-1) is the smooth face between slabs j-1 and j.

    // The cosine in each slab of the direction whose cosine is c_f in slab f (Snell): c[j] = 0 where total internal
    // reflection at a joint between keeps it out.
    void snell_chain(std::size_t f, Real c_f, Real* c) const noexcept {
        const std::vector<Real>& eta = beam_->eta;
        const Real s_f = (Real(1) - c_f) * (Real(1) + c_f);
        auto at = [&](std::size_t j, Real previous) {
            const Real r = eta[f] / eta[j], cc = Real(1) - r * r * s_f;
            return previous > 0 && cc > 0 ? std::sqrt(cc) : Real(0);
        };
        c[f] = c_f;
        for (std::size_t j = f + 1; j < eta.size(); ++j) c[j] = at(j, c[j - 1]);
        for (std::size_t j = f; j-- > 0;) c[j] = at(j, c[j + 1]);
    }

    // Solves the small dense system a x = b in place (n unknowns, a row-major n x n; partial pivoting).
    static void solve_small(Real* a, Real* b, std::size_t n) noexcept {
        for (std::size_t k = 0; k < n; ++k) {
            std::size_t p = k;
            for (std::size_t i = k + 1; i < n; ++i)
                if (std::fabs(a[i * n + k]) > std::fabs(a[p * n + k])) p = i;
            if (p != k) {
                for (std::size_t j = 0; j < n; ++j) std::swap(a[k * n + j], a[p * n + j]);
                std::swap(b[k], b[p]);
            }
            const Real pivot = a[k * n + k];
            if (!(pivot != 0)) continue;  // (a row of an unreachable slab: identity, never 0)
            for (std::size_t i = k + 1; i < n; ++i) {
                const Real f = a[i * n + k] / pivot;
                if (f == Real(0)) continue;
                for (std::size_t j = k; j < n; ++j) a[i * n + j] -= f * a[k * n + j];
                b[i] -= f * b[k];
            }
        }
        for (std::size_t i = n; i-- > 0;) {
            Real v = b[i];
            for (std::size_t j = i + 1; j < n; ++j) v -= a[i * n + j] * b[j];
            b[i] = a[i * n + i] != 0 ? v / a[i * n + i] : Real(0);
        }
    }

    // Light at a single cosine (the beam's, or an exit direction's) bounced through the stack. With c[j] its cosine
    // in slab j (0: unreachable), e[j] = e^{-tau_j / c[j]}, and the faces' reflectances and transmittances (Fresnel;
    // `radiance`: the radiance transmittance, with its n^2, else the flux one), unknowns P_j (up at the top of slab j)
    // and Q_j (down at its bottom):
    //     P_j = up_j + e_j G_j,   Q_j = down_j + e_j F_j,
    //     F_0 = r_top P_0 (plus `from_top`), F_j = t_j Q_{j-1} + r_j P_j;  G_{L-1} = r_bottom Q_{L-1}, G_j = t'_{j+1} P_{j+1} + r'_{j+1} Q_j
    // (over a Lambertian floor r_bottom = 0: the floor's diffuse light is in up_{L-1}). Solved in place: on return
    // up[j] = P_j and down[j] = Q_j. For the beam: up = 0, down = 0 and from_top = T_12(mu_i) (flux) gives the
    // flux entering each slab going down, e F (its top), and going up, e G (its bottom).
    // `faces` (optional): the faces' flux reflectances (top, joints, bottom; beam_faces) in place of those at c.
    void bounce(const Real* c, const Real* e, bool radiance, Real from_top, Real* up, Real* down, Workspace& ws,
                const Real* faces = nullptr) const {
        const std::size_t count = beam_->slabs.size(), n = 2 * count;
        std::vector<Real>& a = ws.small;
        std::vector<Real>& x = ws.small_rhs;
        a.assign(n * n, Real(0));
        x.assign(n, Real(0));
        const SmoothDielectric<Real>& top = top_.smooth_interface();
        const SmoothDielectric<Real>& bottom = bottom_.smooth_interface();
        auto trans = [&](const SmoothDielectric<Real>& f, Real cosine) {
            return radiance ? f.radiance_transmittance(cosine) : f.transmittance(cosine);
        };
        for (std::size_t j = 0; j < count; ++j) {
            const std::size_t p = 2 * j, q = 2 * j + 1;  // rows / columns of P_j and Q_j
            a[p * n + p] = a[q * n + q] = Real(1);
            if (!(c[j] > 0)) continue;  // unreachable: P_j = Q_j = 0
            x[p] = up[j];
            x[q] = down[j];
            // F_j (down-going entering slab j from above), times e_j, into Q_j's row
            if (j == 0) {
                a[q * n + p] -= e[j] * (faces ? faces[0] : top.reflectance(-c[0]));
                x[q] += e[j] * from_top;
            } else {
                const SmoothDielectric<Real>& joint = beam_->joints[j - 1];
                a[q * n + (2 * (j - 1) + 1)] -= e[j] * (faces ? 1 - faces[j] : trans(joint, c[j - 1]));
                a[q * n + p] -= e[j] * (faces ? faces[j] : joint.reflectance(-c[j]));
            }
            // G_j (up-going entering slab j from below), times e_j, into P_j's row
            if (j + 1 == count) {
                if (beam_->floor < 0) a[p * n + q] -= e[j] * (faces ? faces[count] : bottom.reflectance(c[j]));
            } else {
                const SmoothDielectric<Real>& joint = beam_->joints[j];
                if (c[j + 1] > 0) a[p * n + (2 * (j + 1))] -= e[j] * (faces ? 1 - faces[j + 1] : trans(joint, -c[j + 1]));
                a[p * n + q] -= e[j] * (c[j + 1] > 0 ? (faces ? faces[j + 1] : joint.reflectance(c[j])) : Real(1));
            }
        }
        solve_small(a.data(), x.data(), n);
        for (std::size_t j = 0; j < count; ++j) up[j] = x[2 * j], down[j] = x[2 * j + 1];
    }

    // For the beam entering at mu_i from above: its cosine x[j] in each slab (0 where none reaches) and the faces'
    // flux reflectances r[0] (top), r[j] (joint j, between slabs j - 1 and j), r[count] (bottom), each taken from the
    // face's less dense side, where Fresnel is well conditioned (its flux reflectance is the same from both sides;
    // 1 where nothing passes). Every cosine comes from the outside's by the invariant n sin(theta),
    // x_j^2 = ((n_j - n_a)(n_j + n_a) + n_a^2 mu_i^2) / n_j^2: exact where n_j = n_a, without cancellation where
    // n_j > n_a. (Followed from cosine to cosine inside, a grazing beam's rounded onto a critical cosine: 1 | 1.4 |
    // 1.5 | 1 with empty slabs at mu 1e-4 in float gave T 6.0e-4 for 3.0e-4, and double lost the beam at 1e-9.)
    void beam_faces(Real mu_i, Real* x, Real* r) const noexcept {
        const std::vector<Real>& eta = beam_->eta;
        const std::size_t count = eta.size();
        const SmoothDielectric<Real>& top = top_.smooth_interface();
        const SmoothDielectric<Real>& bottom = bottom_.smooth_interface();
        const Real na = top.eta_above();
        for (std::size_t j = 0; j < count; ++j) x[j] = snell_cosine(eta[j], na, mu_i);
        for (std::size_t j = 1; j < count; ++j) x[j] = x[j - 1] > 0 ? x[j] : Real(0);  // (beyond a total reflection)
        r[0] = face_reflectance(top, mu_i, x[0]);
        for (std::size_t j = 1; j < count; ++j) r[j] = face_reflectance(beam_->joints[j - 1], x[j - 1], x[j]);
        r[count] = face_reflectance(bottom, x[count - 1], snell_cosine(bottom.eta_below(), na, mu_i));
    }

    // The beam's passes for incidence mu_i: per slab its cosine x[j], and the flux entering it going down (at its
    // top, f_down) and going up (at its bottom, f_up), attenuated by the delta-M scaled thicknesses (`scaled`: what the
    // discrete field loses to it) or the true ones (the unscattered beam). False where no light enters.
    bool beam_passes(Real mu_i, bool scaled, Real* x, Real* f_down, Real* f_up, Workspace& ws) const {
        const std::size_t count = beam_->slabs.size();
        const Real entering = top_.smooth_interface().transmittance(mu_i);
        std::vector<Real>& r = ws.faces;
        r.resize(count + 1);
        beam_faces(mu_i, x, r.data());
        if (!(x[0] > 0) || !(entering > 0)) return false;
        std::vector<Real>& e = ws.small_e;
        e.resize(count);
        for (std::size_t j = 0; j < count; ++j) {
            const Real tau = scaled ? beam_->slabs[j].optical_thickness() : beam_->true_tau[j];
            e[j] = !(x[j] > 0) || std::isinf(tau) ? Real(0) : std::exp(-tau / x[j]);
            f_down[j] = f_up[j] = 0;
        }
        bounce(x, e.data(), false, entering, f_up, f_down, ws, r.data());  // P_j, Q_j: up at the top, down at the bottom
        // The fluxes entering each slab, F_j from above and G_j from below, from P and Q by the connections of
        // bounce() (not as P / e and Q / e: e underflows for an opaque slab).
        std::vector<Real>& p = ws.small_rhs;  // (bounce's scratch, free again)
        p.assign(2 * count, Real(0));
        for (std::size_t j = 0; j < count; ++j) {
            if (!(x[j] > 0)) continue;
            Real from_above, from_below = 0;
            if (j == 0) {
                from_above = entering + r[0] * f_up[0];
            } else {
                from_above = (1 - r[j]) * f_down[j - 1] + r[j] * f_up[j];
            }
            if (j + 1 == count) {
                if (beam_->floor < 0) from_below = r[count] * f_down[j];
            } else {
                from_below = (x[j + 1] > 0 ? (1 - r[j + 1]) * f_up[j + 1] : Real(0)) +
                             (x[j + 1] > 0 ? r[j + 1] : Real(1)) * f_down[j];
            }
            p[2 * j] = from_above;
            p[2 * j + 1] = from_below;
        }
        for (std::size_t j = 0; j < count; ++j) f_down[j] = p[2 * j], f_up[j] = p[2 * j + 1];
        return true;
    }

    // The unscattered beam through a stack whose joints refract (see direct()).
    Real stack_direct(Real mu_i, bool transmitted, bool scaled) const {
        Workspace ws;
        const std::size_t count = beam_->slabs.size();
        std::vector<Real> x(count), down(count), up(count);
        if (!beam_passes(mu_i, scaled, x.data(), down.data(), up.data(), ws)) return Real(0);
        const std::size_t last = count - 1;
        if (transmitted) {
            const Real tau = scaled ? beam_->slabs[last].optical_thickness() : beam_->true_tau[last];
            const Real e = !(x[last] > 0) || std::isinf(tau) ? Real(0) : std::exp(-tau / x[last]);
            return beam_->floor >= 0 ? Real(0) : down[last] * e * (1 - ws.faces[count]);
        }
        const Real tau = scaled ? beam_->slabs[0].optical_thickness() : beam_->true_tau[0];
        const Real e = std::isinf(tau) ? Real(0) : std::exp(-tau / x[0]);
        return up[0] * e * (1 - ws.faces[0]);
    }

    // The diffuse field of incidence mu_i, modes < `modes`: each slab's response to the beam's passes (at its own
    // cosine x_j) is the source of the field's system (add_beam_mode); over a Lambertian floor the beam reaching it
    // comes back up diffusely, radiance albedo (flux) / pi entering the last slab from below (mode 0). Stored per mode
    // and slab: what leaves it (u up, v down) and what enters it (d from above, w from below) at the ordinates.
    const detail::BeamField<Real>& beam_field(Real mu_i, int modes, Workspace& ws) const {
        for (std::size_t j = 0; j < cached_beam_.size(); ++j)
            if (cached_beam_[j].mu_i == mu_i && cached_beam_[j].modes >= modes) return cached_beam_[j];
        // (the Workspace's field, if it is this beam source's at this incidence: exits at one incidence share it)
        if (ws.beam_owner == beam_->serial && ws.beam.mu_i == mu_i && ws.beam.modes >= modes) return ws.beam;
        ws.beam_owner = 0;
        compute_beam_field(mu_i, modes, ws.beam, ws);
        ws.beam_owner = beam_->serial;
        return ws.beam;
    }
    void compute_beam_field(Real mu_i, int modes, detail::BeamField<Real>& f, Workspace& ws) const {
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes), count = beam_->slabs.size();
        f.mu_i = mu_i;
        f.modes = modes;
        f.x.assign(count, Real(0));
        f.flux_down.assign(count, Real(0));
        f.flux_up.assign(count, Real(0));
        f.floor_radiance = 0;
        f.response.resize(count);
        for (std::vector<Real>* v : {&f.u, &f.v, &f.d, &f.w}) v->assign(kk * count * m, Real(0));
        if (!beam_passes(mu_i, true, f.x.data(), f.flux_down.data(), f.flux_up.data(), ws)) {
            f.flux_down.assign(count, Real(0));
            return;
        }
        for (std::size_t j = 0; j < count; ++j)
            if (f.x[j] > 0) beam_->slabs[j].respond(f.x[j], modes, f.response[j], ws.scratch);
        const std::size_t last = count - 1;
        const Real tau_last = beam_->slabs[last].optical_thickness();
        const Real e_last = std::isinf(tau_last) || !(f.x[last] > 0) ? Real(0) : std::exp(-tau_last / f.x[last]);
        const Real floor_flux = f.flux_down[last] * e_last;  // the beam reaching the bottom
        const Real floor_beam = beam_->floor > 0 ? beam_->floor * floor_flux / detail::pi_v<Real> : Real(0);
        const std::size_t size = 2 * m * count;
        if (ws.rhs.rows != size) ws.rhs = detail::Matrix<Real>(size, 1);
        for (std::size_t k = 0; k < kk; ++k) {
            const detail::LU<Real>& lu = beam_->lu[k];
            if (lu.pivot.empty() && !beam_->identity_system) continue;
            for (std::size_t j = 0; j < count; ++j) {  // scaled variables (C = diag(sqrt(w mu)), as the factors)
                const bool lit = f.x[j] > 0;
                for (std::size_t n = 0; n < m; ++n) {
                    const Real c = std::sqrt(q_.weights[n] * q_.nodes[n]);
                    const Real up = lit ? f.response[j].up[k * m + n] : Real(0), down = lit ? f.response[j].down[k * m + n] : Real(0);
                    ws.rhs(2 * m * j + n, 0) = c * (f.flux_down[j] * up + f.flux_up[j] * down);
                    ws.rhs(2 * m * j + m + n, 0) = c * (f.flux_down[j] * down + f.flux_up[j] * up);
                }
            }
            if (k == 0 && floor_beam > 0) {
                const detail::SlabBeamMode<Real>& md = beam_->slabs[last].mode(0);
                for (std::size_t n = 0; n < m; ++n)
                    for (std::size_t i = 0; i < m; ++i) {
                        const Real w = std::sqrt(q_.weights[i] * q_.nodes[i]) * floor_beam;
                        ws.rhs(2 * m * last + n, 0) += md.t(n, i) * w;
                        ws.rhs(2 * m * last + m + n, 0) += md.r(n, i) * w;
                    }
            }
            if (!beam_->identity_system) detail::lu_solve(lu, ws.rhs);
            for (std::size_t j = 0; j < count; ++j)
                for (std::size_t n = 0; n < m; ++n) {
                    const Real c = std::sqrt(q_.weights[n] * q_.nodes[n]);
                    f.u[(k * count + j) * m + n] = ws.rhs(2 * m * j + n, 0) / c;
                    f.v[(k * count + j) * m + n] = ws.rhs(2 * m * j + m + n, 0) / c;
                }
            entering(k, f);
        }
        if (beam_->floor > 0 && kk > 0) {  // the floor's radiance: albedo / pi times the flux reaching it
            Real flux = floor_flux;
            const Real* v = f.v.data() + last * m;
            for (std::size_t n = 0; n < m; ++n) flux += 2 * detail::pi_v<Real> * q_.weights[n] * q_.nodes[n] * v[n];
            f.floor_radiance = beam_->floor * flux / detail::pi_v<Real>;
            for (std::size_t n = 0; n < m; ++n) f.w[last * m + n] = f.floor_radiance;  // (mode 0: the floor's light)
        }
    }

    // Mode k of what enters each slab at the ordinates (d from above, w from below; unscaled), from what leaves them
    // (add_beam_mode's connections). Over a floor, w of the last slab is set from its radiance by the caller (mode 0).
    void entering(std::size_t k, detail::BeamField<Real>& f) const {
        const std::size_t m = q_.size(), count = beam_->slabs.size();
        for (std::size_t j = 0; j < count; ++j) {
            Real* d = f.d.data() + (k * count + j) * m;
            Real* w = f.w.data() + (k * count + j) * m;
            const Real* u_j = f.u.data() + (k * count + j) * m;
            const Real* v_j = f.v.data() + (k * count + j) * m;
            if (j == 0) {
                for (std::size_t n = 0; n < m; ++n) d[n] = beam_->r21[n] * u_j[n];
            } else {
                const Real* v_above = f.v.data() + (k * count + j - 1) * m;
                const detail::Matrix<Real>& t = beam_->joint_t_down[k][j - 1];
                const detail::Matrix<Real>& r = beam_->joint_r_up[k][j - 1];
                for (std::size_t n = 0; n < m; ++n) {
                    Real s = 0;
                    for (std::size_t i = 0; i < m; ++i) s += t(n, i) * v_above[i] + r(n, i) * u_j[i];
                    d[n] = s;
                }
            }
            if (j + 1 == count) {
                if (beam_->floor < 0)
                    for (std::size_t n = 0; n < m; ++n) w[n] = beam_->r23[n] * v_j[n];
            } else {
                const Real* u_below = f.u.data() + (k * count + j + 1) * m;
                const detail::Matrix<Real>& t = beam_->joint_t_up[k][j];
                const detail::Matrix<Real>& r = beam_->joint_r_down[k][j];
                for (std::size_t n = 0; n < m; ++n) {
                    Real s = 0;
                    for (std::size_t i = 0; i < m; ++i) s += t(n, i) * u_below[i] + r(n, i) * v_j[i];
                    w[n] = s;
                }
            }
        }
    }

    // Mode k of the diffuse radiance leaving the layer at |cosine| mu_o outside (through the top, or through the
    // bottom when `transmitted`), for the field f, per mode into out[k] (k < f.modes; 0 where nothing leaves). At its
    // cosine y_j in slab j (Snell) slab j emits, up at its top and down at its bottom,
    //     E_up = f_down r(y) + f_up t(y) + row_r(y) d_j + row_t(y) w_j,   E_down = f_down t(y) + f_up r(y) + row_t d_j + row_r w_j
    // (r, t: its radiance at y for the beam; rows: its radiance at y per unit radiance entering at the ordinates:
    // detail/beam_source.hpp); light at a single cosine crosses the slabs unscattered (what they scatter out of it
    // carries no flux) and bounces between the faces and joints (bounce()); the face's radiance transmittance takes
    // it out. Over a Lambertian floor the floor's radiance comes up into the last slab's bottom at every y (mode 0).
    void beam_exit(const detail::BeamField<Real>& f, Real mu_o, bool transmitted, Real* out, Workspace& ws) const {
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(f.modes), count = beam_->slabs.size();
        std::fill(out, out + kk, Real(0));
        if (!f.lit() || !exit_path(mu_o, transmitted, ws)) return;
        const Real* y = ws.path_c.data();
        const Real* e = ws.path_e.data();
        // (the slabs' responses to a beam at the exit cosines: the same for every incidence and azimuth)
        std::vector<detail::BeamResponse<Real>>& at_y = ws.beam_y[transmitted ? 1 : 0];
        auto& key = ws.beam_y_key[transmitted ? 1 : 0];
        if (key.owner != beam_->serial || key.mu_o != mu_o || key.modes < f.modes) {
            key.owner = 0;  // (until the new entry is complete: an exception leaves no valid-looking key)
            at_y.resize(count);
            for (std::size_t j = 0; j < count; ++j)
                if (y[j] > 0) beam_->slabs[j].respond(y[j], f.modes, at_y[j], ws.scratch);
            leave_weights(transmitted, ws.beam_y_leave[transmitted ? 1 : 0], ws);
            key = {beam_->serial, mu_o, f.modes};
        }
        const std::vector<Real>& leaving = ws.beam_y_leave[transmitted ? 1 : 0];
        const Real two_pi = 2 * detail::pi_v<Real>;
        std::vector<Real>& up = ws.path_up;
        std::vector<Real>& down = ws.path_down;
        std::vector<Real>& exits = ws.path_exits;  // per slab, the modes of r, then of t (SlabBeam::exit)
        exits.assign(2 * count * kk, Real(0));
        for (std::size_t j = 0; j < count; ++j)
            if (y[j] > 0 && f.x[j] > 0)
                beam_->slabs[j].exit(f.response[j], at_y[j], f.modes, &exits[2 * j * kk], &exits[(2 * j + 1) * kk]);
        for (std::size_t k = 0; k < kk; ++k) {
            const Real scale = two_pi / (k == 0 ? Real(1) : Real(2));
            up.assign(count, Real(0));
            down.assign(count, Real(0));
            for (std::size_t j = 0; j < count; ++j) {
                if (!(y[j] > 0)) continue;  // (a slab the beam does not reach still emits its diffuse light)
                const Real r = exits[2 * j * kk + k], t = exits[(2 * j + 1) * kk + k];
                Real eu = f.flux_down[j] * r + f.flux_up[j] * t, ed = f.flux_down[j] * t + f.flux_up[j] * r;
                const Real* d = f.d.data() + (k * count + j) * m;
                const Real* w = f.w.data() + (k * count + j) * m;
                for (std::size_t n = 0; n < m; ++n) {
                    const Real wm = scale * q_.weights[n] * q_.nodes[n];
                    const Real row_r = wm * at_y[j].up[k * m + n], row_t = wm * at_y[j].down[k * m + n];
                    eu += row_r * d[n] + row_t * w[n];
                    ed += row_t * d[n] + row_r * w[n];
                }
                up[j] = eu;
                down[j] = ed;
            }
            // (the emissions of slabs the exit direction cannot reach do not leave at it: a slab below a joint that
            // totally reflects y, whose rows were not computed, has y[j] = 0)
            if (beam_->floor >= 0 && k == 0 && y[count - 1] > 0) up[count - 1] += e[count - 1] * f.floor_radiance;
            Real sum = 0;
            for (std::size_t j = 0; j < count; ++j) sum += leaving[2 * j] * up[j] + leaving[2 * j + 1] * down[j];
            out[k] = sum;
        }
    }

    // leave() is linear in the slabs' emissions: its weights w[2j] of up_j and w[2j + 1] of down_j on the exit path
    // (ws.path_c, ws.path_e), one bounce() per emission, so that each mode and incidence costs a dot product (a
    // table's exits see 32 modes and 129 incidences each).
    void leave_weights(bool transmitted, std::vector<Real>& w, Workspace& ws) const {
        const std::size_t count = beam_->slabs.size();
        w.assign(2 * count, Real(0));
        std::vector<Real>& up = ws.path_up;
        std::vector<Real>& down = ws.path_down;
        for (std::size_t i = 0; i < 2 * count; ++i) {
            if (!(ws.path_c[i / 2] > 0)) continue;
            up.assign(count, Real(0));
            down.assign(count, Real(0));
            (i % 2 == 0 ? up : down)[i / 2] = 1;
            w[i] = leave(transmitted, up.data(), down.data(), ws);
        }
    }

    // The exit direction's cosines per slab (ws.path_c, from |cosine| mu_o outside through the top or the bottom) and
    // their attenuations (ws.path_e); false where it reaches no slab.
    bool exit_path(Real mu_o, bool transmitted, Workspace& ws) const {
        const std::size_t count = beam_->slabs.size();
        ws.path_c.assign(count, Real(0));
        ws.path_e.assign(count, Real(0));
        const Face face = transmitted ? bottom_face() : top_face();
        const Real y_face = face.internal_cosine(mu_o);
        if (!(y_face > 0)) return false;
        snell_chain(transmitted ? count - 1 : 0, y_face, ws.path_c.data());
        for (std::size_t j = 0; j < count; ++j) {
            const Real tau = beam_->slabs[j].optical_thickness();
            ws.path_e[j] = !(ws.path_c[j] > 0) || std::isinf(tau) ? Real(0) : std::exp(-tau / ws.path_c[j]);
        }
        return true;
    }

    // The radiance leaving through the top (or bottom) for slab emissions up / down at the exit path's cosines.
    Real leave(bool transmitted, Real* up, Real* down, Workspace& ws) const {
        const std::size_t count = beam_->slabs.size();
        bounce(ws.path_c.data(), ws.path_e.data(), true, Real(0), up, down, ws);
        if (transmitted)
            return beam_->floor >= 0 ? Real(0)
                                     : bottom_.smooth_interface().radiance_transmittance(ws.path_c[count - 1]) * down[count - 1];
        return top_.smooth_interface().radiance_transmittance(-ws.path_c[0]) * up[0];
    }

    // LayerOptions::single_scattering_correction: each slab's exact-minus-truncated single scattering of the beam's
    // passes (SlabBeam::single_scattering_correction; a beam going up sends out the mirror image), taken out as in
    // beam_exit.
    Real single_scattering_correction(const detail::BeamField<Real>& f, Real mu_o, Real cos_dphi, bool transmitted,
                                      Workspace& ws) const {
        const std::size_t count = beam_->slabs.size();
        if (!f.lit() || !exit_path(mu_o, transmitted, ws)) return Real(0);
        std::vector<Real>& up = ws.path_up;
        std::vector<Real>& down = ws.path_down;
        up.assign(count, Real(0));
        down.assign(count, Real(0));
        // IMS, the beam's aureole in its own direction of travel (detail::secondary_scattering_correction): over the
        // whole stack where its joints are index matched (one column, as DISORT: the beam keeps its direction, and a
        // medium split into slabs is the same medium), else per slab.
        const auto aureole = [&](std::size_t first, std::size_t last) {
            const Real x = f.x[first], y = ws.path_c[first];
            const Real sines = std::sqrt((1 - x) * (1 + x) * (1 - y) * (1 + y)) * cos_dphi;
            const Real s = detail::secondary_scattering_correction(beam_->slabs, first, last, x, y, x * y + sines);
            up[first] -= f.flux_up[last] * s;
            down[last] -= f.flux_down[first] * s;
        };
        for (std::size_t j = 0; j < count; ++j) {
            const Real y = ws.path_c[j];
            if (!(y > 0) || !(f.x[j] > 0)) continue;
            Real r = 0, t = 0;
            beam_->slabs[j].single_scattering_correction(f.x[j], y, cos_dphi, &r, &t);
            up[j] = f.flux_down[j] * r + f.flux_up[j] * t;
            down[j] = f.flux_down[j] * t + f.flux_up[j] * r;
            if (beam_->refracting) aureole(j, j);
        }
        if (!beam_->refracting && ws.path_c[0] > 0 && f.x[0] > 0) aureole(0, count - 1);
        return leave(transmitted, up.data(), down.data(), ws);
    }

    // brdf/btdf between specular faces: the modes of beam_exit summed at the azimuth of wo from -wi.
    Real beam_radiance(Vec3<Real> wi, Vec3<Real> wo, bool transmitted, Workspace& ws) const {
        const Real mu_i = std::fmin(wi.z, Real(1)), mu_o = std::fmin(std::fabs(wo.z), Real(1));
        const detail::BeamField<Real>& f = beam_field(mu_i, modes_, ws);
        ws.out.resize(static_cast<std::size_t>(modes_));
        beam_exit(f, mu_o, transmitted, ws.out.data(), ws);
        bool pole = false;
        const Real cos_dphi = azimuth_cosine(wi, wo, pole);
        Real sum = 0, c_prev = 1, c_k = 1;
        for (int k = 0; k < (pole ? std::min(modes_, 1) : modes_); ++k) {
            sum += c_k * ws.out[static_cast<std::size_t>(k)];
            const Real c_next = k == 0 ? cos_dphi : 2 * cos_dphi * c_k - c_prev;
            c_prev = c_k;
            c_k = c_next;
        }
        if (beam_->single_scattering) sum += single_scattering_correction(f, mu_o, cos_dphi, transmitted, ws);
        return non_negative(sum);
    }

    // The value of one mode at outgoing cosine mu_o (used for the mode-0 ambient term).
    Real exit_value(Real mu_o, const Face& face, int k, const Real* fld, Workspace& ws) const {
        exit_weights(mu_o, face, ws);
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
    void exit_weights(Real mu_o, const Face& face, Workspace& ws) const {
        const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes_);
        ws.out.assign(kk * m, Real(0));
        const Real mu_t = face.internal_cosine(mu_o);  // the internal direction, ray reversed
        Real specular =
            mu_t > 0 ? face.boundary().smooth_interface().radiance_transmittance(face.from_inside(mu_t)) : Real(0);
        if (face.rough()) {
            const Real t_outside = face.transmittance_from_outside(mu_o);
            const Real n = face.eta_outside() / face.eta_inside();
            const Real expected = n * n * t_outside;
            if (!(expected > 0)) return;
            couplings(face, Crossing::leaving, mu_o, mu_t, modes_, ws);
            Real gauss = 0;
            for (std::size_t i = 0; i < m; ++i) {
                const Real* in = ws.row.data() + i * kk;
                const Real wm = q_.weights[i] * q_.nodes[i];
                gauss += wm * in[0];
                for (std::size_t k = 0; k < kk; ++k) ws.out[k * m + i] = wm * in[k];
            }
            // The reciprocity behind `expected` needs a reciprocal BTDF: with masking-only shadowing the exit
            // weights are used as they are (tests/test_layer_monte_carlo.cpp measured both against a photon
            // Monte Carlo). Otherwise the blend of entry(): the rescaled lobe where the ordinates resolve it, and
            // the interpolated internal radiance at the Snell direction times `expected`.
            if (face.boundary().rough_interface()->shadowing() == Shadowing::masking_only) return;
            specular = expected * blend(gauss, expected, ws.out);
        }
        if (!(specular > 0) || !(mu_t > 0)) return;
        specular_spread(face, mu_t, 2, ws, modes_, true);
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


    // The unscattered beam between two specular faces at internal cosine mu: d = e^{-tau/mu} per pass, the faces'
    // reflectances from inside, r21 (top) and r23 (bottom), and loss = 1 - r21 r23 d^2, the share of the beam that a
    // round trip does not bring back; its bounces sum to the geometric series 1 + r21 r23 d^2 + ... = 1 / loss.
    // Trapped (loss = 0): total internal reflection at both faces and nothing taken from the beam (d = 1: tau = 0,
    // or tau / mu below rounding). No light from outside reaches such a beam (the value for it is 0) and its
    // series would be 1 / 0: the callers skip it.
    struct DirectBeam {
        Real d, r21, r23, loss;
        bool trapped() const noexcept { return !(loss > 0); }
        Real bounces() const noexcept { return Real(1) / loss; }
        // Energy taken from a beam of unit flux over all its passes: (1 - d)(1 + r23 d) / (1 - r21 r23 d^2).
        Real extracted() const noexcept {
            if (!(d < 1)) return Real(0);  // nothing taken (and 0 / 0 when trapped)
            return (Real(1) - d) * (Real(1) + r23 * d) / loss;
        }
    };
    DirectBeam direct_beam(Real mu, Real tau) const noexcept {
        const Real d = std::isinf(tau) ? Real(0) : std::exp(-tau / mu);
        const Real r21 = top_.smooth_interface().reflectance(-mu), r23 = bottom_.smooth_interface().reflectance(mu);
        return {d, r21, r23, Real(1) - r21 * r23 * d * d};
    }
    // The same for the beam that entered at mu_i (mu_t = top_face().internal_cosine(mu_i) > 0), with the faces'
    // reflectances from their less dense sides at the cosines from the invariant n sin(theta) (face_reflectance,
    // snell_cosine). From mu_t they cancelled for grazing mu_i: mu_t rounds onto the bottom's critical cosine and a
    // beam that leaves was taken as trapped (1 | 1.4 | 1 at mu 1e-4 in float: R + T = 1 - 6e-4; double lost 6e-9 at
    // mu 1e-9; found by a review sweep). (A first version took the bottom's from below always, where a denser
    // substrate's cosine cancels in turn: an index-matched top over n 1.5 gave T 2.1e-3 for 5.8e-4 in float at mu
    // 1e-4; found by review.)
    DirectBeam entering_beam(Real mu_i, Real mu_t, Real tau) const noexcept {
        const SmoothDielectric<Real>& top = top_.smooth_interface();
        const SmoothDielectric<Real>& bottom = bottom_.smooth_interface();
        const Real na = top.eta_above();
        const Real inside = snell_cosine(top.eta_below(), na, mu_i), below = snell_cosine(bottom.eta_below(), na, mu_i);
        const Real d = std::isinf(tau) ? Real(0) : std::exp(-tau / mu_t);
        const Real r21 = face_reflectance(top, mu_i, inside), r23 = face_reflectance(bottom, inside, below);
        return {d, r21, r23, Real(1) - r21 * r23 * d * d};
    }
    // The cosine in a medium of index n of the direction whose cosine is mu in the medium of index n_a (Snell: n
    // sin(theta) invariant), sqrt(((n - n_a)(n + n_a) + n_a^2 mu^2)) / n: exact where n = n_a (while mu^2 is a normal
    // number: mu above 1e-19 in float, 1.5e-154 in double), without cancellation where n > n_a; 0 where no direction
    // has that invariant.
    static Real snell_cosine(Real n, Real n_a, Real mu) noexcept {
        const Real c2 = ((n - n_a) * (n + n_a) + n_a * n_a * mu * mu) / (n * n);
        return c2 > 0 ? std::sqrt(c2) : Real(0);
    }
    // A smooth face's flux reflectance for the direction with cosines c_up above it and c_down below, from its less
    // dense side, where Fresnel is well conditioned (the flux reflectance is the same from both sides; from the
    // denser side it changes like a square root near the critical cosine); 1 where either is 0 (nothing passes).
    static Real face_reflectance(const SmoothDielectric<Real>& f, Real c_up, Real c_down) noexcept {
        if (!(c_up > 0) || !(c_down > 0)) return Real(1);
        return f.eta_above() <= f.eta_below() ? f.reflectance(c_up) : f.reflectance(-c_down);
    }

    // The beam between two specular boundaries (see direct_transmittance), exactly at mu_i, attenuated by the
    // optical thickness tau (beam_tau_: the unscattered beam; direct_tau_: delta-M's, with the forward peak): it
    // enters with T_12(mu_i), bounces between the faces, and leaves through the bottom with T_23 or, after a
    // reflection there, through the top with T_21.
    Real direct(Real mu_i, bool transmitted, Real tau) const {
        if (joint_mirror_) return transmitted ? Real(0) : joint_mirror(mu_i, tau == direct_tau_);
        if (!direct_separated_) return Real(0);
        if (beam_ && beam_->refracting) return stack_direct(mu_i, transmitted, tau == direct_tau_);
        const Real mu_t = top_face().internal_cosine(mu_i);
        if (!(mu_t > 0)) return Real(0);
        const DirectBeam beam = entering_beam(mu_i, mu_t, tau);
        if (beam.trapped()) return Real(0);
        // (out through the bottom with 1 - r23, or back through the top with 1 - r21: entering_beam)
        const Real into = top_.smooth_interface().transmittance(mu_i) * beam.d * beam.bounces();
        return transmitted ? into * (1 - beam.r23) : into * beam.r23 * beam.d * (1 - beam.r21);
    }

    // The fraction of the flux at mu_i (from above) that a specular top over refracting joints and a rough bottom
    // reflects back out as a delta (joint_mirror_): with c_j the cosine in slab j (Snell), d_j = e^{-tau_j / c_j}
    // (tau_j delta-M scaled, as solved, or true) and r, t the joints' flux reflectance and transmittance, the stack's
    // specular reflectance below the top of slab j, R_j = d_j^2 (r + t t' R_{j+1} / (1 - r' R_{j+1})) (joint j
    // seen from above at c_j, primed from below at c_{j+1}; R_L = 0: the rough bottom reflects nothing
    // specularly; TIR at joint j: r = 1), and out through the top, T_12(mu_i) R_0 T_21(c_0) / (1 - r_21(c_0) R_0).
    // (The cosines from the invariant n sin(theta), without storing them: reflectance() and ambient() allocate nothing.)
    Real joint_mirror(Real mu_i, bool scaled) const {
        const SmoothDielectric<Real>& top = top_.smooth_interface();
        const std::size_t count = mirror_eta_.size();
        // in slab j, 0 where no direction has that invariant (from sqrt((1 - x)(1 + x)), x = n_a sin / n_j, it
        // cancelled for a grazing beam in a slab of the outside's index: NaN at mu 1e-4 in float; found by review)
        const auto cosine = [&](std::size_t j) { return snell_cosine(mirror_eta_[j], top.eta_above(), mu_i); };
        std::size_t reached = 0;  // the slabs the light reaches, 0 .. reached - 1
        while (reached < count && cosine(reached) > 0) ++reached;
        const std::vector<Real>& tau = scaled ? mirror_scaled_tau_ : mirror_true_tau_;
        // the reflectance at the bottom of slab j seen from inside it: 0 over the rough bottom (nothing specular), 1
        // over a joint that reflects totally (left 0, that bounce was lost: R + T 0.77 for albedo 1; found by review)
        Real r = reached < count ? Real(1) : Real(0);
        for (std::size_t j = reached; j-- > 0;) {
            const Real c = cosine(j), d = std::isinf(tau[j]) ? Real(0) : std::exp(-tau[j] / c), below = d * d * r;
            // (each face's reflectance from its less dense side: face_reflectance; where it rounds to 1 and so does
            // below, (1 - f)^2 below / (1 - f below) is 0 / 0 for its limit 0)
            const Real f = face_reflectance(j == 0 ? top : mirror_joints_[j - 1], j == 0 ? mu_i : cosine(j - 1), c);
            const Real loss = 1 - f * below, through = loss > 0 ? (1 - f) * (1 - f) * below / loss : Real(0);
            if (j == 0) return through;
            r = f + through;
        }
        return Real(0);
    }

    // Delta-M's beam minus the unscattered one: light scattered into the truncated forward peak (>= 0: the beam's
    // flux grows with its transmission d, and the scaled thickness is the smaller).
    Real forward_peak(Real mu_i, bool transmitted) const {
        return non_negative(direct(mu_i, transmitted, direct_tau_) - direct(mu_i, transmitted, beam_tau_));
    }

    // Between specular faces the scattered light is driven by the beam spread over the ordinates, whose
    // extinction differs from the true beam's. The scattered field is scaled by E(mu_t) / sum_m s_m E(mu_m), with
    // E the energy a beam loses over all its passes (DirectBeam::extracted) and s_m the spread's flux shares, so
    // that it receives exactly the energy the true beam loses (energy is then conserved exactly with the exact
    // direct beam).
    Real scattering_scale(Real mu_i, Workspace& ws) const {
        if (joint_mirror_) return mirror_scale(mu_i, ws);
        if (!direct_separated_ || modes_ == 0) return Real(1);
        const Real mu_t = top_face().internal_cosine(mu_i);
        if (!(mu_t > 0)) return Real(1);
        entry(mu_i, ws, 1);  // (mode 0)
        Real spread = 0, total = 0;
        for (std::size_t n = 0; n < q_.size(); ++n) {
            const Real share = q_.weights[n] * q_.nodes[n] * ws.c[n];  // mode-0 flux share (up to 1 / 2 pi)
            spread += share * direct_beam(q_.nodes[n], direct_tau_).extracted();
            total += share;
        }
        // The shares are Lagrange weights and may be negative; where the spread extracts less than half the
        // true beam's energy the scale is capped at 2, so that the spread's overshoot is not amplified.
        if (!(spread > 0)) return Real(1);
        return std::fmin(total * entering_beam(mu_i, mu_t, direct_tau_).extracted() / spread, Real(2));
    }

    // reflectance(mu_i).subsurface, whatever the outputs requested (ambient() is it by reciprocity).
    Real subsurface_reflectance(Real mu_i, Workspace& ws) const {
        if (beam_) return non_negative(flux_out(beam_field(mu_i, 1, ws).u.data(), exit_top_)) + direct(mu_i, false, direct_tau_);
        const Real scale = scattering_scale(mu_i, ws);  // (before the field: it computes its own entry)
        return non_negative(scale * flux_out(field(mu_i, false, ws, 1), exit_top_)) + direct(mu_i, false, direct_tau_);
    }

    // A specular top over refracting joints (joint_mirror_): the joints' mirror is taken out of the field as the
    // ordinates hold it, M_d (its flux out of the top), and added exactly, R_e, which near a critical cosine differ by
    // ~20% (1 | 1.5 | 0.9 over a rough bottom, M = 16: R + T up to 1.0167 for a non-absorbing stack; found by review).
    // The rest of the light, E - M_d of the flux E let in, is scaled to E - R_e: energy as the true mirror leaves it.
    Real mirror_scale(Real mu_i, Workspace& ws) const {
        const Real in = top_face().transmittance_from_outside(mu_i), exact = joint_mirror(mu_i, true);
        entry(mu_i, ws, 1);  // (mode 0)
        Real discrete = 0;  // M_d = mirror_flux_ . c
        for (std::size_t i = 0; i < q_.size(); ++i) discrete += mirror_flux_[i] * ws.c[i];
        const Real rest = in - discrete;
        return rest > 0 && in - exact > 0 ? (in - exact) / rest : Real(1);
    }

    // Flux leaving through a boundary from the mode-0 internal field: 2 pi sum_n w_n mu_n f_n tau(mu_n).
    Real flux_out(const Real* fld, const std::vector<Real>& exit) const {
        Real s = 0;
        for (std::size_t n = 0; n < q_.size(); ++n) s += q_.weights[n] * q_.nodes[n] * fld[n] * exit[n];
        return 2 * detail::pi_v<Real> * s;
    }

    Boundary<Real> top_, bottom_;
    // A number no other layer of the program has had (copies share it: they are the same layer), which keys what a
    // Workspace keeps for this layer (the last entry: entry()).
    std::uint64_t serial_ = detail::next_beam_serial();
    std::vector<Real> indices_;  // slab_indices()
    detail::SharedOperators<Real> top_ops_, bottom_ops_;  // null when nothing was solved; shared with PreparedBoundary
    bool bottom_turned_top_ = false;                       // bottom_ops_ is top_ops_ flipped (built with it)
    bool symmetric_ = false;  // one slab between a rough face and that face turned over: the same seen from below
    Quadrature<Real> q_;
    int modes_ = 0;
    LayerOutput outputs_ = LayerOutput::all;
    std::vector<detail::Matrix<Real>> qb_, qe_;           // per mode
    std::vector<ComponentOperators<Real>> whole_;         // per mode, if requested
    std::vector<Real> incidence_;
    std::vector<std::vector<Real>> cached_b_, cached_e_;  // per requested incidence: K blocks of M
    std::vector<std::vector<Real>> cached_c_;  // and its entry, where the exact pass needs it (with_exact_pass)
    std::vector<Real> cached_surface_;                    // per requested incidence: the top's reflectance
    std::vector<Real> exit_top_, exit_bottom_;            // hemispherical transmittance out of the layer per ordinate
    bool direct_separated_ = false;                       // specular top and bottom: unscattered beam kept apart
    // A specular top over refracting joints and a rough bottom: the joints' specular reflection kept apart
    // (separate_joint_mirror), and what joint_mirror needs: the joints and the slabs' scaled and true thicknesses.
    bool joint_mirror_ = false;
    std::vector<SmoothDielectric<Real>> mirror_joints_;
    std::vector<Real> mirror_eta_, mirror_scaled_tau_, mirror_true_tau_;  // per slab
    // the flux out of the top of mode 0 of the part of Q_b taken out, per unit entry at each ordinate (mirror_scale)
    std::vector<Real> mirror_flux_;
    bool first_pass_exact_ = false;  // one face rough, the other specular: the BTDF's first pass exact (with_exact_pass)
    bool first_reflection_exact_ = false;  // a specular top over a rough bottom: the BRDF's pass reflected once by it exact
    // The slabs those passes cross, in columns between the joints that refract (one where none does): each column's
    // delta-M scaled thickness and e^{-tau / mu_m} per ordinate, and the refracting joints with the solve's operators.
    std::vector<Real> pass_tau_;
    std::vector<std::vector<Real>> pass_d_;
    std::vector<SmoothDielectric<Real>> pass_joints_;
    std::vector<detail::SharedOperators<Real>> pass_joint_ops_;
    std::vector<detail::Matrix<Real>> pass_down_, pass_reflected_;  // per mode, across refracting joints (compose_passes)
    bool aliased_ = false;  // a slab's phase function was aliased on the ordinates (regularized: slab.hpp)
    Real direct_tau_ = 0;                                 // its optical thickness (delta-M scaled), as solved
    Real beam_tau_ = 0;                                   // the slab's true optical thickness
    // The transmittance of light arriving from outside (Face::transmittance_from_outside), shared with a
    // PreparedBoundary when solved from one.
    std::shared_ptr<const detail::EntryTransmittance<Real>> top_entry_, bottom_entry_;
    // LayerRequest::tabulate_faces: the couplings of the top for light entering and leaving, of the bottom for light
    // leaving; empty where not tabulated.
    detail::CouplingTable<Real> couplings_[3];
    bool faces_tabulated_ = false;
    std::shared_ptr<detail::CouplingCache<Real>> top_cache_, bottom_cache_;  // a prepared face's tables (or null)
    std::vector<Real> ambient_field_;                     // mode-0 up-going field under a uniform sky
    // Per requested depth: its optical depth (true and as solved) and the mode-0 operators from the coefficients
    // entering below the top (c) to the down- and up-going radiance there.
    struct DepthOperators {
        Real depth, scaled_depth;
        detail::Matrix<Real> down, up;
    };
    std::vector<DepthOperators> depth_ops_;
    // Per requested depth, between specular faces (beam_): the slab cut there into A (above) and B (below), each
    // with its beam source (mode 0), R and T, and the LU factors of I - R_A R_B (depth_profile).
    struct BeamDepth {
        Real depth, scaled_depth;  // from the top of the layer; from the top of its slab, delta-M scaled
        std::size_t slab = 0;      // the slab it lies in
        detail::SlabBeam<Real> above, below;
        detail::Matrix<Real> r_a, t_a, r_b, t_b;
        detail::LU<Real> lu;
    };
    std::vector<BeamDepth> beam_depths_;
    // Between specular faces around one slab: the beam as a source (null otherwise), and the fields of the
    // requested incidences.
    std::shared_ptr<detail::BeamSolution<Real>> beam_;
    std::vector<detail::BeamField<Real>> cached_beam_;
};

template <class Real>
LayeredSurface<Real> solve_stack(const detail::non_deduced_t<Boundary<Real>>& top, const std::vector<Slab<Real>>& slabs,
                                 const std::vector<Boundary<Real>>& interior,
                                 const detail::non_deduced_t<Boundary<Real>>& bottom, const LayerOptions& options,
                                 const detail::non_deduced_t<LayerRequest<Real>>& request) {
    return LayeredSurface<Real>::solve(top, slabs, interior, bottom, options, request, {});
}

namespace detail {

/// gauss_legendre_half(n) computed once per n (n <= 256) and copied from then on: each rule costs about 1 us at
/// n = 8 (its nodes to an ulp, by Newton's method), 10% of a flux solve at M = 8. Thread-safe.
template <class Real>
Quadrature<Real> shared_gauss_legendre_half(int n) {
    constexpr int cached = 256;
    if (n < 1 || n > cached) return gauss_legendre_half<Real>(n);
    static std::once_flag once[cached + 1];
    static Quadrature<Real> rules[cached + 1];
    const auto i = static_cast<std::size_t>(n);
    std::call_once(once[i], [i, n] { rules[i] = gauss_legendre_half<Real>(n); });
    return rules[i];
}

/// Whether a rough top's facets spread the directions at every critical cosine inside the slab (its own, for light
/// going up through it, and the bottom's), about sigma sin(theta_c) in cosine, over at least half the spacing of the
/// half-range rule's ordinates around it (as LayeredSurface::sharp_critical_cosine judges it): then the ordinates may
/// be split there. A nearly specular top stays on one rule, where the beam's spread over the ordinates keeps to the
/// sharp cuts (split, such tops leaked trapped light and created energy, up to R + T = 1.10 at 7 ordinates:
/// tests/test_layer_inputs.cpp).
template <class Real>
bool blurs_critical_cosines(const Boundary<Real>& top, const Boundary<Real>& bottom, int m) {
    const Quadrature<Real> plain = shared_gauss_legendre_half<Real>(m);
    for (const Real r : {top.eta_above() / top.eta_below(), bottom.eta_below() / bottom.eta_above()}) {
        if (!(r < 1)) continue;  // no critical cosine inside
        const Real cut = std::sqrt((Real(1) - r) * (Real(1) + r));
        if (top.rough_interface()->sigma() * std::sqrt((Real(1) - cut) * (Real(1) + cut)) < spacing_at(plain.nodes, cut) / 2)
            return false;
    }
    return true;
}

/// The layer's ordinates: the half-range Gauss rule of M points, or, for one slab (or slabs joined by smooth or
/// index-matched faces) under a specular top and over any face or a Lambertian floor, or (one slab, or slabs
/// joined by index-matched faces) under a rough top that blurs the critical cosines (blurs_critical_cosines) over a
/// specular face, with critical cosines inside
/// (LayerOptions::critical_split), Gauss rules on the panels between them: the panels below the larger critical
/// cosine mu_c share min(M/2, ceil(M mu_c)) points (at least one each), the escape cone [mu_c, 1] gets the rest
/// (with too few ordinates, no split); a panel of two or more points above a cut is ruled in s with
/// mu = a + width s^2 (3 - 2 s). Nodes ascending, weights summing to 1.
template <class Real>
Quadrature<Real> layer_quadrature(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior,
                                  const Boundary<Real>& bottom, const LayerOptions& options) {
    const int m = options.ordinates;
    // A rough top over a specular bottom (a rough coat on a smooth base) is split as well, unless the top is nearly
    // specular (blurs_critical_cosines); one half-range rule straddling the bottom's critical cosine left its fluxes
    // off by 0.025 at 16 ordinates and 0.013 at 32 against the photon Monte Carlo for Stam's top over a smooth base
    // (tests/test_layer_monte_carlo.cpp), by up to 0.078 over 16 random such layers (docs/accuracy.md).
    const bool rough_top = top.rough() && !bottom.lambertian() && !bottom.rough() && blurs_critical_cosines(top, bottom, m);
    // Slabs joined by refracting smooth faces (under a specular top) share this rule, split at every face's critical
    // cosine in the denser slab beside it (the union over the slabs): one half-range rule left glass over tissue
    // (1 | 1.5 | 1.4 | 1) off by up to 1.1e-2 at M = 16 against the photon Monte Carlo and converging erratically,
    // the split rule by 1.7e-3 (tests/test_layer_stack.cpp). Where it aliases a peaked phase function, solve()
    // falls back to one rule.
    // A specular top over a rough bottom is split at the bottom's critical cosine as well: over 24 random such layers
    // (RMS slope 1e-3 to 1) against the photon Monte Carlo, mean and worst error at M = 16 1.6e-3 and 1.8e-2 (one
    // rule: 5.2e-3, 5.5e-2), at M = 32 7.2e-4 and 4.4e-3 (1.9e-3, 8.3e-3) (docs/accuracy.md).
    bool eligible = options.critical_split && (!top.rough() || rough_top) && !top.lambertian() &&
                    (!bottom.rough() || !top.rough());
    for (const Boundary<Real>& b : interior)
        eligible = eligible && !b.rough() && !b.lambertian() && (!top.rough() || b.eta_above() == b.eta_below());
    if (!eligible) return shared_gauss_legendre_half<Real>(m);
    // A cut only where the ordinates resolve it: at least half the half-range rule's spacing there from 0 (and, for
    // a joint, from 1). A nearly matched joint (index ratio 1 + 1e-12: a cut at 1.4e-6) took a share of the points
    // for a cone that holds no light, and the layer jumped by 2.9e-2 from the matched one at 8 ordinates (now
    // 2.5e-3, the size of the discretization error there; 4.3e-4 at 12, 5.2e-5 at 16: tests/test_layer_stack.cpp);
    // a nearly matched bottom face (1.4 | 1.4 (1 - 1e-12)) took 4 of 16 ordinates there, and a semi-infinite
    // layer's BRDF, which that face cannot touch, came out 0.52 instead of 0.27 (found by review; test_layer_inputs).
    // Where a cut crosses the limit the rule changes, and the layer jumps by the size of its discretization error
    // (a bottom 1.4 | 1.4 r at r = 0.99916, 8 ordinates: the BRDF by 29%, both sides 15-20% from the value at 64
    // ordinates; found by the next review).
    // (Dropping a cut within that distance of another cut as well cost 4e-3 against the photon Monte Carlo at 16
    // ordinates for 1 | 1.4 | 1.2 | 1.)
    const Quadrature<Real> plain = shared_gauss_legendre_half<Real>(m);
    std::vector<Real> cuts;  // critical cosines inside the slabs: sqrt(1 - (n_out / n_in)^2) where n_out < n_in
    std::vector<Real> ratios{top.eta_above() / top.eta_below()};
    if (!bottom.lambertian()) ratios.push_back(bottom.eta_below() / bottom.eta_above());
    for (const Real r : ratios) {
        const Real cut = std::sqrt((1 - r) * (1 + r));
        if (r < 1 && cut > spacing_at(plain.nodes, cut) / 2) cuts.push_back(cut);
    }
    for (const Boundary<Real>& b : interior) {  // (the denser side's)
        const Real r = std::fmin(b.eta_above(), b.eta_below()) / std::fmax(b.eta_above(), b.eta_below());
        if (!(r < 1)) continue;
        const Real cut = std::sqrt((1 - r) * (1 + r)), half = spacing_at(plain.nodes, cut) / 2;
        if (cut > half && 1 - cut > half) cuts.push_back(cut);
    }
    // Over a Lambertian floor (no critical cosine of its own) the floor's diffuse light meets the top's escape cone,
    // the invariant n sin(theta) = n_above of the top, in every slab: its Snell image there is a cut too. Without
    // them R of 1 | 1.5 | 1.4 | 1.38 over a floor wandered over 1.6e-2 from M = 8 to 48, with them over 3.2e-3;
    // against the photon Monte Carlo within 2e-3 at M = 16 and 32, where it was off by up to 6.8e-3
    // (tests/test_layer_stack.cpp). (Over a specular bottom the same images did not help: mixed against the photon
    // Monte Carlo, worse at M = 32 for three slabs.)
    if (bottom.lambertian() && top.eta_above() < top.eta_below())
        for (const Boundary<Real>& b : interior) {
            const Real s = top.eta_above() / b.eta_below();  // sine of the image in the slab below the joint
            if (!(s < 1)) continue;
            const Real image = std::sqrt((1 - s) * (1 + s)), half = spacing_at(plain.nodes, image) / 2;
            if (image > half && 1 - image > half) cuts.push_back(image);
        }
    std::sort(cuts.begin(), cuts.end());
    cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
    const int panels = static_cast<int>(cuts.size()) + 1;
    if (panels == 1 || m < panels) return shared_gauss_legendre_half<Real>(m);
    std::vector<Real> edges{Real(0)};
    edges.insert(edges.end(), cuts.begin(), cuts.end());
    edges.push_back(Real(1));
    // The lower panels share min(M/2, ceil(M mu_c)) points (at least one each): half when the trapped cone is wide,
    // few when it is narrow (nearly matched indices), where the escape cone needs them.
    const int below = std::max(panels - 1, std::min(m / 2, static_cast<int>(std::ceil(Real(m) * cuts.back()))));
    const int top_points = m - below;
    if (top_points < 1) return shared_gauss_legendre_half<Real>(m);
    Quadrature<Real> q;
    for (int p = 0; p < panels; ++p) {
        const int points = p == panels - 1 ? top_points : below / (panels - 1) + (p < below % (panels - 1) ? 1 : 0);
        const Quadrature<Real> g = shared_gauss_legendre_half<Real>(points);
        const Real a = edges[static_cast<std::size_t>(p)], width = edges[static_cast<std::size_t>(p + 1)] - a;
        // Above a critical cosine F ~ 1 - c sqrt(mu - mu_c): the panel is ruled in s with mu = a + width s^2 (3 - 2s)
        // (dmu = 6 width s (1 - s) ds), in which that is smooth near s = 0, and which also gathers points towards the
        // panel's top, mu = 1 for the escape cone, where a forward peak scatters a beam at normal incidence.
        // Measured against adding-doubling (12 Fresnel slabs at normal incidence, 12 oblique; the beam exact at its
        // angle), worst error at M = 16 / 24 / 32 / 48: plain Gauss on the panel 2.1e-4 / 6.5e-5 / 2.9e-5 / 9.1e-6;
        // s = sqrt((mu - a) / width) 3.8e-3 / 1.2e-3 / 3.8e-5 / 3.7e-6 (it thins the points at mu = 1); this map
        // 6.2e-4 / 5.1e-5 / 1.0e-5 / 4.2e-7, and all but g = 0.9 at normal incidence within 3.6e-5 / 9e-7 / 2e-8 /
        // 1.2e-8 (adding-doubling's own accuracy; docs/physics.md section 6).
        // (One point integrates the map's quadratic Jacobian wrongly: sum of weights 1.5 width. That panel stays in mu.)
        const bool graded = p > 0 && points > 1;
        for (std::size_t i = 0; i < g.size(); ++i) {
            const Real s = g.nodes[i];
            q.nodes.push_back(graded ? a + width * s * s * (3 - 2 * s) : a + width * s);
            q.weights.push_back(graded ? 6 * width * s * (1 - s) * g.weights[i] : width * g.weights[i]);
        }
    }
    return q;
}

/// Every scattering slab needs an ordinate inside its escape cone: where the light it scatters can leave, up or down,
/// through the specular faces on the way (n sin(theta) below every index up to the outside or to a rough face, which
/// lets any direction through; a Lambertian floor lets none out). On one half-range rule (`critical_split = false`,
/// or a stack kept on one rule) every ordinate could lie in the trapped cone: 1 | 2.2753 | 1, lossless, at 2 and 3
/// ordinates gave R + T 0.15, 1 | 3.492 | 1.837 | 3.859 | 1 at 5 0.31 (found by review). Refused
/// (std::invalid_argument). Checked on one half-range rule only: on a split rule a slab's escape cone need not start
/// at a cut, yet the joints' spread lets its light out (energy kept over the random stacks of tests/test_layer_stack.cpp).
template <class Real>
void require_escape_cones(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                          const Quadrature<Real>& q, const std::vector<Slab<Real>>& slabs) {
    const std::size_t faces = interior.size() + 2;
    const auto face = [&](std::size_t k) -> const Boundary<Real>& {
        return k == 0 ? top : (k == faces - 1 ? bottom : interior[k - 1]);
    };
    for (std::size_t j = 0; j < slabs.size(); ++j) {
        if (!(slabs[j].optical_thickness() > 0) || !(slabs[j].albedo() > 0)) continue;
        const Real n = face(j).eta_below();
        const auto cut = [n](Real lowest) {
            const Real r = lowest / n;
            return r < 1 ? std::sqrt((1 - r) * (1 + r)) : Real(0);
        };
        Real lowest = n, need_up = 0, need_down = 2;  // (2: no way out)
        bool open = false;
        for (std::size_t k = j + 1; k-- > 0 && !open;) {
            if (face(k).rough()) open = true;
            else lowest = std::fmin(lowest, face(k).eta_above());
        }
        need_up = open ? Real(0) : cut(lowest);
        lowest = n;
        open = false;
        bool floor = false;
        for (std::size_t k = j + 1; k < faces && !open && !floor; ++k) {
            if (face(k).lambertian()) floor = true;
            else if (face(k).rough()) open = true;
            else lowest = std::fmin(lowest, face(k).eta_below());
        }
        if (!floor) need_down = open ? Real(0) : cut(lowest);
        const Real need = std::fmin(need_up, need_down);
        if (!(q.nodes.back() > need))
            fail_invalid_argument("stratum: options.ordinates = " + std::to_string(q.size()) + ": no ordinate of slab " +
                                  std::to_string(j) + " lies in its escape cone (mu > " + std::to_string(need) +
                                  "): the light it scatters could not leave; use more ordinates (or the critical split)");
    }
}

/// One ordinate (mu = 0.5) inside the cone that a smooth top, bottom or joint traps by total internal reflection
/// (critical cosine above 0.5: index ratio above 1.155) holds all the scattered light, and none crosses that face:
/// under a 1 | 1.4 top a lossless slab reflected nothing (R + T 0.072 at tau = inf, a fluence of 2e16 inside at tau 1),
/// a slab between two such joints kept its light (R + T 0.135; found by review sweeps). Refused (std::invalid_argument),
/// as no placement of one ordinate represents both the trapped and the escaping light; two split at the critical
/// cosine do. (Also where the light could still leave the other way, e.g. a joint above an open bottom, whose
/// reflection is then wrong though energy is kept.)
template <class Real>
void require_escape(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                    const Quadrature<Real>& q, const std::vector<Slab<Real>>& slabs) {
    if (q.size() != 1) {  // (on a split rule the joints' spread lets such light out: 60 random stacks at 5 to 7)
        if (q.nodes == shared_gauss_legendre_half<Real>(static_cast<int>(q.size())).nodes)
            require_escape_cones(top, interior, bottom, q, slabs);
        return;
    }
    const auto check = [&](const Boundary<Real>& face, Real r, const std::string& name) {
        if (face.rough() || face.lambertian() || !(r < 1)) return;
        const Real cut = std::sqrt((1 - r) * (1 + r));
        if (q.nodes[0] < cut)
            fail_invalid_argument("stratum: options.ordinates = 1 puts its one ordinate (mu " + std::to_string(q.nodes[0]) +
                                  ") in the cone that the " + name + " face traps (critical cosine " +
                                  std::to_string(cut) + "): no scattered light could cross that face; use 2 or more");
    };
    check(top, top.eta_above() / top.eta_below(), "top");
    check(bottom, bottom.eta_below() / bottom.eta_above(), "bottom");
    for (std::size_t i = 0; i < interior.size(); ++i)  // (a joint traps the light of the denser slab beside it)
        check(interior[i], std::fmin(interior[i].eta_above(), interior[i].eta_below()) /
                               std::fmax(interior[i].eta_above(), interior[i].eta_below()),
              "interior[" + std::to_string(i) + "]");
}

/// The fewest ordinates a stack takes: slabs joined by a refracting specular face (smooth, indices differing), one of
/// them scattering, need 5, and one more than the stack's distinct critical cosines (each face's, on its denser side)
/// where that is more; 1 otherwise. With fewer, the critical cosines leave more panels than ordinates
/// (layer_quadrature falls back to one rule) or the split gives a dense slab no ordinate the joints let out, and light
/// scattered there was trapped: of lossless stacks with smooth faces, R + T 0.36 of 1 at 2 ordinates
/// (1 | 1.1 | 1.8 | 1.1 | 1, tau 1 each; the BRDF 1.3e14), 0.65 at 4 with a dense film among the slabs, 0.29 at 5
/// for 1 | 3.334 | 1.747 | 3.733 | 3.602 | 1 (five cuts), 0.46 at 6 for a stack of six slabs with seven, 0.30 at 5
/// over a white floor whose escape-cone images layer_quadrature cuts as well, now counted (found by reviews). Over 1600 random stacks (2 to 4 slabs, indices 1 to 2.6, tau 0 to 10, smooth or rough top, a floor or
/// not, double and float) R + T failed at 4 ordinates in 6 and at none of 5, 6 and 7 (tests/test_layer_stack.cpp).
template <class Real>
int minimum_ordinates(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                      const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom) {
    bool refracting = false, scattering = false;
    for (const Boundary<Real>& b : interior)
        refracting = refracting || (!b.rough() && !b.lambertian() && b.eta_above() != b.eta_below());
    for (const Slab<Real>& s : slabs) scattering = scattering || (s.albedo() > 0 && s.optical_thickness() > 0);
    if (!refracting || !scattering) return 1;
    // The critical cosines inside the slabs as layer_quadrature takes them (before its spacing filter): the top's and
    // the bottom's where the outside is less dense, each joint's on its denser side.
    std::vector<Real> cuts;
    const auto add = [&cuts](Real r) {
        if (r < 1) cuts.push_back(std::sqrt((1 - r) * (1 + r)));
    };
    add(top.eta_above() / top.eta_below());
    for (const Boundary<Real>& b : interior) add(std::fmin(b.eta_above(), b.eta_below()) / std::fmax(b.eta_above(), b.eta_below()));
    if (!bottom.lambertian()) add(bottom.eta_below() / bottom.eta_above());
    if (bottom.lambertian() && top.eta_above() < top.eta_below())  // (the top's escape cone in every slab, as
        for (const Boundary<Real>& b : interior) {                 // layer_quadrature cuts it over a floor)
            const Real s = top.eta_above() / b.eta_below();
            if (s < 1) cuts.push_back(std::sqrt((1 - s) * (1 + s)));
        }
    std::sort(cuts.begin(), cuts.end());
    const auto distinct = std::unique(cuts.begin(), cuts.end()) - cuts.begin();
    return std::max(5, static_cast<int>(distinct) + 1);
}

/// Refuses (std::invalid_argument) fewer ordinates than minimum_ordinates.
template <class Real>
void require_ordinates_for_joints(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                  const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                                  int ordinates) {
    const int needed = minimum_ordinates(top, slabs, interior, bottom);
    if (ordinates >= needed) return;
    fail_invalid_argument("stratum: options.ordinates = " + std::to_string(ordinates) +
                          " is too few for slabs joined by a refracting face: light scattered in a slab could be "
                          "trapped; this stack needs " + std::to_string(needed) + " or more");
}

/// Whether some slab lets through less than 4 eps of any light falling on it, by the diffusion bound for a lossless
/// slab, T <= 1 / (1 + (3/4) (1 - g) tau) (absorption and delta-M, which keeps (1 - g) tau or raises it, only
/// lower T).
template <class Real>
bool opaque(const std::vector<Slab<Real>>& slabs) noexcept {
    for (const Slab<Real>& slab : slabs)
        if (Real(0.75) * (1 - slab.g()) * slab.optical_thickness() > 1 / (4 * std::numeric_limits<Real>::epsilon()))
            return true;
    return false;
}

/// The first slab of a stack that is nothing, or slabs.size() if none: optical thickness 0 (or, without requested
/// depths, below sqrt(eps) times the smallest ordinate: its effect is O(tau)) and index-matched joints on both sides
/// inside the stack: dropped with a joint, the result is the stack without it, exactly. (With depths requested, a
/// slab of 0 < tau < that limit is kept, so that the depths keep their meaning.)
template <class Real>
std::size_t empty_slab(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                       const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                       const LayerOptions& options, bool depths) {
    if (slabs.size() < 2) return slabs.size();
    const Real thin = std::sqrt(std::numeric_limits<Real>::epsilon()) * layer_quadrature(top, interior, bottom, options).nodes.front();
    const auto matched = [&](std::size_t j) { return interior[j].eta_above() == interior[j].eta_below(); };
    for (std::size_t i = 0; i < slabs.size(); ++i) {
        const Real tau = slabs[i].optical_thickness();
        const bool negligible = tau == 0 || (!depths && tau < thin);
        if (negligible && (i == 0 || matched(i - 1)) && (i + 1 == slabs.size() || matched(i))) return i;
    }
    return slabs.size();
}

}  // namespace detail

// The method (see the top of this file), in its steps:
//  1. check the input and count the modes to solve (none for the surface reflection alone);
//  2. the boundaries' operators on the ordinates, and the stack below the top prepared for the adding: delta-M
//     scaled slabs with their phase matrices, the interior faces' operators (detail::prepare_stack);
//  3. tau(mu_m), the transmittance out of the layer through each face at each ordinate (reflectance, transmittance);
//  4. per mode, everything below the top by the adding equations, then the internal-field operators Q_b and Q_e
//     (solve_modes);
//  5. the ambient field under a uniform sky, from Q_b of mode 0 (solve_ambient);
//  6. between two specular faces, the unscattered beam taken out of Q_b and Q_e, to be added back exactly at the
//     true angle (separate_direct_beam);
//  7. the internal fields of the requested incidences (precompute_incidences; their surface reflectance in step 1).
template <class Real>
std::optional<LayeredSurface<Real>> LayeredSurface<Real>::solve_simpler(
    const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs, const std::vector<Boundary<Real>>& interior,
    const Boundary<Real>& bottom, const LayerOptions& options, const LayerRequest<Real>& request,
    const detail::PreparedOperators<Real>& prepared) {
    // An empty slab between index-matched joints is nothing: solved without it (detail::empty_slab).
    const std::size_t empty = detail::empty_slab(top, slabs, interior, bottom, options, !request.depths.empty());
    if (empty < slabs.size()) {
        const std::size_t joint = empty + 1 == slabs.size() ? empty - 1 : empty;  // the joint dropped with the slab
        std::vector<Slab<Real>> fewer_slabs = slabs;
        std::vector<Boundary<Real>> fewer_joints = interior;
        detail::PreparedOperators<Real> fewer_prepared = prepared;
        fewer_slabs.erase(fewer_slabs.begin() + static_cast<std::ptrdiff_t>(empty));
        fewer_joints.erase(fewer_joints.begin() + static_cast<std::ptrdiff_t>(joint));
        if (!fewer_prepared.interior.empty())
            fewer_prepared.interior.erase(fewer_prepared.interior.begin() + static_cast<std::ptrdiff_t>(joint));
        return solve(top, fewer_slabs, fewer_joints, bottom, options, request, fewer_prepared);
    }
    // A floor under slabs that let through less than 4 eps of the light changes what leaves the top by less than
    // that, but a bright floor under a (nearly) lossless slab makes the floor's coupling singular to rounding: a
    // non-absorbing slab of tau 3e16 over a white floor gave R = 7e259 (float: 8e17 at tau 1e8, g 0.8; found by a
    // review sweep). Such a floor is solved as a black one (bottom() then says so). Fields at depth, which the floor's
    // trapped light reaches, cannot be had so: refused (they came out with the reflectance itself broken, R = 3e16
    // in float at tau 1e8 over a white floor; found by review).
    if (bottom.lambertian() && bottom.floor_albedo() > 0 && detail::opaque(slabs) && !request.depths.empty())
        detail::fail_invalid_argument("stratum: request.depths over a Lambertian floor of albedo > 0 under a slab that "
                                      "lets through less than 4 eps of the light (diffusion bound): the floor's coupling "
                                      "is singular to rounding; solve without depths (the floor then acts as black), "
                                      "or in a wider floating type");
    if (bottom.lambertian() && bottom.floor_albedo() > 0 && detail::opaque(slabs)) {
        detail::PreparedOperators<Real> without_floor = prepared;  // (a prepared floor's operators are the bright one's)
        without_floor.bottom = nullptr;
        without_floor.bottom_entry = nullptr;
        without_floor.bottom_exit.clear();
        without_floor.bottom_couplings = nullptr;
        return solve(top, slabs, interior, Boundary<Real>::lambertian(Real(0), bottom.eta_above()), options, request,
                     without_floor);
    }
    return std::nullopt;
}

template <class Real>
LayeredSurface<Real> LayeredSurface<Real>::solve(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                                 const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                                                 const LayerOptions& options, const LayerRequest<Real>& request,
                                                 const detail::PreparedOperators<Real>& prepared) {
    detail::validate_stack(top, slabs, interior, bottom, options, request);  // 1.
    if (std::optional<LayeredSurface> simpler = solve_simpler(top, slabs, interior, bottom, options, request, prepared))
        return std::move(*simpler);
    LayeredSurface s(top, bottom);
    s.indices_.push_back(top.eta_below());
    for (const Boundary<Real>& b : interior) s.indices_.push_back(b.eta_below());
    s.top_entry_ = prepared.top_entry ? prepared.top_entry
                                      : std::make_shared<const detail::EntryTransmittance<Real>>(top, Incidence::from_above);
    // A bottom face that is the top turned over lets light in from below as the top does from above (bit for bit).
    s.bottom_entry_ = prepared.bottom_entry ? prepared.bottom_entry
                      : detail::turned_over(top, bottom)
                          ? s.top_entry_
                          : std::make_shared<const detail::EntryTransmittance<Real>>(bottom, Incidence::from_below);
    s.outputs_ = request.outputs;
    s.top_cache_ = prepared.top_couplings;
    s.bottom_cache_ = prepared.bottom_couplings;
    s.q_ = detail::layer_quadrature(top, interior, bottom, options);
    s.incidence_ = request.incidence;
    if (includes(request.outputs, LayerOutput::surface_reflection))  // (an integral each for a rough face)
        for (const Real mu : s.incidence_) s.cached_surface_.push_back(top.hemispherical_reflectance(mu));
    const int modes = detail::mode_count(options, request);
    if (modes == 0) {
        if (request.tabulate_faces) s.tabulate_faces();  // (the top's reflectance alone: its entry table)
        return s;
    }
    detail::require_escape(top, interior, bottom, s.q_, slabs);
    detail::require_ordinates_for_joints(top, slabs, interior, bottom, options.ordinates);

    // 2. A rough face built here for a request with a tolerance gets the modes it is expected to need, and more if
    // the solve reaches them (extend_faces); prepared faces hold all.
    // Their integrals are no finer than the tolerance needs (integrals_for_tolerance).
    const int face_modes = detail::first_face_modes(request.tolerance, modes);
    const LayerOptions face_options = integrals_for_tolerance(options, request.tolerance);
    const auto face = [&](const Boundary<Real>& b, const detail::SharedOperators<Real>& ready) {
        return ready ? ready
                     : std::make_shared<const InterfaceOperators<Real>>(
                           b.operators(s.q_, b.rough() ? face_modes : modes, face_options));
    };
    s.top_ops_ = face(top, prepared.top);
    s.bottom_turned_top_ = !prepared.bottom && detail::turned_over(top, bottom);
    s.symmetric_ = slabs.size() == 1 && detail::turned_over(top, bottom);  // (prepared faces too: equal bit for bit)
    if (s.bottom_turned_top_)
        s.bottom_ops_ = std::make_shared<const InterfaceOperators<Real>>(s.top_ops_->flipped());  // (bit for bit)
    else
        s.bottom_ops_ = face(bottom, prepared.bottom);
    detail::PreparedStack<Real> stack =
        detail::prepare_stack(top, slabs, interior, bottom, s.q_, modes, options, request, prepared.interior);
    s.exit_top_ = prepared.top_exit.empty() ? s.top_face().transmittance_at_ordinates() : prepared.top_exit;  // 3.
    s.exit_bottom_ = prepared.bottom_exit.empty() ? s.bottom_face().transmittance_at_ordinates() : prepared.bottom_exit;
    if (detail::beam_is_a_source(top, interior, bottom) && detail::needs_beam_source(request))
        s.set_up_beam(top, slabs, interior, bottom, stack, modes, options);
    s.set_up_exact_passes(top, interior, bottom, stack, request.outputs);
    s.solve_modes(stack, modes, request.tolerance);  // 4.
    if (s.pass_d_.size() > 1) s.compose_passes();  // 4b.
    // A rule split at refracting joints (layer_quadrature) integrates a peaked phase function less exactly than one
    // half-range rule; where it aliases it, the beam would be spread over the ordinates and the unscattered beam
    // lost (1% of random two- and three-slab stacks with g up to 0.95 at M = 6 to 32): one rule then, as before
    // the split.
    if (s.aliased_ && options.critical_split && !interior.empty() &&
        s.q_.nodes != detail::shared_gauss_legendre_half<Real>(options.ordinates).nodes) {
        bool refracting = false;
        for (const Boundary<Real>& b : interior) refracting = refracting || b.eta_above() != b.eta_below();
        if (refracting) {
            LayerOptions one_rule = options;
            one_rule.critical_split = false;
            return solve(top, slabs, interior, bottom, one_rule, request, prepared);
        }
    }
    if (includes(request.outputs, LayerOutput::ambient) && !s.beam_) s.solve_ambient();  // 5. (specular faces: ambient())
    if (!request.depths.empty()) s.solve_depths(stack, slabs, options, request.depths);
    if (detail::beam_stays_on_its_ordinate(top, interior, bottom)) {  // 6.
        Real scaled_tau = 0, true_tau = 0;
        for (std::size_t i = 0; i < slabs.size(); ++i) {
            scaled_tau += stack.slabs[i].slab.optical_thickness();
            true_tau += slabs[i].optical_thickness();
        }
        s.separate_direct_beam(scaled_tau, true_tau);
    }
    if (detail::joints_mirror_the_beam(top, interior, bottom)) s.separate_joint_mirror(interior, slabs, stack);  // 6b.
    s.precompute_incidences();  // 7.
    if (request.tabulate_faces) s.tabulate_faces();  // 8.
    return s;
}

// Step 2 between specular faces (the beam a source): each slab's beam solution on the ordinates with its exact phase
// function, the faces' reflectances there, the joints, and the thicknesses the direct beam is attenuated by.
template <class Real>
void LayeredSurface<Real>::set_up_beam(const Boundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                       const std::vector<Boundary<Real>>& interior, const Boundary<Real>& bottom,
                                       const detail::PreparedStack<Real>& stack, int modes, const LayerOptions& options) {
    beam_ = std::make_shared<detail::BeamSolution<Real>>();
    Real scaled_tau = 0, true_tau = 0;
    for (std::size_t i = 0; i < slabs.size(); ++i) {
        const detail::SlabModes<Real>& p = stack.slabs[i];
        beam_->slabs.emplace_back(q_, p.slab.optical_thickness(),
                                  detail::PhaseAtOrdinates<Real>(p.moments, q_.nodes, q_.weights, modes));
        beam_->slabs.back().set_exact_phase(p.slab.albedo(), p.truncation, slabs[i].henyey_greenstein(), slabs[i].g(),
                                            slabs[i].phase_moments());
        scaled_tau += p.slab.optical_thickness();
        true_tau += slabs[i].optical_thickness();
    }
    for (const Real mu : q_.nodes) {
        beam_->r21.push_back(top.smooth_interface().reflectance(-mu));
        beam_->r23.push_back(bottom.lambertian() ? Real(0) : bottom.smooth_interface().reflectance(mu));
    }
    if (bottom.lambertian()) beam_->floor = bottom.floor_albedo();
    beam_->identity_system = slabs.size() == 1 && !(beam_->floor > 0);
    for (std::size_t i = 0; i < q_.size(); ++i)
        beam_->identity_system = beam_->identity_system && beam_->r21[i] == 0 && beam_->r23[i] == 0;
    beam_->single_scattering = options.single_scattering_correction;
    beam_->eta.push_back(top.eta_below());
    for (const Boundary<Real>& b : interior) {
        beam_->joints.push_back(b.smooth_interface());
        beam_->eta.push_back(b.eta_below());
        beam_->refracting = beam_->refracting || b.eta_above() != b.eta_below();
    }
    for (const Slab<Real>& slab : slabs) beam_->true_tau.push_back(slab.optical_thickness());
    // The unscattered beam out of a refracting stack is direct_*: what its joints reflect back out through the
    // top, and what leaves through a specular bottom (over a Lambertian floor, reflection alone: the floor makes
    // the rest diffuse). (Over a floor it was left out, and a non-absorbing stack lost the joints' specular
    // reflection: R = 0.99973 for 1 | 1.5 | 1.4 over a white floor, tests/test_layer_stack.cpp.)
    if (beam_->refracting) direct_separated_ = true;
    direct_tau_ = scaled_tau;
    beam_tau_ = std::isinf(scaled_tau) ? scaled_tau : true_tau;
}

// Step 8 (LayerRequest::tabulate_faces): the entry tables, and the couplings of the faces that light enters and
// leaves by for the outputs requested, where a face is rough and light crosses from the less dense side (the
// integrals keep the onset at a critical cosine exactly).
template <class Real>
void LayeredSurface<Real>::tabulate_faces() {
    faces_tabulated_ = true;
    const bool fields = detail::needs_reflected(outputs_) || detail::needs_transmitted(outputs_);
    const bool out_top = includes(outputs_, LayerOutput::subsurface_reflection);
    const bool out_bottom = includes(outputs_, LayerOutput::transmission) && !bottom_.lambertian();
    top_entry_->prepare(includes(outputs_, LayerOutput::surface_reflection));  // (light in, out through the top)
    if (out_bottom) bottom_entry_->prepare(false);                               // (out through the bottom)
    if (modes_ == 0) return;
    const Face top = top_face(), bottom = bottom_face();
    const auto tabulable = [](const Face& f) { return f.rough() && !(f.eta_outside() > f.eta_inside()); };
    const bool turned = detail::turned_over(top_, bottom_);
    if (tabulable(top) && fields) couplings_[0] = coupling_table_for(top, Crossing::entering);
    if (tabulable(top) && (out_top || (out_bottom && turned))) {
        // Light leaving through the top: the entering light's table times (n_1 / n_2)^2 where the BTDF is reciprocal.
        if (top_.rough_interface()->shadowing() != Shadowing::masking_only) {
            const Real n = top.eta_outside() / top.eta_inside();
            couplings_[1] = couplings_[0];
            couplings_[1].scale = n * n;
        } else {
            couplings_[1] = coupling_table_for(top, Crossing::leaving);
        }
    }
    if (tabulable(bottom) && out_bottom) couplings_[2] = turned ? couplings_[1] : coupling_table_for(bottom, Crossing::leaving);
    if (!out_top) couplings_[1] = {};
}

// One face's table for light crossing it the given way: kept with a prepared face (built, with all its operators'
// modes, by the first solve that asks for it, and reused by the next), or built for this solve's modes.
template <class Real>
detail::CouplingTable<Real> LayeredSurface<Real>::coupling_table_for(const Face& face, Crossing c) const {
    const std::shared_ptr<detail::CouplingCache<Real>>& cache = face.bottom ? bottom_cache_ : top_cache_;
    if (!cache) return tabulate_couplings(face, c, modes_);
    const std::size_t i = face.bottom ? 2 : c == Crossing::entering ? 0 : 1;
    std::call_once(cache->once[i], [&] { cache->table[i] = tabulate_couplings(face, c, face.ops().modes()); });
    return cache->table[i];
}

// One face's couplings (`modes` of them) for light crossing it the given way, at the table's nodes by their
// integrals; the table is
// kept where it agrees with the integrals (CouplingTable::limit) at the midpoints of every eighth interval from the
// third on (16 points; the first two intervals, whose stencils would reach the limit mu -> 0+, keep the integrals).
template <class Real>
detail::CouplingTable<Real> LayeredSurface<Real>::tabulate_couplings(const Face& face, Crossing c, int modes) const {
    using Table = detail::CouplingTable<Real>;
    const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes), width = (m + 1) * kk;
    Workspace ws;
    const auto direct = [&](Real mu) {
        couplings(face, c, mu, face.internal_cosine(mu), modes, ws);  // (no table yet: the integrals)
        return ws.row;
    };
    auto table = std::make_shared<detail::MuTable<Real>>();
    table->arcsine = true;
    table->build(Table::intervals, static_cast<int>(width), [&](Real mu, Real* out) {
        const std::vector<Real> row = direct(mu);
        std::copy(row.begin(), row.end(), out);
    });
    Table t;
    t.modes = modes;
    t.grazing = table->cosine(Real(2) / Real(Table::intervals));
    std::vector<Real> interpolated(width);
    for (int j = 2; j < Table::intervals; j += 8) {
        const Real mu = table->cosine((Real(j) + Real(0.5)) / Real(Table::intervals));
        const std::vector<Real> exact = direct(mu);
        table->interpolate(mu, interpolated.data(), static_cast<int>(width));
        Real flux = 0, error = 0;
        for (std::size_t i = 0; i < m; ++i) {
            const Real w = q_.weights[i] * q_.nodes[i];
            flux += w * std::fabs(exact[i * kk]);
            for (std::size_t k = 0; k < kk; ++k) error += w * std::fabs(interpolated[i * kk + k] - exact[i * kk + k]);
        }
        t.error = std::fmax(t.error, flux > 0 ? error / flux : error);
    }
    if (t.error <= Table::limit) t.table = std::move(table);
    return t;
}

// Step 4: modes 0, 1, ... up to `modes`: mode k of everything below the top face (detail::stack_mode), its Q_b and
// Q_e (add_field_operators) and, when requested, the whole layer's operators. With a tolerance, mode k is
// negligible when the BRDF and BTDF Fourier coefficients it adds are each below tolerance relative to mode 0's
// (coefficient_size); through specular boundaries only, the unscattered beam is a delta that no number of modes
// represents, so the slabs' diffuse operators are measured instead. The loop stops after two consecutive
// negligible modes.
template <class Real>
void LayeredSurface<Real>::solve_modes(detail::PreparedStack<Real>& stack, int modes, Real tolerance) {
    // Where the beam is a source, the fields and fluxes come from the slabs' own solutions (add_beam_mode): the
    // adding of the stack and Q_b, Q_e serve only the ambient term and the whole layer's operators.
    bool slabs_only = beam_ && !includes(outputs_, LayerOutput::ambient) && !includes(outputs_, LayerOutput::operators);
    std::array<Real, 2> size0{Real(0), Real(0)};  // mode 0's sizes, reflected and transmitted (coefficient_size)
    std::array<std::size_t, 2> size_column{0, 0};  // the columns where mode 0's sizes were found
    int negligible = 0;  // consecutive negligible modes
    for (int k = 0; k < modes; ++k) {
        if (k >= top_ops_->modes() || k >= bottom_ops_->modes()) extend_faces(modes);
        detail::extend_phase_modes(stack, q_, k + 1);
        std::vector<detail::SlabModeSolution<Real>> solved;
        std::optional<detail::StackMode<Real>> below;
        Real slab_size = 0;
        if (slabs_only) {
            for (const detail::SlabModes<Real>& p : stack.slabs) {
                solved.push_back(detail::slab_mode_solution(p.slab, q_, p.phase.same_k(k), p.phase.opposite_k(k), k, true));
                if (!(tolerance > 0)) continue;  // (the size serves the mode cut alone)
                const Real tau = p.slab.optical_thickness();
                slab_size = std::fmax(slab_size, detail::diffuse_size(slab_component(detail::slab_mode_operators(solved.back(), q_, tau)),
                                                                      q_.nodes, tau));
            }
        } else {
            below = detail::stack_mode(stack, *bottom_ops_, q_, k, beam_ ? &solved : nullptr,
                                       includes(outputs_, LayerOutput::operators) && !symmetric_);
            slab_size = below->slab_size;
        }
        // An aliased phase function (regularized operators: slab.hpp) does not scatter the beam as it scatters the
        // ordinates, and energy would not be conserved: the beam is spread over the ordinates instead (solve()), and
        // the modes solved so far without the adding are solved again with it.
        bool aliased = false;
        for (const detail::SlabModeSolution<Real>& x : solved) aliased = aliased || x.eigen.regularized;
        aliased_ = aliased_ || aliased;
        if (beam_ && aliased) {
            if (beam_->refracting) direct_separated_ = false;  // (the spread keeps the beam in the field there)
            beam_.reset();
            if (slabs_only) {
                slabs_only = false;
                size0 = {Real(0), Real(0)};
                negligible = 0;
                modes_ = 0;
                k = -1;
                continue;
            }
        }
        if (beam_) add_beam_mode(k, std::move(solved), stack);
        if (below) add_field_operators(k, *below);
        modes_ = k + 1;
        if (!(tolerance > 0)) continue;
        const Real none = std::numeric_limits<Real>::infinity();
        const std::array<Real, 2> exceeds = k == 0 ? std::array<Real, 2>{none, none}
                                                   : std::array<Real, 2>{tolerance * size0[0], tolerance * size0[1]};
        const std::array<Real, 2> size = stack.any_rough ? coefficient_size(k, below->bottom, exceeds, size_column)
                                                         : std::array<Real, 2>{slab_size, Real(0)};
        if (k == 0) size0 = size;
        negligible = (k > 0 && size[0] <= tolerance * size0[0] && size[1] <= tolerance * size0[1]) ? negligible + 1 : 0;
        if (negligible == 2) break;
    }
}

// Step 4, when the loop reaches a mode beyond those of a rough face built for a tolerance (detail::first_face_modes):
// the face's operators for all `modes`, without its hemispherical integrals again (InterfaceOperators::with_modes).
// The modes solved so far keep the first operators (equal within 2e-10 of an entry).
template <class Real>
void LayeredSurface<Real>::extend_faces(int modes) {
    if (top_ops_->modes() < modes) top_ops_ = std::make_shared<const InterfaceOperators<Real>>(top_ops_->with_modes(q_, modes));
    if (bottom_ops_->modes() < modes)
        bottom_ops_ = std::make_shared<const InterfaceOperators<Real>>(
            bottom_turned_top_ ? top_ops_->flipped() : bottom_ops_->with_modes(q_, modes));
}

// Step 4, between specular faces: mode k of each slab's beam source (its eigen-solution, R~ and T~) and the LU
// factors of the diffuse field's system in scaled variables (beam_field). Unknowns, per slab j of L: the radiance
// leaving it up through its top (U_j) and down through its bottom (V_j); what enters it is
//     from above  D_j = r21 U_0 (j = 0) or T_12 V_{j-1} + R_21 U_j (the joint's operators),
//     from below  W_j = r23 V_{L-1} (j = L - 1) or T_21 U_{j+1} + R_12 V_j
// (an index-matched joint passes light unchanged; over a Lambertian floor, mode 0, r23 is the rank-one 2 albedo c c^T,
// radiance albedo / pi times the flux 2 pi sum_m w_m mu_m V_m), and the slab's equations are
//     U_j - R_j D_j - T_j W_j = source,   V_j - T_j D_j - R_j W_j = source.
template <class Real>
void LayeredSurface<Real>::add_beam_mode(int k, std::vector<detail::SlabModeSolution<Real>>&& slabs,
                                         const detail::PreparedStack<Real>& stack) {
    const std::size_t m = q_.size(), count = slabs.size();
    bool diffuse = beam_->floor > 0 && k == 0;
    for (std::size_t j = 0; j < count; ++j) {
        detail::SlabModeSolution<Real>& x = slabs[j];
        const detail::SlabModes<Real>& prepared = stack.slabs[j];
        if (!x.scatters) {  // R = 0 and T = diag(e^{-tau/mu}) (the same in scaled variables)
            const Real tau = prepared.slab.optical_thickness();
            x.r_scaled = detail::Matrix<Real>(m, m);
            x.t_scaled = detail::Matrix<Real>(m, m);
            for (std::size_t i = 0; i < m; ++i) x.t_scaled(i, i) = std::isinf(tau) ? Real(0) : std::exp(-tau / q_.nodes[i]);
        }
        diffuse = diffuse || x.scatters;
        detail::SlabBeamMode<Real> md;
        md.scatters = x.scatters;
        md.omega_k = prepared.slab.albedo() * (k == 0 ? Real(0.5) : Real(0.25));
        md.lambda = std::move(x.eigen.lambda);
        md.n = std::move(x.eigen.n);
        md.y = std::move(x.eigen.y);
        md.r = std::move(x.r_scaled);
        md.t = std::move(x.t_scaled);
        beam_->slabs[j].add_mode(std::move(md));
    }
    // The joints' operators of mode k (the identity and 0 where a joint is index matched), kept unscaled for
    // LayeredSurface::entering and scaled (X~ = C X C^-1) for the system.
    std::vector<detail::Matrix<Real>> t_down, r_up, t_up, r_down;
    for (std::size_t i = 0; i + 1 < count; ++i) {
        const SmoothDielectric<Real>& joint = beam_->joints[i];
        if (joint.eta_above() == joint.eta_below()) {
            t_down.push_back(detail::Matrix<Real>::identity(m));
            t_up.push_back(detail::Matrix<Real>::identity(m));
            r_up.emplace_back(m, m);
            r_down.emplace_back(m, m);
        } else {
            const InterfaceOperators<Real>& ops = *stack.interior[i];
            t_down.push_back(detail::mode_matrix(ops.T12(), k));
            r_up.push_back(detail::mode_matrix(ops.R21(), k));
            t_up.push_back(detail::mode_matrix(ops.T21(), k));
            r_down.push_back(detail::mode_matrix(ops.R12(), k));
        }
    }
    beam_->joint_t_down.push_back(t_down);
    beam_->joint_r_up.push_back(r_up);
    beam_->joint_t_up.push_back(t_up);
    beam_->joint_r_down.push_back(r_down);
    std::vector<Real> c(m);
    for (std::size_t i = 0; i < m; ++i) c[i] = std::sqrt(q_.weights[i] * q_.nodes[i]);
    for (std::vector<detail::Matrix<Real>>* v : {&t_down, &r_up, &t_up, &r_down})
        for (detail::Matrix<Real>& x : *v)
            for (std::size_t i = 0; i < m; ++i)
                for (std::size_t n = 0; n < m; ++n) x(i, n) *= c[i] / c[n];
    detail::LU<Real> lu;
    if (diffuse && !beam_->identity_system) {  // (without scattering or a floor, no diffuse field: no factors)
        detail::Matrix<Real> rb(m, m);  // the bottom's reflection (scaled)
        for (std::size_t i = 0; i < m; ++i) {
            rb(i, i) = beam_->r23[i];
            if (beam_->floor > 0 && k == 0)
                for (std::size_t j = 0; j < m; ++j) rb(i, j) = 2 * beam_->floor * c[i] * c[j];
        }
        detail::Matrix<Real> rt(m, m);
        for (std::size_t i = 0; i < m; ++i) rt(i, i) = beam_->r21[i];
        const std::size_t size = 2 * m * count;
        detail::Matrix<Real> sys = detail::Matrix<Real>::identity(size);
        // sys(rows of `row`, columns of `col`) -= a b (b: the identity where null), blocks of M; diagonal b (a face's
        // reflection, but for a floor's mode 0) without a product
        const bool full_floor = beam_->floor > 0 && k == 0;
        auto subtract = [&](std::size_t row, std::size_t col, const detail::Matrix<Real>& a, const detail::Matrix<Real>* b,
                            bool diagonal) {
            if (b && !diagonal) {
                const detail::Matrix<Real> ab = detail::multiply(a, *b);
                for (std::size_t i = 0; i < m; ++i)
                    for (std::size_t n = 0; n < m; ++n) sys(row + i, col + n) -= ab(i, n);
                return;
            }
            for (std::size_t i = 0; i < m; ++i)
                for (std::size_t n = 0; n < m; ++n) sys(row + i, col + n) -= a(i, n) * (b ? (*b)(n, n) : Real(1));
        };
        for (std::size_t j = 0; j < count; ++j) {
            const detail::SlabBeamMode<Real>& md = beam_->slabs[j].mode(k);
            const std::size_t up = 2 * m * j, down = up + m;
            // What enters slab j, as (operator, unknown) terms: D_j from above, W_j from below (add_beam_mode's
            // comment); each slab equation takes R_j and T_j of them.
            auto take = [&](const detail::Matrix<Real>& r_or_t, std::size_t row) {
                if (j == 0) {
                    subtract(row, up, r_or_t, &rt, true);
                } else {
                    const bool matched = beam_->joints[j - 1].eta_above() == beam_->joints[j - 1].eta_below();
                    subtract(row, 2 * m * (j - 1) + m, r_or_t, matched ? nullptr : &t_down[j - 1], matched);
                    if (!matched) subtract(row, up, r_or_t, &r_up[j - 1], false);
                }
            };
            auto take_below = [&](const detail::Matrix<Real>& r_or_t, std::size_t row) {
                if (j + 1 == count) {
                    subtract(row, down, r_or_t, &rb, !full_floor);
                } else {
                    const bool matched = beam_->joints[j].eta_above() == beam_->joints[j].eta_below();
                    subtract(row, 2 * m * (j + 1), r_or_t, matched ? nullptr : &t_up[j], matched);
                    if (!matched) subtract(row, down, r_or_t, &r_down[j], false);
                }
            };
            take(md.r, up);
            take_below(md.t, up);
            take(md.t, down);
            take_below(md.r, down);
        }
        lu = detail::lu_factor(std::move(sys));
    }
    beam_->lu.push_back(std::move(lu));
}

// Q_b and Q_e of mode k: with S the reflection of everything below the top face and
// A = (I - R_21 S)^{-1} (the down-going field just below the top per unit transmitted coefficient),
//     Q_b = S A,    Q_e = (I - R_mid,up R_23)^{-1} T_mid,down A = X A   (only when transmission is requested),
// R_mid,up and T_mid,down those of the slabs and interior faces, R_23 the bottom's, X kept by the adding of the
// lower part (detail::StackMode). When requested, the whole layer's operators, the top face added to the lower
// part L through A (adding.hpp's equations, (I - S R_21)^{-1} = I + Q_b R_21 by the push-through identity):
//     R_d = R_12 + T_21 Q_b T_12,   T_d = T_L,d A T_12,
//     R_u = R_L,u + T_L,d R_21 Y,   T_u = T_21 Y,   Y = (I + Q_b R_21) T_L,u,
// or, for one slab between a rough face and that face turned over (Stam's skin layer), R_u = R_d and T_u = T_d:
// the layer seen from below is the layer seen from above (the lower part's upward half is then not computed).
template <class Real>
void LayeredSurface<Real>::add_field_operators(int k, const detail::StackMode<Real>& below) {
    using detail::Matrix;
    using detail::multiply;
    const std::size_t m = q_.size();
    const Matrix<Real> S = detail::as_matrix(m, below.lower.reflection_down);
    const Matrix<Real> r21 = detail::mode_matrix(top_ops_->R21(), k);
    Matrix<Real> a = Matrix<Real>::identity(m);
    detail::lu_solve(detail::lu_factor(detail::one_minus_product(r21, S)), a);
    qb_.push_back(multiply(S, a));
    if (detail::needs_transmitted(outputs_)) qe_.push_back(multiply(below.x, a));
    if (!includes(outputs_, LayerOutput::operators)) return;
    const Matrix<Real> t12 = detail::mode_matrix(top_ops_->T12(), k), t21 = detail::mode_matrix(top_ops_->T21(), k);
    const Matrix<Real>& qb = qb_.back();
    ComponentOperators<Real> w;
    w.size = m;
    Matrix<Real> rd = multiply(t21, multiply(qb, t12));
    const Real* r12 = top_ops_->R12().mode(k);
    for (std::size_t i = 0; i < m * m; ++i) rd.data[i] += r12[i];
    w.reflection_down = std::move(rd.data);
    if (symmetric_) {  // the layer seen from below is the layer seen from above: 6 of the 10 products saved
        // T_d = T_L,d A T_12 = T_23 X A T_12 = T_23 Q_e T_12 (T_L,d = T_23 X, not computed: detail::add_from_above)
        const Matrix<Real> qe = detail::needs_transmitted(outputs_) ? qe_.back() : multiply(below.x, a);
        w.transmission_down = multiply(detail::as_matrix(m, below.bottom.transmission_down), multiply(qe, t12)).data;
        w.reflection_up = w.reflection_down;
        w.transmission_up = w.transmission_down;
        whole_.push_back(std::move(w));
        return;
    }
    const Matrix<Real> lower_td = detail::as_matrix(m, below.lower.transmission_down);
    w.transmission_down = multiply(lower_td, multiply(a, t12)).data;
    Matrix<Real> y = detail::as_matrix(m, below.lower.transmission_up);
    const Matrix<Real> bounce = multiply(qb, multiply(r21, y));
    for (std::size_t i = 0; i < m * m; ++i) y.data[i] += bounce.data[i];
    Matrix<Real> ru = multiply(lower_td, multiply(r21, y));
    const Matrix<Real> lower_ru = detail::as_matrix(m, below.lower.reflection_up);
    for (std::size_t i = 0; i < m * m; ++i) ru.data[i] += lower_ru.data[i];
    w.reflection_up = std::move(ru.data);
    w.transmission_up = multiply(t21, y).data;
    whole_.push_back(std::move(w));
}

// The size of mode k for the adaptive mode count, {reflected, transmitted}: the largest BRDF (BTDF) Fourier coefficient
// it adds at the ordinate pairs, (2 - delta_k0) (T_21 Q_b T_12)_nj / (w_j mu_j) (T_23 Q_e T_12; the common 1 / (2 pi)
// left out), for the outputs that were requested, each compared with its own mode 0 (solve_modes: measured against
// the larger of the two, a reflection swollen at grazing ordinates hid the BTDF's modes, 6.6% of its peak lost at
// tolerance 1e-2 with every output asked for, where asking for the transmission alone kept 13 of 16 modes; found by
// review); the layer's operators count as both (their transmission directly, where Q_e is not kept). (They were not measured: with the operators alone every mode was negligible, and the solve
// stopped after 3 modes where mode 3 is 0.34 of mode 0's; found by review.) Like the BRDF's, the reflection's size
// leaves out the top face's own R_12, which at grazing ordinates rings in every mode: measured with it, no mode
// of Stam's layer was ever negligible. Only whether a mode is negligible matters after mode 0: where one column
// (the one of the last size computed in full) already exceeds `exceeds`, its value is returned, with products by a
// vector in place of two matrix products (a mode that is not negligible, the usual case, costs O(M^2) here).
template <class Real>
std::array<Real, 2> LayeredSurface<Real>::coefficient_size(int k, const ComponentOperators<Real>& bottom,
                                                           const std::array<Real, 2>& exceeds,
                                                           std::array<std::size_t, 2>& column) const {
    using detail::Matrix;
    const std::size_t m = q_.size();
    const Matrix<Real> t12 = detail::mode_matrix(top_ops_->T12(), k);
    const Real factor = k == 0 ? Real(1) : Real(2);
    auto largest = [&](const Matrix<Real>& x, std::size_t& at) {  // (2 - delta_k0) max |x_nj| / (w_j mu_j), its column
        Real big = 0;
        for (std::size_t n = 0; n < m; ++n)
            for (std::size_t j = 0; j < m; ++j) {
                const Real v = std::fabs(x(n, j)) / (q_.weights[j] * q_.nodes[j]);
                if (v > big) {
                    big = v;
                    at = j;
                }
            }
        return big * factor;
    };
    // The size of exit inner T_12, or, where its column `at` alone (two products with a vector) already exceeds
    // `floor`, that column's: a lower bound that decides as the size does (the mode is not negligible).
    auto size = [&](const Matrix<Real>& exit, const Matrix<Real>& inner, Real floor, std::size_t& at) {
        if (floor < std::numeric_limits<Real>::infinity()) {  // (after mode 0)
            Matrix<Real> v(m, 1);
            for (std::size_t i = 0; i < m; ++i) v(i, 0) = t12(i, at);
            const Matrix<Real> x = detail::multiply(exit, detail::multiply(inner, v));
            Real big = 0;
            for (std::size_t n = 0; n < m; ++n) big = std::fmax(big, std::fabs(x(n, 0)));
            big *= factor / (q_.weights[at] * q_.nodes[at]);
            if (big > floor) return big;
        }
        return largest(detail::multiply(exit, detail::multiply(inner, t12)), at);
    };
    const bool operators = includes(outputs_, LayerOutput::operators) && !whole_.empty();
    std::array<Real, 2> size_k{Real(0), Real(0)};
    if (detail::needs_reflected(outputs_) || includes(outputs_, LayerOutput::ambient) || operators)
        size_k[0] = size(detail::mode_matrix(top_ops_->T21(), k), qb_.back(), exceeds[0], column[0]);
    if (detail::needs_transmitted(outputs_)) {
        size_k[1] = size(detail::as_matrix(m, bottom.transmission_down), qe_.back(), exceeds[1], column[1]);
    } else if (operators) {
        size_k[1] = largest(detail::as_matrix(m, whole_.back().transmission_down), column[1]);
    }
    return size_k;
}

// Step 5: the mode-0 up-going field just below the top under a uniform sky of unit radiance (computed before the
// unscattered beam is taken out of Q_b: under a diffuse sky it is diffuse too). The radiance transmitted to
// internal ordinate m is (n2/n1)^2 tau_21(mu_m) by reciprocity of the top's BTDF (t_12 / n_2^2 = t_21 / n_1^2
// with the arguments swapped); the field is Q_b of it.
template <class Real>
void LayeredSurface<Real>::solve_ambient() {
    const std::size_t m = q_.size();
    const Real ratio = top_.eta_below() / top_.eta_above();
    std::vector<Real> c(m);
    for (std::size_t i = 0; i < m; ++i) c[i] = ratio * ratio * exit_top_[i];
    ambient_field_.assign(m, Real(0));
    for (std::size_t n = 0; n < m; ++n)
        for (std::size_t i = 0; i < m; ++i) ambient_field_[n] += qb_[0](n, i) * c[i];
}

// Step 5b: the fields at the requested depths t (mode 0). With the slab cut at t into A (above) and B (below, with
// the bottom face: reflection S_B), and a0 = (I - R_21 S)^{-1} mapping the coefficients c entering below the top to
// the down-going field there, the down- and up-going fields at t are
//     D = (I - R_A S_B)^{-1} T_A a0 c,   U = S_B D
// (A's reflection of up-going light back down is R_A: a bare slab is the same seen from either side).
template <class Real>
void LayeredSurface<Real>::solve_depths(const detail::PreparedStack<Real>& stack, const std::vector<Slab<Real>>& slabs,
                                        const LayerOptions& options, const std::vector<Real>& depths) {
    using detail::Matrix;
    // The slab holding depth t (on a joint: the slab above) and the true optical depth of its top.
    const auto holding = [&](Real t) {
        std::size_t j = 0;
        Real top = 0;
        while (j + 1 < slabs.size() && t > top + slabs[j].optical_thickness()) top += slabs[j++].optical_thickness();
        return std::pair<std::size_t, Real>{j, top};
    };
    if (beam_) {  // through a stack, slab by slab
        for (const Real t : depths) {
            const auto [j, top] = holding(t);
            beam_depths_.push_back(beam_depth(slabs[j], options, std::fmin(t - top, slabs[j].optical_thickness())));
            beam_depths_.back().depth = t;
            beam_depths_.back().slab = j;
        }
        return;
    }
    const std::size_t m = q_.size();
    const Matrix<Real> r21 = detail::mode_matrix(top_ops_->R21(), 0);
    const detail::StackMode<Real> whole = detail::stack_mode(stack, *bottom_ops_, q_, 0);
    Matrix<Real> a0 = Matrix<Real>::identity(m);
    detail::lu_solve(detail::lu_factor(detail::one_minus_product(r21, detail::as_matrix(m, whole.lower.reflection_down))), a0);
    const ComponentOperators<Real> bottom = detail::interface_component(*bottom_ops_, 0);
    const auto slab_mode0 = [&](std::size_t i) { return detail::slab_mode(stack.slabs[i], q_, 0); };
    const auto joint = [&](std::size_t i) { return detail::interface_component(*stack.interior[i], 0); };
    for (const Real t : depths) {
        // Slab j holds depth t (on a joint: the slab above), t - top into it; A is everything above the cut (the
        // slabs and joints above slab j, then its part above t), B everything below (its part below t, the joints
        // and slabs below, the bottom face).
        const auto [j, top] = holding(t);
        Real scaled_top = 0;
        for (std::size_t i = 0; i < j; ++i) scaled_top += stack.slabs[i].slab.optical_thickness();
        const Real tau = slabs[j].optical_thickness(), into = std::fmin(t - top, tau);
        const detail::SlabModes<Real> above = detail::prepare_slab(slabs[j], q_, 1, options.delta_m, into);
        const detail::SlabModes<Real> below = detail::prepare_slab(slabs[j], q_, 1, options.delta_m, tau - into);
        ComponentOperators<Real> a = detail::slab_mode(above, q_, 0);
        if (j > 0) {
            ComponentOperators<Real> upper = slab_mode0(0);
            for (std::size_t i = 0; i < j; ++i) {
                upper = add_components(upper, joint(i));
                if (i + 1 < j) upper = add_components(upper, slab_mode0(i + 1));
            }
            a = add_components(upper, a);
        }
        ComponentOperators<Real> b = detail::slab_mode(below, q_, 0);
        for (std::size_t i = j; i < stack.interior.size(); ++i) b = add_components(add_components(b, joint(i)), slab_mode0(i + 1));
        b = add_components(b, bottom);
        const Matrix<Real> s_b = detail::as_matrix(m, b.reflection_down);
        Matrix<Real> down = detail::multiply(detail::as_matrix(m, a.transmission_down), a0);
        detail::lu_solve(detail::lu_factor(detail::one_minus_product(detail::as_matrix(m, a.reflection_up), s_b)), down);
        Matrix<Real> up = detail::multiply(s_b, down);
        depth_ops_.push_back({t, scaled_top + above.slab.optical_thickness(), std::move(down), std::move(up)});
    }
}

// Step 5b between specular faces (beam_): the slab cut at depth t into A and B, each a slab with its own beam
// source (mode 0), for depth_profile.
template <class Real>
typename LayeredSurface<Real>::BeamDepth LayeredSurface<Real>::beam_depth(const Slab<Real>& slab, const LayerOptions& options,
                                                                         Real t) const {
    using detail::Matrix;
    const std::size_t m = q_.size();
    BeamDepth d;
    d.depth = t;
    auto part = [&](Real thickness, detail::SlabBeam<Real>& beam, Matrix<Real>& r, Matrix<Real>& tr) {
        const detail::SlabModes<Real> p = detail::prepare_slab(slab, q_, 1, options.delta_m, thickness);
        detail::SlabModeSolution<Real> sol =
            detail::slab_mode_solution(p.slab, q_, p.phase.same_k(0), p.phase.opposite_k(0), 0, true);
        const SlabModeOperators<Real> ops = detail::slab_mode_operators(sol, q_, p.slab.optical_thickness());
        r = detail::as_matrix(m, ops.reflection);
        tr = detail::as_matrix(m, ops.transmission);
        beam = detail::SlabBeam<Real>(q_, p.slab.optical_thickness(),
                                      detail::PhaseAtOrdinates<Real>(p.moments, q_.nodes, q_.weights, 1));
        detail::SlabBeamMode<Real> md;
        md.scatters = sol.scatters;
        md.omega_k = p.slab.albedo() / 2;
        md.lambda = std::move(sol.eigen.lambda);
        md.n = std::move(sol.eigen.n);
        md.y = std::move(sol.eigen.y);
        md.r = std::move(sol.r_scaled);
        md.t = std::move(sol.t_scaled);
        beam.add_mode(std::move(md));
        return p.slab.optical_thickness();
    };
    d.scaled_depth = part(t, d.above, d.r_a, d.t_a);
    part(slab.optical_thickness() - t, d.below, d.r_b, d.t_b);
    d.lu = detail::lu_factor(detail::one_minus_product(d.r_a, d.r_b));
    return d;
}

// depth_profile between specular faces: with the whole layer's field (beam_field: U up at the top face, V down at
// the bottom face, so that D_0 = r21 U enters A from above and W = r23 V enters B from below), and the beam's flux
// at depth t, a_down e^{-t/x} going down and a_up e^{-(tau - t)/x} going up, the down- and up-going diffuse fields
// at t are
//     D_t = s_A + R_A U_t,  U_t = s_B + R_B D_t,   so  (I - R_A R_B) D_t = s_A + R_A s_B,
//     s_A = a_down down_A + a_up e^{-(tau - t)/x} up_A + T_A D_0,   s_B = a_down e^{-t/x} up_B + a_up down_B + T_B W
// (up_A, down_A: A's response to a beam at x entering its top; a beam entering from below gets the mirror image).
template <class Real>
std::vector<typename LayeredSurface<Real>::DepthPoint> LayeredSurface<Real>::beam_depth_profile(Real mu_i) const {
    std::vector<DepthPoint> out;
    Workspace ws;
    const detail::BeamField<Real>& f = beam_field(mu_i, 1, ws);
    const std::size_t m = q_.size();
    const Real two_pi = 2 * detail::pi_v<Real>;
    detail::BeamResponse<Real> a, b;
    detail::Matrix<Real> rhs(m, 1);
    std::vector<Real> s_b(m);
    for (const BeamDepth& d : beam_depths_) {
        Real fluence = 0, net = 0;
        if (f.lit()) {
            // slab j's beam (cosine x: 0 where it does not reach the slab), and the diffuse light entering the slab
            // from above (d0) and from below (w), mode 0
            const std::size_t j = d.slab;
            const Real x = f.x[j], tau = beam_->slabs[j].optical_thickness();
            const Real* d0 = f.d.data() + j * m;
            const Real* w = f.w.data() + j * m;
            const Real down_at = x > 0 ? std::exp(-d.scaled_depth / x) : Real(0);
            const Real up_at = !(x > 0) || std::isinf(tau) ? Real(0) : std::exp(-(tau - d.scaled_depth) / x);
            a.up.assign(m, Real(0)), a.down.assign(m, Real(0)), b.up.assign(m, Real(0)), b.down.assign(m, Real(0));
            if (x > 0) {
                d.above.respond(x, 1, a, ws.scratch);
                d.below.respond(x, 1, b, ws.scratch);
            }
            for (std::size_t n = 0; n < m; ++n) {
                Real sa = f.flux_down[j] * a.down[n] + f.flux_up[j] * up_at * a.up[n],
                     sb = f.flux_down[j] * down_at * b.up[n] + f.flux_up[j] * b.down[n];
                for (std::size_t i = 0; i < m; ++i) sa += d.t_a(n, i) * d0[i], sb += d.t_b(n, i) * w[i];
                rhs(n, 0) = sa;
                s_b[n] = sb;
            }
            for (std::size_t n = 0; n < m; ++n)
                for (std::size_t i = 0; i < m; ++i) rhs(n, 0) += d.r_a(n, i) * s_b[i];
            detail::lu_solve(d.lu, rhs);
            for (std::size_t n = 0; n < m; ++n) {
                Real up = s_b[n];
                for (std::size_t i = 0; i < m; ++i) up += d.r_b(n, i) * rhs(i, 0);
                fluence += two_pi * q_.weights[n] * (rhs(n, 0) + up);
                net += two_pi * q_.weights[n] * q_.nodes[n] * (rhs(n, 0) - up);
            }
            // the beam itself (delta-M's: with the forward peak, as the fluxes)
            if (x > 0) {
                const Real going_down = f.flux_down[j] * down_at, going_up = f.flux_up[j] * up_at;
                fluence += (going_down + going_up) / x;
                net += going_down - going_up;
            }
        }
        out.push_back({d.depth, non_negative(fluence), net});  // (rounding: -3e-15 where no light reaches)
    }
    return out;
}

template <class Real>
std::vector<typename LayeredSurface<Real>::DepthPoint> LayeredSurface<Real>::depth_profile(Real mu_i) const {
    std::vector<DepthPoint> out;
    if (!(mu_i > 0 && mu_i <= 1)) return out;
    if (beam_) return beam_depth_profile(mu_i);
    if (depth_ops_.empty()) return out;
    Workspace ws;
    // The scattered light's scale (scattering_scale: the beam's spread between specular faces, or the joints' mirror
    // under a specular top), as reflectance and transmittance take it: inside too, the light is what they account for.
    const Real scale = scattering_scale(mu_i, ws);
    entry(mu_i, ws);  // ws.c: mode 0 first
    const std::size_t m = q_.size();
    const Real two_pi = 2 * detail::pi_v<Real>;
    // Between specular faces the solve's field holds the beam spread over the ordinates: take that out (its terms
    // are diagonal, as in separate_direct_beam) and put the beam back exactly at the true angle mu_t.
    const Real mu_t = direct_separated_ ? top_face().internal_cosine(mu_i) : Real(0);
    for (const DepthOperators& d : depth_ops_) {
        Real fluence = 0, net = 0;
        for (std::size_t n = 0; n < m; ++n) {
            Real down = 0, up = 0;
            for (std::size_t i = 0; i < m; ++i) {
                down += d.down(n, i) * ws.c[i];
                up += d.up(n, i) * ws.c[i];
            }
            if (direct_separated_) {
                const DirectBeam beam = direct_beam(q_.nodes[n], direct_tau_);
                if (!beam.trapped()) {
                    down -= std::exp(-d.scaled_depth / q_.nodes[n]) * beam.bounces() * ws.c[n];
                    up -= beam.r23 * std::exp(-(2 * direct_tau_ - d.scaled_depth) / q_.nodes[n]) * beam.bounces() * ws.c[n];
                }
            }
            down *= scale;
            up *= scale;
            fluence += two_pi * q_.weights[n] * (down + up);
            net += two_pi * q_.weights[n] * q_.nodes[n] * (down - up);
        }
        if (direct_separated_ && mu_t > 0) {
            const DirectBeam beam = entering_beam(mu_i, mu_t, direct_tau_);
            if (!beam.trapped()) {
                const Real into = top_.smooth_interface().transmittance(mu_i) * beam.bounces();
                const Real going_down = into * std::exp(-d.scaled_depth / mu_t);
                const Real going_up = std::isinf(direct_tau_) ? Real(0)
                                                              : into * beam.r23 * std::exp(-(2 * direct_tau_ - d.scaled_depth) / mu_t);
                fluence += (going_down + going_up) / mu_t;
                net += going_down - going_up;
            }
        }
        out.push_back({d.depth, non_negative(fluence), net});  // (rounding: -3e-15 where no light reaches)
    }
    return out;
}

// Step 4b: across joints that refract, the pass as the solution holds it, composed once per mode solved: down
// D_(G-1) T_12 ... T_12 D_0 (the columns' D_g = e^{-tau'_g / mu_m}, the joints' own T_12), and for reflection on
// through the bottom's R_23 and back up, D_0 T_21 ... T_21 D_(G-1) (applied factor by factor at every evaluation,
// they made brdf 4.7 times slower at M = 16 with three slabs, 10 times at 64; found by review).
template <class Real>
void LayeredSurface<Real>::compose_passes() {
    using detail::Matrix;
    const std::size_t m = q_.size(), columns = pass_d_.size();
    const auto scale_rows = [m](const std::vector<Real>& d, Matrix<Real>& a) {  // a = diag(d) a
        for (std::size_t n = 0; n < m; ++n)
            for (std::size_t i = 0; i < m; ++i) a(n, i) *= d[n];
    };
    for (int k = 0; k < modes_; ++k) {
        Matrix<Real> down(m, m);
        for (std::size_t i = 0; i < m; ++i) down(i, i) = pass_d_[0][i];
        for (std::size_t g = 1; g < columns; ++g) {
            down = detail::multiply(detail::mode_matrix(pass_joint_ops_[g - 1]->T12(), k), down);
            scale_rows(pass_d_[g], down);
        }
        if (first_reflection_exact_) {
            Matrix<Real> up = detail::multiply(detail::mode_matrix(bottom_ops_->R12(), k), down);
            for (std::size_t g = columns; g-- > 0;) {
                scale_rows(pass_d_[g], up);
                if (g > 0) up = detail::multiply(detail::mode_matrix(pass_joint_ops_[g - 1]->T21(), k), up);
            }
            pass_reflected_.push_back(std::move(up));
        }
        if (first_pass_exact_) pass_down_.push_back(std::move(down));
    }
}

// Step 3b: one face rough and the other specular, slabs joined by specular faces: the BTDF's unscattered pass, and
// under a specular top the BRDF's pass reflected once by the rough bottom, exact at their angles (with_exact_pass).
template <class Real>
void LayeredSurface<Real>::set_up_exact_passes(const Boundary<Real>& top, const std::vector<Boundary<Real>>& interior,
                                               const Boundary<Real>& bottom, const detail::PreparedStack<Real>& stack,
                                               LayerOutput outputs) {
    bool specular_joints = true;
    for (const Boundary<Real>& b : interior) specular_joints = specular_joints && !b.rough() && !b.lambertian();
    if (!specular_joints || top.lambertian() || bottom.lambertian()) return;
    first_pass_exact_ = top.rough() != bottom.rough() && includes(outputs, LayerOutput::transmission);
    first_reflection_exact_ = !top.rough() && bottom.rough() && includes(outputs, LayerOutput::subsurface_reflection);
    if (!first_pass_exact_ && !first_reflection_exact_) return;
    // the columns: the slabs between the joints that refract (an index-matched joint passes light unchanged)
    pass_tau_.push_back(Real(0));
    for (std::size_t j = 0; j < stack.slabs.size(); ++j) {
        pass_tau_.back() += stack.slabs[j].slab.optical_thickness();
        if (j + 1 == stack.slabs.size() || interior[j].eta_above() == interior[j].eta_below()) continue;
        pass_joints_.push_back(interior[j].smooth_interface());
        pass_joint_ops_.push_back(stack.interior[j]);
        pass_tau_.push_back(Real(0));
    }
    for (const Real tau : pass_tau_) {
        pass_d_.emplace_back();
        for (const Real mu : q_.nodes) pass_d_.back().push_back(std::exp(-tau / mu));
    }
}

// Step 6: between two specular boundaries the unscattered beam stays on its own ordinate (every operator on its
// path is diagonal): take it out of Q_b and Q_e, per ordinate (DirectBeam)
//   Q_e^dir = d / (1 - r21 r23 d^2),   Q_b^dir = d^2 r23 / (1 - r21 r23 d^2),   d = e^{-tau/mu_m},
// so that brdf/btdf hold scattered light only, and add it back exactly at the true angle (direct()). A trapped
// beam is reached by no light from outside: there is nothing to take out (and its series would be 1 / 0).
template <class Real>
void LayeredSurface<Real>::separate_direct_beam(Real scaled_tau, Real true_tau) {
    direct_separated_ = true;
    direct_tau_ = scaled_tau;
    // The semi-infinite shortcut (LayerRequest::tolerance) made the solved slab infinitely thick: so is the beam's.
    beam_tau_ = std::isinf(scaled_tau) ? scaled_tau : true_tau;
    const bool want_t = detail::needs_transmitted(outputs_);
    for (std::size_t i = 0; i < q_.size(); ++i) {
        const DirectBeam beam = direct_beam(q_.nodes[i], direct_tau_);
        if (beam.trapped()) continue;
        const Real bounces = beam.bounces();
        for (std::size_t k = 0; k < qb_.size(); ++k) {  // (none where the beam is a source and no adding was needed)
            qb_[k](i, i) -= beam.d * beam.d * beam.r23 * bounces;
            if (want_t) qe_[k](i, i) -= beam.d * bounces;
        }
    }
}

// Step 6b: a specular top over refracting joints and a rough bottom (detail::joints_mirror_the_beam). The joints
// reflect part of the beam specularly, and it leaves the top as a delta in the mirror direction; in Q_b it was spread
// over the ordinates and read out between them as a spike, ringing in azimuth (1 | 1.5 | 1.4 over a rough bottom,
// M = 48: the subsurface BRDF near the normal 4.2 in the mirror direction, 0 (clamped from negative) beside it,
// where the truth is ~0.02; found by a reciprocity sweep). Its part of Q_b, the paths that neither scatter nor reach
// the bottom, is the Q_b of the stack with its slabs clear (transmission e^{-tau'/mu_m}, no reflection) over a black
// bottom: S' = reflection of that stack, Q_b' = S' (I - R_21 S')^{-1}. Taken out, and direct() adds the delta exactly
// (joint_mirror).
template <class Real>
void LayeredSurface<Real>::separate_joint_mirror(const std::vector<Boundary<Real>>& interior,
                                                 const std::vector<Slab<Real>>& slabs,
                                                 const detail::PreparedStack<Real>& stack) {
    using detail::Matrix;
    const std::size_t m = q_.size(), count = stack.slabs.size();
    // (whatever the outputs: the scale it sets, mirror_scale, applies to the transmission too, which came out
    // otherwise as the unscaled field, T 0.206 where it is 0.255 with the reflection requested; found by review)
    if (qb_.empty()) return;  // (no modes solved: the top's own reflection alone)
    joint_mirror_ = true;
    direct_tau_ = beam_tau_ = 0;
    for (std::size_t j = 0; j < count; ++j) {
        mirror_scaled_tau_.push_back(stack.slabs[j].slab.optical_thickness());
        const Real scaled = mirror_scaled_tau_.back();  // (infinite where the semi-infinite shortcut made it so)
        mirror_true_tau_.push_back(std::isinf(scaled) ? scaled : slabs[j].optical_thickness());
        direct_tau_ += scaled;
        beam_tau_ += mirror_true_tau_.back();
    }
    mirror_eta_.push_back(top_.eta_below());
    for (const Boundary<Real>& b : interior) {
        mirror_joints_.push_back(b.smooth_interface());
        mirror_eta_.push_back(b.eta_below());
    }
    std::vector<ComponentOperators<Real>> clear(count);
    for (std::size_t j = 0; j < count; ++j) {
        clear[j].size = m;
        clear[j].reflection_down.assign(m * m, Real(0));
        clear[j].reflection_up = clear[j].reflection_down;
        clear[j].transmission_down = clear[j].reflection_down;
        for (std::size_t i = 0; i < m; ++i)
            clear[j].transmission_down[i * m + i] =
                std::isinf(mirror_scaled_tau_[j]) ? Real(0) : std::exp(-mirror_scaled_tau_[j] / q_.nodes[i]);
        clear[j].transmission_up = clear[j].transmission_down;
    }
    for (std::size_t k = 0; k < qb_.size(); ++k) {
        ComponentOperators<Real> below = clear[count - 1];
        for (std::size_t j = count - 1; j-- > 0;)
            below = add_components(add_components(clear[j], detail::interface_component(*stack.interior[j], static_cast<int>(k))), below);
        const Matrix<Real> s = detail::as_matrix(m, below.reflection_down);
        Matrix<Real> a = Matrix<Real>::identity(m);
        detail::lu_solve(detail::lu_factor(detail::one_minus_product(detail::mode_matrix(top_ops_->R21(), static_cast<int>(k)), s)), a);
        const Matrix<Real> mirror = detail::multiply(s, a);
        for (std::size_t i = 0; i < m * m; ++i) qb_[k].data[i] -= mirror.data[i];
        if (k != 0) continue;
        std::vector<Real> column(m);
        for (std::size_t i = 0; i < m; ++i) {
            for (std::size_t n = 0; n < m; ++n) column[n] = mirror(n, i);
            mirror_flux_.push_back(flux_out(column.data(), exit_top_));
        }
    }
}

// Step 7: the internal fields (K blocks of M) of the requested incidences (LayerRequest::incidence), so that
// evaluation there skips entry() and the per-mode products.
template <class Real>
void LayeredSurface<Real>::precompute_incidences() {
    const std::size_t size = static_cast<std::size_t>(modes_) * q_.size();
    Workspace ws;
    if (beam_) {
        cached_beam_.resize(incidence_.size());
        for (std::size_t j = 0; j < incidence_.size(); ++j) compute_beam_field(incidence_[j], modes_, cached_beam_[j], ws);
        return;
    }
    cached_b_.assign(incidence_.size(), {});
    cached_e_.assign(incidence_.size(), {});
    cached_c_.assign(incidence_.size(), {});
    for (std::size_t j = 0; j < incidence_.size(); ++j) {
        if (first_pass_exact_ || first_reflection_exact_) {  // (the exact pass takes the solution's part out: the entry)
            entry(incidence_[j], ws);
            cached_c_[j] = ws.c;
        }
        if (detail::needs_reflected(outputs_)) {
            const Real* f = field(incidence_[j], false, ws);
            cached_b_[j].assign(f, f + size);
        }
        if (detail::needs_transmitted(outputs_)) {
            const Real* f = field(incidence_[j], true, ws);
            cached_e_[j].assign(f, f + size);
        }
    }
}

/// Solves one layer: `slab` between `top` (media 1 | 2) and `bottom` (2 | 3). See solve_stack.
template <class Real>
LayeredSurface<Real> solve_layer(const Slab<Real>& slab, const detail::non_deduced_t<Boundary<Real>>& top,
                                 const detail::non_deduced_t<Boundary<Real>>& bottom, const LayerOptions& options = {},
                                 const detail::non_deduced_t<LayerRequest<Real>>& request = {}) {
    return solve_stack(top, std::vector<Slab<Real>>{slab}, std::vector<Boundary<Real>>{}, bottom, options, request);
}

namespace detail {

/// Fails unless `options` (those `name` was prepared with) equal `reference` (the top face's) in every field.
inline void require_same_options(const std::string& name, const LayerOptions& options, const LayerOptions& reference) {
    const auto differ = [&](const char* field, long long value, long long top) {
        fail_invalid_argument("stratum: prepared boundaries must share one discretization: " + name +
                              " was prepared with options." + field + " = " + std::to_string(value) + ", the top with " +
                              std::to_string(top));
    };
    if (options.ordinates != reference.ordinates) differ("ordinates", options.ordinates, reference.ordinates);
    const auto resolved = [](const LayerOptions& o) { return o.modes > 0 ? o.modes : 2 * o.ordinates; };  // 0: 2M
    if (resolved(options) != resolved(reference)) differ("modes", resolved(options), resolved(reference));
    if (options.delta_m != reference.delta_m) differ("delta_m", options.delta_m, reference.delta_m);
    if (options.renormalization != reference.renormalization)
        differ("renormalization", static_cast<long long>(options.renormalization),
               static_cast<long long>(reference.renormalization));
    if (options.hemispherical_nodes != reference.hemispherical_nodes)
        differ("hemispherical_nodes", options.hemispherical_nodes, reference.hemispherical_nodes);
    if (options.azimuthal_points != reference.azimuthal_points)
        differ("azimuthal_points", options.azimuthal_points, reference.azimuthal_points);
    if (options.specular_transmission != reference.specular_transmission)
        differ("specular_transmission", static_cast<long long>(options.specular_transmission),
               static_cast<long long>(reference.specular_transmission));
    if (options.critical_split != reference.critical_split)
        differ("critical_split", options.critical_split, reference.critical_split);
    if (options.single_scattering_correction != reference.single_scattering_correction)
        differ("single_scattering_correction", options.single_scattering_correction, reference.single_scattering_correction);
}


}  // namespace detail

template <class Real>
LayeredSurface<Real> solve_stack(const PreparedBoundary<Real>& top, const std::vector<Slab<Real>>& slabs,
                                 const std::vector<PreparedBoundary<Real>>& interior, const PreparedBoundary<Real>& bottom,
                                 const detail::non_deduced_t<LayerRequest<Real>>& request) {
    const LayerOptions& options = top.options();
    detail::require_same_options("bottom", bottom.options(), options);
    std::vector<Boundary<Real>> faces;
    for (std::size_t i = 0; i < interior.size(); ++i) {
        detail::require_same_options("interior[" + std::to_string(i) + "]", interior[i].options(), options);
        faces.push_back(interior[i].boundary());
    }
    // The faces on the layer's rule (split at critical cosines for a rough top over a smooth bottom). Light leaves
    // the layer through the top from below it, through the bottom from above it.
    const Quadrature<Real> q = detail::layer_quadrature(top.boundary(), faces, bottom.boundary(), options);
    const auto& top_rule = top.on_rule(q);
    const auto& bottom_rule = bottom.on_rule(q);
    detail::PreparedOperators<Real> prepared{top_rule.operators,
                                             bottom_rule.operators,
                                             {},
                                             top.entry_transmittance(Incidence::from_above),
                                             bottom.entry_transmittance(Incidence::from_below),
                                             top_rule.transmittance(Incidence::from_below),
                                             bottom_rule.transmittance(Incidence::from_above),
                                             top_rule.couplings,
                                             bottom_rule.couplings};
    for (const PreparedBoundary<Real>& face : interior) prepared.interior.push_back(face.on_rule(q).operators);
    return LayeredSurface<Real>::solve(top.boundary(), slabs, faces, bottom.boundary(), options, request, prepared);
}

/// Solves one layer between prepared boundaries (see PreparedBoundary and solve_stack).
template <class Real>
LayeredSurface<Real> solve_layer(const Slab<Real>& slab, const PreparedBoundary<Real>& top,
                                 const PreparedBoundary<Real>& bottom,
                                 const detail::non_deduced_t<LayerRequest<Real>>& request = {}) {
    return solve_stack(top, std::vector<Slab<Real>>{slab}, std::vector<PreparedBoundary<Real>>{}, bottom, request);
}

/// Solves one layer per slab between the same two faces: spectral samples (RGB, or 16 to 64 wavelengths of one
/// material), or variants of a material. The faces' operators are built once (PreparedBoundary), so n slabs cost
/// one face preparation and n slab solves; each result equals its own solve_layer (bit for bit, or, as for
/// PreparedBoundary, when the request solves fewer modes than the options give, within the azimuthal rule's error:
/// 1e-12 at the default 24 points, ~5e-7 at 12, as a request with a tolerance takes them: measured 3.1e-11 relative
/// for fluxes and the ambient term at tolerance 1e-3; found by review). Faces whose index or
/// roughness varies with wavelength cannot be shared: solve those one by one.
template <class Real>
std::vector<LayeredSurface<Real>> solve_spectral(const std::vector<Slab<Real>>& slabs,
                                                 const detail::non_deduced_t<Boundary<Real>>& top,
                                                 const detail::non_deduced_t<Boundary<Real>>& bottom,
                                                 const LayerOptions& options = {},
                                                 const detail::non_deduced_t<LayerRequest<Real>>& request = {}) {
    const LayerOptions face_options = integrals_for_tolerance(options, request.tolerance);  // (as solve_layer's)
    const PreparedBoundary<Real> prepared_top(top, face_options);
    const PreparedBoundary<Real> prepared_bottom =
        detail::turned_over(top, bottom) ? prepared_top.turned_over() : PreparedBoundary<Real>(bottom, face_options);
    std::vector<LayeredSurface<Real>> layers;
    layers.reserve(slabs.size());
    for (const Slab<Real>& slab : slabs) layers.push_back(solve_layer(slab, prepared_top, prepared_bottom, request));
    return layers;
}

template <class Real>
std::vector<Real> LayeredSurface<Real>::fourier_coefficients(LayerOutput which, const std::vector<Real>& mu_i,
                                                             const std::vector<Real>& mu_o) const {
    const bool transmitted = which == LayerOutput::transmission;
    if (!transmitted && which != LayerOutput::subsurface_reflection)
        detail::fail_invalid_argument("stratum: fourier_coefficients: which must be LayerOutput::subsurface_reflection or "
                                    "LayerOutput::transmission");
    for (const std::vector<Real>* v : {&mu_i, &mu_o})
        for (const Real mu : *v) detail::require_closed("fourier_coefficients: cosine", mu, Real(0), Real(1));
    const std::size_t m = q_.size(), kk = static_cast<std::size_t>(modes_), no = mu_o.size();
    std::vector<Real> out(mu_i.size() * no * kk, Real(0));
    const bool requested = transmitted ? includes(outputs_, LayerOutput::transmission) && !bottom_.lambertian()
                                       : includes(outputs_, LayerOutput::subsurface_reflection);
    if (!requested || kk == 0) return out;
    Workspace ws;
    if (beam_) {  // between specular faces: the modes of the radiance at the true exit angle (beam_exit)
        // A block of incidences' fields first, then the exits outermost: beam_exit computes the slabs' responses at
        // an exit cosine once for the block (per pair they cost 25x the rest: 129 nodes, 16 ordinates). Blocks of 32
        // bound the fields held (all 129 at once: 623 MB at M = 64 for three slabs; found by review), for 28% more
        // time than all at once (a 129-node table at M = 16; blocks of 16: 62%).
        constexpr std::size_t block = 32;
        std::vector<detail::BeamField<Real>> fields(std::min(block, mu_i.size()));
        for (std::size_t first = 0; first < mu_i.size(); first += block) {
            const std::size_t last = std::min(mu_i.size(), first + block);
            for (std::size_t a = first; a < last; ++a)
                if (mu_i[a] > 0) fields[a - first] = beam_field(mu_i[a], modes_, ws);
            for (std::size_t b = 0; b < no; ++b) {
                if (!(mu_o[b] > 0)) continue;
                for (std::size_t a = first; a < last; ++a) {
                    if (!(mu_i[a] > 0)) continue;
                    Real* a_k = out.data() + (a * no + b) * kk;
                    beam_exit(fields[a - first], mu_o[b], transmitted, a_k, ws);
                    for (std::size_t k = 0; k < kk; ++k) a_k[k] *= mu_o[b];
                }
            }
        }
        return out;
    }
    const Face face = transmitted ? bottom_face() : top_face();
    std::vector<Real> exits(no * kk * m, Real(0));  // exit weights (ws.out) per mu_o
    for (std::size_t b = 0; b < no; ++b) {
        if (!(mu_o[b] > 0)) continue;
        exit_weights(mu_o[b], face, ws);
        std::copy(ws.out.begin(), ws.out.end(), exits.begin() + static_cast<std::ptrdiff_t>(b * kk * m));
    }
    const bool exact_pass = transmitted ? first_pass_exact_ : first_reflection_exact_;
    for (std::size_t a = 0; a < mu_i.size(); ++a) {
        if (!(mu_i[a] > 0)) continue;
        const Real scale = scattering_scale(mu_i[a], ws);
        const Real* fld = nullptr;
        const Real* c = exact_pass ? entry_and_field(mu_i[a], transmitted, ws, fld) : nullptr;  // (as with_exact_pass)
        if (!exact_pass) fld = field(mu_i[a], transmitted, ws);
        for (std::size_t b = 0; b < no; ++b) {
            const Real* w = exits.data() + b * kk * m;
            Real* a_k = out.data() + (a * no + b) * kk;
            std::fill(a_k, a_k + kk, Real(0));
            if (exact_pass && mu_o[b] > 0) {
                subtract_discrete_pass(transmitted, w, c, ws, a_k);
                add_exact_pass_modes(mu_i[a], mu_o[b], transmitted, ws, a_k);
            }
            for (std::size_t k = 0; k < kk; ++k) {
                Real s = a_k[k];
                for (std::size_t i = 0; i < m; ++i) s += w[k * m + i] * fld[k * m + i];
                a_k[k] = scale * mu_o[b] * s;
            }
        }
    }
    return out;
}

}  // namespace stratum
