// The planner (planner.hpp): the closed form where no solve is needed; fluxes from mode 0 alone; angular outputs at
// the chosen ordinates with the modes cut at the tolerance, equal to the solve the plan names; and the error
// estimate checked against a converged solve on random materials (it must bound the true error in at least 95% of
// them, as the issue asks; the calibration sweep behind the estimate used other materials: docs/accuracy.md).
#include <doctest/doctest.h>

#include <stratum/planner.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "test_util.hpp"

using stratum::Boundary;
using stratum::LayerOptions;
using stratum::LayerOutput;
using stratum::LayerRequest;
using stratum::Material;
using stratum::Model;
using stratum::RoughDielectric;
using stratum::SceneRequest;
using stratum::Slab;
using stratum::SmoothDielectric;
using stratum::Vec3;
using stratum::solve_planned;
using stratum::solve_stack;
using stratum_test::uniform;

namespace {

// Stam's skin layer (docs/physics.md section 1).
Material<double> skin() {
    return {RoughDielectric<double>(0.3, 1.0, 1.4), {Slab<double>(0.9, 0.8, std::log(2.0))}, {},
            RoughDielectric<double>(0.3, 1.4, 1.0)};
}

// The plan's options (its integrals' knobs too) at other ordinates and modes.
LayerOptions with_ordinates(const LayerOptions& plan, int m, int modes = 0) {
    LayerOptions o = plan;
    o.ordinates = m;
    o.modes = modes;
    return o;
}

}  // namespace

TEST_CASE("the top face's reflection alone is the closed form: no solve") {
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::surface_reflection;
    const auto planned = solve_planned(skin(), scene);
    CHECK(planned.plan.model == Model::closed_form);
    CHECK(planned.plan.ordinates_tried.empty());
    CHECK(planned.plan.estimated_error == 0);
    const RoughDielectric<double> top(0.3, 1.0, 1.4);
    const Vec3<double> wi{0.6, 0.0, 0.8}, wo{-0.28, 0.0, 0.96};
    CHECK(planned.surface.brdf(wi, wo) == doctest::Approx(top.brdf(wi, wo)).epsilon(1e-14));
    CHECK(planned.surface.reflectance(0.8).subsurface == 0);
}

TEST_CASE("fluxes alone: mode 0 at doubling ordinates, the last solve is the answer") {
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::reflectance | LayerOutput::transmittance | LayerOutput::surface_reflection;
    scene.incidence = {0.5, 1.0};
    scene.tolerance = 1e-2;
    const auto planned = solve_planned(skin(), scene);
    const auto& plan = planned.plan;
    CHECK(plan.model == Model::layer_solver);
    CHECK(plan.modes == 1);
    CHECK(plan.tolerance_met);
    CHECK(plan.estimated_error <= scene.tolerance);
    CHECK(plan.solve_seconds == 0);
    REQUIRE(plan.ordinates_tried.size() >= 3);
    for (std::size_t i = 0; i < plan.ordinates_tried.size(); ++i) CHECK(plan.ordinates_tried[i] == 4 << i);
    const int m = plan.options.ordinates;
    CHECK(m == plan.ordinates_tried.back());
    CHECK(plan.options.hemispherical_nodes == 9);  // (integrals no finer than a tolerance of 1e-2 needs, as a plain
    CHECK(plan.options.azimuthal_points == 12);    //  solve with that tolerance: stratum::integrals_for_tolerance)
    // The estimate is twice the change from the level before (plan_error_estimate), recomputed here from plain solves.
    const Material<double> mat = skin();
    LayerRequest<double> fluxes;
    fluxes.outputs = scene.outputs;
    fluxes.incidence = scene.incidence;
    fluxes.tolerance = scene.tolerance;
    const auto at = solve_stack<double>(mat.top, mat.slabs, mat.interior, mat.bottom, with_ordinates(plan.options, m, 1), fluxes);
    const auto half = solve_stack<double>(mat.top, mat.slabs, mat.interior, mat.bottom, with_ordinates(plan.options, m / 2, 1), fluxes);
    const auto quarter = solve_stack<double>(mat.top, mat.slabs, mat.interior, mat.bottom, with_ordinates(plan.options, m / 4, 1), fluxes);
    double change = 0, previous = 0;
    for (const double mu : scene.incidence) {
        CHECK(planned.surface.reflectance(mu).subsurface == at.reflectance(mu).subsurface);  // bit for bit
        CHECK(planned.surface.transmittance(mu) == at.transmittance(mu));
        change = std::max({change, std::fabs(at.reflectance(mu).subsurface - half.reflectance(mu).subsurface),
                           std::fabs(at.transmittance(mu) - half.transmittance(mu))});
        previous = std::max({previous, std::fabs(half.reflectance(mu).subsurface - quarter.reflectance(mu).subsurface),
                             std::fabs(half.transmittance(mu) - quarter.transmittance(mu))});
    }
    CHECK(plan.estimated_error == 2 * std::max(change, previous / 4));
    CHECK(plan.estimated_error > 2 * change);  // (here the guard decides: Stam's layer converges fast from 16 on)
    const Vec3<double> wi{0.6, 0.0, 0.8}, wo{-0.28, 0.0, 0.96};
    CHECK(planned.surface.brdf(wi, wo) == at.brdf(wi, wo));  // the top's own reflection, asked
    CHECK(planned.surface.brdf(wi, wo) > 0);
    CHECK(planned.surface.subsurface_brdf(wi, wo) == 0);     // (not asked)
}

