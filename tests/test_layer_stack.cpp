// Stacks between specular faces whose joints refract (glass over tissue: 1 | 1.5 | 1.4 | 1): the beam is a source
// in every slab at its own refracted angle and the unscattered beam is exact (docs/physics.md section 6). Checked
// against a scalar adding of the faces and slabs written here, energy at albedo 1, continuity as a joint's index
// ratio tends to 1, reciprocity, the integrals of the BRDF and BTDF, and the photon Monte Carlo.
#include <doctest/doctest.h>

#include <stratum/fresnel.hpp>
#include <stratum/layer.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <new>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "test_util.hpp"

#include "reference/mc_stack.hpp"

using stratum::Boundary;
using stratum::LayerOptions;
using stratum::LayeredSurface;
using stratum::Slab;
using stratum::SmoothDielectric;
using stratum::Vec3;

// Every allocation of this test program is counted (a Workspace's evaluations must make none once it is sized).
namespace {
std::atomic<long> allocations{0};
}  // namespace
void* operator new(std::size_t n) {
    ++allocations;
    if (void* p = std::malloc(n > 0 ? n : 1)) return p;
    throw std::bad_alloc();
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"  // (GCC 12 takes this pair, malloc and free, for a mismatch)
#endif
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

namespace {

const double pi = 3.14159265358979323846;

Vec3<double> direction(double mu, double phi) { return stratum_test::direction_at(mu, phi); }

// air | eta[0] | eta[1] | ... | air, one slab per index.
LayeredSurface<double> stack(const std::vector<double>& eta, const std::vector<Slab<double>>& slabs, int m,
                             bool split = true, std::vector<double> incidence = {}) {
    std::vector<Boundary<double>> joints;
    for (std::size_t j = 1; j < eta.size(); ++j) joints.push_back(SmoothDielectric<double>(eta[j - 1], eta[j]));
    LayerOptions o;
    o.ordinates = m;
    o.critical_split = split;
    stratum::LayerRequest<double> request;
    request.incidence = std::move(incidence);  // (their fields solved once)
    return stratum::solve_stack<double>(SmoothDielectric<double>(1.0, eta.front()), slabs, joints,
                                        SmoothDielectric<double>(eta.back(), 1.0), o, request);
}

// Flux reflectance (from above, from below) and transmittance of an element met by a beam; elements added by
//     R = R1 + T1 T1' R2 / (1 - R1' R2),  T = T1 T2 / (1 - R1' R2),  R' = R2' + T2' T2 R1' / (1 - R1' R2),
// T' = T2' T1' / (1 - R1' R2) (primes: from below). A smooth face has equal flux R (and T) from both sides at
// Snell-corresponding angles; a slab crossed at cosine x has R = 0, T = e^{-tau / x}.
struct Element {
    double r, r_below, t, t_below;
};
Element add(const Element& a, const Element& b) {
    const double d = 1 - a.r_below * b.r;
    return {a.r + a.t * a.t_below * b.r / d, b.r_below + b.t_below * b.t * a.r_below / d, a.t * b.t / d,
            b.t_below * a.t_below / d};
}

}  // namespace

TEST_CASE("refracting stack, no scattering: the unscattered beam is the scalar adding of its faces and slabs") {
    // air | 1.5 (tau 0.3) | 1.4 (tau 0.8) | 1.38 (tau 0.5) | air: a glass slide on epidermis on dermis, albedo 0.
    const std::vector<double> eta{1.5, 1.4, 1.38}, tau{0.3, 0.8, 0.5};
    std::vector<Slab<double>> slabs;
    for (double t : tau) slabs.emplace_back(0.0, 0.0, t);
    const auto layer = stack(eta, slabs, 8);
    for (double mu0 : {1.0, 0.7, 0.3, 0.05}) {
        // cosines in each medium (Snell from air)
        const double s2 = 1 - mu0 * mu0;
        Element total{0, 0, 1, 1};
        double n_prev = 1, c_prev = mu0;
        for (std::size_t j = 0; j <= eta.size(); ++j) {
            const double n = j < eta.size() ? eta[j] : 1.0, c = std::sqrt(1 - s2 / (n * n));
            const double r = stratum::fresnel_dielectric(c_prev, n / n_prev);
            total = add(total, {r, r, 1 - r, 1 - r});
            if (j < eta.size()) {
                const double e = std::exp(-tau[j] / c);
                total = add(total, {0, 0, e, e});
            }
            n_prev = n;
            c_prev = c;
        }
        const double specular = stratum::fresnel_dielectric(mu0, 1.5);
        INFO("mu0 " << mu0);
        CHECK(layer.direct_transmittance(mu0) == doctest::Approx(total.t).epsilon(1e-13));
        CHECK(layer.direct_reflectance(mu0) == doctest::Approx(total.r - specular).epsilon(1e-12));
        CHECK(layer.transmittance(mu0) == doctest::Approx(total.t).epsilon(1e-13));  // nothing scattered
    }
}

TEST_CASE("refracting stack over a Lambertian floor: energy at albedo 1, and the joint's specular reflection is direct") {
    // air | 1.5 (tau 0.7) | 1.4 (tau 1.3) | white floor, both slabs non-absorbing: everything comes back, R = 1. The
    // beam the joint reflects specularly leaves through the top as direct_reflectance (the scalar adding of the faces
    // and slabs; the floor reflects none of it specularly). That reflection was left out over a floor: R = 0.99973
    // at every M, the joint's Fresnel reflection attenuated twice by the top slab.
    const std::vector<Slab<double>> slabs{Slab<double>(1.0, 0.8, 0.7), Slab<double>(1.0, 0.5, 1.3)};
    for (const int m : {5, 8, 16}) {
        LayerOptions o;
        o.ordinates = m;
        const auto layer = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), slabs,
                                                        {SmoothDielectric<double>(1.5, 1.4)},
                                                        Boundary<double>::lambertian(1.0, 1.4), o);
        for (double mu0 : {1.0, 0.6, 0.2, 0.01}) {
            const double c0 = std::sqrt(1 - (1 - mu0 * mu0) / (1.5 * 1.5)), c1 = std::sqrt(1 - (1 - mu0 * mu0) / (1.4 * 1.4));
            const double r_top = stratum::fresnel_dielectric(mu0, 1.5), r_joint = stratum::fresnel_dielectric(c0, 1.4 / 1.5);
            Element total{r_top, r_top, 1 - r_top, 1 - r_top};
            total = add(total, {0, 0, std::exp(-0.7 / c0), std::exp(-0.7 / c0)});
            total = add(total, {r_joint, r_joint, 1 - r_joint, 1 - r_joint});
            total = add(total, {0, 0, std::exp(-1.3 / c1), std::exp(-1.3 / c1)});
            total = add(total, {0, 0, 0, 0});  // the floor: nothing specular
            INFO("M = " << m << ", mu0 " << mu0);
            CHECK(std::fabs(layer.reflectance(mu0).total() - 1) < 1e-12);
            CHECK(layer.direct_reflectance(mu0) == doctest::Approx(total.r - r_top).epsilon(1e-12));
            CHECK(layer.direct_transmittance(mu0) == 0);
        }
    }
}

