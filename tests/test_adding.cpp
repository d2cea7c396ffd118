// The adding equations (adding.hpp). References: the direct slab solution of the combined thickness (the
// discrete-ordinate equations are exact in depth, so stacking sub-slabs is exact up to rounding), scalar
// closed forms (M = 1: the geometric series of inter-reflections), associativity, energy conservation.
#include <doctest/doctest.h>

#include <stratum/adding.hpp>
#include <stratum/slab.hpp>  // slabs as components

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "reference/reference_phase.hpp"

using stratum::add_components;
using stratum::ComponentOperators;
using stratum::Quadrature;
using stratum::Slab;

namespace {

const double inf = std::numeric_limits<double>::infinity();

ComponentOperators<double> slab(double albedo, double g, double tau, const Quadrature<double>& q, int k) {
    const stratum_test::Phase p = stratum_test::henyey_greenstein(g, q.nodes, k, 2 * static_cast<int>(q.size()) - 1);
    return stratum::slab_component(stratum::solve_slab_mode(Slab<double>(albedo, g, tau), q, p.same, p.opposite, k));
}

double max_diff(const std::vector<double>& a, const std::vector<double>& b) {
    double d = 0;
    for (std::size_t i = 0; i < a.size(); ++i) d = std::fmax(d, std::fabs(a[i] - b[i]));
    return d;
}

double max_diff(const ComponentOperators<double>& a, const ComponentOperators<double>& b) {
    return std::fmax(std::fmax(max_diff(a.reflection_down, b.reflection_down), max_diff(a.transmission_down, b.transmission_down)),
                     std::fmax(max_diff(a.reflection_up, b.reflection_up), max_diff(a.transmission_up, b.transmission_up)));
}

struct Random {
    std::mt19937_64 engine;
    explicit Random(std::uint64_t seed) : engine(seed) {}
    double operator()() { return static_cast<double>(engine() >> 11) * 0x1.0p-53; }  // [0, 1)
};

// A lossy, non-symmetric component with positive entries (not a slab: tests the general algebra).
ComponentOperators<double> random_component(std::size_t m, Random& rng) {
    ComponentOperators<double> c;
    c.size = m;
    for (auto* v : {&c.reflection_down, &c.transmission_down, &c.reflection_up, &c.transmission_up}) {
        v->resize(m * m);
        for (double& x : *v) x = 0.4 * rng() / static_cast<double>(m);
    }
    return c;
}

}  // namespace

TEST_CASE("a slab of tau1 over a slab of tau2 equals one slab of tau1 + tau2 (to 1e-10), every mode") {
    const Quadrature<double> q = stratum::gauss_legendre_half<double>(16);
    struct Pair { double tau1, tau2; };
    double worst = 0;
    for (const Pair& p : {Pair{0.5, 1.5}, Pair{1e-3, 2.0}, Pair{3.0, 7.0}, Pair{2.0, inf}}) {
        for (double albedo : {0.9, 1.0}) {
            for (int k : {0, 1, 3}) {
                const auto top = slab(albedo, 0.8, p.tau1, q, k), bottom = slab(albedo, 0.8, p.tau2, q, k);
                const auto direct = slab(albedo, 0.8, p.tau1 + p.tau2, q, k);
                const double d = max_diff(add_components(top, bottom), direct);
                // The discrete-ordinate equations are exact in depth: only rounding separates the two
                // (measured 1.2e-15).
                CHECK(d <= 1e-10);
                worst = std::fmax(worst, d);
            }
        }
    }
    MESSAGE("adding vs direct: max difference " << worst);
}

TEST_CASE("doubling 2^n thin slabs reproduces the thick slab") {
    const Quadrature<double> q = stratum::gauss_legendre_half<double>(12);
    const auto thin = slab(0.95, 0.6, 1.0 / 64, q, 0);
    const auto thick = slab(0.95, 0.6, 4.0, q, 0);
    CHECK(max_diff(stratum::double_component(thin, 8), thick) <= 1e-10);
    CHECK(max_diff(stratum::double_component(thick, 0), thick) == 0.0);
}

TEST_CASE("an empty slab (tau = 0) is the identity of adding, on either side") {
    const Quadrature<double> q = stratum::gauss_legendre_half<double>(8);
    const auto empty = slab(0.9, 0.5, 0.0, q, 0), s = slab(0.9, 0.5, 1.3, q, 0);
    CHECK(max_diff(add_components(empty, s), s) <= 1e-15);
    CHECK(max_diff(add_components(s, empty), s) <= 1e-15);
}

TEST_CASE("scalar components (M = 1) follow the geometric series of inter-reflections") {
    ComponentOperators<double> a, b;
    a.size = b.size = 1;
    a.reflection_down = {0.3}, a.transmission_down = {0.5}, a.reflection_up = {0.2}, a.transmission_up = {0.6};
    b.reflection_down = {0.4}, b.transmission_down = {0.35}, b.reflection_up = {0.1}, b.transmission_up = {0.45};
    const auto c = add_components(a, b);
    const double loop = 1 / (1 - 0.2 * 0.4);  // sum of (R1u R2d)^n
    CHECK(c.reflection_down[0] == doctest::Approx(0.3 + 0.6 * 0.4 * loop * 0.5).epsilon(1e-15));
    CHECK(c.transmission_down[0] == doctest::Approx(0.35 * loop * 0.5).epsilon(1e-15));
    CHECK(c.reflection_up[0] == doctest::Approx(0.1 + 0.35 * 0.2 * loop * 0.45).epsilon(1e-15));
    CHECK(c.transmission_up[0] == doctest::Approx(0.6 * loop * 0.45).epsilon(1e-15));
}

TEST_CASE("adding is associative for general (non-symmetric) components") {
    Random rng(42);
    const std::size_t m = 10;
    const auto a = random_component(m, rng), b = random_component(m, rng), c = random_component(m, rng);
    const auto left = add_components(add_components(a, b), c), right = add_components(a, add_components(b, c));
    CHECK(max_diff(left, right) <= 1e-14);
}

TEST_CASE("stacking non-absorbing slabs conserves energy") {
    const Quadrature<double> q = stratum::gauss_legendre_half<double>(16);
    const auto stack = add_components(slab(1.0, 0.8, 0.7, q, 0), slab(1.0, 0.0, 2.5, q, 0));
    for (std::size_t m = 0; m < q.size(); ++m)
        for (bool down : {true, false}) {
            const auto& r = down ? stack.reflection_down : stack.reflection_up;
            const auto& t = down ? stack.transmission_down : stack.transmission_up;
            double sum = 0;
            for (std::size_t n = 0; n < q.size(); ++n)
                sum += q.weights[n] * q.nodes[n] * (r[n * q.size() + m] + t[n * q.size() + m]);
            CHECK(std::fabs(sum / (q.weights[m] * q.nodes[m]) - 1) <= 1e-12);
        }
}

TEST_CASE("components of different sizes are rejected") {
    ComponentOperators<double> a, b;
    a.size = 1;
    b.size = 2;
    a.reflection_down = a.transmission_down = a.reflection_up = a.transmission_up = {0.1};
    b.reflection_down = b.transmission_down = b.reflection_up = b.transmission_up = {0.1, 0, 0, 0.1};
    CHECK_THROWS_AS(add_components(a, b), std::invalid_argument);
}