TEST_CASE("angular outputs: the plan's solve, modes cut at the tolerance") {
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::subsurface_reflection;
    scene.incidence = {0.8};
    scene.tolerance = 1e-3;
    scene.max_ordinates = 16;  // (the estimate asks for more here: the plan says the tolerance is not met)
    const auto planned = solve_planned(skin(), scene);
    const auto& plan = planned.plan;
    CHECK(plan.options.ordinates == 16);
    CHECK_FALSE(plan.tolerance_met);
    CHECK(plan.estimated_error > scene.tolerance);
    CHECK(plan.estimated_error < 0.1);
    CHECK(plan.modes > 1);
    CHECK(plan.modes < 32);
    const Material<double> mat = skin();
    const auto direct = solve_stack<double>(mat.top, mat.slabs, mat.interior, mat.bottom, with_ordinates(plan.options, 16), plan.request);
    CHECK(direct.modes() == plan.modes);
    const Vec3<double> wi{0.6, 0.0, 0.8};
    for (const Vec3<double> wo : {Vec3<double>{0.0, 0.0, 1.0}, Vec3<double>{-0.6, 0.0, 0.8}, Vec3<double>{0.0, 0.8, 0.6}})
        CHECK(planned.surface.subsurface_brdf(wi, wo) == doctest::Approx(direct.subsurface_brdf(wi, wo)).epsilon(1e-12));
    CHECK(planned.surface.transmittance(0.8) == 0);  // not asked
}

TEST_CASE("a scene that evaluates at any incidence: the final solve tabulates the faces") {
    // The same plan as without (the levels and the estimate do not change), the final solve with
    // LayerRequest::tabulate_faces: its outputs at incidences not listed are the untabulated solve's within the
    // table's error (tests/test_layer_tabulated.cpp), for fluxes alone (the last level solved again) and angular ones;
    // the closed form's surface reflectance from the top's checked table.
    SceneRequest<double> surface;
    surface.outputs = LayerOutput::surface_reflection;
    surface.tabulate_faces = true;
    const auto closed = solve_planned(skin(), surface);
    CHECK(closed.plan.model == Model::closed_form);
    CHECK(closed.plan.request.tabulate_faces);
    for (const double mu : {0.93, 0.51, 0.07}) {
        const double exact = skin().top.hemispherical_reflectance(mu);
        CHECK(closed.surface.reflectance(mu).surface != exact);  // (from the table)
        CHECK(closed.surface.reflectance(mu).surface == doctest::Approx(exact).epsilon(3e-6));
    }
    SceneRequest<double> base;
    base.incidence.push_back(0.8);
    base.tolerance = 1e-2;
    base.max_ordinates = 16;
    for (const LayerOutput outputs : {LayerOutput::reflectance | LayerOutput::transmittance, LayerOutput::subsurface_reflection}) {
        SceneRequest<double> scene = base;
        scene.outputs = outputs;
        const auto plain = solve_planned(skin(), scene);
        scene.tabulate_faces = true;
        const auto fast = solve_planned(skin(), scene);
        CHECK(fast.plan.options.ordinates == plain.plan.options.ordinates);
        CHECK(fast.plan.estimated_error == plain.plan.estimated_error);
        CHECK(fast.plan.request.tabulate_faces);
        CHECK(fast.surface.tabulated_couplings() >= 1);
        CHECK(plain.surface.tabulated_couplings() == 0);
        CHECK(fast.plan.reason.find("the faces tabulated") != std::string::npos);
        for (const double mu : {0.93, 0.51, 0.07}) {
            CAPTURE(mu);
            if (outputs == LayerOutput::subsurface_reflection) {
                const Vec3<double> wi = stratum::spherical_direction(mu, 0.0), wo{0.0, 0.6, 0.8};
                CHECK(fast.surface.subsurface_brdf(wi, wo) == doctest::Approx(plain.surface.subsurface_brdf(wi, wo)).epsilon(1e-4));
            } else {
                CHECK(fast.surface.reflectance(mu).subsurface == doctest::Approx(plain.surface.reflectance(mu).subsurface).epsilon(1e-4));
                CHECK(fast.surface.transmittance(mu) == doctest::Approx(plain.surface.transmittance(mu)).epsilon(1e-4));
            }
        }
    }
}