TEST_CASE("a specular top over refracting joints and a rough bottom: the joints' mirror reflection is a delta") {
    // The joints reflect part of the beam specularly and it leaves the top as a delta in the mirror direction. The
    // solution on the ordinates held it spread over them, and the BRDF read it out between them as a spike ringing in
    // azimuth: at the pole (mu 0.999 in and out) 1.1 / 4.5 / 1.9 / 4.2 in the mirror direction at M = 16 / 24 / 32
    // / 48, and 0 (clamped from negative) beside it, where the BRDF is ~0.04 and cannot depend on the azimuth there.
    // (1) direct_reflectance is that delta: the scalar adding of the faces and slabs over a black bottom (true
    // thicknesses), and forward_peak_reflectance the same with the delta-M scaled ones less it.
    const std::vector<double> eta{1.5, 1.4, 1.38}, tau{0.3, 0.8, 0.5};
    const std::vector<Slab<double>> slabs{Slab<double>(0.9, 0.9, tau[0]), Slab<double>(0.95, 0.7, tau[1]),
                                          Slab<double>(0.8, 0.5, tau[2])};
    const std::vector<Boundary<double>> joints{SmoothDielectric<double>(1.5, 1.4), SmoothDielectric<double>(1.4, 1.38)};
    for (const int m : {8, 16}) {
        LayerOptions o;
        o.ordinates = m;
        const auto layer = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), slabs, joints,
                                                        stratum::RoughDielectric<double>(0.3, 1.38, 1.0), o);
        for (double mu0 : {1.0, 0.7, 0.3, 0.05}) {
            const auto mirror = [&](bool scaled) {
                const double s2 = 1 - mu0 * mu0;
                Element total{0, 0, 1, 1};
                double n_prev = 1, c_prev = mu0;
                for (std::size_t j = 0; j < eta.size(); ++j) {
                    const double c = std::sqrt(1 - s2 / (eta[j] * eta[j]));
                    const double r = stratum::fresnel_dielectric(c_prev, eta[j] / n_prev);
                    total = add(total, {r, r, 1 - r, 1 - r});
                    const double g = slabs[j].g(), f = std::pow(g, 2 * m), albedo = slabs[j].albedo();
                    const double e = std::exp(-(scaled ? (1 - f * albedo) * tau[j] : tau[j]) / c);
                    total = add(total, {0, 0, e, e});
                    n_prev = eta[j];
                    c_prev = c;
                }
                total = add(total, {0, 0, 0, 0});  // the rough bottom: nothing specular
                return total.r - stratum::fresnel_dielectric(mu0, 1.5);
            };
            INFO("M = " << m << ", mu0 " << mu0);
            CHECK(layer.direct_reflectance(mu0) == doctest::Approx(mirror(false)).epsilon(1e-12));
            CHECK(layer.forward_peak_reflectance(mu0) == doctest::Approx(mirror(true) - mirror(false)).epsilon(1e-9));
            CHECK(layer.direct_transmittance(mu0) == 0);
        }
    }
    // A joint that reflects totally (reached from outside where the top is index matched to a denser medium, or where
    // a slab's index is below the outside's): the bounce is the whole reflection there, and a non-absorbing stack
    // keeps its energy (that bounce was left out of the delta once taken out of the field: R + T 0.77 and 0.82 at
    // mu 0.42 and 0.3 below; found by review). And a rough joint reflects a lobe, not a delta (it was taken for one:
    // direct_reflectance 4.0e-4; found by review).
    const std::vector<Slab<double>> pair{Slab<double>(0.9, 0.0, 0.5), Slab<double>(0.9, 0.0, 1.0)};
    const auto matched = stratum::solve_stack<double>(Boundary<double>::index_matched(1.5), pair,
                                                      {SmoothDielectric<double>(1.5, 1.2)},
                                                      stratum::RoughDielectric<double>(0.3, 1.2, 1.0), LayerOptions{});
    CHECK(matched.direct_reflectance(0.5) == doctest::Approx(std::exp(-2.0)).epsilon(1e-13));  // (critical cosine 0.6)
    const std::vector<Slab<double>> clear{Slab<double>(1.0, 0.5, 0.5), Slab<double>(1.0, 0.5, 1.0)};
    const auto below_air = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), clear,
                                                        {SmoothDielectric<double>(1.5, 0.9)},
                                                        stratum::RoughDielectric<double>(0.3, 0.9, 1.0), LayerOptions{});
    // The delta is exact but what is taken out of the field is the mirror as the ordinates hold it, 20% off near the
    // critical cosines: the rest of the light is scaled to what the true mirror leaves (mirror_scale). Without it R + T
    // was 1.0167 at mu0 0.15 and 0.983 at 0.5 (found by review); with it 0.9937 to 0.9992 (the rough bottom's Smith
    // shadowing loses light), as before the delta was kept apart (0.995 to 0.9985).
    for (double mu0 : {0.6, 0.5, 0.42, 0.3, 0.2, 0.15, 0.12, 0.05}) {
        INFO("mu0 " << mu0);
        const double total = below_air.reflectance(mu0).total() + below_air.transmittance(mu0);
        CHECK(total < 1 + 1e-3);
        CHECK(total > 0.99);
    }
    // The scale applies to the transmission as well, whatever the outputs requested (with the transmission alone it
    // was left 1: T 0.206 where it is 0.255 with every output, at mu0 0.4467; found by review).
    const std::vector<Slab<double>> films{Slab<double>(0.5, 0.0, 0.03), Slab<double>(0.5, 0.0, 0.03)};
    stratum::LayerRequest<double> transmission_only;
    transmission_only.outputs = stratum::LayerOutput::transmission;
    const auto thin = [&](const stratum::LayerRequest<double>& request) {
        return stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), films, {SmoothDielectric<double>(1.5, 0.9)},
                                            stratum::RoughDielectric<double>(0.3, 0.9, 1.0), LayerOptions{}, request);
    };
    const auto all_outputs = thin({}), transmission_alone = thin(transmission_only);
    for (double mu0 : {0.01, 0.1, 0.4467}) {
        INFO("mu0 " << mu0);
        CHECK(transmission_alone.transmittance(mu0) == doctest::Approx(all_outputs.transmittance(mu0)).epsilon(1e-12));
        const Vec3<double> wo{0.6, 0.0, -0.8};
        CHECK(transmission_alone.btdf(direction(mu0, 0), wo) == doctest::Approx(all_outputs.btdf(direction(mu0, 0), wo)).epsilon(1e-12));
    }
    const auto rough_joint = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), pair,
                                                          {stratum::RoughDielectric<double>(0.05, 1.5, 1.4)},
                                                          stratum::RoughDielectric<double>(0.3, 1.4, 1.0), LayerOptions{});
    CHECK(rough_joint.direct_reflectance(1.0) == 0);
    // (2) the BRDF without it: independent of the azimuth at the pole, and near the mirror direction within 5.5% of
    // M = 48 from M = 16 on (air | 1.5 | 1.4 over a rough 0.3 bottom; measured: pole 1.8e-3 / 8.9e-4 of its value over
    // the azimuth at M = 16 / 32; mirror at mu 0.95 and 0.9 3.5e-2 / 7.6e-3 from M = 48).
    const std::vector<Slab<double>> two{Slab<double>(0.9, 0.5, 0.5), Slab<double>(0.95, 0.7, 1.0)};
    const auto solve = [&](int m) {
        LayerOptions o;
        o.ordinates = m;
        return stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), two, {SmoothDielectric<double>(1.5, 1.4)},
                                            stratum::RoughDielectric<double>(0.3, 1.4, 1.0), o);
    };
    const auto reference = solve(48);
    for (const int m : {16, 32}) {
        const auto layer = solve(m);
        double low = 1e300, high = 0;
        for (int i = 0; i <= 36; ++i) {
            const double f = layer.subsurface_brdf(direction(0.999, 0), direction(0.999, i * pi / 36));
            low = std::fmin(low, f);
            high = std::fmax(high, f);
        }
        INFO("M = " << m);
        CHECK(low > 0);
        CHECK((high - low) / high < 3e-3);
        for (double mu : {0.95, 0.9}) {
            const double f = layer.subsurface_brdf(direction(mu, 0), direction(mu, pi));
            const double r = reference.subsurface_brdf(direction(mu, 0), direction(mu, pi));
            CHECK(std::fabs(f - r) / r < 5.5e-2);
        }
        // (3) the ambient term by reciprocity, r_a(wo) = R_s(wo.z): read from the field at the normal it was 0.173 /
        // 0.179 / 0.181 at M = 16 / 32 / 48 where R_s is 0.1185 / 0.1190 / 0.1191, and so it stayed where the ambient
        // term was asked for without the reflection (found by reviews)
        LayerOptions o;
        o.ordinates = m;
        stratum::LayerRequest<double> ambient_only;
        ambient_only.outputs = stratum::LayerOutput::ambient;
        const auto alone = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), two, {SmoothDielectric<double>(1.5, 1.4)},
                                                        stratum::RoughDielectric<double>(0.3, 1.4, 1.0), o, ambient_only);
        // (4) evaluation with a Workspace allocates nothing, the ambient term included (it built a Workspace of its
        // own; found by review)
        LayeredSurface<double>::Workspace ws;
        const auto evaluate = [&] {
            double sum = 0;
            for (double mu : {1.0, 0.7, 0.3})
                sum += layer.ambient(direction(mu, 0), ws) + layer.subsurface_brdf(direction(mu, 0), direction(0.5, 2.0), ws) +
                       layer.btdf(direction(mu, 0), Vec3<double>{0.6, 0.0, -0.8}, ws);
            return sum;
        };
        const double first = evaluate();
        const long before = allocations.load();
        CHECK(evaluate() == first);
        CHECK(allocations.load() == before);
        for (double mu : {1.0, 0.99, 0.5}) {
            CHECK(layer.ambient(direction(mu, 0)) == doctest::Approx(layer.reflectance(mu).subsurface).epsilon(1e-12));
            CHECK(layer.ambient(direction(mu, 0)) == doctest::Approx(reference.ambient(direction(mu, 0))).epsilon(1e-2));
            CHECK(alone.ambient(direction(mu, 0)) == doctest::Approx(layer.ambient(direction(mu, 0))).epsilon(1e-12));
        }
    }
}

