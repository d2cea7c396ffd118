// Benchmarks of the bare-slab solver: the eigen-solution alone, a whole mode (eigen + boundary system),
// and one adding step. Stam's skin slab: Omega = 0.9, g = 0.8, transparency 0.5 (tau = ln 2); mode k = 0,
// Henyey-Greenstein series cut at degree 2M - 1. Argument: M, the number of half-range ordinates.
#include <benchmark/benchmark.h>

#include <stratum/adding.hpp>
#include <stratum/slab.hpp>

#include <cmath>
#include <vector>

namespace {

struct Setup {
    stratum::Quadrature<double> q;
    std::vector<double> same, opposite;
    explicit Setup(int m) : q(stratum::gauss_legendre_half<double>(m)) {
        const std::size_t size = q.size();
        const int nmax = 2 * m - 1;
        same.assign(size * size, 0.0);
        opposite.assign(size * size, 0.0);
        std::vector<std::vector<double>> p(size, std::vector<double>(static_cast<std::size_t>(nmax + 1)));
        for (std::size_t i = 0; i < size; ++i) {  // Legendre polynomials at the ordinates
            const double x = q.nodes[i];
            p[i][0] = 1;
            p[i][1] = x;
            for (int l = 2; l <= nmax; ++l) {
                const auto ul = static_cast<std::size_t>(l);
                p[i][ul] = ((2.0 * l - 1) * x * p[i][ul - 1] - (l - 1.0) * p[i][ul - 2]) / l;
            }
        }
        for (std::size_t n = 0; n < size; ++n)
            for (std::size_t j = 0; j < size; ++j)
                for (int l = 0; l <= nmax; ++l) {
                    const auto ul = static_cast<std::size_t>(l);
                    const double term = (2.0 * l + 1) * std::pow(0.8, l) * p[n][ul] * p[j][ul];
                    same[n * size + j] += term;
                    opposite[n * size + j] += l % 2 == 0 ? term : -term;
                }
    }
};

void BM_slab_eigen(benchmark::State& state) {
    const Setup s(static_cast<int>(state.range(0)));
    for (auto _ : state) {
        auto es = stratum::detail::slab_eigensystem(0.1, s.q.nodes, s.q.weights, s.same.data(), s.opposite.data(), 0);
        benchmark::DoNotOptimize(es.lambda.data());
    }
}
BENCHMARK(BM_slab_eigen)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Arg(64)->Unit(benchmark::kMicrosecond);

void BM_slab_mode(benchmark::State& state) {
    const Setup s(static_cast<int>(state.range(0)));
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    for (auto _ : state) {
        auto ops = stratum::solve_slab_mode(slab, s.q, s.same, s.opposite, 0);
        benchmark::DoNotOptimize(ops.reflection.data());
    }
}
BENCHMARK(BM_slab_mode)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Arg(64)->Unit(benchmark::kMicrosecond);

void BM_slab_mode_semi_infinite(benchmark::State& state) {
    const Setup s(static_cast<int>(state.range(0)));
    const stratum::Slab<double> slab(0.9, 0.8, std::numeric_limits<double>::infinity());
    for (auto _ : state) {
        auto ops = stratum::solve_slab_mode(slab, s.q, s.same, s.opposite, 0);
        benchmark::DoNotOptimize(ops.reflection.data());
    }
}
BENCHMARK(BM_slab_mode_semi_infinite)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Arg(64)->Unit(benchmark::kMicrosecond);

void BM_adding_add(benchmark::State& state) {
    const Setup s(static_cast<int>(state.range(0)));
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    const auto c = stratum::slab_component(stratum::solve_slab_mode(slab, s.q, s.same, s.opposite, 0));
    for (auto _ : state) {
        auto sum = stratum::add_components(c, c);
        benchmark::DoNotOptimize(sum.reflection_down.data());
    }
}
BENCHMARK(BM_adding_add)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Arg(64)->Unit(benchmark::kMicrosecond);

// The dense kernels under every mode: C = A B and A X = B with M right-hand sides (LU factors prepared), n x n.
stratum::detail::Matrix<double> random_matrix(std::size_t n, unsigned seed) {
    stratum::detail::Matrix<double> a(n, n);
    for (std::size_t i = 0; i < n * n; ++i) a.data[i] = std::sin(1.0 + seed + 0.7 * static_cast<double>(i));
    for (std::size_t i = 0; i < n; ++i) a(i, i) += static_cast<double>(n);
    return a;
}

void BM_multiply(benchmark::State& state) {
    const auto n = static_cast<std::size_t>(state.range(0));
    const auto a = random_matrix(n, 1), b = random_matrix(n, 2);
    for (auto _ : state) benchmark::DoNotOptimize(stratum::detail::multiply(a, b).data.data());
}
BENCHMARK(BM_multiply)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Arg(64);

void BM_lu_solve(benchmark::State& state) {
    const auto n = static_cast<std::size_t>(state.range(0));
    const auto lu = stratum::detail::lu_factor(random_matrix(n, 1));
    const auto b = random_matrix(n, 2);
    for (auto _ : state) {
        auto x = b;
        stratum::detail::lu_solve(lu, x);
        benchmark::DoNotOptimize(x.data.data());
    }
}
BENCHMARK(BM_lu_solve)->Arg(8)->Arg(16)->Arg(24)->Arg(32)->Arg(64);

}  // namespace
