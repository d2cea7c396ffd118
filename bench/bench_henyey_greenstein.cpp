// Henyey-Greenstein and Legendre functions: per-call cost of eval and sample (float, double), of the
// normalized associated Legendre recurrence, of one azimuthal Fourier coefficient, and of the
// Fourier-mode matrices the layer solver needs (M ordinates, 2M modes). Inputs cycle through
// precomputed tables so the compiler cannot hoist the call.
#include <benchmark/benchmark.h>

#include <stratum/henyey_greenstein.hpp>
#include <stratum/legendre.hpp>
#include <stratum/quadrature.hpp>

#include <cstddef>
#include <vector>

namespace {

template <class Real>
std::vector<Real> grid(std::size_t n, double lo, double hi) {
    std::vector<Real> v(n);
    for (std::size_t i = 0; i < n; ++i)
        v[i] = static_cast<Real>(lo + (hi - lo) * (static_cast<double>(i) + 0.5) / static_cast<double>(n));
    return v;
}

// g = range(0) / 100.
template <class Real>
void BM_hg_eval(benchmark::State& state) {
    const stratum::HenyeyGreenstein<Real> hg(static_cast<Real>(state.range(0)) / Real(100));
    const std::vector<Real> c = grid<Real>(1024, -1, 1);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(hg.eval(c[i]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_hg_eval, float)->Arg(90);
BENCHMARK_TEMPLATE(BM_hg_eval, double)->Arg(90);

// Cosine, direction around +z and pdf from (u1, u2).
template <class Real>
void BM_hg_sample(benchmark::State& state) {
    const stratum::HenyeyGreenstein<Real> hg(static_cast<Real>(state.range(0)) / Real(100));
    const std::vector<Real> u1 = grid<Real>(1024, 0, 1), u2 = grid<Real>(1021, 0, 1);
    std::size_t i = 0, j = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(hg.sample(u1[i], u2[j]));
        i = (i + 1) & 1023;
        j = j == 1020 ? 0 : j + 1;
    }
}
BENCHMARK_TEMPLATE(BM_hg_sample, float)->Arg(90);
BENCHMARK_TEMPLATE(BM_hg_sample, double)->Arg(90);

// The same, rotated into the frame of an arbitrary unit axis.
void BM_hg_sample_around_axis(benchmark::State& state) {
    const stratum::HenyeyGreenstein<double> hg(0.9);
    const std::vector<double> u1 = grid<double>(1024, 0, 1), u2 = grid<double>(1021, 0, 1);
    const stratum::Vec3<double> axis = stratum::normalize(stratum::Vec3<double>{0.3, -0.5, 0.8});
    std::size_t i = 0, j = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(hg.sample(axis, u1[i], u2[j]));
        i = (i + 1) & 1023;
        j = j == 1020 ? 0 : j + 1;
    }
}
BENCHMARK(BM_hg_sample_around_axis);

// Lambda_l^k(x) for all l <= L at one k: range(0) = L, range(1) = k. Items = L + 1 values.
void BM_legendre_lambda_all(benchmark::State& state) {
    const int L = static_cast<int>(state.range(0)), k = static_cast<int>(state.range(1));
    const std::vector<double> x = grid<double>(64, -1, 1);
    std::vector<double> out(static_cast<std::size_t>(L) + 1);
    std::size_t i = 0;
    for (auto _ : state) {
        stratum::legendre_lambda_all(k, L, x[i], out.data());
        benchmark::DoNotOptimize(out.data());
        i = (i + 1) & 63;
    }
    state.SetItemsProcessed(state.iterations() * (L + 1));
}
BENCHMARK(BM_legendre_lambda_all)->Args({100, 0})->Args({2000, 0})->Args({2000, 200});

// One coefficient p_k(mu', mu) from N + 1 = range(0) moments (g = 0.9), k = 3.
void BM_hg_fourier_coefficient(benchmark::State& state) {
    const auto chi = stratum::HenyeyGreenstein<double>(0.9).legendre_moments(static_cast<int>(state.range(0)));
    const std::vector<double> mu = grid<double>(64, -1, 1);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(stratum::phase_fourier_coefficient(chi, mu[i], mu[63 - i], 3));
        i = (i + 1) & 63;
    }
}
BENCHMARK(BM_hg_fourier_coefficient)->Arg(32)->Arg(263);