TEST_CASE("refracting stack: a conservative stack keeps energy; a joint of index ratio 1 + 1e-12 is the matched one") {
    const std::vector<Slab<double>> slabs{Slab<double>(1.0, 0.8, 0.7), Slab<double>(1.0, 0.5, 1.3), Slab<double>(1.0, 0.9, 2.0)};
    // (At M = 12 the rule split at all four critical cosines aliases the g = 0.9 slab's phase function: the solve
    // falls back to one half-range rule, which keeps the unscattered beam apart.)
    const auto layer = stack({1.5, 1.4, 1.38}, slabs, 12);
    for (double mu0 : {1.0, 0.6, 0.2, 0.01}) {
        const double total = layer.reflectance(mu0).total() + layer.transmittance(mu0);
        INFO("mu0 " << mu0 << ": R + T = " << total);
        CHECK(std::fabs(total - 1) < 1e-12);
        CHECK(layer.direct_transmittance(mu0) > 0);
    }
    // (one half-range rule in both: a refracting joint keeps the ordinates unsplit, an index-matched one would split
    // them at the critical cosine, a different discretization)
    const std::vector<Slab<double>> two{Slab<double>(0.9, 0.7, 0.6), Slab<double>(0.95, 0.8, 1.1)};
    const auto matched = stack({1.4, 1.4}, two, 12, false), nearly = stack({1.4, 1.4 * (1 + 1e-12)}, two, 12, false);
    for (double mu0 : {1.0, 0.5, 0.1}) {
        CHECK(std::fabs(matched.reflectance(mu0).total() - nearly.reflectance(mu0).total()) < 1e-10);
        CHECK(std::fabs(matched.transmittance(mu0) - nearly.transmittance(mu0)) < 1e-10);
        CHECK(std::fabs(matched.direct_transmittance(mu0) - nearly.direct_transmittance(mu0)) < 1e-10);
        const Vec3<double> wi = direction(mu0, 0.0), wo = direction(0.6, 2.0), wt = direction(-0.8, 0.5);
        CHECK(matched.subsurface_brdf(wi, wo) == doctest::Approx(nearly.subsurface_brdf(wi, wo)).epsilon(1e-9));
        CHECK(matched.btdf(wi, wt) == doctest::Approx(nearly.btdf(wi, wt)).epsilon(1e-9));
    }
    // With the default split the two differ by their discretizations alone (the matched joint passes light as the
    // identity, the other through its Snell map; a cut at the nearly matched joint's critical cosine, 1.4e-6, is
    // not taken: detail::layer_quadrature), shrinking with M: measured 4.3e-4 at M = 12 and 5.2e-5 at 16 (with
    // that cut: 1.6e-2 and 1.8e-3).
    for (const auto& c : {std::pair<int, double>{12, 1e-3}, std::pair<int, double>{16, 1.2e-4}}) {
        const auto a = stack({1.4, 1.4}, two, c.first), b = stack({1.4, 1.4 * (1 + 1e-12)}, two, c.first);
        for (double mu0 : {1.0, 0.5, 0.1}) {
            INFO("M = " << c.first << ", mu0 " << mu0);
            CHECK(std::fabs(a.reflectance(mu0).total() - b.reflectance(mu0).total()) < c.second);
            CHECK(std::fabs(a.transmittance(mu0) - b.transmittance(mu0)) < c.second);
        }
    }
}

