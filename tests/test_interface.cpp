// Rough and smooth dielectric interfaces, pointwise: reciprocity, index matching, eta -> 1, total internal
// reflection, hard limits, the propagation-direction adapter, the smooth interface, and sampling.
// Integrals (energies, Monte Carlo) are in test_interface_energy.cpp.
#include <doctest/doctest.h>

#include <stratum/interface.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "test_util.hpp"

using stratum::RoughDielectric;
using stratum::Shadowing;
using stratum::SmoothDielectric;
using stratum::Vec3;

namespace {

using stratum_test::fresnel_closed_form;
using stratum_test::pi;
using stratum_test::random_direction;
using stratum_test::uniform;

Vec3<double> dir(double mu, double phi) {
    const double s = std::sqrt(std::fmax(0.0, (1 - mu) * (1 + mu)));
    return {s * std::cos(phi), s * std::sin(phi), mu};
}

bool finite_nonnegative(double v) { return std::isfinite(v) && v >= 0; }

}  // namespace

TEST_CASE("the BRDF is reciprocal on both sides: brdf(wi, wo) = brdf(wo, wi)") {
    std::mt19937_64 rng(1);
    for (double sigma : {0.02, 0.3, 1.0})
        for (double eta : {1 / 2.5, 1 / 1.4, 1.4, 2.5})
            for (auto form : {Shadowing::height_correlated, Shadowing::separable}) {
                const RoughDielectric<double> rd(sigma, 1.0, eta, form);
                int nonzero = 0;
                for (int i = 0; i < 400; ++i) {
                    Vec3<double> wi = random_direction(rng), wo = random_direction(rng);
                    if (wi.z * wo.z < 0) wo.z = -wo.z;
                    const double a = rd.brdf(wi, wo), b = rd.brdf(wo, wi);
                    nonzero += a > 0;
                    // Same formula with the roles swapped: h, F(i.h) = F(o.h), G2 symmetric; a few roundings.
                    CHECK(std::fabs(a - b) <= 1e-13 * std::fmax(a, b) + 1e-300);
                }
                CHECK(nonzero > 100);  // the check is not vacuous
            }
}

TEST_CASE("the BTDF obeys generalized reciprocity t_ij(i, o) / n_j^2 = t_ji(o, i) / n_i^2") {
    std::mt19937_64 rng(2);
    for (double sigma : {0.02, 0.3, 1.0})
        for (double eta : {1 / 2.5, 1 / 1.4, 1.4, 2.5})
            for (auto form : {Shadowing::height_correlated, Shadowing::separable}) {
                const double n_above = 1.0, n_below = eta;
                const RoughDielectric<double> rd(sigma, n_above, n_below, form);
                int nonzero = 0;
                for (int i = 0; i < 400; ++i) {
                    // Half the pairs uniformly at random, half from the sampler (inside the lobe for small sigma).
                    const Vec3<double> wi = random_direction(rng);
                    Vec3<double> wo = random_direction(rng);
                    if (i % 2) {
                        const auto smp = rd.sample(wi, 0.999999, uniform(rng), uniform(rng));  // refraction lobe
                        if (smp.valid()) wo = smp.wo;
                    }
                    if (wi.z * wo.z > 0) wo.z = -wo.z;
                    const double n_i = wi.z > 0 ? n_above : n_below, n_o = wo.z > 0 ? n_above : n_below;
                    const double a = rd.btdf(wi, wo) / (n_o * n_o), b = rd.btdf(wo, wi) / (n_i * n_i);
                    nonzero += a > 0;
                    // Fresnel from either side of a facet is the same number computed two ways: ~1e-15 relative
                    // in F, i.e. eps / (1 - F) relative in 1 - F, which reaches 1e-10 where 1 - F ~ 1e-6 (facets
                    // at the critical angle): tolerance 1e-9. Near-grazing facets make (o.h) ill-conditioned, but
                    // there the BTDF is negligible: absolute floor 1e-12.
                    CHECK(std::fabs(a - b) <= 1e-9 * std::fmax(a, b) + 1e-12);
                }
                CHECK(nonzero > 50);
            }
}

TEST_CASE("an index-matched interface reflects nothing and transmits straight through (a delta)") {
    for (double n : {1.0, 1.33, 2.5}) {
        const RoughDielectric<double> rd(0.3, n, n);
        CHECK(rd.index_matched());
        const Vec3<double> wi = dir(0.6, 0.4);
        CHECK(rd.brdf(wi, dir(0.6, 0.4 + pi)) == 0.0);
        CHECK(rd.btdf(wi, -wi) == 0.0);  // a delta is not evaluated
        CHECK(rd.pdf(wi, -wi) == 0.0);
        for (double mu : {1.0, 0.5, 1e-8, -0.5}) {
            const auto a = rd.hemispherical_totals(mu);
            CHECK(a.reflectance == 0.0);
            CHECK(a.transmittance == 1.0);
        }
        const auto s = rd.sample(wi, 0.3, 0.4, 0.5);
        CHECK(s.delta);
        CHECK(s.valid());
        CHECK(s.wo.x == -wi.x);
        CHECK(s.wo.z == -wi.z);
        CHECK(s.value * std::fabs(s.wo.z) / s.pdf == doctest::Approx(1.0).epsilon(1e-15));
        const SmoothDielectric<double> sd(n, n);
        const auto sc = sd.scatter(wi);
        CHECK(sc.reflectance == 0.0);
        CHECK(sc.transmittance == 1.0);
        CHECK(sc.radiance_transmittance == 1.0);
        CHECK(std::fabs(sc.transmitted.x + wi.x) < 1e-15);
        CHECK(std::fabs(sc.transmitted.z + wi.z) < 1e-15);
    }
}

