// Fresnel reflectance: closed forms, limits and the hemispherical averages.
#include <doctest/doctest.h>

#include <stratum/fresnel.hpp>

#include <cmath>
#include <stdexcept>

#include "test_util.hpp"

using stratum::fresnel_dielectric;
using stratum::fresnel_diffuse_reflectance;
using stratum::fresnel_diffuse_reflectance_fit;
using stratum::fresnel_hemispherical_reflectance;
using stratum_test::ulp_distance;

TEST_CASE("normal incidence gives ((eta - 1) / (eta + 1))^2") {
    for (double eta : {1.0 / 3, 0.5, 1.0 / 1.4, 1.0001, 1.4, 1.5, 2.5, 3.0}) {
        const double r = (eta - 1) / (eta + 1);
        CHECK(ulp_distance(fresnel_dielectric(1.0, eta), r * r) <= 4);
    }
    const float rf = (1.5f - 1) / (1.5f + 1);
    CHECK(ulp_distance(fresnel_dielectric(1.0f, 1.5f), rf * rf) <= 2);
}

TEST_CASE("index matching reflects nothing at any angle, including grazing") {
    for (double mu : {0.0, 1e-300, 1e-8, 0.3, 1.0}) CHECK(fresnel_dielectric(mu, 1.0) == 0.0);
}

TEST_CASE("total internal reflection gives exactly 1 beyond the critical angle") {
    const double eta = 1 / 1.4;                              // from the dense side
    const double mu_c = std::sqrt(1 - eta * eta);            // critical cosine
    CHECK(fresnel_dielectric(mu_c * 0.999, eta) == 1.0);
    CHECK(fresnel_dielectric(0.0, eta) == 1.0);
    CHECK(fresnel_dielectric(mu_c * 1.001, eta) < 1.0);
    CHECK(fresnel_dielectric(0.0, 1.4) == 1.0);              // grazing from the light side
}

TEST_CASE("grazing incidence gives exactly 1, never an ulp above (found by fuzz_pointwise at eta = 974.67)") {
    for (double eta : {974.67113628700076, 1.5, 3.0, 1e3, 1e4, 1e-4, 0.5}) CHECK(stratum::fresnel_dielectric(0.0, eta) == 1.0);
    for (float eta : {974.671f, 1.5f, 1e4f, 1e-4f}) CHECK(stratum::fresnel_dielectric(0.0f, eta) == 1.0f);
    // Just above grazing the formulas round to 1 + 4.4e-16 without the clamp (e.g. eta = 1.2099, cos = 7.1e-18).
    double worst = 0;
    for (int e = 0; e <= 800; ++e) {
        const double eta = std::pow(10.0, -4 + e / 100.0);
        for (int k = 1; k <= 60; ++k) worst = std::fmax(worst, stratum::fresnel_dielectric(std::ldexp(1.0, -k), eta));
    }
    CHECK(worst <= 1.0);
    CHECK(stratum::fresnel_dielectric(7.105427357601002e-18, 1.2099224003493465) <= 1.0);
}

TEST_CASE("a negative cosine means the light arrives from the other side") {
    // (to rounding: the negative branch forms eta^2 - 1 of the ratio 1 / 1.4 exactly, the positive one of the rounded
    // 1 / 1.4, below; away from the critical cosine 0.7, where F's condition in eta grows without bound: 1.6e-14 there)
    for (double mu : {0.2, 0.8, 0.95})
        CHECK(std::fabs(fresnel_dielectric(-mu, 1.4) - fresnel_dielectric(mu, 1 / 1.4)) <= 4e-16 * fresnel_dielectric(mu, 1 / 1.4));
}

TEST_CASE("reflectance agrees with the textbook s/p form written with cos_t") {
    // An independent form: r_s = (n_i c_i - n_t c_t)/(n_i c_i + n_t c_t), r_p = (n_t c_i - n_i c_t)/(n_t c_i + n_i c_t).
    for (double eta : {1.33, 2.0, 0.75}) {
        for (double ci : {0.05, 0.3, 0.6, 0.99}) {
            const double s2 = (1 - ci * ci) / (eta * eta);
            if (s2 >= 1) continue;
            const double ct = std::sqrt(1 - s2);
            const double rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
            CHECK(std::fabs(fresnel_dielectric(ci, eta) - (rs * rs + rp * rp) / 2) <= 4e-16);
        }
    }
}

