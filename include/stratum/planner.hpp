// stratum/planner.hpp -- simulate only the effects a scene calls for: given a layered material, the outputs a
// renderer needs and a tolerance, choose the model and its discretization, estimate the error, run it, and say
// what it cost (docs/physics.md section 10).
//
// The models. The top face's own reflection (LayerOutput::surface_reflection alone) is a closed form: the rough
// face's BRDF or the Fresnel mirror, no solve. Everything that enters the layer is the discrete-ordinate solution
// (layer.hpp), whose error is set by the number of ordinates M: the planner solves M = 4, 8, 16, ... (4 times a
// power of 2, up to SceneRequest::max_ordinates; from 8 or more for scattering slabs joined by a refracting face,
// where fewer can trap light: detail::minimum_ordinates) and takes the first M from the second level on whose
// estimated error is within the tolerance, then solves the requested outputs there.
//
// The error estimate. The checked quantities are the hemispherical fluxes the request implies (the subsurface
// reflectance and the transmittance, each where asked) at the scene's incidences (SceneRequest::incidence; when
// none are given, at mu = 1, 0.7, 0.4 and 0.1). Each level solves mode 0 alone (the fluxes need no other; for
// angular outputs the rough faces are prepared with every mode at each level, so that the chosen level's faces
// serve the final solve), and the error at M is estimated from the changes between levels (plan_error_estimate).
// Its reliability is measured, not assumed: tests/test_planner.cpp checks on random materials that it bounds the
// true error (against M = 128) in at least 95% of them, and docs/accuracy.md reports a larger sweep. Angular
// outputs (BRDF, BTDF, the layer's operators) are then solved at that M with their Fourier modes cut at the same
// tolerance relative to mode 0 (LayerRequest::tolerance); their error is estimated apart and reported, not held to
// the tolerance (Plan::angular_error).
//
// The diffusion profile. A renderer's BSSRDF needs the radial profile R_d(r), which only the dipole gives
// (dipole.hpp: a half-space, diffusion, similarity). Asked for (SceneRequest::diffusion_profile), the plan builds it
// from the slab (albedo, g and Material::extinction) and estimates its error as that of its integral: the dipole's
// total diffuse reflectance at normal incidence, F_t(1) R_d,total, against the layer solver's subsurface
// reflectance R(1) of the same material at the chosen ordinates (within 1.6% of R(1) for reduced albedos of 0.99 and
// above, tens of percent at 0.5: docs/accuracy.md). With the scene's length scale it also says whether the profile
// matters at all.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "dipole.hpp"
#include "fresnel.hpp"
#include "layer.hpp"
#include "vec3.hpp"