TEST_CASE("indices within 1e-9 of matching: finite BTDF, vanishing reflection, continuous energies") {
    // eta = 1 + 1e-9: the BTDF's Jacobian denominator |eta_i i + eta_o o|^2 is ~1e-18 at straight-through;
    // the value is huge but finite. Energies come from the facet-space integral and are smooth in eta.
    for (double eta : {1 + 1e-9, 1 / (1 + 1e-9), 1.0001, 1 / 1.0001}) {
        const RoughDielectric<double> rd(0.3, 1.0, eta);
        for (double mu : {1.0, 0.7, 0.2}) {
            const Vec3<double> wi = dir(mu, 0.0);
            const double straight = rd.btdf(wi, -wi);
            CHECK(std::isfinite(straight));
            CHECK(straight > 0);
            for (double d : {1e-12, 1e-9, 1e-6, 1e-3}) {
                const Vec3<double> wo = stratum::normalize(Vec3<double>{-wi.x + d, d, -wi.z});
                CHECK(finite_nonnegative(rd.btdf(wi, wo)));
                CHECK(finite_nonnegative(rd.pdf(wi, wo)));
            }
            // F ~ (eta - 1)^2 / (16 mu^4) at the mirror direction, times D / (4 mu^2) <= 1.8 / (4 mu^2).
            CHECK(rd.brdf(wi, dir(mu, pi)) < (eta - 1) * (eta - 1) * 1e4);
        }
    }
    // Continuity of the hemispherical energies as eta -> 1, for the masking-only form towards exact
    // index matching {0, 1} (the error is F ~ (eta - 1)^2 plus the quadrature's 1e-8).
    for (double mu : {0.9, 0.5}) {
        const RoughDielectric<double> near(0.3, 1.0, 1 + 1e-9, Shadowing::masking_only);
        const auto a = near.hemispherical_totals(mu);
        CHECK(a.reflectance < 1e-12);
        CHECK(std::fabs(a.transmittance - 1) < 1e-7);
        // With shadowing the eta -> 1 limit keeps the model's shadowing loss (documented in interface.hpp):
        // continuous in eta, and equal for eta = 1 +- 1e-9 and 1 + 1e-6 to within the quadrature error.
        const RoughDielectric<double> hc1(0.3, 1.0, 1 + 1e-9), hc2(0.3, 1.0, 1 / (1 + 1e-9)), hc3(0.3, 1.0, 1 + 1e-6);
        const double t1 = hc1.hemispherical_totals(mu).transmittance, t2 = hc2.hemispherical_totals(mu).transmittance, t3 = hc3.hemispherical_totals(mu).transmittance;
        CHECK(std::fabs(t1 - t2) < 1e-7);
        CHECK(std::fabs(t1 - t3) < 1e-7);
        CHECK(t1 <= 1.0);
    }
}

TEST_CASE("total internal reflection: none transmitted by a smooth interface, a falling tail by a rough one") {
    const double eta_dense = 1.4;  // light from below (inside the dense medium), wi.z < 0
    const double mu_c = std::sqrt(1 - 1 / (eta_dense * eta_dense));  // critical cosine inside
    const SmoothDielectric<double> sd(1.0, eta_dense);
    for (double mu : {0.01, 0.5 * mu_c, 0.99 * mu_c}) {
        CHECK(sd.transmittance(-mu) == 0.0);
        CHECK(sd.reflectance(-mu) == 1.0);
        CHECK(sd.scatter(dir(-mu, 0.3)).total_internal_reflection);
    }
    CHECK(sd.transmittance(-1.01 * mu_c) > 0.0);
    // Rough: beyond the critical angle only tilted facets transmit; the transmittance grows with sigma
    // and vanishes as sigma -> 0.
    const double mu = 0.8 * mu_c;
    double prev = -1;
    for (double sigma : {1e-3, 0.02, 0.1, 0.3, 1.0}) {
        const RoughDielectric<double> rd(sigma, 1.0, eta_dense);
        const auto a = rd.hemispherical_totals(-mu);
        CHECK(a.transmittance >= prev);
        prev = a.transmittance;
        if (sigma == 1e-3) CHECK(a.transmittance < 1e-12);  // the lobe is ~100 sigma away from any transmitting facet
    }
    CHECK(prev > 0.01);
    // Continuity across the critical angle for the rough interface.
    const RoughDielectric<double> rd(0.3, 1.0, eta_dense);
    const double t_below = rd.hemispherical_totals(-(mu_c - 1e-7)).transmittance, t_above = rd.hemispherical_totals(-(mu_c + 1e-7)).transmittance;
    CHECK(std::fabs(t_below - t_above) < 1e-5);
}