TEST_CASE("angular outputs: the estimate of their error against a finer solve") {
    // The probes of Plan::angular_error, recomputed against the same request at 64 ordinates (relative to the largest
    // probe value of the reference). The true errors, 1.81e-3 (skin) and 0.239 (the smooth slab), are the same to
    // three digits against 48, 64 and 96 ordinates; the estimates 2.6e-2 and 1.03. (96 took 18 s of the sanitized suite.)
    const auto probe_error = [](const stratum::LayeredSurface<double>& a, const stratum::LayeredSurface<double>& b,
                                double mu_i, bool transmission) {
        double worst = 0, scale = 0;
        const Vec3<double> wi{std::sqrt(1 - mu_i * mu_i), 0.0, mu_i};
        for (const double mu_o : {0.2, 0.5, 0.8, 1.0})
            for (const double phi : {0.0, stratum_test::pi / 2, stratum_test::pi}) {
                const double s = std::sqrt(1 - mu_o * mu_o);
                const Vec3<double> up{s * std::cos(phi), s * std::sin(phi), mu_o}, down{up.x, up.y, -mu_o};
                worst = std::max(worst, mu_i * mu_o * std::fabs(a.subsurface_brdf(wi, up) - b.subsurface_brdf(wi, up)));
                scale = std::max(scale, mu_i * mu_o * b.subsurface_brdf(wi, up));
                if (!transmission) continue;
                worst = std::max(worst, mu_i * mu_o * std::fabs(a.btdf(wi, down) - b.btdf(wi, down)));
                scale = std::max(scale, mu_i * mu_o * b.btdf(wi, down));
            }
        return worst / scale;
    };
    const Material<double> smooth_slab{SmoothDielectric<double>(1.0, 1.4), {Slab<double>(0.9, 0.8, 1.0)}, {},
                                       SmoothDielectric<double>(1.4, 1.0)};
    for (const Material<double>& mat : {skin(), smooth_slab}) {
        SceneRequest<double> scene;
        scene.outputs = LayerOutput::subsurface_reflection | LayerOutput::transmission;
        scene.incidence = {0.8};
        scene.tolerance = 1e-2;
        const auto planned = solve_planned(mat, scene);
        LayerOptions fine;
        fine.ordinates = 64;
        LayerRequest<double> request = planned.plan.request;
        request.tolerance = 0;
        const auto reference = solve_stack<double>(mat.top, mat.slabs, mat.interior, mat.bottom, fine, request);
        const double truth = probe_error(planned.surface, reference, 0.8, true);
        INFO(planned.plan.reason << "; true angular error " << truth);
        CHECK(planned.plan.angular_error > 0);
        CHECK(truth <= planned.plan.angular_error);
        scene.estimate_angular_error = false;
        CHECK(solve_planned(mat, scene).plan.angular_error == 0);
    }
}

