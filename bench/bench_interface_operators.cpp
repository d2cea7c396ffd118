// Fourier-mode interface operators: construction cost of all four operators (R12, T12, R21, T21) of a rough
// dielectric interface on M half-range ordinates with K = 2M modes, and the cost of one call to the
// coefficient function at arbitrary angles (K = 48).
#include <benchmark/benchmark.h>

#include <stratum/interface_operators.hpp>

namespace {

// Argument: M (ordinates); K = 2M. sigma = 0.3, air over n = 1.4 (skin), default phi rule.
void BM_interface_operators_build(benchmark::State& state) {
    const int m = static_cast<int>(state.range(0));
    const stratum::RoughDielectric<double> interface(0.3, 1.0, 1.4);
    const stratum::Quadrature<double> ordinates = stratum::gauss_legendre_half<double>(m);
    for (auto _ : state) {
        stratum::InterfaceOperators<double> ops(interface, ordinates, 2 * m);
        benchmark::DoNotOptimize(ops.T12().data.data());
    }
}
BENCHMARK(BM_interface_operators_build)->Arg(8)->Arg(24)->Arg(64)->Unit(benchmark::kMillisecond);

// The narrow lobe sigma = 0.02 at M = 24, K = 48 (the graded phi panels add samples near phi = 0).
void BM_interface_operators_build_narrow(benchmark::State& state) {
    const int m = static_cast<int>(state.range(0));
    const stratum::RoughDielectric<double> interface(0.02, 1.0, 1.4);
    const stratum::Quadrature<double> ordinates = stratum::gauss_legendre_half<double>(m);
    for (auto _ : state) {
        stratum::InterfaceOperators<double> ops(interface, ordinates, 2 * m);
        benchmark::DoNotOptimize(ops.T12().data.data());
    }
}
BENCHMARK(BM_interface_operators_build_narrow)->Arg(24)->Unit(benchmark::kMillisecond);

// One set of K = 48 transmission coefficients at a true (non-ordinate) angle pair.
void BM_interface_operators_coefficients(benchmark::State& state) {
    const stratum::RoughDielectric<double> interface(0.3, 1.0, 1.4);
    const stratum::InterfaceOperators<double> ops(interface, stratum::gauss_legendre_half<double>(2), 48);
    double out[48];
    double mu = 0.3;
    for (auto _ : state) {
        ops.t12_coefficients(mu, 0.8, out);
        benchmark::DoNotOptimize(out);
        mu = mu == 0.3 ? 0.7 : 0.3;
    }
}
BENCHMARK(BM_interface_operators_coefficients)->Unit(benchmark::kMicrosecond);

// The smooth (specular) interface: exact diagonal reflection and interpolated Snell transmission.
void BM_interface_operators_build_smooth(benchmark::State& state) {
    const int m = static_cast<int>(state.range(0));
    const stratum::SmoothDielectric<double> interface(1.0, 1.4);
    const stratum::Quadrature<double> ordinates = stratum::gauss_legendre_half<double>(m);
    for (auto _ : state) {
        stratum::InterfaceOperators<double> ops(interface, ordinates, 2 * m);
        benchmark::DoNotOptimize(ops.T12().data.data());
    }
}
BENCHMARK(BM_interface_operators_build_smooth)->Arg(24)->Unit(benchmark::kMillisecond);

}  // namespace
