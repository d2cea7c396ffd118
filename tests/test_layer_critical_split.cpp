// The ordinates split at the critical cosines (LayerOptions::critical_split, docs/physics.md section 6): where
// they are split, the rule itself, and what it buys between smooth faces -- agreement with converged
// adding-doubling and a convergence in M that the single half-range rule does not have.
#include <stratum/layer.hpp>

#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace stratum;

namespace {

LayerOptions options(int m, bool split = true) {
    LayerOptions o;
    o.ordinates = m;
    o.critical_split = split;
    return o;
}

// Reflectance (surface + subsurface, the unscattered beam included) and transmittance at mu0 of a slab between
// smooth faces of index n in air, mode 0 only.
struct Fluxes {
    double r, t;
};
Fluxes fluxes(double n, double albedo, double g, double tau, double mu0, int m, bool split = true) {
    LayerRequest<double> request;
    request.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
    const auto l = solve_layer(Slab<double>(albedo, g, tau), SmoothDielectric<double>(1.0, n),
                               SmoothDielectric<double>(n, 1.0), options(m, split), request);
    return {l.reflectance(mu0).total(), l.transmittance(mu0)};
}

}  // namespace

TEST_CASE("critical split: where the ordinates are split, and the rule") {
    const double mu_c = std::sqrt(1 - 1 / (1.4 * 1.4));
    const auto smooth = solve_layer(Slab<double>(0.9, 0.5, 1.0), SmoothDielectric<double>(1.0, 1.4),
                                    SmoothDielectric<double>(1.4, 1.0), options(8));
    const Quadrature<double>& q = smooth.quadrature();
    REQUIRE(q.size() == 8);
    double sum = 0, below = 0, first = 0;
    for (std::size_t i = 0; i < q.size(); ++i) {
        sum += q.weights[i];
        if (q.nodes[i] < mu_c) below += q.weights[i];
        if (i > 0) CHECK(q.nodes[i] > q.nodes[i - 1]);
        first += q.nodes[i] < mu_c ? 1 : 0;
    }
    CHECK(sum == doctest::Approx(1.0).epsilon(1e-15));
    CHECK(below == doctest::Approx(mu_c).epsilon(1e-14));  // the lower panel's weights sum to its width
    CHECK(first == 4);                                      // half the ordinates on each side of mu_c
    // Two different critical cosines (glass over water in air): three panels, the escape cone [0.745, 1] with half.
    const auto three = solve_layer(Slab<double>(0.9, 0.5, 1.0), SmoothDielectric<double>(1.0, 1.5),
                                   SmoothDielectric<double>(1.5, 1.33), options(8));
    int in_cone = 0;
    for (double x : three.quadrature().nodes) in_cone += x > std::sqrt(1 - 1 / 2.25) ? 1 : 0;
    CHECK(in_cone == 4);
    // A rough top over a smooth bottom splits as smooth faces do (its facets blur the critical cosines over more than
    // half the ordinate spacing: sigma sin(theta_c) = 0.21 here).
    const auto coat = solve_layer(Slab<double>(0.9, 0.5, 1.0), RoughDielectric<double>(0.3, 1.0, 1.4),
                                  SmoothDielectric<double>(1.4, 1.0), options(8));
    CHECK(coat.quadrature().nodes == q.nodes);
    // No split: a nearly specular rough top (sigma sin(theta_c) = 0.007 against half the spacing, 0.06), a rough
    // bottom, a rough top over a Lambertian floor, index matching on both sides, or the option off.
    const Quadrature<double> plain = gauss_legendre_half<double>(8);
    const auto glossy = solve_layer(Slab<double>(0.9, 0.5, 1.0), RoughDielectric<double>(0.01, 1.0, 1.4),
                                    SmoothDielectric<double>(1.4, 1.0), options(8));
    const auto rough = solve_layer(Slab<double>(0.9, 0.5, 1.0), RoughDielectric<double>(0.3, 1.0, 1.4),
                                   RoughDielectric<double>(0.3, 1.4, 1.0), options(8));
    const auto rough_floor = solve_layer(Slab<double>(0.9, 0.5, 1.0), RoughDielectric<double>(0.3, 1.0, 1.4),
                                         Boundary<double>::lambertian(0.5, 1.4), options(8));
    const auto matched = solve_layer(Slab<double>(0.9, 0.5, 1.0), Boundary<double>::index_matched(),
                                     Boundary<double>::index_matched(), options(8));
    const auto off = solve_layer(Slab<double>(0.9, 0.5, 1.0), SmoothDielectric<double>(1.0, 1.4),
                                 SmoothDielectric<double>(1.4, 1.0), options(8, false));
    for (const auto* l : {&glossy, &rough, &rough_floor, &matched, &off}) CHECK(l->quadrature().nodes == plain.nodes);
    // A Lambertian floor splits at the top's critical cosine alone.
    const auto floor = solve_layer(Slab<double>(0.9, 0.5, 1.0), SmoothDielectric<double>(1.0, 1.4),
                                   Boundary<double>::lambertian(0.5, 1.4), options(8));
    CHECK(floor.quadrature().nodes == q.nodes);
}