TEST_CASE("an angular tolerance doubles the ordinates until the angular estimate meets it") {
    // The smooth slab whose fluxes meet 1e-2 at 8 ordinates while its BTDF is 0.24 off (previous test case).
    const Material<double> smooth_slab{SmoothDielectric<double>(1.0, 1.4), {Slab<double>(0.9, 0.8, 1.0)}, {},
                                       SmoothDielectric<double>(1.4, 1.0)};
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::subsurface_reflection | LayerOutput::transmission;
    scene.incidence = std::vector<double>(1, 0.8);
    scene.tolerance = 1e-2;
    scene.angular_tolerance = 0.05;
    const auto planned = solve_planned(smooth_slab, scene);
    INFO(planned.plan.reason);
    CHECK(planned.plan.options.ordinates > 8);
    CHECK(planned.plan.angular_tolerance_met);
    CHECK(planned.plan.angular_error <= 0.05);
    CHECK(planned.plan.ordinates_tried.back() == planned.plan.options.ordinates);
    // The same request solved plainly at the final ordinates (the plan's faces were prepared from the levels).
    const auto direct = solve_stack<double>(smooth_slab.top, smooth_slab.slabs, smooth_slab.interior, smooth_slab.bottom,
                                            with_ordinates(planned.plan.options, planned.plan.options.ordinates), planned.plan.request);
    const Vec3<double> wi{0.6, 0.0, 0.8}, wo{0.0, 0.6, -0.8};
    CHECK(planned.surface.btdf(wi, wo) == doctest::Approx(direct.btdf(wi, wo)).epsilon(1e-12));
    // Not met within max_ordinates: said so.
    scene.angular_tolerance = 1e-9;
    scene.max_ordinates = 16;
    const auto capped = solve_planned(smooth_slab, scene);
    CHECK_FALSE(capped.plan.angular_tolerance_met);
    CHECK(capped.plan.options.ordinates == 16);
    CHECK(capped.plan.reason.find("angular tolerance not met") != std::string::npos);
    scene.angular_tolerance = 1.0;
    CHECK_THROWS_WITH_AS(solve_planned(smooth_slab, scene), doctest::Contains("angular_tolerance"), std::invalid_argument);
}

TEST_CASE("the layer's operators asked for: the angular estimate compares their series, not zeros") {
    // The operators hold the BRDF's and the BTDF's modes, so their error is that of the two angular outputs. The
    // solve kept did not hold the series the estimate compares (only the coarse one did), so that the estimate was 0
    // and an angular tolerance of 0.05 was met at 8 ordinates (the BRDF and BTDF need 32); with the BRDF also asked
    // it was 15.4, the BTDF's series against zeros (found by review).
    const Material<double> smooth_slab{SmoothDielectric<double>(1.0, 1.4), {Slab<double>(0.9, 0.8, 1.0)}, {},
                                       SmoothDielectric<double>(1.4, 1.0)};
    SceneRequest<double> scene;
    scene.incidence = std::vector<double>(1, 0.8);
    scene.tolerance = 1e-2;
    scene.outputs = LayerOutput::subsurface_reflection | LayerOutput::transmission;
    const double angular = solve_planned(smooth_slab, scene).plan.angular_error;
    REQUIRE(angular > 0.1);
    for (const LayerOutput outputs : {LayerOutput::operators, LayerOutput::operators | LayerOutput::subsurface_reflection}) {
        scene.outputs = outputs;
        scene.angular_tolerance = 0;
        CHECK(solve_planned(smooth_slab, scene).plan.angular_error == doctest::Approx(angular).epsilon(1e-12));
        scene.angular_tolerance = 0.05;
        const auto planned = solve_planned(smooth_slab, scene);
        CHECK(planned.plan.options.ordinates == 32);
        CHECK(planned.plan.angular_error <= 0.05);
        // the plan's request is what its surface was solved for (the angular outputs added)
        CHECK(planned.surface.outputs() == planned.plan.request.outputs);
    }
    // The operators carry reflection too: over a floor (transmittance 0 at every level) the levels compared only
    // the transmittance, saw no change and stopped at 8 ordinates with an estimated error of 0 where R is 1.4e-4 off
    // at a tolerance of 1e-5 (found by review); now as for the operators with the reflectance.
    const Material<double> floored{RoughDielectric<double>(0.3, 1.0, 1.4), {Slab<double>(0.9, 0.8, 1.0)}, {},
                                   Boundary<double>::lambertian(0.5, 1.4)};
    SceneRequest<double> deep;
    deep.tolerance = 1e-5;
    deep.max_ordinates = 64;
    deep.outputs = LayerOutput::operators;
    const auto alone = solve_planned(floored, deep);
    deep.outputs = LayerOutput::operators | LayerOutput::reflectance;
    const auto with_reflectance = solve_planned(floored, deep);
    CHECK(alone.plan.options.ordinates > 8);
    CHECK(alone.plan.estimated_error > 0);
    CHECK(alone.plan.options.ordinates == with_reflectance.plan.options.ordinates);
}

