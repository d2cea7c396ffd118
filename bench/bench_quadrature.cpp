// Gauss-Legendre rule generation: full-range and half-range rules per n, and the two methods behind them
// (Newton on the recurrence, O(n^2); Bogaert's asymptotic formulas, O(n)) side by side for the crossover.
#include <benchmark/benchmark.h>

#include <stratum/quadrature.hpp>

namespace {

template <class Real>
void BM_quadrature_gauss_legendre(benchmark::State& state) {
    const int n = static_cast<int>(state.range(0));
    for (auto _ : state) {
        auto q = stratum::gauss_legendre<Real>(n);
        benchmark::DoNotOptimize(q.nodes.data());
        benchmark::DoNotOptimize(q.weights.data());
    }
    state.SetItemsProcessed(state.iterations() * n);  // items/s = nodes per second
}

template <class Real>
void BM_quadrature_gauss_legendre_half(benchmark::State& state) {
    const int n = static_cast<int>(state.range(0));
    for (auto _ : state) {
        auto q = stratum::gauss_legendre_half<Real>(n);
        benchmark::DoNotOptimize(q.nodes.data());
        benchmark::DoNotOptimize(q.weights.data());
    }
    state.SetItemsProcessed(state.iterations() * n);
}

// One rule's worth of nodes (the non-negative half) by each method, whatever n is: the crossover.
void BM_quadrature_newton_nodes(benchmark::State& state) {
    const int n = static_cast<int>(state.range(0)), half = (n + 1) / 2;
    for (auto _ : state) {
        for (int k = 1; k <= half; k += 2) {
            stratum::detail::GaussLegendreNode pair[2];
            stratum::detail::gauss_legendre_nodes_newton(n, k, k + 1 <= half ? k + 1 : k, pair);
            benchmark::DoNotOptimize(pair);
        }
    }
    state.SetItemsProcessed(state.iterations() * n);
}

void BM_quadrature_asymptotic_nodes(benchmark::State& state) {
    const int n = static_cast<int>(state.range(0));
    for (auto _ : state)
        for (int k = 1; k <= (n + 1) / 2; ++k)
            benchmark::DoNotOptimize(stratum::detail::gauss_legendre_node_asymptotic(n, k));
    state.SetItemsProcessed(state.iterations() * n);
}

}  // namespace

BENCHMARK_TEMPLATE(BM_quadrature_gauss_legendre, double)->Arg(8)->Arg(32)->Arg(128)->Arg(1024)->Arg(10000);
BENCHMARK_TEMPLATE(BM_quadrature_gauss_legendre_half, double)->Arg(8)->Arg(32)->Arg(128)->Arg(1024)->Arg(10000);
BENCHMARK_TEMPLATE(BM_quadrature_gauss_legendre, float)->Arg(32)->Arg(1024);
BENCHMARK_TEMPLATE(BM_quadrature_gauss_legendre_half, float)->Arg(32)->Arg(1024);
BENCHMARK(BM_quadrature_newton_nodes)->Arg(16)->Arg(64)->Arg(128)->Arg(200)->Arg(256);
BENCHMARK(BM_quadrature_asymptotic_nodes)->Arg(16)->Arg(64)->Arg(128)->Arg(200)->Arg(256);