TEST_CASE("hard limits: every sigma, eta near 1 and far, grazing and horizon directions give finite values") {
    const double sigmas[] = {1e-4, 1e-3, 0.02, 0.3, 1.0, 2.0};
    const double etas[] = {1.0, 1 + 1e-9, 1.0001, 1.4, 3.0, 1 / (1 + 1e-9), 1 / 1.0001, 1 / 1.4, 1 / 3.0};
    const double mus[] = {1.0, 0.5, 1e-4, 1e-8, 0.0};
    for (double sigma : sigmas)
        for (double eta : etas) {
            const RoughDielectric<double> rd(sigma, 1.0, eta);
            for (double mi : mus)
                for (double mo : mus)
                    for (double side_i : {1.0, -1.0})
                        for (double side_o : {1.0, -1.0})
                            for (double phi : {0.0, 1.0, pi}) {
                                const Vec3<double> wi = dir(side_i * mi, 0.0), wo = dir(side_o * mo, phi);
                                INFO("sigma " << sigma << " eta " << eta << " mu_i " << side_i * mi << " mu_o " << side_o * mo);
                                CHECK(finite_nonnegative(rd.eval(wi, wo)));
                                CHECK(finite_nonnegative(rd.pdf(wi, wo)));
                            }
            for (double mu : {1.0, 1e-8, 0.0, -1e-4, -0.5}) {
                const auto a = rd.hemispherical_totals(mu);
                INFO("sigma " << sigma << " eta " << eta << " mu " << mu);
                CHECK(finite_nonnegative(a.reflectance));
                CHECK(finite_nonnegative(a.transmittance));
                CHECK(a.reflectance + a.transmittance <= 1 + 1e-9);  // quadrature error budget (see header)
            }
        }
    // Directions on the horizon are degenerate input: 0, as in pbrt.
    const RoughDielectric<double> rd(0.3, 1.0, 1.4);
    CHECK(rd.eval({1, 0, 0}, dir(0.5, 0)) == 0.0);
    CHECK(rd.eval(dir(0.5, 0), {0, 1, 0}) == 0.0);
}

TEST_CASE("as sigma -> 0 the rough energies converge to the smooth interface's") {
    for (double eta : {1 / 1.4, 1.4, 2.5})
        for (double mu : {0.95, 0.6, -0.9, -0.4}) {
            const SmoothDielectric<double> sd(1.0, eta);
            double prev_err = 1;
            for (double sigma : {0.1, 0.02, 1e-3, 1e-4}) {
                const RoughDielectric<double> rd(sigma, 1.0, eta);
                const auto a = rd.hemispherical_totals(mu);
                const double err = std::fmax(std::fabs(a.reflectance - sd.reflectance(mu)),
                                             std::fabs(a.transmittance - sd.transmittance(mu)));
                INFO("eta " << eta << " mu " << mu << " sigma " << sigma << " err " << err);
                // The difference is O(sigma^2) (second moment of the slopes) away from the critical angle.
                CHECK(err <= prev_err + 1e-9);
                if (sigma == 1e-4) CHECK(err < 1e-6);
                prev_err = err;
            }
        }
}

TEST_CASE("eval_propagation is eval with wi = -(incident propagation) and peaks at dphi = 0") {
    const RoughDielectric<double> rd(0.1, 1.0, 1.4);
    std::mt19937_64 rng(3);
    for (int i = 0; i < 200; ++i) {
        const double mu_in = 2 * uniform(rng) - 1, mu_out = 2 * uniform(rng) - 1, dphi = 2 * pi * uniform(rng);
        // Independent construction: incident propagation d_in at azimuth 0, wi = -d_in; wo at azimuth dphi.
        const Vec3<double> d_in = dir(mu_in, 0.0), wo = dir(mu_out, dphi);
        const double a = rd.eval_propagation(mu_in, mu_out, std::cos(dphi)), b = rd.eval(-d_in, wo);
        CHECK(std::fabs(a - b) <= 1e-10 * std::fmax(a, b) + 1e-300);
    }
    // Light travelling down at 40 degrees: specular reflection leaves upwards at the same cosine, dphi = 0;
    // refraction continues downwards at Snell's cosine, dphi = 0.
    const double mu_in = -std::cos(40 * pi / 180);
    const SmoothDielectric<double> sd(1.0, 1.4);
    const double mu_t = sd.transmitted_cosine(-mu_in);  // < 0: downwards
    for (double d : {0.05, 0.2, pi / 2, pi}) {
        CHECK(rd.eval_propagation(mu_in, -mu_in, 1.0) > rd.eval_propagation(mu_in, -mu_in, std::cos(d)));
        CHECK(rd.eval_propagation(mu_in, mu_t, 1.0) > rd.eval_propagation(mu_in, mu_t, std::cos(d)));
    }
    CHECK(rd.eval_propagation(mu_in, mu_t, 1.0) > 10 * rd.eval_propagation(mu_in, -mu_t, 1.0));
}