namespace stratum {

/// A layered material as solve_stack takes it: a top face, slabs joined by interior faces (slabs.size() - 1 of
/// them, top to bottom), a bottom face.
template <class Real = double>
struct Material {
    Boundary<Real> top;
    std::vector<Slab<Real>> slabs;
    std::vector<Boundary<Real>> interior;
    Boundary<Real> bottom;
    /// The extinction coefficient sigma_t of a one-slab material in 1/length (its optical depth per unit length), for
    /// a diffusion profile in that length unit; 0: not given.
    Real extinction = 0;
};

/// What a scene needs from a material.
template <class Real = double>
struct SceneRequest {
    LayerOutput outputs = LayerOutput::all;
    /// The incidence cosines in (0, 1] the scene evaluates at: precomputed (LayerRequest::incidence) and where the
    /// error is estimated. Empty: estimated at mu = 1, 0.7, 0.4 and 0.1, and any incidence evaluated on the fly.
    std::vector<Real> incidence;
    /// Absolute error allowed in the fluxes, as fractions of the incident flux, in (0, 1).
    Real tolerance = Real(1e-3);
    /// The largest number of ordinates the planner may use, 8 to 256 (the levels are 4 times powers of 2: 100 stops
    /// at 64; at least twice the first level, 16 for scattering slabs joined by a refracting face); past it the plan
    /// says the tolerance is not met.
    int max_ordinates = 64;
    /// With angular outputs, estimate their error (Plan::angular_error): one more solve at half the ordinates and a
    /// comparison at probe directions, about a tenth of the plan for Stam's layer but twice a smooth slab's 0.24 ms
    /// solve at 8 ordinates (docs/accuracy.md). Off: Plan::angular_error stays 0.
    bool estimate_angular_error = true;
    /// With angular outputs, > 0: also double the ordinates (up to max_ordinates) until Plan::angular_error is within
    /// this (relative to the largest probe value; [0, 1)); each doubling one more solve with every mode. 0: the
    /// ordinates the fluxes need. Implies estimate_angular_error.
    Real angular_tolerance = 0;
    /// Also the diffusion profile R_d(r) for a BSSRDF (the dipole, PlannedLayer::dipole): needs one slab and
    /// Material::extinction.
    bool diffusion_profile = false;
    /// The smallest length the scene resolves (a pixel's footprint on the surface), in the unit of
    /// Material::extinction; 0: not given. With a diffusion profile, the plan says whether it is local
    /// (Plan::profile_local).
    Real length_scale = 0;
    /// The scene evaluates at any incidence, beyond `incidence` (a renderer, or a TabulatedBSDF built from the
    /// layer): the final solve tabulates the faces (LayerRequest::tabulate_faces), so that reflectance,
    /// transmittance, brdf and btdf cost microseconds at any angle, within that table's error.
    bool tabulate_faces = false;
};

/// Which model answers the request.
enum class Model {
    closed_form,   ///< the top face alone (LayerOutput::surface_reflection): no solve, exact
    layer_solver,  ///< the discrete-ordinate solution (solve_stack) at the plan's ordinates
};

/// The plan: the model, its settings, the estimated error and the measured cost.
template <class Real = double>
struct Plan {
    Model model = Model::closed_form;
    /// The discretization of the final solve: the ordinates chosen, the modes prepared (1 for fluxes alone, 0 = 2M
    /// otherwise) and the rough faces' integrals no finer than the tolerance needs (hemispherical_nodes,
    /// azimuthal_points: integrals_for_tolerance, as LayerRequest::tolerance); the rest default.
    LayerOptions options;
    LayerRequest<Real> request;   ///< what the final solve computed
    Real estimated_error = 0;     ///< estimated largest absolute error of the checked fluxes (0: closed form; finite otherwise)
    bool tolerance_met = true;    ///< false: max_ordinates reached with estimated_error above the tolerance
    std::vector<int> ordinates_tried;  ///< the mode-0 solves that chose the ordinates, in order
    int modes = 0;                ///< Fourier modes of the final solve (1 for fluxes and ambient alone)
    double planning_seconds = 0;  ///< measured: the mode-0 solves that chose the ordinates
    double solve_seconds = 0;     ///< measured: the final solve and the angular estimate's (0 for fluxes alone)
    /// With angular outputs: the estimated largest error of f |wi.z| |wo.z| of the subsurface BRDF and the BTDF, as
    /// asked, at probe directions (the checked incidences; exit cosines 0.2, 0.5, 0.8 and 1 at azimuths 0, pi/2 and pi
    /// from the plane of incidence), relative to the largest such value: twice the change from the previous level's
    /// ordinates, whose faces the levels prepared already (that solve costs about an eighth of the final one). Not
    /// held to the tolerance (which bounds the fluxes): a renderer reads it to decide. 0 otherwise.
    Real angular_error = 0;
    /// With a diffusion profile: |F_t(1) R_d,total - R(1)|, the dipole's total diffuse reflectance at normal incidence
    /// against the layer solver's (fractions of the incident flux; see the file comment). 0 otherwise.
    Real profile_error = 0;
    /// With a diffusion profile and a length scale: the profile's diffuse mean free path 1 / sigma_tr is below a tenth
    /// of the length scale, so the dipole's sampling density (dipole.hpp) puts all but 11 e^-10 = 5e-4 of it within
    /// the scene's resolution: subsurface transport is local there, and the layer's BRDF answers it without a BSSRDF.
    bool profile_local = false;
    /// With SceneRequest::angular_tolerance: whether angular_error met it within max_ordinates (true otherwise).
    bool angular_tolerance_met = true;
    std::string reason;           ///< one line: why this model and these settings
};

template <class Real = double>
struct PlannedLayer {
    Plan<Real> plan;
    LayeredSurface<Real> surface;  ///< evaluate the requested outputs here (the others give 0)
    std::optional<Dipole<Real>> dipole;  ///< the diffusion profile, when asked for
};

/// One material at several wavelengths (solve_planned_spectral): one plan for all, a solution per wavelength.
template <class Real = double>
struct PlannedSpectrum {
    /// The estimate is the worst wavelength's, modes the most any wavelength kept, profile_error the largest, and
    /// profile_local true only when every wavelength's profile is local.
    Plan<Real> plan;
    std::vector<LayeredSurface<Real>> surfaces;  ///< per wavelength
    std::vector<Dipole<Real>> dipoles;           ///< per wavelength, when a diffusion profile was asked for
};

/// The estimated error at the ordinates of the last level, from the largest changes of the checked fluxes between
/// levels (changes[i]: from level i to level i + 1, each with twice the ordinates of the one before):
///   estimate = 2 max(last change, previous change / 4).
/// With an error falling as M^-p the last change is (2^p - 1) times the error: the factor 2 covers convergence down
/// to p = 0.58 (a rough bottom face converges about as 1/M). Convergence is not monotone (the ordinates move past
/// the critical cosines as M doubles), and a level can land near the answer by chance: the previous change, a
/// quarter of it, guards against that (from the second change on: the first level, 8 ordinates, has only the one
/// change from 4). Measured on 560 random materials (docs/physics.md section 10): without the
/// guard the estimate bounded the error at 98.2% of the levels 8 to 64 but was once 64 times below it; with it,
/// 98.9%, at worst 3.2 times below, for 3 to 7% more levels.
template <class Real>
Real plan_error_estimate(const std::vector<Real>& changes) noexcept {
    if (changes.empty()) return std::numeric_limits<Real>::infinity();
    const Real last = changes.back();
    const Real previous = changes.size() > 1 ? changes[changes.size() - 2] : Real(0);
    return 2 * std::max(last, previous / 4);
}

namespace detail {

// The faces of a material prepared for one discretization; the next level shares their entry tables.
template <class Real>
struct PreparedFaces {
    PreparedBoundary<Real> top, bottom;
    std::vector<PreparedBoundary<Real>> interior;
};

template <class Real>
PreparedFaces<Real> prepare_faces(const Material<Real>& m, const LayerOptions& o, const PreparedFaces<Real>* before) {
    const bool turned = turned_over(m.top, m.bottom);
    PreparedBoundary<Real> top = before ? PreparedBoundary<Real>(before->top, o) : PreparedBoundary<Real>(m.top, o);
    PreparedBoundary<Real> bottom = turned   ? top.turned_over()
                                    : before ? PreparedBoundary<Real>(before->bottom, o)
                                             : PreparedBoundary<Real>(m.bottom, o);
    std::vector<PreparedBoundary<Real>> interior;
    for (std::size_t i = 0; i < m.interior.size(); ++i)
        interior.push_back(before ? PreparedBoundary<Real>(before->interior[i], o) : PreparedBoundary<Real>(m.interior[i], o));
    return {std::move(top), std::move(bottom), std::move(interior)};
}

// The checked fluxes of a solved layer: the subsurface reflectance and the transmittance at each incidence, as asked.
template <class Real>
std::vector<Real> checked_fluxes(const LayeredSurface<Real>& s, const std::vector<Real>& incidence, bool reflected,
                                 bool transmitted) {
    std::vector<Real> out;
    for (const Real mu : incidence) {
        if (reflected) out.push_back(s.reflectance(mu).subsurface);
        if (transmitted) out.push_back(s.transmittance(mu));
    }
    return out;
}

inline double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

inline std::string format_number(double x) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.2g", x);
    return buffer;
}

// The dipole of a one-slab material (sigma_a = (1 - albedo) sigma_t, sigma_s' = albedo (1 - g) sigma_t, eta of the top
// face), its error against the solved layer's reflectance at normal incidence, and whether it is local at the
// scene's length scale; folded into the plan's (the largest error; local only if every profile is).
template <class Real>
Dipole<Real> plan_profile(const Material<Real>& m, const SceneRequest<Real>& scene, const LayeredSurface<Real>& solved,
                          Plan<Real>& plan) {
    const Slab<Real>& slab = m.slabs.front();
    // Jensen's fit of F_dr where it holds (production's convention, section 8), the exact F_dr elsewhere (a top
    // leading into a less dense medium, or eta above 3).
    const Real eta = m.top.eta_below() / m.top.eta_above();
    const DiffuseFresnel model = eta >= 1 && eta <= 3 ? DiffuseFresnel::jensen_fit : DiffuseFresnel::exact;
    const Dipole<Real> dipole(slab.one_minus_albedo() * m.extinction, slab.albedo() * (1 - slab.g()) * m.extinction,
                              eta, model);
    const Real entry = 1 - fresnel_dielectric(Real(1), eta);
    plan.profile_error = std::max(plan.profile_error,
                                  std::fabs(entry * dipole.total_reflectance() - solved.reflectance(Real(1)).subsurface));
    plan.profile_local = plan.profile_local && scene.length_scale > 0 &&
                         dipole.diffuse_mean_free_path() < scene.length_scale / 10;
    return dipole;
}

// Two boundaries that prepare alike: the same kind, indices, roughness and shadowing, or floor albedo.
template <class Real>
bool same_boundary(const Boundary<Real>& a, const Boundary<Real>& b) noexcept {
    if (a.rough() != b.rough() || a.lambertian() != b.lambertian() || a.eta_above() != b.eta_above() ||
        a.eta_below() != b.eta_below() || a.floor_albedo() != b.floor_albedo())
        return false;
    return !a.rough() || (a.rough_interface()->sigma() == b.rough_interface()->sigma() &&
                          a.rough_interface()->shadowing() == b.rough_interface()->shadowing());
}

// The first level: 4, or the smallest 4 times a power of 2 that a stack with refracting joints takes
// (detail::minimum_ordinates: 8 for up to 7 critical cosines).
template <class Real>
int first_level(const Material<Real>& m) {
    const int needed = minimum_ordinates(m.top, m.slabs, m.interior, m.bottom);
    int first = 4;
    while (first < needed) first *= 2;
    return first;
}

// The request's checks, in solve_planned's order: outputs, tolerance, max_ordinates, incidences, length scale,
// profile. (Outputs beyond LayerOutput::all, or none without a diffusion profile, were accepted: the levels ran to
// max_ordinates for nothing, or the final solve refused them after the whole search; found by review.)
template <class Real>
void require_scene(const Material<Real>& material, const SceneRequest<Real>& scene) {
    const auto outputs = static_cast<unsigned>(scene.outputs);
    if ((outputs & ~static_cast<unsigned>(LayerOutput::all)) != 0)
        throw_out_of_range("outputs", static_cast<long long>(outputs), "combinations of LayerOutput's flags, [0, 127]");
    if (outputs == 0 && !scene.diffusion_profile)
        fail_invalid_argument("stratum: solve_planned: outputs = 0 and no diffusion profile: nothing is asked for");
    require_open("tolerance", scene.tolerance, Real(0), Real(1));
    if (scene.max_ordinates < 8 || scene.max_ordinates > 256)
        throw_out_of_range("max_ordinates", scene.max_ordinates, "[8, 256]");
    // Two levels at least, for an estimate (slabs joined by a refracting face start at 8 or more: with max_ordinates 8
    // one level ran and the estimate stayed infinite; found by review).
    if (scene.max_ordinates < 2 * first_level(material))
        throw_out_of_range("max_ordinates", scene.max_ordinates,
                           "[" + std::to_string(2 * first_level(material)) + ", 256] for this material (two levels)");
    for (std::size_t j = 0; j < scene.incidence.size(); ++j)
        require_closed(("incidence[" + std::to_string(j) + "]").c_str(), scene.incidence[j],
                       std::nextafter(Real(0), Real(1)), Real(1));
    require_nonnegative("length_scale", scene.length_scale);
    require_closed("angular_tolerance", scene.angular_tolerance, Real(0), std::nextafter(Real(1), Real(0)));
    if (scene.diffusion_profile) {
        if (material.slabs.size() != 1)
            fail_invalid_argument("stratum: a diffusion profile needs a material of one slab, got " +
                                  std::to_string(material.slabs.size()));
        require_positive("extinction", material.extinction);
    }
}

// The request's checks, in solve_planned's order: tolerance, max_ordinates, incidences, length scale, profile; for
// several wavelengths also that there is one and that their faces agree.
template <class Real>
void require_scene(const std::vector<Material<Real>>& wavelengths, const SceneRequest<Real>& scene) {
    if (wavelengths.empty()) fail_invalid_argument("stratum: solve_planned_spectral: no wavelengths");
    for (std::size_t w = 1; w < wavelengths.size(); ++w) {
        const Material<Real>& a = wavelengths[0];
        const Material<Real>& b = wavelengths[w];
        bool same = same_boundary(a.top, b.top) && same_boundary(a.bottom, b.bottom) && a.interior.size() == b.interior.size();
        for (std::size_t i = 0; same && i < a.interior.size(); ++i) same = same_boundary(a.interior[i], b.interior[i]);
        if (!same)
            fail_invalid_argument("stratum: solve_planned_spectral: the faces of wavelengths[" + std::to_string(w) +
                                  "] differ from those of wavelengths[0] (faces that vary with wavelength: plan each alone)");
    }
    for (const Material<Real>& material : wavelengths) require_scene(material, scene);
}

// What the levels check: the fluxes the outputs imply, at the scene's incidences (or a default set; with normal
// incidence added for a diffusion profile), and the mode-0 request that computes them with what else the request asks
// of mode 0.
template <class Real>
struct Checked {
    bool angular, transmitted, reflected;
    std::vector<Real> incidence;
    LayerRequest<Real> request;
    explicit Checked(const SceneRequest<Real>& scene)
        : angular(includes(scene.outputs, LayerOutput::subsurface_reflection | LayerOutput::transmission | LayerOutput::operators)),
          transmitted(includes(scene.outputs, LayerOutput::transmission | LayerOutput::transmittance | LayerOutput::operators)),
          // (the operators carry both: with reflection left out, over a floor whose transmittance is 0 the levels
          // saw no change, estimated error 0 at 8 ordinates where R was 1.4e-4 off at a tolerance of 1e-5; found by
          // review)
          reflected(!transmitted || scene.diffusion_profile ||
                    includes(scene.outputs, LayerOutput::subsurface_reflection | LayerOutput::reflectance |
                                                LayerOutput::ambient | LayerOutput::operators)),
          incidence(scene.incidence.empty() ? std::vector<Real>{Real(1), Real(0.7), Real(0.4), Real(0.1)} : scene.incidence) {
        if (scene.diffusion_profile && std::find(incidence.begin(), incidence.end(), Real(1)) == incidence.end())
            incidence.push_back(Real(1));  // (the dipole is checked at normal incidence)
        const auto mode_zero = static_cast<unsigned>(LayerOutput::surface_reflection | LayerOutput::ambient);
        request.outputs = (reflected ? LayerOutput::reflectance : LayerOutput{}) |
                          (transmitted ? LayerOutput::transmittance : LayerOutput{}) |
                          static_cast<LayerOutput>(static_cast<unsigned>(scene.outputs) & mode_zero);
        request.incidence = incidence;
        request.tolerance = scene.tolerance;
    }
};

// The largest difference of f |wi.z| |wo.z| between two solutions of the angular outputs asked (subsurface BRDF,
// BTDF), at the checked incidences, exit cosines 0.2, 0.5, 0.8, 1 and azimuths dphi = 0, pi/2, pi; and the largest
// value of a there. From their Fourier series (LayeredSurface::fourier_coefficients: one field per incidence, no
// azimuthal integral), not from brdf/btdf, which cost tens of microseconds each.
template <class Real>
std::pair<Real, Real> angular_change(const LayeredSurface<Real>& a, const LayeredSurface<Real>& b,
                                     const std::vector<Real>& incidence, LayerOutput outputs) {
    const std::vector<Real> exit{Real(0.2), Real(0.5), Real(0.8), Real(1)};
    Real change = 0, scale = 0;
    for (const LayerOutput which : {LayerOutput::subsurface_reflection, LayerOutput::transmission}) {
        if (!includes(outputs, which | LayerOutput::operators)) continue;
        const std::vector<Real> ca = a.fourier_coefficients(which, incidence, exit);
        const std::vector<Real> cb = b.fourier_coefficients(which, incidence, exit);
        const std::size_t ka = static_cast<std::size_t>(a.modes()), kb = static_cast<std::size_t>(b.modes());
        for (std::size_t i = 0; i < incidence.size(); ++i)
            for (std::size_t o = 0; o < exit.size(); ++o)
                for (const Real dphi : {Real(0), pi_v<Real> / 2, pi_v<Real>}) {
                    Real fa = 0, fb = 0;  // f |wo.z| = sum_k a_k cos(k dphi)
                    for (std::size_t k = 0; k < ka; ++k) fa += ca[(i * exit.size() + o) * ka + k] * std::cos(Real(k) * dphi);
                    for (std::size_t k = 0; k < kb; ++k) fb += cb[(i * exit.size() + o) * kb + k] * std::cos(Real(k) * dphi);
                    change = std::max(change, incidence[i] * std::fabs(fa - fb));
                    scale = std::max(scale, incidence[i] * fa);
                }
    }
    return {change, scale};
}

// The level search's result: the chosen level's faces and its mode-0 solves, one per wavelength.
template <class Real>
struct Levels {
    PreparedFaces<Real> faces;
    std::optional<PreparedFaces<Real>> before;  // the previous level's faces (angular outputs: every mode prepared)
    std::vector<LayeredSurface<Real>> last;
};

// Solves the levels M = 4 (or first_level), 8, 16, ... until the estimate meets the tolerance or max_ordinates is reached; writes the
// options, the ordinates tried, the estimate and the first part of the reason into the plan.
template <class Real>
Levels<Real> solve_levels(const std::vector<Material<Real>>& wavelengths, const SceneRequest<Real>& scene,
                          const Checked<Real>& checked, Plan<Real>& plan) {
    // Integrals no finer than the tolerance needs, as a plain solve with this tolerance takes them: every level
    // shares their error, which the estimate cannot see, so it is kept 35 times or more inside the tolerance.
    plan.options = integrals_for_tolerance(plan.options, scene.tolerance);
    std::vector<Real> previous, changes;
    std::optional<PreparedFaces<Real>> faces, before;
    std::vector<LayeredSurface<Real>> last;
    Real estimate = std::numeric_limits<Real>::infinity();
    int first = 4;  // (the largest over the wavelengths: an absorbing first one took 4 for all, found by review)
    for (const Material<Real>& w : wavelengths) first = std::max(first, first_level(w));
    for (int m = first; m <= scene.max_ordinates; m *= 2) {
        plan.options.ordinates = m;
        plan.options.modes = checked.angular ? 0 : 1;  // angular: every mode now, so that the chosen level's faces serve the final solve
        if (faces) before = *faces;
        faces = prepare_faces(wavelengths.front(), plan.options, faces ? &*faces : nullptr);
        last.clear();
        std::vector<Real> fluxes;
        for (const Material<Real>& material : wavelengths) {
            last.push_back(solve_stack(faces->top, material.slabs, faces->interior, faces->bottom, checked.request));
            const std::vector<Real> f = checked_fluxes(last.back(), checked.incidence, checked.reflected, checked.transmitted);
            fluxes.insert(fluxes.end(), f.begin(), f.end());
        }
        plan.ordinates_tried.push_back(m);
        if (!previous.empty()) {
            Real change = 0;
            for (std::size_t i = 0; i < fluxes.size(); ++i) {
                const Real d = std::fabs(fluxes[i] - previous[i]);
                if (!(d < std::numeric_limits<Real>::infinity()))
                    fail_domain_error("stratum: solve_planned: a flux at " + std::to_string(m) + " ordinates is not finite");
                change = std::max(change, d);
            }
            changes.push_back(change);
            estimate = plan_error_estimate(changes);
            if (estimate <= scene.tolerance) break;
        }
        previous = std::move(fluxes);
    }
    plan.estimated_error = estimate;
    plan.tolerance_met = estimate <= scene.tolerance;
    plan.reason = "layer solver: " + std::to_string(plan.options.ordinates) + " ordinates, estimated error " +
                  format_number(double(estimate)) + (plan.tolerance_met ? " <= " : " > (max_ordinates reached) ") +
                  format_number(double(scene.tolerance));
    return {std::move(*faces), std::move(before), std::move(last)};
}

}  // namespace detail