TEST_CASE("stacks: the interior faces are prepared at every level too") {
    // A rough coat (n 1.5) on a slab of index 1.4 over a rough base into air: three different rough faces.
    const Material<double> stack{RoughDielectric<double>(0.2, 1.0, 1.5),
                                 {Slab<double>(0.5, 0.3, 0.4), Slab<double>(0.95, 0.8, 3.0)},
                                 {RoughDielectric<double>(0.4, 1.5, 1.4)},
                                 RoughDielectric<double>(0.3, 1.4, 1.0)};
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
    scene.incidence = {0.7};
    scene.tolerance = 3e-3;
    const auto planned = solve_planned(stack, scene);
    CHECK(planned.plan.tolerance_met);
    LayerRequest<double> fluxes;
    fluxes.outputs = scene.outputs;
    fluxes.incidence = scene.incidence;
    fluxes.tolerance = scene.tolerance;
    const auto direct = solve_stack<double>(stack.top, stack.slabs, stack.interior, stack.bottom,
                                            with_ordinates(planned.plan.options, planned.plan.options.ordinates, 1), fluxes);
    CHECK(planned.surface.reflectance(0.7).subsurface == direct.reflectance(0.7).subsurface);
    CHECK(planned.surface.transmittance(0.7) == direct.transmittance(0.7));
}

TEST_CASE("a diffusion profile: the dipole of the slab, checked against the layer's reflectance at normal incidence") {
    // Milk-like: a thick slab (tau 1e3) under a smooth face n 1.35, sigma_t 10 / mm.
    for (const double albedo : {0.999, 0.9, 0.5}) {
        const Material<double> milk{SmoothDielectric<double>(1.0, 1.35), {Slab<double>(albedo, 0.7, 1e3)}, {},
                                    Boundary<double>::index_matched(1.35), 10.0};
        SceneRequest<double> scene;
        scene.outputs = LayerOutput::subsurface_reflection;
        scene.incidence = {0.6};
        scene.tolerance = 1e-3;
        scene.diffusion_profile = true;
        scene.length_scale = 2;  // mm per pixel
        const auto planned = solve_planned(milk, scene);
        REQUIRE(planned.dipole.has_value());
        const stratum::Dipole<double>& d = *planned.dipole;
        CHECK(d.sigma_a() == doctest::Approx((1 - albedo) * 10).epsilon(1e-12));
        CHECK(d.sigma_s_prime() == doctest::Approx(albedo * 0.3 * 10).epsilon(1e-12));
        CHECK(d.eta() == doctest::Approx(1.35).epsilon(1e-15));
        // The error recomputed: the dipole's total at normal incidence (entry Fresnel factor, closed form) against the
        // planned layer's subsurface reflectance at mu = 1 (added to the checked incidences).
        const double entry = 1 - stratum_test::fresnel_closed_form(1.0, 1.35);
        const double layer = planned.surface.reflectance(1.0).subsurface;
        CHECK(planned.plan.profile_error == doctest::Approx(std::fabs(entry * d.total_reflectance() - layer)).epsilon(1e-12));
        // Within 2% of the layer's reflectance near alpha' = 1; far off at low albedo, where diffusion fails.
        if (albedo == 0.999) CHECK(planned.plan.profile_error < 0.02 * layer);
        if (albedo == 0.5) CHECK(planned.plan.profile_error > 0.5 * layer);
        // Local at 2 mm only where the diffuse mean free path 1 / sqrt(3 sigma_a sigma_t') is below 0.2 mm.
        CHECK(planned.plan.profile_local == (d.diffuse_mean_free_path() < 0.2));
        if (albedo == 0.999) CHECK_FALSE(planned.plan.profile_local);  // (ld = 3.3 mm)
        if (albedo == 0.5) CHECK(planned.plan.profile_local);          // (ld = 0.10 mm)
    }
}

TEST_CASE("a diffusion profile under a face into a less dense medium: the exact F_dr where Jensen's fit does not hold") {
    // Water (1.33) under glass (1.5): eta = 1.33 / 1.5 < 1, outside the fit's [1, 3].
    const Material<double> under_glass{SmoothDielectric<double>(1.5, 1.33), {Slab<double>(0.99, 0.5, 1e3)}, {},
                                       Boundary<double>::index_matched(1.33), 2.0};
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::reflectance;
    scene.tolerance = 1e-2;
    scene.diffusion_profile = true;
    const auto planned = solve_planned(under_glass, scene);
    REQUIRE(planned.dipole.has_value());
    CHECK(planned.dipole->eta() == doctest::Approx(1.33 / 1.5).epsilon(1e-15));
    CHECK(planned.dipole->A() == doctest::Approx(stratum::dipole_A(1.33 / 1.5, stratum::DiffuseFresnel::exact)).epsilon(1e-15));
    CHECK(std::isfinite(planned.plan.profile_error));
}

