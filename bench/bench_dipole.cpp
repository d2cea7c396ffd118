// Dipole benchmarks: the radial profile, the total diffuse reflectance, the three inversion paths
// R_d -> alpha' (exact, tabulated, and the 16-step bisection some renderers ship, with its error as a
// counter), the radial sampler and Lambert W_{-1}. The argument is the number of evaluations per
// iteration (items_per_second is the throughput; time / arg is the cost of one call).
#include <benchmark/benchmark.h>

#include <stratum/dipole.hpp>
#include <stratum/lambert_w.hpp>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace {

/// The baseline: bisection on alpha' in [0, 1] for a fixed 16 steps, returning the midpoint.
double alpha_prime_bisection16(double Rd, const stratum::DipoleBoundary<double>& b) {
    double lo = 0, hi = 1;
    for (int i = 0; i < 16; ++i) {
        const double mid = (lo + hi) / 2;
        (stratum::total_diffuse_reflectance(mid, b) < Rd ? lo : hi) = mid;
    }
    return (lo + hi) / 2;
}

template <class Real>
std::vector<Real> uniform_inputs(std::size_t n, Real lo, Real hi, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::vector<Real> v(n);
    for (auto& x : v) x = lo + (hi - lo) * static_cast<Real>(static_cast<double>(rng() >> 11) * 0x1.0p-53);
    return v;
}

/// Largest |f(Rd) - exact(Rd)| over 1e5 uniform Rd in [0, 1] plus approaches to both ends.
template <class F>
double max_inversion_error(F f, const stratum::DipoleBoundary<double>& b) {
    double worst = 0;
    auto check = [&](double rd) {
        worst = std::fmax(worst, std::fabs(f(rd) - stratum::alpha_prime_from_reflectance(rd, b)));
    };
    for (int i = 0; i <= 100000; ++i) check(i / 100000.0);
    for (int e = 1; e <= 60; ++e) check(std::pow(10.0, -e / 4.0)), check(1 - std::pow(10.0, -e / 4.0));
    return worst;
}

template <class Real>
void BM_dipole_Rd(benchmark::State& state) {
    const stratum::Dipole<Real> skin(Real(0.032), Real(0.74), Real(1.3));  // Jensen skin1, red, 1/mm
    const auto r = uniform_inputs<Real>(static_cast<std::size_t>(state.range(0)), Real(0), Real(10), 1);
    for (auto _ : state)
        for (Real x : r) benchmark::DoNotOptimize(skin.Rd(x));
    state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK_TEMPLATE(BM_dipole_Rd, float)->Arg(1024);
BENCHMARK_TEMPLATE(BM_dipole_Rd, double)->Arg(1024);

void BM_dipole_total_diffuse_reflectance(benchmark::State& state) {
    const auto b = stratum::DipoleBoundary<double>::from_eta(1.3);
    const auto a = uniform_inputs<double>(static_cast<std::size_t>(state.range(0)), 0, 1, 2);
    for (auto _ : state)
        for (double x : a) benchmark::DoNotOptimize(stratum::total_diffuse_reflectance(x, b));
    state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_dipole_total_diffuse_reflectance)->Arg(1024);

void BM_dipole_alpha_prime_exact(benchmark::State& state) {
    const auto b = stratum::DipoleBoundary<double>::from_eta(1.3);
    const auto rd = uniform_inputs<double>(static_cast<std::size_t>(state.range(0)), 0, 1, 3);
    for (auto _ : state)
        for (double x : rd) benchmark::DoNotOptimize(stratum::alpha_prime_from_reflectance(x, b));
    state.SetItemsProcessed(state.iterations() * state.range(0));
    state.counters["max_abs_error"] = 0;  // the reference itself; its error against mpmath is ~2.7e-16 (tests)
}
BENCHMARK(BM_dipole_alpha_prime_exact)->Arg(1024);

template <int Size>
void BM_dipole_alpha_prime_table(benchmark::State& state) {
    const auto b = stratum::DipoleBoundary<double>::from_eta(1.3);
    const stratum::AlphaPrimeTable<double> table(b, Size);
    const auto rd = uniform_inputs<double>(static_cast<std::size_t>(state.range(0)), 0, 1, 3);
    for (auto _ : state)
        for (double x : rd) benchmark::DoNotOptimize(table(x));
    state.SetItemsProcessed(state.iterations() * state.range(0));
    state.counters["max_abs_error"] = max_inversion_error([&](double x) { return table(x); }, b);
}
BENCHMARK_TEMPLATE(BM_dipole_alpha_prime_table, 2001)->Arg(1024);
BENCHMARK_TEMPLATE(BM_dipole_alpha_prime_table, 129)->Arg(1024);

void BM_dipole_alpha_prime_table_float(benchmark::State& state) {
    const stratum::AlphaPrimeTable<float> table(1.3f);
    const auto rd = uniform_inputs<float>(static_cast<std::size_t>(state.range(0)), 0, 1, 3);
    for (auto _ : state)
        for (float x : rd) benchmark::DoNotOptimize(table(x));
    state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_dipole_alpha_prime_table_float)->Arg(1024);

void BM_dipole_alpha_prime_bisection16(benchmark::State& state) {
    const auto b = stratum::DipoleBoundary<double>::from_eta(1.3);
    const auto rd = uniform_inputs<double>(static_cast<std::size_t>(state.range(0)), 0, 1, 3);
    for (auto _ : state)
        for (double x : rd) benchmark::DoNotOptimize(alpha_prime_bisection16(x, b));
    state.SetItemsProcessed(state.iterations() * state.range(0));
    state.counters["max_abs_error"] = max_inversion_error([&](double x) { return alpha_prime_bisection16(x, b); }, b);
}
BENCHMARK(BM_dipole_alpha_prime_bisection16)->Arg(1024);

void BM_dipole_table_construction(benchmark::State& state) {
    for (auto _ : state)
        benchmark::DoNotOptimize(stratum::AlphaPrimeTable<double>(1.3, stratum::DiffuseFresnel::jensen_fit,
                                                                   static_cast<int>(state.range(0))));
}
BENCHMARK(BM_dipole_table_construction)->Arg(2001)->Unit(benchmark::kMicrosecond);

void BM_dipole_sample_radius(benchmark::State& state) {
    const stratum::Dipole<double> skin(0.032, 0.74, 1.3);
    const auto xi = uniform_inputs<double>(static_cast<std::size_t>(state.range(0)), 0, 1, 4);
    for (auto _ : state)
        for (double x : xi) benchmark::DoNotOptimize(skin.sample_radius(x));
    state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_dipole_sample_radius)->Arg(1024);

void BM_lambert_wm1(benchmark::State& state) {
    const auto u = uniform_inputs<double>(static_cast<std::size_t>(state.range(0)), 0, 1, 5);
    std::vector<double> x(u.size());
    for (std::size_t i = 0; i < u.size(); ++i) x[i] = -0.36787944117144233 * std::pow(10.0, -20 * u[i] * u[i]);
    for (auto _ : state)
        for (double v : x) benchmark::DoNotOptimize(stratum::lambert_wm1(v));
    state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_lambert_wm1)->Arg(1024);

}  // namespace