template <class Real>
PlannedSpectrum<Real> solve_planned_spectral(const std::vector<Material<Real>>& wavelengths, const SceneRequest<Real>& scene);

/// Plans and solves: the closed form for the top face's reflection alone; otherwise the layer solver at the fewest
/// ordinates (8, 16, 32, ... up to request.max_ordinates) whose estimated error in the checked fluxes is within
/// request.tolerance (see the file comment), with only the Fourier modes the outputs need; and the dipole for a
/// diffusion profile. Throws std::invalid_argument for a tolerance outside (0, 1), max_ordinates outside [8, 256],
/// an incidence outside (0, 1], a negative or non-finite length scale, a diffusion profile without one slab or a
/// positive finite extinction, or a material solve_stack rejects; std::domain_error if a level's fluxes are not
/// finite (the solver's contract is that they are).
template <class Real>
PlannedLayer<Real> solve_planned(const Material<Real>& material, const SceneRequest<Real>& scene) {
    PlannedSpectrum<Real> one = solve_planned_spectral(std::vector<Material<Real>>{material}, scene);
    std::optional<Dipole<Real>> dipole;
    if (!one.dipoles.empty()) dipole = one.dipoles.front();
    return {std::move(one.plan), std::move(one.surfaces.front()), std::move(dipole)};
}

