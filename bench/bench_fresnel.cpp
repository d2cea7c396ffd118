// Fresnel reflectance: per-call cost of the exact unpolarized formula, and of the (construction-time)
// diffuse reflectance F_dr. Inputs cycle through a precomputed table so the compiler cannot hoist the call.
#include <benchmark/benchmark.h>

#include <stratum/fresnel.hpp>

#include <cstddef>
#include <vector>

namespace {

template <class Real>
std::vector<Real> cosines(std::size_t n) {
    std::vector<Real> c(n);
    for (std::size_t i = 0; i < n; ++i) c[i] = static_cast<Real>((static_cast<double>(i) + 0.5) / static_cast<double>(n));
    return c;
}

template <class Real>
void BM_fresnel_dielectric(benchmark::State& state) {
    const std::vector<Real> c = cosines<Real>(1024);
    const Real eta = static_cast<Real>(state.range(0)) / Real(100);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(stratum::fresnel_dielectric(c[i], eta));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_fresnel_dielectric, float)->Arg(140)->Arg(71);
BENCHMARK_TEMPLATE(BM_fresnel_dielectric, double)->Arg(140)->Arg(71);

void BM_fresnel_diffuse_reflectance(benchmark::State& state) {
    double eta = 1.3;
    for (auto _ : state) {
        benchmark::DoNotOptimize(stratum::fresnel_diffuse_reflectance(eta));
        eta = eta == 1.3 ? 1.4 : 1.3;
    }
}
BENCHMARK(BM_fresnel_diffuse_reflectance);

}  // namespace