TEST_CASE("the smooth interface: Fresnel, Snell's law, the radiance factor (n_t/n_i)^2") {
    const double n1 = 1.0, n2 = 1.4;
    const SmoothDielectric<double> sd(n1, n2);
    for (double mu : {1.0, 0.8, 0.3, 0.05, -1.0, -0.9, -0.75}) {
        const Vec3<double> wi = dir(mu, 0.7);
        const auto s = sd.scatter(wi);
        const double ni = mu > 0 ? n1 : n2, nt = mu > 0 ? n2 : n1;
        CHECK(s.reflectance == stratum::fresnel_dielectric(std::fabs(mu), nt / ni));
        CHECK(s.reflectance + s.transmittance == 1.0);
        CHECK(s.reflected.x == -wi.x);
        CHECK(s.reflected.z == wi.z);
        if (s.total_internal_reflection) continue;
        // Snell: n_i sin_i = n_t sin_t, opposite side, same plane (transmitted is -wi bent towards the normal).
        const double sin_i = std::sqrt(1 - mu * mu), sin_t = std::sqrt(1 - s.transmitted.z * s.transmitted.z);
        CHECK(std::fabs(ni * sin_i - nt * sin_t) < 1e-14);
        CHECK(s.transmitted.z * mu < 0);
        CHECK(std::fabs(s.transmitted.x * wi.y - s.transmitted.y * wi.x) < 1e-15);  // coplanar with the normal
        CHECK(std::fabs(stratum::length(s.transmitted) - 1) < 1e-15);
        CHECK(s.transmitted.z == doctest::Approx(sd.transmitted_cosine(mu)).epsilon(1e-14));
        CHECK(s.radiance_transmittance == doctest::Approx((nt / ni) * (nt / ni) * s.transmittance).epsilon(1e-15));
        // Reversing the ray (light arriving along the transmitted direction) gives back wi.
        CHECK(std::fabs(sd.transmitted_cosine(sd.transmitted_cosine(mu)) - mu) < 1e-14);
    }
}

TEST_CASE("sample returns eval and pdf of its direction, with a weight G2/G1(wi) in [0, 1]") {
    // For a visible-normal sampler with Fresnel lobe selection, f |wo.z| / pdf = G2(wi, wo) / G1(wi) exactly
    // (D, F and the Jacobian cancel): an independent identity between eval, pdf and the Smith functions.
    std::mt19937_64 rng(4);
    for (double sigma : {0.02, 0.3, 1.0})
        for (double eta : {1 / 1.4, 1.4}) {
            const RoughDielectric<double> rd(sigma, 1.0, eta);
            const auto& b = rd.distribution();
            int valid = 0;
            for (int i = 0; i < 2000; ++i) {
                const Vec3<double> wi = random_direction(rng);
                const auto s = rd.sample(wi, uniform(rng), uniform(rng), uniform(rng));
                if (!s.valid()) continue;
                ++valid;
                CHECK(s.value == rd.eval(wi, s.wo));
                CHECK(s.pdf == rd.pdf(wi, s.wo));
                CHECK(s.reflected == (wi.z * s.wo.z > 0));
                const double li = b.Lambda(wi.z), lo = b.Lambda(s.wo.z);
                const double g2_over_g1 = s.reflected ? (1 + li) / (1 + li + lo)
                                                      : std::exp(std::lgamma(1 + li) + std::lgamma(1 + lo) - std::lgamma(2 + li + lo)) * (1 + li);
                const double weight = s.value * std::fabs(s.wo.z) / s.pdf;
                CHECK(weight == doctest::Approx(g2_over_g1).epsilon(1e-9));
                CHECK(weight <= 1 + 1e-12);
            }
            CHECK(valid > 1500);  // only samples sent into the wrong hemisphere fail (~15% at sigma = 1)
        }
}

TEST_CASE("sample never produces NaN for any u in [0, 1)") {
    const double us[] = {0.0, 1e-300, 0x1p-53, 0.5, 1 - 0x1p-53};
    const Vec3<double> dirs[] = {{0, 0, 1}, {0, 0, -1}, {std::sqrt(1 - 1e-16), 0, 1e-8}, {0.6, 0, -0.8}, {1, 0, 0}};
    int bad = 0;
    for (double sigma : {1e-4, 0.3, 2.0})
        for (double eta : {1 / 1.4, 1 + 1e-9, 2.5})
            for (const auto& wi : dirs) {
                const RoughDielectric<double> rd(sigma, 1.0, eta);
                for (double a : us)
                    for (double b : us)
                        for (double c : us) {
                            const auto s = rd.sample(wi, a, b, c);
                            const bool ok = std::isfinite(s.value) && std::isfinite(s.pdf) && std::isfinite(s.wo.x) &&
                                            std::isfinite(s.wo.y) && std::isfinite(s.wo.z) && s.value >= 0 && s.pdf >= 0;
                            bad += !ok;
                        }
            }
    CHECK(bad == 0);
}

