// The layer solver on Stam's skin layer (n 1 | 1.4 | 1, sigma 0.3 both sides, albedo 0.9, g 0.8, e^-tau 0.5):
// the full request against the shortcuts a scene can ask for, and evaluation at true angles.
#include <benchmark/benchmark.h>

#include <stratum/layer.hpp>
#include <stratum/planner.hpp>

#include <cmath>
#include <vector>

namespace {

using Real = double;

stratum::LayeredSurface<Real> skin(int ordinates, const stratum::LayerRequest<Real>& request = {}) {
    const stratum::RoughDielectric<Real> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    stratum::LayerOptions options;
    options.ordinates = ordinates;
    return stratum::solve_layer(stratum::Slab<Real>::from_transparency(0.9, 0.8, 0.5), top, bottom, options, request);
}

// Full request: every output, K = 2M modes.
void BM_layer_solve_full(benchmark::State& state) {
    for (auto _ : state) benchmark::DoNotOptimize(skin(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_layer_solve_full)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// The planner (planner.hpp) on Stam's layer at mu0 = 0.5, one material per albedo (with g 0.8, e^-tau 0.5): outputs
// state.range(0) (0: fluxes, 1: subsurface reflection, 2: all) at tolerance 10^-state.range(1), from nothing.
void plan_skin(benchmark::State& state, const std::vector<Real>& albedos) {
    std::vector<stratum::Material<Real>> materials;
    for (const Real albedo : albedos)
        materials.push_back({stratum::RoughDielectric<Real>(0.3, 1.0, 1.4),
                             {stratum::Slab<Real>::from_transparency(albedo, 0.8, 0.5)}, {},
                             stratum::RoughDielectric<Real>(0.3, 1.4, 1.0)});
    stratum::SceneRequest<Real> scene;
    const stratum::LayerOutput outputs[] = {stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance,
                                            stratum::LayerOutput::subsurface_reflection, stratum::LayerOutput::all};
    scene.outputs = outputs[state.range(0)];
    scene.incidence = {0.5};
    scene.tolerance = std::pow(Real(10), -Real(state.range(1)));
    int ordinates = 0;
    for (auto _ : state) {
        if (materials.size() == 1) {
            const auto one = stratum::solve_planned(materials.front(), scene);
            ordinates = one.plan.options.ordinates;
            benchmark::DoNotOptimize(one.surface.reflectance(0.5).subsurface);
        } else {
            const auto all = stratum::solve_planned_spectral(materials, scene);
            ordinates = all.plan.options.ordinates;
            benchmark::DoNotOptimize(all.surfaces[0].reflectance(0.5).subsurface);
        }
    }
    state.counters["ordinates"] = ordinates;
}

// Stam's layer (albedo 0.9). It chooses 32 ordinates at 1e-2 and 64 at 1e-3: compare with BM_layer_solve_full at
// those (docs/accuracy.md, "Planner: cost against the full solve").
void BM_planner_skin(benchmark::State& state) { plan_skin(state, {0.9}); }
BENCHMARK(BM_planner_skin)->ArgsProduct({{0, 1, 2}, {2, 3}})->Unit(benchmark::kMillisecond);

// Red, green and blue at once (albedos 0.95, 0.9, 0.9; solve_planned_spectral): compare with BM_planner_skin at the
// same arguments (README's speed table: three wavelengths at 1.08 to 1.21 times one).
void BM_planner_skin_rgb(benchmark::State& state) { plan_skin(state, {0.95, 0.9, 0.9}); }
BENCHMARK(BM_planner_skin_rgb)->ArgsProduct({{0, 1, 2}, {2}})->Unit(benchmark::kMillisecond);

// Stam's layer solved for `request` from faces prepared once (PreparedBoundary), M = state.range(0): what a new
// albedo, g, thickness or wavelength costs. The albedo changes every iteration so that nothing but the faces is reused.
void solve_from_prepared_faces(benchmark::State& state, const stratum::LayerRequest<Real>& request) {
    stratum::LayerOptions options;
    options.ordinates = static_cast<int>(state.range(0));
    const stratum::PreparedBoundary<Real> top(stratum::RoughDielectric<Real>(0.3, 1.0, 1.4), options);
    const stratum::PreparedBoundary<Real> bottom(stratum::RoughDielectric<Real>(0.3, 1.4, 1.0), options);
    Real albedo = 0.9;
    for (auto _ : state) {
        albedo = albedo == 0.9 ? 0.91 : 0.9;
        benchmark::DoNotOptimize(
            stratum::solve_layer(stratum::Slab<Real>::from_transparency(albedo, 0.8, 0.5), top, bottom, request));
    }
}

// The same solve from prepared faces.
void BM_layer_solve_full_prepared(benchmark::State& state) { solve_from_prepared_faces(state, {}); }
BENCHMARK(BM_layer_solve_full_prepared)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// The same without the whole layer's operators (LayerOutput::operators, needed only to stack the layer): every
// other output, from prepared faces.
void BM_layer_solve_no_operators_prepared(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.outputs = static_cast<stratum::LayerOutput>(static_cast<unsigned>(stratum::LayerOutput::all) &
                                                  ~static_cast<unsigned>(stratum::LayerOutput::operators));
    solve_from_prepared_faces(state, r);
}
BENCHMARK(BM_layer_solve_no_operators_prepared)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// Preparing the two faces (their operators; the entry tables are built as evaluations need them).
void BM_layer_prepare_faces(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = static_cast<int>(state.range(0));
    for (auto _ : state) {
        benchmark::DoNotOptimize(stratum::PreparedBoundary<Real>(stratum::RoughDielectric<Real>(0.3, 1.0, 1.4), options));
        benchmark::DoNotOptimize(stratum::PreparedBoundary<Real>(stratum::RoughDielectric<Real>(0.3, 1.4, 1.0), options));
    }
}
BENCHMARK(BM_layer_prepare_faces)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// Solve plus the first reflectance(mu) evaluation, which computes the 4 points of the top face's entry
// transmittance table that interpolate at mu: from plain faces every solve pays for them, from prepared faces only
// the first.
void BM_layer_solve_and_first_reflectance(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = 16;
    const stratum::RoughDielectric<Real> rough_top(0.3, 1.0, 1.4), rough_bottom(0.3, 1.4, 1.0);
    const stratum::PreparedBoundary<Real> top(rough_top, options), bottom(rough_bottom, options);
    const bool prepared = state.range(0) == 1;
    Real albedo = 0.9;
    for (auto _ : state) {
        albedo = albedo == 0.9 ? 0.91 : 0.9;
        const auto slab = stratum::Slab<Real>::from_transparency(albedo, 0.8, 0.5);
        const auto layer = prepared ? stratum::solve_layer(slab, top, bottom)
                                    : stratum::solve_layer(slab, rough_top, rough_bottom, options);
        benchmark::DoNotOptimize(layer.reflectance(0.7).total());
    }
    state.SetLabel(prepared ? "prepared faces, M = 16" : "plain faces, M = 16");
}
BENCHMARK(BM_layer_solve_and_first_reflectance)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Three wavelengths (RGB) of Stam's skin from nothing, all outputs: the faces are prepared once (solve_spectral).
// Compare with BM_layer_solve_full at the same M (one wavelength).
void BM_layer_solve_spectral_rgb(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = static_cast<int>(state.range(0));
    const stratum::RoughDielectric<Real> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const std::vector<stratum::Slab<Real>> rgb = {stratum::Slab<Real>::from_transparency(0.9, 0.8, 0.5),
                                                  stratum::Slab<Real>::from_transparency(0.85, 0.8, 0.45),
                                                  stratum::Slab<Real>::from_transparency(0.8, 0.8, 0.4)};
    for (auto _ : state) benchmark::DoNotOptimize(stratum::solve_spectral(rgb, top, bottom, options));
}
BENCHMARK(BM_layer_solve_spectral_rgb)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// Reflection only, modes chosen by a tolerance of 1e-3.
void BM_layer_solve_reflection_tol1e3(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.outputs = stratum::LayerOutput::surface_reflection | stratum::LayerOutput::subsurface_reflection;
    r.tolerance = 1e-3;
    for (auto _ : state) benchmark::DoNotOptimize(skin(static_cast<int>(state.range(0)), r));
}
BENCHMARK(BM_layer_solve_reflection_tol1e3)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// The same from faces prepared once (README, known limitations: 1 ms aimed at for M = 24).
void BM_layer_solve_reflection_tol1e3_prepared(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.outputs = stratum::LayerOutput::surface_reflection | stratum::LayerOutput::subsurface_reflection;
    r.tolerance = 1e-3;
    solve_from_prepared_faces(state, r);
}
BENCHMARK(BM_layer_solve_reflection_tol1e3_prepared)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// Reflectance and transmittance alone (fluxes: Fourier mode 0, chosen by the solver), from plain faces and from
// prepared ones.
void BM_layer_solve_fluxes(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
    for (auto _ : state) benchmark::DoNotOptimize(skin(static_cast<int>(state.range(0)), r));
}
BENCHMARK(BM_layer_solve_fluxes)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

void BM_layer_solve_fluxes_prepared(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
    solve_from_prepared_faces(state, r);
}
BENCHMARK(BM_layer_solve_fluxes_prepared)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// Ambient term only: Fourier mode 0.
void BM_layer_solve_ambient(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.outputs = stratum::LayerOutput::ambient;
    for (auto _ : state) benchmark::DoNotOptimize(skin(static_cast<int>(state.range(0)), r));
}
BENCHMARK(BM_layer_solve_ambient)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

// Evaluation at true angles: subsurface BRDF with the incidence computed on the fly (a new one on every call: the
// Workspace keeps the last), with the same incidence on every call and a new exit, and with the incidence
// precomputed through LayerRequest::incidence (what a renderer with a fixed light direction does).
void eval_subsurface_brdf(benchmark::State& state, bool same_incidence) {
    const auto layer = skin(static_cast<int>(state.range(0)));
    stratum::LayeredSurface<Real>::Workspace ws;
    int i = 0;
    for (auto _ : state) {
        const double step = 1e-9 * (i++ % 1000);
        const auto wi = stratum::spherical_direction(same_incidence ? 0.8 : 0.8 + step, 0.0);
        const auto wo = stratum::spherical_direction(same_incidence ? 0.5 + step : 0.5, 2.0);
        benchmark::DoNotOptimize(layer.subsurface_brdf(wi, wo, ws));
    }
}
void BM_layer_eval_subsurface_brdf(benchmark::State& state) { eval_subsurface_brdf(state, false); }
BENCHMARK(BM_layer_eval_subsurface_brdf)->Arg(8)->Arg(16)->Arg(24)->Unit(benchmark::kMicrosecond);
void BM_layer_eval_subsurface_brdf_same_incidence(benchmark::State& state) { eval_subsurface_brdf(state, true); }
BENCHMARK(BM_layer_eval_subsurface_brdf_same_incidence)->Arg(8)->Arg(16)->Arg(24)->Unit(benchmark::kMicrosecond);

void BM_layer_eval_subsurface_brdf_cached_incidence(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.incidence = {0.8};
    const auto layer = skin(static_cast<int>(state.range(0)), r);
    stratum::LayeredSurface<Real>::Workspace ws;
    const auto wi = stratum::spherical_direction(0.8, 0.0), wo = stratum::spherical_direction(0.5, 2.0);
    for (auto _ : state) benchmark::DoNotOptimize(layer.subsurface_brdf(wi, wo, ws));
}
BENCHMARK(BM_layer_eval_subsurface_brdf_cached_incidence)->Arg(8)->Arg(16)->Arg(24)->Unit(benchmark::kMicrosecond);

}  // namespace

// reflectance(mu) (surface and subsurface) at an incidence computed on the fly, at a requested one, and on the
// fly from tabulated faces (LayerRequest::tabulate_faces); transmittance(mu) on the fly and from tabulated faces.
void BM_layer_eval_reflectance(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    if (state.range(1) == 1) r.incidence = {0.8};
    r.tabulate_faces = state.range(1) == 2;
    const auto layer = skin(static_cast<int>(state.range(0)), r);
    for (auto _ : state) benchmark::DoNotOptimize(layer.reflectance(0.8).total());
    state.SetLabel(state.range(1) == 1 ? "precomputed incidence" : state.range(1) == 2 ? "tabulated faces" : "on the fly");
}
BENCHMARK(BM_layer_eval_reflectance)->Args({16, 0})->Args({16, 1})->Args({16, 2})->Unit(benchmark::kMicrosecond);

void BM_layer_eval_transmittance(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.tabulate_faces = state.range(1) == 2;
    const auto layer = skin(static_cast<int>(state.range(0)), r);
    for (auto _ : state) benchmark::DoNotOptimize(layer.transmittance(0.8));
    state.SetLabel(state.range(1) == 2 ? "tabulated faces" : "on the fly");
}
BENCHMARK(BM_layer_eval_transmittance)->Args({16, 0})->Args({16, 2})->Unit(benchmark::kMicrosecond);

// brdf (surface and subsurface) at true angles, the incidence new on every call, from tabulated faces (compare
// BM_layer_eval_subsurface_brdf, the integrals).
void BM_layer_eval_brdf_tabulated(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.tabulate_faces = true;
    const auto layer = skin(static_cast<int>(state.range(0)), r);
    stratum::LayeredSurface<Real>::Workspace ws;
    const auto wo = stratum::spherical_direction(0.5, 2.0);
    int i = 0;
    for (auto _ : state) {
        const auto wi = stratum::spherical_direction(0.8 + 1e-9 * (i++ % 1000), 0.0);
        benchmark::DoNotOptimize(layer.brdf(wi, wo, ws));
    }
}
BENCHMARK(BM_layer_eval_brdf_tabulated)->Arg(8)->Arg(16)->Arg(24)->Unit(benchmark::kMicrosecond);

// The solve with the faces tabulated (all outputs), beside BM_layer_solve_full.
void BM_layer_solve_full_tabulated(benchmark::State& state) {
    stratum::LayerRequest<Real> r;
    r.tabulate_faces = true;
    for (auto _ : state) benchmark::DoNotOptimize(skin(static_cast<int>(state.range(0)), r));
}
BENCHMARK(BM_layer_solve_full_tabulated)->Arg(16)->Arg(24)->Unit(benchmark::kMillisecond);

// The same from prepared faces, which keep their tables: a new albedo, g, thickness or wavelength pays for the slab
// (the first solve, outside the timing, built the tables).
void BM_layer_solve_full_tabulated_prepared(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = static_cast<int>(state.range(0));
    const stratum::PreparedBoundary<Real> top(stratum::RoughDielectric<Real>(0.3, 1.0, 1.4), options),
        bottom(stratum::RoughDielectric<Real>(0.3, 1.4, 1.0), options);
    stratum::LayerRequest<Real> r;
    r.tabulate_faces = true;
    benchmark::DoNotOptimize(stratum::solve_layer(stratum::Slab<Real>::from_transparency(0.9, 0.8, 0.5), top, bottom, r));
    Real albedo = 0.9;
    for (auto _ : state) {
        albedo = albedo == 0.9 ? 0.91 : 0.9;
        benchmark::DoNotOptimize(stratum::solve_layer(stratum::Slab<Real>::from_transparency(albedo, 0.8, 0.5), top, bottom, r));
    }
}
BENCHMARK(BM_layer_solve_full_tabulated_prepared)->Arg(16)->Arg(24)->Unit(benchmark::kMillisecond);

namespace {

// A slab between smooth Fresnel faces (n 1 | 1.4 | 1, albedo 0.9, g 0.8, tau 1), reflectance and transmittance
// at normal incidence (mode 0), with the ordinates split at the critical cosine (default) and with one
// half-range rule: accuracy against Prahl's converged adding-doubling in docs/accuracy.md.
void BM_layer_fresnel_slab_fluxes(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = static_cast<int>(state.range(0));
    options.critical_split = state.range(1) != 0;
    stratum::LayerRequest<Real> request;
    request.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
    for (auto _ : state) {
        const auto layer = stratum::solve_layer(stratum::Slab<Real>(0.9, 0.8, 1.0), stratum::SmoothDielectric<Real>(1.0, 1.4),
                                                stratum::SmoothDielectric<Real>(1.4, 1.0), options, request);
        benchmark::DoNotOptimize(layer.reflectance(1.0).total() + layer.transmittance(1.0));
    }
}
BENCHMARK(BM_layer_fresnel_slab_fluxes)->Args({8, 1})->Args({16, 1})->Args({18, 1})->Args({24, 1})->Args({32, 1})->Args({16, 0})->Args({32, 0})
    ->Unit(benchmark::kMicrosecond);

// Between smooth faces the beam is a source and the exit an integral of the source function (docs/physics.md
// section 6): the subsurface BRDF at a true angle, the incidence new on every call (Arg 0) or precomputed (Arg 1),
// or not precomputed but the same on every call, the exit new (Arg 2: the Workspace keeps the incidence's field),
// M = 16; the same slab as above.
void BM_layer_smooth_brdf_true_angle(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = 16;
    stratum::LayerRequest<Real> request;
    if (state.range(0) == 1) request.incidence = {Real(0.6)};
    const auto layer = stratum::solve_layer(stratum::Slab<Real>(0.9, 0.8, 1.0), stratum::SmoothDielectric<Real>(1.0, 1.4),
                                            stratum::SmoothDielectric<Real>(1.4, 1.0), options, request);
    typename stratum::LayeredSurface<Real>::Workspace ws;
    int i = 0;
    for (auto _ : state) {
        const Real step = Real(1e-9) * static_cast<Real>(i++ % 1000);
        const Real mu = state.range(0) == 0 ? Real(0.6) + step : Real(0.6), z = std::sqrt(Real(0.87)) - (state.range(0) == 2 ? step : 0);
        const stratum::Vec3<Real> wi{-std::sqrt(Real(1) - mu * mu), 0, mu}, wo{Real(0.3), Real(0.2), z};
        benchmark::DoNotOptimize(layer.subsurface_brdf(wi, wo, ws));
    }
}
BENCHMARK(BM_layer_smooth_brdf_true_angle)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

// The same problem's fluxes at its incidence alone (mode 0): stratum's side of bench/disort_compare, which times
// DISORT (cdisort, built outside this repository) beside it in one run.
void BM_layer_fluxes_disort_p1(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = static_cast<int>(state.range(0));
    stratum::LayerRequest<Real> request;
    request.incidence = {Real(0.5)};
    request.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
    for (auto _ : state) {
        const auto layer = stratum::solve_layer(stratum::Slab<Real>(Real(0.9), Real(0.75), 1),
                                                stratum::Boundary<Real>::index_matched(),
                                                stratum::Boundary<Real>::index_matched(), options, request);
        benchmark::DoNotOptimize(layer.reflectance(Real(0.5)).subsurface + layer.transmittance(Real(0.5)));
    }
}
BENCHMARK(BM_layer_fluxes_disort_p1)->Arg(2)->Arg(4)->Arg(8)->Arg(16)->Arg(32)->Unit(benchmark::kMicrosecond);

// DISORT's test problem P1 of tests/data/disort_intensity_reference.txt (g 0.75, albedo 0.9, tau 1, mu0 0.5, black
// faces): the solve and the 56 lit intensities at true angles, with the single-scattering correction; accuracy
// against converged DISORT in docs/accuracy.md.
void BM_layer_intensities_disort_p1(benchmark::State& state) {
    stratum::LayerOptions options;
    options.ordinates = static_cast<int>(state.range(0));
    options.single_scattering_correction = true;
    stratum::LayerRequest<Real> request;
    request.incidence = {Real(0.5)};
    request.outputs = stratum::LayerOutput::subsurface_reflection | stratum::LayerOutput::transmission;
    const Real umu[] = {1, Real(0.999), Real(0.9), Real(0.7), Real(0.5), Real(0.3), Real(0.1)};
    for (auto _ : state) {
        const auto layer = stratum::solve_layer(stratum::Slab<Real>(Real(0.9), Real(0.75), 1),
                                                stratum::Boundary<Real>::index_matched(),
                                                stratum::Boundary<Real>::index_matched(), options, request);
        typename stratum::LayeredSurface<Real>::Workspace ws;
        const stratum::Vec3<Real> wi{-std::sqrt(Real(0.75)), 0, Real(0.5)};
        Real sum = 0;
        for (const Real u : umu)
            for (const Real phi : {Real(0), Real(1.0471975511965976), Real(2.0943951023931953), Real(3.141592653589793)}) {
                const Real s = std::sqrt(1 - u * u);
                sum += layer.subsurface_brdf(wi, {s * std::cos(phi), s * std::sin(phi), u}, ws);
                sum += layer.btdf(wi, {s * std::cos(phi), s * std::sin(phi), -u}, ws);
            }
        benchmark::DoNotOptimize(sum);
    }
}
BENCHMARK(BM_layer_intensities_disort_p1)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Unit(benchmark::kMillisecond);

}  // namespace