TEST_CASE("several wavelengths: one plan, the faces prepared once per level, each wavelength's solve as its own") {
    // Stam's skin in red, green and blue (albedos 0.95, 0.9, 0.7): the worst wavelength sets the ordinates.
    std::vector<Material<double>> rgb;
    for (const double albedo : {0.95, 0.9, 0.7}) {
        Material<double> m = skin();
        m.slabs = {Slab<double>(albedo, 0.8, std::log(2.0))};
        rgb.push_back(m);
    }
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
    scene.incidence = {0.5};
    scene.tolerance = 3e-3;
    const auto spectrum = stratum::solve_planned_spectral(rgb, scene);
    REQUIRE(spectrum.surfaces.size() == 3);
    int most = 0;
    for (std::size_t w = 0; w < 3; ++w) {
        const auto alone = solve_planned(rgb[w], scene);
        most = std::max(most, alone.plan.options.ordinates);
        // Each wavelength is its own solve at the common ordinates, bit for bit.
        LayerRequest<double> fluxes = spectrum.plan.request;
        const auto direct = solve_stack<double>(rgb[w].top, rgb[w].slabs, rgb[w].interior, rgb[w].bottom,
                                                with_ordinates(spectrum.plan.options, spectrum.plan.options.ordinates, 1), fluxes);
        CHECK(spectrum.surfaces[w].reflectance(0.5).subsurface == direct.reflectance(0.5).subsurface);
        CHECK(spectrum.surfaces[w].transmittance(0.5) == direct.transmittance(0.5));
    }
    CHECK(spectrum.plan.options.ordinates == most);  // (the changes are the worst over the wavelengths)
    CHECK(spectrum.plan.tolerance_met);
    CHECK(spectrum.plan.estimated_error <= scene.tolerance);

    std::vector<Material<double>> mixed = rgb;
    mixed[1].top = RoughDielectric<double>(0.2, 1.0, 1.4);
    CHECK_THROWS_WITH_AS(stratum::solve_planned_spectral(mixed, scene), doctest::Contains("wavelengths[1]"),
                         std::invalid_argument);
    CHECK_THROWS_WITH_AS(stratum::solve_planned_spectral(std::vector<Material<double>>{}, scene),
                         doctest::Contains("no wavelengths"), std::invalid_argument);
}

TEST_CASE("the plan names what it could not reach, and refuses bad requests by name") {
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::transmittance;
    scene.tolerance = 1e-9;
    scene.max_ordinates = 8;
    const auto planned = solve_planned(skin(), scene);
    CHECK_FALSE(planned.plan.tolerance_met);
    CHECK(planned.plan.options.hemispherical_nodes == 16);  // (the defaults below 1e-4)
    CHECK(planned.plan.options.azimuthal_points == 24);
    CHECK(std::isfinite(planned.plan.estimated_error));
    CHECK(planned.plan.reason.find("max_ordinates") != std::string::npos);
    CHECK(planned.surface.transmittance(0.5) > 0);

    for (const double bad : {0.0, 1.0, -1e-3, std::numeric_limits<double>::quiet_NaN()}) {
        SceneRequest<double> s;
        s.tolerance = bad;
        CHECK_THROWS_WITH_AS(solve_planned(skin(), s), doctest::Contains("tolerance"), std::invalid_argument);
    }
    for (const int bad : {4, 7, 257}) {  // (at least two levels, 4 and 8, for an estimate)
        SceneRequest<double> s;
        s.max_ordinates = bad;
        CHECK_THROWS_WITH_AS(solve_planned(skin(), s), doctest::Contains("max_ordinates"), std::invalid_argument);
    }
    SceneRequest<double> s;
    s.incidence = {0.5, 0.0};
    CHECK_THROWS_WITH_AS(solve_planned(skin(), s), doctest::Contains("incidence[1]"), std::invalid_argument);
    SceneRequest<double> profile;
    profile.diffusion_profile = true;
    CHECK_THROWS_WITH_AS(solve_planned(skin(), profile), doctest::Contains("extinction"), std::invalid_argument);
    Material<double> two = skin();
    two.slabs.push_back(two.slabs.front());
    two.interior.push_back(Boundary<double>::index_matched(1.4));
    two.extinction = 1;
    CHECK_THROWS_WITH_AS(solve_planned(two, profile), doctest::Contains("one slab"), std::invalid_argument);
    SceneRequest<double> scale;
    scale.length_scale = -1;
    CHECK_THROWS_WITH_AS(solve_planned(skin(), scale), doctest::Contains("length_scale"), std::invalid_argument);
    // Outputs: a bit beyond LayerOutput::all, or nothing at all without a profile (both were planned up to
    // max_ordinates, the first refused only by the final solve; found by review).
    for (const unsigned bad : {1u << 9, (1u << 9) | static_cast<unsigned>(LayerOutput::transmittance)}) {
        SceneRequest<double> o;
        o.outputs = static_cast<LayerOutput>(bad);
        CHECK_THROWS_WITH_AS(solve_planned(skin(), o), doctest::Contains("outputs"), std::invalid_argument);
    }
    SceneRequest<double> nothing;
    nothing.outputs = static_cast<LayerOutput>(0u);
    CHECK_THROWS_WITH_AS(solve_planned(skin(), nothing), doctest::Contains("nothing is asked"), std::invalid_argument);
}