TEST_CASE("critical split: Fresnel slabs agree with converged adding-doubling, converging in M") {
    // Prahl's adding-doubling (tests/data/adding_doubling_reference.txt, good to ~1e-8): 12 slabs (n 1.4 and 1.5,
    // albedo 0.5 to 1, g 0 to 0.9, tau 1 to 16) at normal incidence, and 12 oblique incidences (mu0 = 0.05 to 0.99
    // in air, two slabs). The beam is a source exact at its angle (docs/physics.md section 6), so that an oblique
    // beam costs no more than a normal one. Measured worst |R - ref| / |T - ref| at normal incidence without the
    // forward peak (g <= 0.8); the forward peak (g = 0.9, normal incidence: the ordinates must resolve its first
    // scattering near mu = 1); oblique, worst of R and T:
    //   M = 16: 1.6e-5 / 3.6e-5;  1.5e-4 / 6.2e-4;  2.9e-5
    //   M = 24: 1.2e-7 / 5.3e-7;  1.9e-5 / 5.1e-5;  9.0e-7
    //   M = 32: 5.7e-9 / 2.0e-8;  3.4e-6 / 1.0e-5;  1.3e-8
    //   M = 48: 4.2e-9 / 3.3e-9;  2.1e-7 / 4.2e-7;  1.2e-8
    //   M = 64: 4.2e-9 / 3.3e-9;  1.2e-8 / 2.7e-8;  1.2e-8   (from M = 32 on: adding-doubling's own accuracy)
    // Before the beam was a source (spread over the ordinates): oblique 1.9e-3 / 8.1e-4 / 4.8e-4 / 6.6e-5 / 1.2e-5 at
    // M = 16 / 24 / 32 / 48 / 64, at grazing incidence. With one half-range rule, normal incidence: 6.4e-3 / 7.9e-3
    // (16) and 1.4e-3 / 1.5e-3 (48), not converging. Bounds: the measured worst x 1.5 (x 3 at adding-doubling's
    // accuracy).
    std::ifstream in(STRATUM_TEST_DATA_DIR "/adding_doubling_reference.txt");
    REQUIRE(in.good());
    struct Reference {
        double n, albedo, g, tau, mu0, r, t;
    };
    std::vector<Reference> refs;
    for (std::string line; std::getline(in, line);) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream row(line);
        Reference x{};
        row >> x.n >> x.albedo >> x.g >> x.tau >> x.mu0 >> x.r >> x.t;
        REQUIRE(!row.fail());
        refs.push_back(x);
    }
    REQUIRE(refs.size() == 24);
    const struct {
        int m;
        double r, t, peak_r, peak_t, oblique;
    } bounds[] = {{16, 2.4e-5, 5.4e-5, 2.2e-4, 9.3e-4, 4.4e-5},
                  {24, 1.9e-7, 8e-7, 2.9e-5, 7.7e-5, 1.4e-6},
                  {32, 1.7e-8, 6e-8, 5.1e-6, 1.5e-5, 4e-8},
                  {48, 1.3e-8, 1.6e-8, 3.2e-7, 6.4e-7, 3.6e-8},
                  {64, 1.3e-8, 1.6e-8, 3.6e-8, 8.1e-8, 3.6e-8}};
    for (const auto& b : bounds) {
        double worst_r = 0, worst_t = 0, peak_r = 0, peak_t = 0, oblique = 0;
        for (const Reference& x : refs) {
            const Fluxes f = fluxes(x.n, x.albedo, x.g, x.tau, x.mu0, b.m);
            const double dr = std::fabs(f.r - x.r), dt = std::fabs(f.t - x.t);
            if (x.mu0 == 1 && x.g > 0.85) {
                peak_r = std::fmax(peak_r, dr);
                peak_t = std::fmax(peak_t, dt);
            } else if (x.mu0 == 1) {
                worst_r = std::fmax(worst_r, dr);
                worst_t = std::fmax(worst_t, dt);
            } else {
                oblique = std::fmax(oblique, std::fmax(dr, dt));
            }
        }
        MESSAGE("M = " << b.m << ": normal incidence, worst |R - AD| " << worst_r << ", |T - AD| " << worst_t
                       << "; forward peak " << peak_r << ", " << peak_t << "; oblique, worst " << oblique);
        CHECK(worst_r < b.r);
        CHECK(worst_t < b.t);
        CHECK(peak_r < b.peak_r);
        CHECK(peak_t < b.peak_t);
        CHECK(oblique < b.oblique);
    }
    // Convergence: the distance to the M = 96 solution falls with M (it did not with one rule), at normal and
    // oblique incidence, for forward and isotropic scattering, thin and thick slabs, n = 1.33 and 1.5.
    struct Case {
        double n, albedo, g, tau, mu0;
    };
    const Case cases[] = {{1.5, 0.9, 0.8, 1.0, 1.0}, {1.5, 0.9, 0.8, 1.0, 0.5}, {1.33, 0.5, 0.0, 1.0, 1.0},
                          {1.4, 0.99, 0.8, 4.0, 0.3}, {1.5, 1.0, 0.0, 2.0, 0.7}};
    for (const Case& c : cases) {
        const Fluxes converged = fluxes(c.n, c.albedo, c.g, c.tau, c.mu0, 96);
        double previous = 1;
        for (int m : {12, 24, 48}) {
            const Fluxes f = fluxes(c.n, c.albedo, c.g, c.tau, c.mu0, m);
            const double e = std::fmax(std::fabs(f.r - converged.r), std::fabs(f.t - converged.t));
            INFO("n " << c.n << " albedo " << c.albedo << " g " << c.g << " tau " << c.tau << " mu0 " << c.mu0 << " M " << m
                      << ": " << e);
            CHECK(e < previous);
            previous = e;
        }
        CHECK(previous < 2e-5);
    }
}