TEST_CASE("slabs joined by an index-matched face: the BRDF is reciprocal and the BRDF and BTDF integrate to the fluxes") {
    // Two different slabs (the ordinates split at the critical cosine), M = 24: measured asymmetry 1.7e-11, the
    // integrals within 3.2e-6 of the fluxes (the fluxes' sums over the ordinates converge with M: 1.3e-7 at M = 32).
    // (With a refracting joint its operators spread each ordinate's beam over the ordinates around its Snell image:
    // 3e-3 asymmetry and 1.4e-3 between the integrals and the fluxes at M = 16, README, known limitations.)
    const std::vector<Slab<double>> slabs{Slab<double>(0.8, 0.6, 0.4), Slab<double>(0.95, 0.85, 2.0)};
    const auto layer = stack({1.4, 1.4}, slabs, 24, true, {1.0, 0.4});
    LayeredSurface<double>::Workspace ws;
    double worst = 0;
    for (const double a : {0.1, 0.5, 0.9, 1.0})
        for (const double b : {0.2, 0.6, 0.95})
            for (const double phi : {0.0, 1.5, 3.0}) {
                const double f = layer.subsurface_brdf(direction(a, 0.0), direction(b, phi), ws);
                const double g = layer.subsurface_brdf(direction(b, phi), direction(a, 0.0), ws);
                worst = std::fmax(worst, std::fabs(f - g) / f);
            }
    MESSAGE("worst relative asymmetry " << worst);
    CHECK(worst < 1e-10);
    const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(64);
    for (double mu0 : {1.0, 0.4}) {
        const Vec3<double> wi = direction(mu0, 0.0);
        double r = layer.direct_reflectance(mu0) + layer.forward_peak_reflectance(mu0);
        double t = layer.direct_transmittance(mu0) + layer.forward_peak_transmittance(mu0);
        for (std::size_t a = 0; a < g.size(); ++a)
            for (std::size_t b = 0; b < g.size(); ++b) {
                const Vec3<double> up = direction(g.nodes[a], pi * g.nodes[b]);
                const double w = 2 * pi * g.weights[a] * g.weights[b] * g.nodes[a];
                r += w * layer.subsurface_brdf(wi, up, ws);
                t += w * layer.btdf(wi, {up.x, up.y, -up.z}, ws);
            }
        INFO("mu0 " << mu0 << ": integrals " << r << ", " << t << "; fluxes " << layer.reflectance(mu0).subsurface << ", "
                    << layer.transmittance(mu0));
        CHECK(std::fabs(r - layer.reflectance(mu0).subsurface) < 5e-6);
        CHECK(std::fabs(t - layer.transmittance(mu0)) < 5e-6);
    }
}