TEST_CASE("the planner in float") {
    const Material<float> mat{RoughDielectric<float>(0.3f, 1.0f, 1.4f), {Slab<float>(0.9f, 0.8f, 0.7f)}, {},
                              SmoothDielectric<float>(1.4f, 1.0f)};
    SceneRequest<float> scene;
    scene.outputs = LayerOutput::reflectance;
    scene.tolerance = 1e-2f;
    const auto planned = solve_planned(mat, scene);
    CHECK(planned.plan.tolerance_met);
    CHECK(planned.surface.reflectance(0.5f).subsurface > 0.01f);
}

// Random materials of every face kind (smooth, rough, index-matched tops; smooth, rough, index-matched and Lambertian
// bottoms), random tolerances and incidences; the truth is a mode-0 solve at 128 ordinates. The planner stops at 32
// here (CI time), where the reference's own error is at most a quarter of the planner's for convergence as 1/M.
TEST_CASE("randomized sweep: the planner's error estimate bounds the true error in at least 95% of materials") {
    std::mt19937_64 rng(20261126);  // (the estimate's calibration used seeds 7, 8 and 9 of another generator)
    int bounded = 0, met = 0, within = 0;
    const int count = 60;
    for (int t = 0; t < count; ++t) {
        const int top_kind = static_cast<int>(3 * uniform(rng)), bottom_kind = static_cast<int>(4 * uniform(rng));
        const double n = top_kind == 2 ? 1.0 : 1 + 0.6 * uniform(rng);
        const double albedo = uniform(rng) < 0.2 ? 1.0 : uniform(rng), g = 0.95 * uniform(rng);
        const double tau = std::pow(10.0, -1.3 + 2.8 * uniform(rng));
        const double sigma_top = std::pow(10.0, -1.5 + 1.5 * uniform(rng)), sigma_bottom = std::pow(10.0, -1.5 + 1.5 * uniform(rng));
        const Boundary<double> top = top_kind == 0   ? Boundary<double>(SmoothDielectric<double>(1.0, n))
                                     : top_kind == 1 ? Boundary<double>(RoughDielectric<double>(sigma_top, 1.0, n))
                                                     : Boundary<double>::index_matched(1.0);
        const Boundary<double> bottom = bottom_kind == 0   ? Boundary<double>(SmoothDielectric<double>(n, 1.0))
                                        : bottom_kind == 1 ? Boundary<double>(RoughDielectric<double>(sigma_bottom, n, 1.0))
                                        : bottom_kind == 2 ? Boundary<double>::index_matched(n)
                                                           : Boundary<double>::lambertian(uniform(rng), n);
        const Material<double> mat{top, {Slab<double>(albedo, g, tau)}, {}, bottom};
        SceneRequest<double> scene;
        const bool floor = bottom_kind == 3;
        scene.outputs = floor ? LayerOutput::reflectance : LayerOutput::reflectance | LayerOutput::transmittance;
        scene.incidence = {0.05 + 0.95 * uniform(rng)};
        if (uniform(rng) < 0.5) scene.incidence.push_back(1.0);
        scene.tolerance = std::pow(10.0, -3 + 1.5 * uniform(rng));
        scene.max_ordinates = 32;
        const auto planned = solve_planned(mat, scene);
        LayerRequest<double> reference_request;
        reference_request.outputs = scene.outputs;
        reference_request.incidence = scene.incidence;
        reference_request.tolerance = scene.tolerance;
        const auto reference =
            solve_stack<double>(mat.top, mat.slabs, mat.interior, mat.bottom, with_ordinates(LayerOptions{}, 128, 1), reference_request);
        double error = 0;
        for (const double mu : scene.incidence) {
            error = std::max(error, std::fabs(planned.surface.reflectance(mu).subsurface - reference.reflectance(mu).subsurface));
            if (!floor) error = std::max(error, std::fabs(planned.surface.transmittance(mu) - reference.transmittance(mu)));
        }
        INFO("material " << t << ": top " << top_kind << ", bottom " << bottom_kind << ", n " << n << ", albedo " << albedo
                         << ", g " << g << ", tau " << tau << ", sigma " << sigma_top << " " << sigma_bottom << "; " << planned.plan.reason << "; true error " << error);
        CHECK(std::isfinite(planned.plan.estimated_error));
        if (error > planned.plan.estimated_error) MESSAGE("not bounded: material " << t << ", true error " << error << ", " << planned.plan.reason);
        bounded += error <= planned.plan.estimated_error;
        if (planned.plan.tolerance_met) {
            ++met;
            within += error <= scene.tolerance;
        }
    }
    CHECK(bounded >= 0.95 * count);
    CHECK(met >= count / 2);  // (a test that could pass with every plan giving up would not test the estimate)
    CHECK(within >= 0.95 * met);
}