// All K = 2M mode matrices (same and opposite) on M half-range Gauss ordinates: range(0) = M.
// Moments: 2M of them (N = 2M - 1, the delta-M truncation a 2M-stream solver uses) for
// BM_hg_fourier_matrices; 263 (g = 0.9 to 1e-12, no delta-M) for BM_hg_fourier_matrices_full_series.
void fourier_matrices(benchmark::State& state, int moments) {
    const int M = static_cast<int>(state.range(0));
    const auto mu = stratum::gauss_legendre_half<double>(M).nodes;
    const auto chi = stratum::HenyeyGreenstein<double>(0.9).legendre_moments(moments);
    for (auto _ : state) benchmark::DoNotOptimize(stratum::phase_fourier_matrices(chi, mu, 2 * M));
}
void BM_hg_fourier_matrices(benchmark::State& state) { fourier_matrices(state, 2 * static_cast<int>(state.range(0))); }
void BM_hg_fourier_matrices_full_series(benchmark::State& state) { fourier_matrices(state, 263); }
BENCHMARK(BM_hg_fourier_matrices)->Arg(8)->Arg(24)->Arg(64)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_hg_fourier_matrices_full_series)->Arg(8)->Arg(24)->Arg(64)->Unit(benchmark::kMicrosecond);

// Route comparison at g = range(0) / 1000 (0.9, 0.99, 0.999), untruncated HG to ~1e-16:
// the Legendre series with N = legendre_terms_for_tolerance(1e-17) terms (263 -> 39100) against the
// closed form (elliptic integrals + recurrence in k). Per pair: all 48 modes p_k(0.3, 0.7).
void BM_hg_fourier_pair_series(benchmark::State& state) {
    const stratum::HenyeyGreenstein<double> hg(static_cast<double>(state.range(0)) / 1000);
    const auto chi = hg.legendre_moments(hg.legendre_terms_for_tolerance(1e-17) + 1);
    for (auto _ : state)
        for (int k = 0; k < 48; ++k) benchmark::DoNotOptimize(stratum::phase_fourier_coefficient(chi, 0.3, 0.7, k));
}
void BM_hg_fourier_pair_closed_form(benchmark::State& state) {
    const stratum::HenyeyGreenstein<double> hg(static_cast<double>(state.range(0)) / 1000);
    double out[48];
    for (auto _ : state) {
        hg.fourier_coefficients(0.3, 0.7, 48, out);
        benchmark::DoNotOptimize(out);
    }
}
BENCHMARK(BM_hg_fourier_pair_series)->Arg(900)->Arg(990)->Arg(999)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_hg_fourier_pair_closed_form)->Arg(900)->Arg(990)->Arg(999)->Unit(benchmark::kMicrosecond);

// Matrices for M = 24 ordinates, 48 modes, by both routes at g = range(0) / 1000.
void BM_hg_fourier_matrices_series_g(benchmark::State& state) {
    const stratum::HenyeyGreenstein<double> hg(static_cast<double>(state.range(0)) / 1000);
    const auto chi = hg.legendre_moments(hg.legendre_terms_for_tolerance(1e-17) + 1);
    const auto mu = stratum::gauss_legendre_half<double>(24).nodes;
    for (auto _ : state) benchmark::DoNotOptimize(stratum::phase_fourier_matrices(chi, mu, 48));
}
void BM_hg_fourier_matrices_closed_form_g(benchmark::State& state) {
    const stratum::HenyeyGreenstein<double> hg(static_cast<double>(state.range(0)) / 1000);
    const auto mu = stratum::gauss_legendre_half<double>(24).nodes;
    for (auto _ : state) benchmark::DoNotOptimize(stratum::phase_fourier_matrices(hg, mu, 48));
}
BENCHMARK(BM_hg_fourier_matrices_series_g)->Arg(900)->Arg(990)->Arg(999)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_hg_fourier_matrices_closed_form_g)->Arg(900)->Arg(990)->Arg(999)->Unit(benchmark::kMillisecond);

// The closed-form matrices for M in {8, 24, 64} with 2M modes (g = 0.9), beside BM_hg_fourier_matrices.
void BM_hg_fourier_matrices_closed_form(benchmark::State& state) {
    const int M = static_cast<int>(state.range(0));
    const stratum::HenyeyGreenstein<double> hg(0.9);
    const auto mu = stratum::gauss_legendre_half<double>(M).nodes;
    for (auto _ : state) benchmark::DoNotOptimize(stratum::phase_fourier_matrices(hg, mu, 2 * M));
}
BENCHMARK(BM_hg_fourier_matrices_closed_form)->Arg(8)->Arg(24)->Arg(64)->Unit(benchmark::kMicrosecond);

}  // namespace