TEST_CASE("sample with a NaN or infinite wi gives a failed sample on every face, smooth and index-matched included") {
    // (the delta branches returned a valid sample with a NaN direction, pdf 0.04 for a smooth 1 | 1.5 face and 1 for
    // an index-matched one; found by a review sweep)
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    const Vec3<double> dirs[] = {{nan, 0, 1}, {0, nan, -1}, {inf, 0, 1}, {0, -inf, -0.5}, {0, 0, nan}, {0, 0, inf}};
    for (double sigma : {0.0, 1e-9, 0.3})
        for (double eta : {1.0, 1.5})
            for (const auto& wi : dirs) {
                const RoughDielectric<double> rd(sigma, 1.0, eta);
                for (const stratum::TransportMode mode : {stratum::TransportMode::importance, stratum::TransportMode::radiance}) {
                    const auto s = rd.sample(wi, 0.5, 0.5, 0.5, mode);
                    CHECK(!s.valid());
                    CHECK(s.pdf == 0);
                }
            }
}

TEST_CASE("brdf and btdf are facet_brdf / facet_btdf times shadowing_over_cosines, within 4 ulp") {
    // The factored form that InterfaceOperators evaluates (the shadowing computed once per pair of cosines) against
    // the whole evaluation, for every shadowing form, both sides, random directions (1e-3 < |z| < 1). Measured: at
    // most 1.7 eps relative apart (1.8 million pairs).
    std::mt19937_64 rng(5);
    for (Shadowing form : {Shadowing::height_correlated, Shadowing::separable, Shadowing::masking_only})
        for (double sigma : {0.02, 0.3, 1.5}) {
            const RoughDielectric<double> r(sigma, 1.0, 1.4, form);
            int nonzero = 0;
            for (int i = 0; i < 2000; ++i) {
                const Vec3<double> wi = random_direction(rng), wo = random_direction(rng);
                if (std::fabs(wi.z) < 1e-3 || std::fabs(wo.z) < 1e-3) continue;
                const bool transmission = wi.z * wo.z < 0;
                const double whole = transmission ? r.btdf(wi, wo) : r.brdf(wi, wo);
                const double facet = transmission ? r.facet_btdf(wi, wo) : r.facet_brdf(wi, wo);
                const double factored = facet * r.shadowing_over_cosines(std::fabs(wi.z), std::fabs(wo.z), transmission);
                CAPTURE(wi.z);
                CAPTURE(wo.z);
                // (+ the smallest normal: far outside narrow lobes both forms underflow, in different places)
                CHECK(std::fabs(factored - whole) <= 4 * std::numeric_limits<double>::epsilon() * whole + std::numeric_limits<double>::min());
                nonzero += whole > 0;
            }
            CHECK(nonzero > 300);  // measured 395 to 413 at sigma 0.02 (narrow lobes), more above
        }
}

TEST_CASE("float, double and long double instantiations agree") {
    const RoughDielectric<float> f(0.3f, 1.0f, 1.4f);
    const RoughDielectric<double> d(0.3, 1.0, 1.4);
    const RoughDielectric<long double> l(0.3L, 1.0L, 1.4L);
    const Vec3<double> wi = dir(0.7, 0.1), wo_r = dir(0.5, 2.9), wo_t = dir(-0.8, 3.0);
    auto to_f = [](Vec3<double> v) { return Vec3<float>{float(v.x), float(v.y), float(v.z)}; };
    auto to_l = [](Vec3<double> v) { return Vec3<long double>{v.x, v.y, v.z}; };
    for (const auto& wo : {wo_r, wo_t}) {
        const double ref = d.eval(wi, wo);
        CHECK(ref > 0);
        CHECK(static_cast<double>(f.eval(to_f(wi), to_f(wo))) == doctest::Approx(ref).epsilon(1e-4));
        CHECK(static_cast<double>(l.eval(to_l(wi), to_l(wo))) == doctest::Approx(ref).epsilon(1e-13));
    }
    CHECK(static_cast<double>(f.hemispherical_totals(0.7f).transmittance) == doctest::Approx(d.hemispherical_totals(0.7).transmittance).epsilon(1e-6));
}