TEST_CASE("slabs joined by a refracting face: the levels start at 8 ordinates (4 are refused there)") {
    // glass | epidermis | dermis-like: 1 | 1.5 | 1.4 | 1 with smooth faces (detail::require_ordinates_for_joints).
    const Material<double> glass_over_tissue{SmoothDielectric<double>(1.0, 1.5),
                                             {Slab<double>(0.0, 0.0, 0.1), Slab<double>(0.95, 0.8, 2.0)},
                                             {SmoothDielectric<double>(1.5, 1.4)},
                                             SmoothDielectric<double>(1.4, 1.0)};
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
    scene.incidence.push_back(0.7);
    scene.tolerance = 1e-2;
    const auto planned = solve_planned(glass_over_tissue, scene);
    REQUIRE(!planned.plan.ordinates_tried.empty());
    CHECK(planned.plan.ordinates_tried.front() == 8);
    // Two levels at least: max_ordinates 8 ran one and left the estimate infinite (found by review).
    SceneRequest<double> one_level = scene;
    one_level.max_ordinates = 8;
    CHECK_THROWS_WITH_AS(solve_planned(glass_over_tissue, one_level), doctest::Contains("max_ordinates"), std::invalid_argument);
    CHECK(planned.plan.options.ordinates >= 16);
    // Its answer against a fine solve at the tolerance.
    LayerOptions fine;
    fine.ordinates = 64;
    const auto reference = solve_stack<double>(glass_over_tissue.top, glass_over_tissue.slabs, glass_over_tissue.interior,
                                               glass_over_tissue.bottom, fine);
    CHECK(std::fabs(planned.surface.reflectance(0.7).total() - reference.reflectance(0.7).total()) < scene.tolerance);
    CHECK(std::fabs(planned.surface.transmittance(0.7) - reference.transmittance(0.7)) < scene.tolerance);
}

TEST_CASE("several wavelengths of a refracting stack: the levels start where every wavelength can be solved") {
    // An absorbing first wavelength (albedo 0: no minimum) took 4 ordinates for all, and the second, scattering,
    // was refused there (found by review).
    std::vector<Material<double>> wavelengths;
    for (double albedo : {0.0, 0.9})
        wavelengths.push_back({SmoothDielectric<double>(1.0, 1.5), {Slab<double>(albedo, 0.5, 1.0), Slab<double>(albedo, 0.5, 1.0)},
                               {SmoothDielectric<double>(1.5, 1.3)}, SmoothDielectric<double>(1.3, 1.0)});
    SceneRequest<double> scene;
    scene.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
    scene.tolerance = 1e-2;
    const auto planned = stratum::solve_planned_spectral(wavelengths, scene);
    CHECK(planned.plan.ordinates_tried.front() == 8);
}