/// One material at several wavelengths (RGB, or 16 to 64 spectral samples): the faces the same at every wavelength,
/// the slabs (and extinction) per wavelength. One plan for all, as solve_planned's: each level prepares the faces
/// once and solves every wavelength's mode 0 from them, the estimate is the largest change over all wavelengths'
/// fluxes, and the final solve runs per wavelength from the chosen level's faces. Throws as solve_planned, and
/// std::invalid_argument for no wavelengths or faces that differ between them.
template <class Real>
PlannedSpectrum<Real> solve_planned_spectral(const std::vector<Material<Real>>& wavelengths, const SceneRequest<Real>& scene) {
    const auto start = std::chrono::steady_clock::now();
    detail::require_scene(wavelengths, scene);
    PlannedSpectrum<Real> out;
    Plan<Real>& plan = out.plan;
    plan.request.outputs = scene.outputs;
    plan.request.incidence = scene.incidence;
    plan.request.tolerance = scene.tolerance;
    plan.request.tabulate_faces = scene.tabulate_faces;
    if (scene.outputs == LayerOutput::surface_reflection && !scene.diffusion_profile) {
        plan.options.ordinates = 1;
        plan.reason = "closed form: the top face's own reflection needs no solve";
        for (const Material<Real>& m : wavelengths)
            out.surfaces.push_back(solve_stack(m.top, m.slabs, m.interior, m.bottom, plan.options, plan.request));
        plan.solve_seconds = detail::seconds_since(start);
        return out;
    }
    plan.model = Model::layer_solver;
    const detail::Checked<Real> checked(scene);
    detail::Levels<Real> levels = detail::solve_levels(wavelengths, scene, checked, plan);
    plan.planning_seconds = detail::seconds_since(start);
    plan.profile_local = scene.diffusion_profile;  // (then and-ed over the wavelengths)
    if (scene.diffusion_profile)
        for (std::size_t w = 0; w < wavelengths.size(); ++w)
            out.dipoles.push_back(detail::plan_profile(wavelengths[w], scene, levels.last[w], plan));
    const std::string profile =
        !scene.diffusion_profile
            ? std::string()
            : "; diffusion profile: the dipole, its total reflectance " + detail::format_number(double(plan.profile_error)) +
                  " from the layer's" + (plan.profile_local ? " (local at the scene's length scale: the BRDF suffices)" : "");
    if (!checked.angular) {
        plan.request = checked.request;
        plan.request.tabulate_faces = scene.tabulate_faces;
        plan.modes = 1;
        plan.reason += "; Fourier mode 0 only (no angular output asked)" + profile;
        if (!scene.tabulate_faces) {
            out.surfaces = std::move(levels.last);
            return out;
        }
        const auto solve_start = std::chrono::steady_clock::now();  // (the last level again, with the tables)
        for (const Material<Real>& m : wavelengths)
            out.surfaces.push_back(solve_stack(levels.faces.top, m.slabs, levels.faces.interior, levels.faces.bottom, plan.request));
        plan.solve_seconds = detail::seconds_since(solve_start);
        plan.reason += "; the faces tabulated";
        return out;
    }
    const auto solve_start = std::chrono::steady_clock::now();
    LayerRequest<Real> untabulated = plan.request;  // (the faces are tabulated once, for the solve kept)
    untabulated.tabulate_faces = false;
    const bool estimate = scene.estimate_angular_error || scene.angular_tolerance > 0;
    // The estimate compares the angular series of two solves, which a request for the layer's operators does not
    // hold: the solves compared get them too (compared with zeros, the estimate was 0 for the operators alone, where
    // it is 1.03 for the BRDF and BTDF, and 15.4 for the BRDF with the operators, where it is 0.39: found by review).
    const LayerOutput angular = LayerOutput::subsurface_reflection | LayerOutput::transmission;
    if (estimate && includes(untabulated.outputs, LayerOutput::operators)) {
        untabulated.outputs = untabulated.outputs | angular;
        plan.request.outputs = untabulated.outputs;  // (the plan's request describes the surfaces it returns)
    }
    for (const Material<Real>& m : wavelengths) {
        out.surfaces.push_back(solve_stack(levels.faces.top, m.slabs, levels.faces.interior, levels.faces.bottom, untabulated));
        plan.modes = std::max(plan.modes, out.surfaces.back().modes());
    }
    // The angular estimate: the same request at the previous level's ordinates (its faces are prepared), compared;
    // with an angular tolerance, the ordinates doubled (faces prepared from the last) until the estimate meets it.
    const int flux_ordinates = plan.options.ordinates;
    LayerRequest<Real> probe = untabulated;  // (the coarse solve needs the angular series, not the layer's operators)
    probe.outputs = static_cast<LayerOutput>(static_cast<unsigned>(probe.outputs) & ~static_cast<unsigned>(LayerOutput::operators));
    std::vector<LayeredSurface<Real>> coarse;
    for (std::size_t w = 0; estimate && levels.before && w < wavelengths.size(); ++w) {
        const Material<Real>& m = wavelengths[w];
        coarse.push_back(solve_stack(levels.before->top, m.slabs, levels.before->interior, levels.before->bottom, probe));
    }
    while (estimate && !coarse.empty()) {
        plan.angular_error = 0;
        for (std::size_t w = 0; w < wavelengths.size(); ++w) {
            const auto [change, scale] = detail::angular_change(out.surfaces[w], coarse[w], checked.incidence, scene.outputs);
            if (scale > 0) plan.angular_error = std::max(plan.angular_error, 2 * change / scale);
        }
        plan.angular_tolerance_met = !(scene.angular_tolerance > 0) || plan.angular_error <= scene.angular_tolerance;
        if (plan.angular_tolerance_met || 2 * plan.options.ordinates > scene.max_ordinates) break;
        plan.options.ordinates *= 2;
        plan.ordinates_tried.push_back(plan.options.ordinates);
        levels.faces = detail::prepare_faces(wavelengths.front(), plan.options, &levels.faces);
        coarse = std::move(out.surfaces);
        out.surfaces.clear();
        for (const Material<Real>& m : wavelengths) {
            out.surfaces.push_back(solve_stack(levels.faces.top, m.slabs, levels.faces.interior, levels.faces.bottom, untabulated));
            plan.modes = std::max(plan.modes, out.surfaces.back().modes());
        }
    }
    if (scene.tabulate_faces)  // the solve kept, again from its prepared faces, with the tables
        for (std::size_t w = 0; w < wavelengths.size(); ++w)
            out.surfaces[w] = solve_stack(levels.faces.top, wavelengths[w].slabs, levels.faces.interior, levels.faces.bottom, plan.request);
    plan.solve_seconds = detail::seconds_since(solve_start);
    plan.reason += "; " + std::to_string(plan.modes) + " of " + std::to_string(2 * plan.options.ordinates) +
                   " Fourier modes (cut at the tolerance)" +
                   (estimate ? ", angular error about " + detail::format_number(double(plan.angular_error)) +
                                   " of the largest probe" +
                                   (plan.angular_tolerance_met ? "" : " (angular tolerance not met at max_ordinates)")
                             : std::string()) +
                   (plan.options.ordinates > flux_ordinates
                        ? "; " + std::to_string(plan.options.ordinates) + " ordinates for the angular tolerance"
                        : std::string()) +
                   (scene.tabulate_faces ? "; the faces tabulated" : "") + profile;
    return out;
}

}  // namespace stratum