TEST_CASE("a beam totally reflected at a joint: the slabs below it still send their diffuse light out (found by mutation testing)") {
    // 1.33 | 1.5 | 1.0 | 1.5 | 1.33 (three slabs, M = 16): light from the 1.33 side beyond n sin = 1 (mu < 0.66) is
    // totally reflected at the 1.5 | 1.0 joint, and the beam reaches neither slab below it. Their diffuse light was
    // dropped from the radiance leaving at true angles (beam_exit skipped every slab the beam did not reach): at
    // mu 0.35 the BTDF integrated to 0.22 of the diffuse transmittance and the BRDF to 0.966 of the diffuse
    // reflectance. The lobes' integrals (fourier_coefficients' mode 0, 2 x 64 Gauss points split at the exit's
    // critical cosine) against the fluxes less the deltas: measured within 1.2e-3 (as at incidences the beam
    // crosses); bound 3e-3.
    LayerOptions o;
    o.ordinates = 16;
    const std::vector<Slab<double>> slabs{Slab<double>(0.9, 0.6, 0.5), Slab<double>(0.95, 0.8, 0.7), Slab<double>(0.8, 0.3, 1.0)};
    const auto layer = stratum::solve_stack<double>(SmoothDielectric<double>(1.33, 1.5), slabs,
                                                    {Boundary<double>(SmoothDielectric<double>(1.5, 1.0)),
                                                     Boundary<double>(SmoothDielectric<double>(1.0, 1.5))},
                                                    SmoothDielectric<double>(1.5, 1.33), o);
    const double critical = std::sqrt(1 - 1 / (1.33 * 1.33));
    const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(64);
    std::vector<double> mu_o, weight;
    for (const double a : {0.0, critical}) {
        const double b = a == 0 ? critical : 1;
        for (std::size_t i = 0; i < g.size(); ++i) {
            mu_o.push_back(a + (b - a) * g.nodes[i]);
            weight.push_back((b - a) * g.weights[i]);
        }
    }
    for (const double mu : {0.35, 0.1, 0.8}) {
        for (const bool transmitted : {false, true}) {
            const auto c = layer.fourier_coefficients(
                transmitted ? stratum::LayerOutput::transmission : stratum::LayerOutput::subsurface_reflection, {mu}, mu_o);
            double integral = 0;
            for (std::size_t b = 0; b < mu_o.size(); ++b) integral += weight[b] * c[b * static_cast<std::size_t>(layer.modes())];
            integral *= 2 * stratum_test::pi;
            const double flux = transmitted ? layer.transmittance(mu) - layer.direct_transmittance(mu) - layer.forward_peak_transmittance(mu)
                                            : layer.reflectance(mu).subsurface - layer.direct_reflectance(mu) -
                                                  layer.forward_peak_reflectance(mu);
            CAPTURE(mu);
            CAPTURE(transmitted);
            CHECK(std::fabs(integral / flux - 1) <= 3e-3);
        }
    }
}

TEST_CASE("glass over tissue against the photon Monte Carlo: exact unscattered beam, diffuse part converging") {
    // air | 1.5 (tau 0.3, albedo 0.5, g 0.5) | 1.4 (tau 2, albedo 0.95, g 0.8) | air; tests/reference/mc_stack.hpp
    // (an independent photon Monte Carlo, 1e6 photons: standard errors 3e-4 to 5e-4). The unscattered beam is exact
    // (within 4 standard errors of the Monte Carlo's). The ordinates are split at every face's critical cosine,
    // the joint's included (detail::layer_quadrature): measured R - MC, T - MC at M = 16 and 32, mu0 = 1:
    // -1.7e-3, +8.9e-4 and -7.3e-4, +6.2e-4; mu0 = 0.5: -2.4e-3, +1.7e-3 and -1.0e-3, +1.2e-3 (at M = 32 within
    // 2.5 standard errors). One half-range rule, as before the joint's split: 6.2e-3, 7.5e-3 and 1.1e-3, 2.4e-3;
    // 8.7e-3, 1.1e-2 and 1.3e-3, 3.8e-3. Bounds: the measured x 1.5.
    mc_stack::Stack s;
    s.eta = {1.5, 1.4};
    s.tau = {0.3, 2.0};
    s.albedo = {0.5, 0.95};
    s.g = {0.5, 0.8};
    const std::vector<Slab<double>> slabs{Slab<double>(0.5, 0.5, 0.3), Slab<double>(0.95, 0.8, 2.0)};
    const struct {
        double mu0;
        int m;
        double r, t;
    } cases[] = {{1.0, 16, 2.6e-3, 1.4e-3}, {1.0, 32, 1.1e-3, 9.3e-4}, {0.5, 16, 3.6e-3, 2.5e-3}, {0.5, 32, 1.6e-3, 1.8e-3}};
    for (const double mu0 : {1.0, 0.5}) {
        const mc_stack::Result mc = mc_stack::simulate(s, mu0, 1000000, 11);
        for (const auto& c : cases) {
            if (c.mu0 != mu0) continue;
            const auto layer = stack({1.5, 1.4}, slabs, c.m, true, {mu0});
            const double r = layer.reflectance(mu0).total(), t = layer.transmittance(mu0);
            INFO("mu0 " << mu0 << ", M = " << c.m << ": R " << r << " (MC " << mc.R() << " +- " << mc.se_r << "), T " << t
                        << " (MC " << mc.T() << " +- " << mc.se_t << "); direct T " << layer.direct_transmittance(mu0)
                        << " (MC " << mc.t_direct << " +- " << mc.se_t_direct << ")");
            CHECK(std::fabs(layer.direct_transmittance(mu0) - mc.t_direct) < 4 * mc.se_t_direct);
            CHECK(std::fabs(layer.direct_reflectance(mu0) - mc.r_direct) < 4 * mc.se_r_direct + 1e-6);
            CHECK(std::fabs(r - mc.R()) < c.r);
            CHECK(std::fabs(t - mc.T()) < c.t);
        }
    }
}