TEST_CASE("float computes its shadowing in float, within a few float ulp of double") {
    // Both cosines >= 1e-4: Smith's Lambda and G2 in float (interface.hpp, narrow_cosine_min), against the double
    // instantiation at the same (float) inputs. Measured worst relative difference over these 3 x 2 x 20000 draws:
    // 5.8e-7 (4.9 float ulp), but for the height-correlated transmission's log B, whose terms cancel: 5.8e-6 where
    // G2 / (mu_i mu_o) >= 1e-6 (the bound below), 4.2e-5 at 1e-28. Below 1e-4 the wide path, as double.
    std::mt19937_64 rng(11);
    for (const Shadowing form : {Shadowing::height_correlated, Shadowing::separable, Shadowing::masking_only})
        for (const bool transmission : {false, true}) {
            const bool log_beta = form == Shadowing::height_correlated && transmission;
            double worst = 0;
            for (int i = 0; i < 20000; ++i) {
                const float sigma = static_cast<float>(std::pow(10.0, 4 * uniform(rng) - 3));
                const float mu_i = static_cast<float>(std::pow(10.0, -4 * uniform(rng)));
                const float mu_o = static_cast<float>(std::pow(10.0, -4 * uniform(rng)));
                const double narrow = RoughDielectric<float>(sigma, 1.0f, 1.5f, form).shadowing_over_cosines(mu_i, mu_o, transmission);
                const double wide = RoughDielectric<double>(sigma, 1.0, 1.5, form).shadowing_over_cosines(mu_i, mu_o, transmission);
                if (wide * mu_i * mu_o < (log_beta ? 1e-6 : 1e-30)) continue;
                worst = std::fmax(worst, std::fabs(narrow - wide) / wide);
            }
            CAPTURE(static_cast<int>(form));
            CAPTURE(transmission);
            CHECK(worst <= (log_beta ? 1e-5 : 1e-6));
        }
    // Across the switch to the wide path at 1e-4, and at grazing cosines (where float's range needs it).
    const RoughDielectric<float> f(0.3f, 1.0f, 1.5f);
    const RoughDielectric<double> d(0.3, 1.0, 1.5);
    for (const float mu : {9.9999e-5f, 1e-4f, 1.0001e-4f, 1e-30f}) {
        CAPTURE(mu);
        CHECK(f.shadowing_over_cosines(mu, 0.5f, false) == doctest::Approx(d.shadowing_over_cosines(mu, 0.5, false)).epsilon(1e-6));
    }
}

TEST_CASE("the shadowing in double equals its formula with Beckmann's Lambda, bit for bit") {
    // Where a = cot(theta) / alpha >= 6.25, Lambda (<= 6.0e-21) is taken as 0 (interface.hpp, negligible_lambda_a):
    // 1 + Lambda cannot tell it from 0 in double, so nothing changes. (A cut at a = 5, Lambda 1.5e-13, fails this.)
    std::mt19937_64 rng(5);
    int differ = 0, cut = 0;
    for (const Shadowing form : {Shadowing::height_correlated, Shadowing::separable, Shadowing::masking_only})
        for (const bool transmission : {false, true})
            for (int i = 0; i < 4000; ++i) {
                const double sigma = std::pow(10.0, 3 * uniform(rng) - 3);
                const double mu_i = uniform(rng), mu_o = uniform(rng);
                const RoughDielectric<double> r(sigma, 1.0, 1.5, form);
                const double g2 = stratum::detail::smith_g2<double>(r.distribution().Lambda(mu_i), r.distribution().Lambda(mu_o),
                                                                    form, transmission);
                differ += r.shadowing_over_cosines(mu_i, mu_o, transmission) != g2 / mu_i / mu_o;
                // (a negative cosine too: only |mu| matters, as in Beckmann::Lambda; found by review)
                differ += r.shadowing_over_cosines(-mu_i, mu_o, transmission) !=
                          stratum::detail::smith_g2<double>(r.distribution().Lambda(-mu_i), r.distribution().Lambda(mu_o),
                                                            form, transmission) / -mu_i / mu_o;
                cut += r.distribution().Lambda(std::fmax(mu_i, mu_o)) <= 6.0e-21;  // (a >= 6.25 for one of the two)
            }
    CHECK(differ == 0);
    CHECK(cut > 4000);  // the cut is exercised (measured: 16329 of 24000 draws)
}