TEST_CASE("critical split: a strong forward peak converges more slowly at every incidence, not only at the normal") {
    // The known limitation of README ("Smooth or index-matched layer boundaries"): the split rule's panels integrate a
    // delta-M truncated phase function of g = 0.9 only approximately, so at M = 24 the fluxes of a Fresnel slab (n 1.4,
    // albedo 0.8, tau 2) are ~5e-5 from M = 128 at every incidence (measured 5.1e-5 / 5.2e-5 / 5.1e-5 / 5.2e-5 at
    // mu0 = 1 / 0.8 / 0.5 / 0.2), where g = 0.8 is within 8.7e-7 and the same g = 0.9 slab between index-matched faces
    // (one Gauss rule) within 3.4e-7. Bounds: the measured x 1.5; the limitation should only ever shrink. The row
    // defects of mode 0's matrices on the split rule, before make_discretely_conservative: 3.9e-3 (g 0.9), 2.6e-5 (0.8).
    const double measured_09 = 5.2e-5, measured_08 = 8.7e-7;
    for (const double mu0 : {1.0, 0.8, 0.5, 0.2}) {
        for (const double g : {0.8, 0.9}) {
            const Fluxes converged = fluxes(1.4, 0.8, g, 2.0, mu0, 128), f = fluxes(1.4, 0.8, g, 2.0, mu0, 24);
            const double e = std::fmax(std::fabs(f.r - converged.r), std::fabs(f.t - converged.t));
            INFO("g " << g << " mu0 " << mu0 << ": " << e);
            CHECK(e < 1.5 * (g > 0.85 ? measured_09 : measured_08));
        }
    }
    // and between index-matched faces (one Gauss rule) the same g = 0.9 slab converges as fast as g = 0.8 does here
    LayerRequest<double> request;
    request.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
    const auto matched = [&](int m) {
        return solve_layer(Slab<double>(0.8, 0.9, 2.0), Boundary<double>::index_matched(), Boundary<double>::index_matched(),
                           options(m), request);
    };
    const auto a = matched(24), b = matched(128);
    CHECK(std::fabs(a.reflectance(1.0).total() - b.reflectance(1.0).total()) < 1.5 * 3.4e-7);
    CHECK(std::fabs(a.transmittance(1.0) - b.transmittance(1.0)) < 1.5 * 3.4e-7);
}