TEST_CASE("refracting stacks over a Lambertian floor against the photon Monte Carlo") {
    // tests/reference/mc_stack.hpp with its floor (1e6 photons, standard error 4e-4 to 5e-4). The top's escape cone
    // is a cut in every slab over a floor (detail::layer_quadrature): measured |R - MC| at M = 16 and 32 within
    // 9.0e-4 and 2.0e-3 (three slabs, mu0 = 1). Without those cuts up to 5.8e-3 and 6.8e-3 (same cases, 2e6
    // photons), and converging erratically. Bound: the measured worst x 1.5.
    struct Case {
        std::vector<double> eta, tau, albedo, g;
        double floor;
    };
    // (The first, one slab, checks the Monte Carlo's floor against the solver's single-slab floor, which converges
    // smoothly: within 2.4e-5 of 2e7 photons at mu0 = 1, M = 64.)
    const Case cases[] = {{{1.4}, {0.8}, {0.9}, {0.6}, 0.7},
                          {{1.5, 1.4}, {0.7, 1.3}, {0.9, 0.95}, {0.8, 0.5}, 0.5},
                          {{1.5, 1.4, 1.38}, {0.2, 0.5, 4.0}, {0.3, 0.9, 0.99}, {0.0, 0.8, 0.85}, 0.6}};
    for (const Case& c : cases)
        for (const double mu0 : {1.0, 0.4}) {
            const mc_stack::Stack s{1.0, 1.0, c.eta, c.tau, c.albedo, c.g, c.floor};
            const mc_stack::Result mc = mc_stack::simulate(s, mu0, 1000000, 5);
            std::vector<Slab<double>> slabs;
            std::vector<Boundary<double>> joints;
            for (std::size_t j = 0; j < c.eta.size(); ++j) {
                slabs.emplace_back(c.albedo[j], c.g[j], c.tau[j]);
                if (j > 0) joints.push_back(SmoothDielectric<double>(c.eta[j - 1], c.eta[j]));
            }
            for (const int m : {16, 32}) {
                LayerOptions o;
                o.ordinates = m;
                stratum::LayerRequest<double> request;
                request.incidence = {mu0};
                const auto layer = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, c.eta.front()), slabs, joints,
                                                                Boundary<double>::lambertian(c.floor, c.eta.back()), o, request);
                const double r = layer.reflectance(mu0).total();
                INFO(c.eta.size() << " slabs, mu0 " << mu0 << ", M = " << m << ": R " << r << ", MC " << mc.R() << " +- " << mc.se_r);
                CHECK(std::fabs(r - mc.R()) < 3e-3);
            }
        }
}

TEST_CASE("glass over tissue: R and T converge monotonically with the ordinates") {
    // Below the Monte Carlo's noise: the distance to M = 48 shrinks from M = 16 to 24 to 32 (measured at mu0 = 1:
    // R 1.1e-3, 1.9e-4, 1.6e-4; T 4.0e-4, 2.0e-4, 1.3e-4). One half-range rule, as before the joint's split, jumped:
    // R 5.7e-3, 4.0e-4, 1.5e-3.
    const std::vector<Slab<double>> slabs{Slab<double>(0.5, 0.5, 0.3), Slab<double>(0.95, 0.8, 2.0)};
    const auto reference = stack({1.5, 1.4}, slabs, 48, true, {1.0});
    const double r48 = reference.reflectance(1.0).total(), t48 = reference.transmittance(1.0);
    double last_r = 1, last_t = 1;
    for (const int m : {16, 24, 32}) {
        const auto layer = stack({1.5, 1.4}, slabs, m, true, {1.0});
        const double dr = std::fabs(layer.reflectance(1.0).total() - r48), dt = std::fabs(layer.transmittance(1.0) - t48);
        INFO("M = " << m << ": |R - R_48| " << dr << ", |T - T_48| " << dt);
        CHECK(dr < last_r);
        CHECK(dt < last_t);
        CHECK(dr < 1.5e-3);
        CHECK(dt < 6e-4);
        last_r = dr;
        last_t = dt;
    }
}

TEST_CASE("an empty slab between index-matched joints is nothing; beside a refracting joint it is a film") {
    // tau = 0 (or below sqrt(eps) times the smallest ordinate, 1e-12 here) between matched joints: the solve drops it
    // with a joint, so the result is the stack without it, bit for bit. Kept, it turned the beam's source off and
    // R and T moved by 9e-5 at 16 ordinates (the spread beam's error).
    const Slab<double> a(0.9, 0.5, 0.5), b(0.8, 0.3, 0.7);
    const auto without = stack({1.4, 1.4}, {a, b}, 16);
    for (double tau : {0.0, 1e-12})
        for (int place = 0; place < 3; ++place) {
            std::vector<Slab<double>> slabs = {a, b};
            slabs.insert(slabs.begin() + place, Slab<double>(0.9, 0.5, tau));
            const auto with = stack({1.4, 1.4, 1.4}, slabs, 16);
            CAPTURE(tau);
            CAPTURE(place);
            for (double mu : {1.0, 0.6, 0.1}) {
                CHECK(with.reflectance(mu).total() == without.reflectance(mu).total());
                CHECK(with.transmittance(mu) == without.transmittance(mu));
                CHECK(with.direct_transmittance(mu) == without.direct_transmittance(mu));
            }
            CHECK(with.brdf(direction(0.6, 0.0), direction(0.3, 2.0)) == without.brdf(direction(0.6, 0.0), direction(0.3, 2.0)));
        }
    // An air gap of tau 0 between two glass slabs refracts at both its faces (and reflects totally beyond the
    // critical angle): kept, a film, through which the beam is a source like any slab. Without absorption its
    // R + T is 1.
    const Slab<double> white_a(1.0, 0.5, 0.5), white_b(1.0, 0.3, 0.7);
    const auto gap = stack({1.5, 1.0, 1.5}, {white_a, Slab<double>(1.0, 0.5, 0.0), white_b}, 16);
    const auto no_gap = stack({1.5, 1.5}, {white_a, white_b}, 16);
    for (double mu : {1.0, 0.6, 0.1}) {
        CAPTURE(mu);
        CHECK(std::fabs(gap.transmittance(mu) - no_gap.transmittance(mu)) > 1e-2);
        CHECK(gap.reflectance(mu).total() + gap.transmittance(mu) == doctest::Approx(1.0).epsilon(1e-10));
    }
}