TEST_CASE("invalid parameters are rejected with messages naming them") {
    // sigma = 0 is the smooth limit (test_interface_smooth_limit.cpp); negative, NaN and infinite sigma are not.
    CHECK_THROWS_WITH_AS(RoughDielectric<double>(-0.1, 1.0, 1.4), doctest::Contains("sigma"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(RoughDielectric<double>(4.75e140, 0.217, 0.54), doctest::Contains("sigma"), std::invalid_argument);
    CHECK_NOTHROW(RoughDielectric<double>(1e10, 0.217, 0.54));
    CHECK_THROWS_WITH_AS(RoughDielectric<double>(0.3, -1.0, 1.4), doctest::Contains("eta_above"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(RoughDielectric<double>(0.3, 1.0, std::numeric_limits<double>::quiet_NaN()),
                         doctest::Contains("eta_below"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(SmoothDielectric<double>(0.0, 1.4), doctest::Contains("eta_above"), std::invalid_argument);
    // Indices beyond [1e-4, 1e4] are refused: a layer between 2.34 and 1.6e140 (found by fuzz_layer) gave NaN,
    // the fourth power of the index ratio overflowing.
    CHECK_THROWS_WITH_AS(RoughDielectric<double>(0.3, 1.0, 1.6e140), doctest::Contains("eta_below"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(SmoothDielectric<double>(2.34, 2e4), doctest::Contains("[0.0001, 10000]"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(SmoothDielectric<float>(5e-5f, 1.4f), doctest::Contains("eta_above"), std::invalid_argument);
    CHECK_NOTHROW(SmoothDielectric<float>(1e-4f, 1e4f));
    const RoughDielectric<double> rd(0.3, 1.0, 1.4);
    CHECK_THROWS_WITH_AS((void)rd.hemispherical_totals(0.5, 1), doctest::Contains("nodes"), std::invalid_argument);
}

TEST_CASE("delta samples at subnormal cosines are discarded, never inf (found by fuzz_pointwise)") {
    // Index matched, wi.z = 2e-315: the delta sample's value 1 / |wi.z| overflowed to inf.
    const double tiny = 2.0722615146145237e-315;
    for (const double sigma : {0.3, 0.0}) {
        const RoughDielectric<double> matched(sigma, 0.1, 0.1), smooth_face(0.0, 1.0, 1.5);
        for (const auto& face : {matched, smooth_face}) {
            const auto s = face.sample(Vec3<double>{1.0, 0.0, tiny}, 0.0, 0.0, 0.0);
            CHECK_FALSE(s.valid());
            CHECK(s.value == 0.0);
        }
    }
    const RoughDielectric<float> f(0.0f, 0.1f, 0.1f);
    const auto s = f.sample(Vec3<float>{1.0f, 0.0f, 1e-39f}, 0.0f, 0.0f, 0.0f);
    CHECK_FALSE(s.valid());
    // The smallest normal cosine still gives a finite weight-1 sample.
    const auto n = RoughDielectric<double>(0.3, 1.2, 1.2).sample(Vec3<double>{1.0, 0.0, std::numeric_limits<double>::min()}, 0.5, 0.5, 0.5);
    CHECK(n.valid());
    CHECK(std::isfinite(n.value));
}

TEST_CASE("a BRDF that exceeds the range at a grazing direction saturates; below that it is exact (found by fuzz_pointwise)") {
    // Masking-only shadowing, wi = normal: r = F(c) D(h) G1(wi) / (4 mu_o) with G1(normal) = 1 and h at 45
    // degrees (to within mu_o), D(h) = 2 exp(-1 / (2 sigma^2)) / (pi sigma^2) (Beckmann with RMS slope sigma,
    // docs/physics.md section 4: tan = 1, cos^4 = 1/4): it
    // grows like 1 / mu_o without bound. The fuzzer's input (sigma 2.87, n 10 | 9.99999727, wo.z = 1.39e-309)
    // gave inf: G2 / (mu_i mu_o) alone overflowed although F D / (4 mu_o) = 5e293 does not.
    const double sigma = 2.87;
    const double D45 = 2 * std::exp(-1 / (2 * sigma * sigma)) / (pi * sigma * sigma);
    for (const double eta_t : {9.99999727, 15.0}) {
        const RoughDielectric<double> rd(sigma, 10.0, eta_t, Shadowing::masking_only);
        const double F45 = fresnel_closed_form(std::sqrt(0.5), eta_t / 10.0);
        for (const double mu_o : {1e-200, 1e-300, 1.39e-309, 5e-324}) {
            const Vec3<double> wi{-0.0, 0.0, 1.0}, wo{1.0, 1.3e-178, mu_o};
            const double expected = F45 * D45 / 4 / mu_o;  // inf where the exact value is beyond double's range
            INFO("n " << eta_t << " mu_o " << mu_o << " expected " << expected);
            const double r = rd.eval(wi, wo);
            if (std::isfinite(expected))
                CHECK(r == doctest::Approx(expected).epsilon(1e-12));
            else
                CHECK(r == std::numeric_limits<double>::max());
        }
    }
    // A grazing mirror pair at cosine mu, h = normal: D = 1 / (2 pi sigma^2), F -> 1, Lambda(mu) -> sigma / (sqrt(2 pi) mu)
    // (relative corrections O(mu / sigma)). Height-correlated r = D / (4 mu^2 (1 + 2 Lambda)) -> 1 / (8 sqrt(2 pi) sigma^3 mu),
    // masking-only twice that, separable r = D / (4 mu^2 (1 + Lambda)^2) -> 1 / (4 sigma^4). Below mu ~ 1e-162 (double)
    // or 1e-23 (float) |wi + wo|^2 underflows: the half vector is undefined and the value 0 (degenerate input).
    const double s = 1e-3;
    const double hc = 1 / (8 * std::sqrt(2 * pi) * s * s * s);
    const std::pair<Shadowing, double> forms[] = {{Shadowing::height_correlated, hc}, {Shadowing::masking_only, 2 * hc}, {Shadowing::separable, 0}};
    for (const auto& [form, coefficient] : forms) {
        const RoughDielectric<double> narrow(s, 1.0, 1.5, form);
        const RoughDielectric<float> narrow_f(1e-3f, 1.0f, 1.5f, form);
        for (const double mu : {1e-30, 1e-150}) {
            const double expected = form == Shadowing::separable ? 1 / (4 * s * s * s * s) : coefficient / mu;
            CHECK(narrow.eval(Vec3<double>{1.0, 0.0, mu}, Vec3<double>{-1.0, 0.0, mu}) == doctest::Approx(expected).epsilon(1e-12));
        }
        const float mu_f = 1e-15f;
        const double expected_f = form == Shadowing::separable ? 1 / (4 * s * s * s * s) : coefficient / double(mu_f);
        CHECK(narrow_f.eval(Vec3<float>{1.0f, 0.0f, mu_f}, Vec3<float>{-1.0f, 0.0f, mu_f}) == doctest::Approx(expected_f).epsilon(1e-5));
        CHECK(narrow.eval(Vec3<double>{1.0, 0.0, 1e-170}, Vec3<double>{-1.0, 0.0, 1e-170}) == 0.0);
    }
    // Masking-only in float: 1 / mu_o beyond float's range, computed in double and saturated.
    const RoughDielectric<float> masking_f(2.87f, 10.0f, 15.0f, Shadowing::masking_only);
    CHECK(masking_f.eval(Vec3<float>{0.0f, 0.0f, 1.0f}, Vec3<float>{1.0f, 0.0f, 1e-44f}) == std::numeric_limits<float>::max());
}

TEST_CASE("hemispherical totals at cosines down to the smallest normal double are the grazing limit (found by fuzz_pointwise)") {
    // sigma 2.87, n 10 | 9.87, height-correlated, mu = 2.25e-308: R was NaN (Lambda's 1/a overflowed).
    for (const auto form : {Shadowing::height_correlated, Shadowing::separable, Shadowing::masking_only}) {
        const RoughDielectric<double> face(2.8745131426069297, 10, 9.8673729616057031, form);
        const auto limit = face.hemispherical_totals(1e-20);
        for (double mu : {1e-150, 1e-200, 1e-300, 2.2516916358067193e-308, std::numeric_limits<double>::denorm_min()}) {
            for (double sign : {1.0, -1.0}) {
                const auto a = face.hemispherical_totals(sign * mu), ref = face.hemispherical_totals(sign * 1e-20);
                INFO("mu = " << sign * mu);
                CHECK(std::isfinite(a.reflectance));
                CHECK(std::isfinite(a.transmittance));
                CHECK(a.reflectance == doctest::Approx(ref.reflectance).epsilon(1e-12));
                CHECK(a.transmittance == doctest::Approx(ref.transmittance).epsilon(1e-12));
            }
        }
        CHECK(face.hemispherical_totals(0.0).reflectance == doctest::Approx(limit.reflectance).epsilon(1e-12));
    }
}

TEST_CASE("transport modes: radiance evaluates the BSDF the other way round, with the same sampling density") {
    using stratum::TransportMode;
    std::mt19937_64 rng(91);
    for (const auto form : {Shadowing::height_correlated, Shadowing::masking_only}) {
        const RoughDielectric<double> rd(0.4, 1.0, 1.5, form);
        for (int i = 0; i < 2000; ++i) {
            const Vec3<double> wi = random_direction(rng), wo = random_direction(rng);
            const double u0 = uniform(rng), u1 = uniform(rng), u2 = uniform(rng);
            // By definition: the value with the arguments exchanged.
            CHECK(rd.eval(wi, wo, TransportMode::radiance) == rd.eval(wo, wi));
            // Generalized reciprocity, btdf(wi, wo) / eta_wo^2 = btdf(wo, wi) / eta_wi^2 (height-correlated form),
            // with the tolerance of the reciprocity test above (1 - F computed from either side of a facet).
            const double t = rd.eval(wi, wo);
            if (form == Shadowing::height_correlated && wi.z * wo.z < 0) {
                const double eta_wi = wi.z > 0 ? 1.0 : 1.5, eta_wo = wo.z > 0 ? 1.0 : 1.5;
                CHECK(std::fabs(rd.eval(wi, wo, TransportMode::radiance) - t * (eta_wi / eta_wo) * (eta_wi / eta_wo)) <=
                      1e-9 * t + 1e-12);
            }
            // Sampling: the same direction and density, the radiance mode's value at it.
            const auto a = rd.sample(wi, u0, u1, u2), b = rd.sample(wi, u0, u1, u2, TransportMode::radiance);
            CHECK(a.wo.x == b.wo.x);
            CHECK(a.wo.z == b.wo.z);
            CHECK(a.pdf == b.pdf);
            if (b.valid()) CHECK(b.value == rd.eval(wi, b.wo, TransportMode::radiance));
        }
    }
    // A smooth face's delta samples: a refraction's weight value |wo.z| / pdf becomes (eta_wi / eta_wo)^2.
    const RoughDielectric<double> smooth(0.0, 1.0, 1.5);
    for (const double mu : {0.9, -0.9}) {
        const Vec3<double> wi{std::sqrt(1 - mu * mu), 0.0, mu};
        const auto refracted = smooth.sample(wi, 0.999, 0.5, 0.5, TransportMode::radiance);
        REQUIRE(refracted.valid());
        REQUIRE_FALSE(refracted.reflected);
        const double ratio = mu > 0 ? 1.0 / 1.5 : 1.5;
        CHECK(refracted.value * std::fabs(refracted.wo.z) / refracted.pdf == doctest::Approx(ratio * ratio).epsilon(1e-15));
        const auto reflected = smooth.sample(wi, 0.0, 0.5, 0.5, TransportMode::radiance);
        CHECK(reflected.value * std::fabs(reflected.wo.z) / reflected.pdf == doctest::Approx(1.0).epsilon(1e-15));
    }
}