TEST_CASE("hemispherical reflectance matches mpmath references") {
    // mpmath (50 digits): 2 * quad(F(c, eta) * c, [0, critical, 1]) with the same F.
    struct Ref { double eta, value; };
    const Ref refs[] = {
        // tests/data/gen_fresnel.py
        {1.3, 0.061131825157965757517}, {1 / 1.3, 0.44445670127690285305},
        {1.4, 0.076811545576952902688}, {1 / 1.4, 0.52898548243722080895},
        {2.5, 0.22186657352196287569},  {1 / 2.5, 0.87549865176351406011},
    };
    for (const Ref& r : refs) CHECK(std::fabs(fresnel_hemispherical_reflectance(r.eta) - r.value) <= 2e-16);
    CHECK(fresnel_hemispherical_reflectance(1.0) == 0.0);
    // Large and small eta, where the pole of r_p lies ~1 / eta from the integral's start (its panels were graded at
    // the branch points alone: 4.0e-7 off at eta = 100, 5.1e-7 at 1000; found by review). mpmath (45 digits, panels
    // halving towards 0 and the critical cosine; its F_h(1 / eta) = 1 - (1 - F_h(eta)) / eta^2 holds to all digits).
    const Ref far[] = {{100, 0.95016117123965143026},  {1000, 0.99471993932760363262}, {1e4, 0.99946738350455645616},
                       {50, 0.9051332082687063526},    {0.01, 0.99999501611712396514}, {0.05, 0.99947367125919121722}};
    for (const Ref& r : far) {
        INFO("eta " << r.eta);
        CHECK(std::fabs(fresnel_hemispherical_reflectance(r.eta) - r.value) <= 4e-16);
    }
}

TEST_CASE("internal diffuse reflectance is the hemispherical average seen from inside") {
    for (double eta : {1.1, 1.3, 1.4, 2.5}) CHECK(fresnel_diffuse_reflectance(eta) == fresnel_hemispherical_reflectance(1 / eta));
    // Beyond the critical angle everything is reflected: F_dr >= 1 - 1/eta^2.
    for (double eta : {1.01, 1.3, 3.0}) CHECK(fresnel_diffuse_reflectance(eta) > 1 - 1 / (eta * eta));
}

TEST_CASE("F_dr is continuous through eta = 1") {
    CHECK(fresnel_diffuse_reflectance(1.0 + 1e-9) < 1e-8);
    CHECK(fresnel_diffuse_reflectance(1.0 - 1e-9) < 1e-8);
}

TEST_CASE("the Egan-Hilgeman fit is within its stated error for eta in [1, 2] and [1, 3]") {
    // The bounds are the ones stated in fresnel.hpp (measured on a 2000-point grid).
    auto worst_on = [](double hi) {
        double worst = 0;
        for (int i = 0; i <= 400; ++i) {
            const double eta = 1 + (hi - 1) * i / 400;
            worst = std::fmax(worst, std::fabs(fresnel_diffuse_reflectance_fit(eta) - fresnel_diffuse_reflectance(eta)));
        }
        return worst;
    };
    CHECK(worst_on(2.0) <= 0.00161);
    CHECK(worst_on(3.0) <= 0.0159);
    CHECK(std::fabs(fresnel_diffuse_reflectance_fit(1.3) - 0.444763) < 1e-6);  // docs/physics.md section 8
}

TEST_CASE("bad eta is rejected with a message naming it") {
    CHECK_THROWS_AS(fresnel_hemispherical_reflectance(0.0), std::invalid_argument);
    CHECK_THROWS_AS(fresnel_diffuse_reflectance(std::nan("")), std::invalid_argument);
    CHECK_THROWS_WITH(fresnel_diffuse_reflectance(-1.0), doctest::Contains("eta = -1"));
}

TEST_CASE("light from the other side (cos_i < 0) keeps full relative accuracy as eta -> 1 (found by review)") {
    // F seen from the t side at cosine c equals F seen from the i side at the cosine c_i that Snell's law pairs with
    // it (sin_i = eta sin_t), which the positive branch computes to full relative accuracy. The negative branch took
    // the index ratio as the rounded 1 / eta: 2.2e-4 off at eta = 1 - 1e-12, 23% at 1 - 1e-15.
    for (const double eta : {1 - 1e-9, 1 - 1e-12, 1 - 1e-15, 1 + 1e-12})
        for (const double c : {0.74, 0.5, 0.1}) {
            const long double s2 = (1 - static_cast<long double>(c) * c) * eta * eta;
            const double ci = static_cast<double>(std::sqrt(1 - s2));
            const double from_t = stratum::fresnel_dielectric(-c, eta), from_i = stratum::fresnel_dielectric(ci, eta);
            INFO("eta " << eta << ", c " << c);
            CHECK(std::fabs(from_t - from_i) <= 1e-14 * from_i);
        }
}