// A film (tau 0, or thinner than film_limit) beside refracting joints: the beam stays a source through it, so the
// stack is continuous in tau down to 0 (found by review: where a slab fell below sqrt(eps) mu_min the beam was spread
// over the ordinates, direct_transmittance() was 0, the BTDF held the beam as a truncated Fourier series, 16.1 in the
// forward direction instead of 0.146, and R jumped by 4.6e-3 at mu = 0.1).
TEST_CASE("a film beside refracting joints keeps the beam a source: the stack is continuous as tau -> 0") {
    LayerOptions o;
    o.ordinates = 16;
    const auto with = [&](double tau) {
        return stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.5), {Slab<double>(0.9, 0.5, tau), Slab<double>(0.9, 0.5, 0.3)},
                                            {SmoothDielectric<double>(1.5, 1.2)}, SmoothDielectric<double>(1.2, 1.0), o);
    };
    const auto thin = with(1e-6);
    for (double tau : {0.0, 1e-14, 1e-11}) {
        const auto film = with(tau);
        CAPTURE(tau);
        for (double mu : {1.0, 0.5, 0.1}) {
            CAPTURE(mu);
            CHECK(film.direct_transmittance(mu) == doctest::Approx(thin.direct_transmittance(mu)).epsilon(2e-5));
            CHECK(std::fabs(film.transmittance(mu) - thin.transmittance(mu)) < 2e-5);
            CHECK(std::fabs(film.reflectance(mu).total() - thin.reflectance(mu).total()) < 2e-5);
        }
        CHECK(film.direct_transmittance(0.5) > 0.5);
        const Vec3<double> wi = direction(0.5, 0.0), wo = direction(-0.4, 3.14159);
        CHECK(film.btdf(wi, wo) == doctest::Approx(thin.btdf(wi, wo)).epsilon(1e-4));
    }
}

TEST_CASE("slabs joined by refracting faces: too few ordinates refused (5, and more than the critical cosines), enough keep energy") {
    using stratum::SmoothDielectric;
    const auto lossless = [](double g, double tau) { return Slab<double>(1.0, g, tau); };
    // 1 | 1.1 | 1.8 | 1.1 | 1: at 2 ordinates the light scattered in the dense slab was trapped, R + T 0.36 at
    // mu 0.8 and the BRDF 1.3e14 (found by review); 1 | 1.083 | 2.597 (film) | 1.071 | 1.098 | 1: 0.65 at 4.
    // Each stack (air | slabs | air, smooth faces) refused at `refused` ordinates and lossless at `taken`.
    const auto check_minimum = [](double top, const std::vector<Slab<double>>& slabs, const std::vector<Boundary<double>>& joints,
                                  double bottom, int refused, int taken) {
        LayerOptions o;
        o.ordinates = refused;
        INFO("refused at " << refused << ", taken at " << taken);
        CHECK_THROWS_AS(stratum::solve_stack<double>(SmoothDielectric<double>(1.0, top), slabs, joints,
                                                     SmoothDielectric<double>(bottom, 1.0), o),
                        std::invalid_argument);
        o.ordinates = taken;
        const auto l = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, top), slabs, joints,
                                                    SmoothDielectric<double>(bottom, 1.0), o);
        for (const double mu : {1.0, 0.7, 0.1}) CHECK(std::fabs(l.reflectance(mu).total() + l.transmittance(mu) - 1) < 1e-12);
    };
    const std::vector<Boundary<double>> dense{SmoothDielectric<double>(1.1, 1.8), SmoothDielectric<double>(1.8, 1.1)};
    const std::vector<Slab<double>> three{lossless(0.3, 1), lossless(0.3, 1), lossless(0.3, 1)};
    for (int m : {1, 2, 3, 4}) check_minimum(1.1, three, dense, 1.1, m, 5);
    // five distinct critical cosines: 6 ordinates
    check_minimum(1.083, {lossless(0.202, 0.1), lossless(-0.375, 0), lossless(-0.309, 1), lossless(0.465, 0)},
                  {SmoothDielectric<double>(1.083, 2.597), SmoothDielectric<double>(2.597, 1.071), SmoothDielectric<double>(1.071, 1.098)},
                  1.098, 5, 6);
    // An index-matched joint needs nothing more, nor slabs that scatter nothing (albedo 0: nothing to trap).
    LayerOptions two;
    two.ordinates = 2;
    CHECK_NOTHROW(stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.4), {lossless(0.3, 1), lossless(0.3, 1)},
                                               {SmoothDielectric<double>(1.4, 1.4)}, SmoothDielectric<double>(1.4, 1.0), two));
    CHECK_NOTHROW(stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 1.3), {Slab<double>(0.0, 0.3, 1), Slab<double>(0.0, 0.3, 1)},
                                               {SmoothDielectric<double>(1.3, 1.8)}, SmoothDielectric<double>(1.8, 1.0), two));
    // More critical cosines than 4 need more than 5 ordinates: 1 | 3.334 | 1.747 | 3.733 | 3.602 | 1 has five, and at
    // 5 ordinates R + T was 0.29 (found by review); it takes 6.
    check_minimum(3.334, {lossless(0.3, 1), lossless(0.3, 1), lossless(0.3, 1), lossless(0.3, 1)},
                  {SmoothDielectric<double>(3.334, 1.747), SmoothDielectric<double>(1.747, 3.733), SmoothDielectric<double>(3.733, 3.602)},
                  3.602, 5, 6);

    // Random lossless stacks of smooth faces (a quarter over a white floor): R + T = 1 at 5 to 7 ordinates where
    // they are taken (more than the stack's distinct critical cosines), refused where not (at 4, 6 of 1600 failed,
    // by up to 0.79, in the sweep behind minimum_ordinates; here 60 per M, double).
    std::mt19937_64 rng(20261127);
    const auto uniform = [&rng] { return stratum_test::uniform(rng); };
    const double taus[] = {0, 1e-3, 0.1, 1, 10};
    double worst = 0;
    for (int m : {5, 6, 7})
        for (int c = 0; c < 60; ++c) {
            const int count = 2 + static_cast<int>(uniform() * 3);
            std::vector<double> eta;
            std::vector<Slab<double>> slabs;
            std::vector<Boundary<double>> joints;
            for (int j = 0; j < count; ++j) {
                eta.push_back(uniform() < 0.2 ? 1.0 + 0.1 * uniform() : 1.2 + 1.4 * uniform());
                slabs.push_back(lossless(-0.5 + 1.45 * uniform(), taus[static_cast<int>(uniform() * 5)]));
                if (j > 0) joints.push_back(SmoothDielectric<double>(eta[static_cast<std::size_t>(j - 1)], eta.back()));
            }
            const bool floor = uniform() < 0.25;
            LayerOptions o;
            o.ordinates = m;
            std::vector<double> cuts;  // the distinct critical cosines (the faces' ratios below 1)
            std::vector<double> outside{1.0};
            outside.insert(outside.end(), eta.begin(), eta.end());
            if (!floor) outside.push_back(1.0);
            for (std::size_t j = 1; j < outside.size(); ++j) {
                const double r = std::min(outside[j - 1], outside[j]) / std::max(outside[j - 1], outside[j]);
                if (r < 1) cuts.push_back(std::sqrt((1 - r) * (1 + r)));
            }
            if (floor)  // (over a floor the top's escape cone in every slab below a joint is a cut too)
                for (std::size_t j = 1; j < eta.size(); ++j) cuts.push_back(std::sqrt((1 - 1 / eta[j]) * (1 + 1 / eta[j])));
            std::sort(cuts.begin(), cuts.end());
            const bool refracting = count > 1 && std::adjacent_find(eta.begin(), eta.end(), std::not_equal_to<double>()) != eta.end();
            const auto solve = [&] {
                return stratum::solve_stack<double>(
                    SmoothDielectric<double>(1.0, eta.front()), slabs, joints,
                    floor ? Boundary<double>::lambertian(1.0, eta.back()) : Boundary<double>(SmoothDielectric<double>(eta.back(), 1.0)), o);
            };
            if (refracting && m < static_cast<int>(std::unique(cuts.begin(), cuts.end()) - cuts.begin()) + 1) {
                CHECK_THROWS_AS(solve(), std::invalid_argument);
                continue;
            }
            const auto s = solve();
            for (const double mu : {1.0, 0.7, 0.3, 0.05})
                worst = std::max(worst, std::fabs(s.reflectance(mu).total() + s.transmittance(mu) - 1));
        }
    CHECK(worst < 1e-9);
}

TEST_CASE("too few ordinates for a slab's escape cone: over a floor, on one rule, and a single slab") {
    // Found by the second review: a white floor under 1 | 3.4213 | 2.1636 | 3.5906 | 3.2414 whose escape-cone images
    // (cut by layer_quadrature) were not counted (R 0.30 at 5 ordinates); on one half-range rule every ordinate of a
    // slab in its trapped cone (1 | 2.2753 | 1 at 2 and 3 ordinates: R + T 0.15; 1 | 3.492 | 1.837 | 3.859 | 1 at 5: 0.31).
    using stratum::SmoothDielectric;
    const auto lossless = [](double tau) { return Slab<double>(1.0, 0.3, tau); };
    LayerOptions o;
    const std::vector<Boundary<double>> joints{SmoothDielectric<double>(3.4213, 2.1636), SmoothDielectric<double>(2.1636, 3.5906),
                                               SmoothDielectric<double>(3.5906, 3.2414)};
    const std::vector<Slab<double>> four{lossless(4.284), lossless(1.533), lossless(0), lossless(0.36)};
    o.ordinates = 5;
    CHECK_THROWS_AS(stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 3.4213), four, joints,
                                                 Boundary<double>::lambertian(1.0, 3.2414), o),
                    std::invalid_argument);
    o.ordinates = 8;
    const auto floor = stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 3.4213), four, joints,
                                                    Boundary<double>::lambertian(1.0, 3.2414), o);
    CHECK(std::fabs(floor.reflectance(1.0).total() - 1) < 1e-9);
    LayerOptions one_rule;
    one_rule.critical_split = false;
    for (int m : {2, 3, 4}) {
        one_rule.ordinates = m;
        const auto solve = [&] {
            return stratum::solve_layer(lossless(10), SmoothDielectric<double>(1.0, 2.2753), SmoothDielectric<double>(2.2753, 1.0),
                                        one_rule);
        };
        if (m < 4) {
            CHECK_THROWS_WITH_AS(solve(), doctest::Contains("escape cone"), std::invalid_argument);
        } else {
            const auto s = solve();
            CHECK(std::fabs(s.reflectance(1.0).total() + s.transmittance(1.0) - 1) < 1e-9);
        }
    }
    one_rule.ordinates = 5;
    CHECK_THROWS_WITH_AS(stratum::solve_stack<double>(SmoothDielectric<double>(1.0, 3.492), {lossless(1), lossless(1), lossless(1)},
                                                      {SmoothDielectric<double>(3.492, 1.8374), SmoothDielectric<double>(1.8374, 3.8594)},
                                                      SmoothDielectric<double>(3.8594, 1.0), one_rule),
                         doctest::Contains("escape cone"), std::invalid_argument);
}
