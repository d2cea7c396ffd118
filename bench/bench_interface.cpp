// Rough dielectric interface (eta 1 / 1.4): per-call cost of brdf, btdf, eval (float, double), sample, and
// of the (not hot-path) hemispherical albedo. Directions cycle through a precomputed table of 1024 random
// pairs (fixed seed) so the compiler cannot hoist the call; the argument is sigma in thousandths.
#include <benchmark/benchmark.h>

#include <stratum/interface.hpp>

#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

namespace {

template <class Real>
struct Pairs {
    std::vector<stratum::Vec3<Real>> wi, wo;
};

// kind: 0 = same hemisphere (reflection), 1 = opposite (transmission; wo drawn from the refraction lobe
// with sample(), so that most pairs are valid refractions rather than early exits), 2 = either.
template <class Real>
Pairs<Real> make_pairs(int kind, const stratum::RoughDielectric<Real>& rd) {
    std::mt19937_64 rng(12345);
    auto u = [&] { return static_cast<double>(rng() >> 11) * 0x1p-53; };
    auto direction = [&] {
        const double z = 2 * u() - 1, phi = 6.283185307179586 * u(), s = std::sqrt(1 - z * z);
        return stratum::Vec3<Real>{static_cast<Real>(s * std::cos(phi)), static_cast<Real>(s * std::sin(phi)), static_cast<Real>(z)};
    };
    Pairs<Real> p;
    for (int i = 0; i < 1024; ++i) {
        auto a = direction(), b = direction();
        if (kind == 0 && a.z * b.z < 0) b.z = -b.z;
        if (kind == 1) {
            const auto smp = rd.sample(a, Real(0.99999), static_cast<Real>(u()), static_cast<Real>(u()));
            if (smp.valid() && !smp.reflected) b = smp.wo;
            if (a.z * b.z > 0) b.z = -b.z;
        }
        p.wi.push_back(a);
        p.wo.push_back(b);
    }
    return p;
}

template <class Real>
stratum::RoughDielectric<Real> make_interface(const benchmark::State& state) {
    return stratum::RoughDielectric<Real>(static_cast<Real>(state.range(0)) / Real(1000), Real(1), Real(1.4));
}

template <class Real>
void BM_interface_brdf(benchmark::State& state) {
    const auto rd = make_interface<Real>(state);
    const auto p = make_pairs<Real>(0, rd);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(rd.brdf(p.wi[i], p.wo[i]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_interface_brdf, float)->Arg(300);
BENCHMARK_TEMPLATE(BM_interface_brdf, double)->Arg(300);

template <class Real>
void BM_interface_btdf(benchmark::State& state) {
    const auto rd = make_interface<Real>(state);
    const auto p = make_pairs<Real>(1, rd);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(rd.btdf(p.wi[i], p.wo[i]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_interface_btdf, float)->Arg(300);
BENCHMARK_TEMPLATE(BM_interface_btdf, double)->Arg(300);

template <class Real>
void BM_interface_eval(benchmark::State& state) {
    const auto rd = make_interface<Real>(state);
    const auto p = make_pairs<Real>(2, rd);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(rd.eval(p.wi[i], p.wo[i]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_interface_eval, float)->Arg(300);
BENCHMARK_TEMPLATE(BM_interface_eval, double)->Arg(20)->Arg(300)->Arg(1000);

template <class Real>
void BM_interface_sample(benchmark::State& state) {
    const auto rd = make_interface<Real>(state);
    const auto p = make_pairs<Real>(2, rd);
    std::size_t i = 0;
    Real u = Real(0.1234);
    for (auto _ : state) {
        u = u + Real(0.6180339887);
        u -= std::floor(u);
        benchmark::DoNotOptimize(rd.sample(p.wi[i], u, p.wo[i].x * Real(0.5) + Real(0.5), p.wo[i].y * Real(0.5) + Real(0.5)));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_interface_sample, float)->Arg(300);
BENCHMARK_TEMPLATE(BM_interface_sample, double)->Arg(300);

void BM_interface_hemispherical_totals(benchmark::State& state) {
    const auto rd = make_interface<double>(state);
    double mu = 0.3;
    for (auto _ : state) {
        benchmark::DoNotOptimize(rd.hemispherical_totals(mu));
        mu = mu == 0.3 ? 0.8 : 0.3;
    }
}
BENCHMARK(BM_interface_hemispherical_totals)->Arg(20)->Arg(300)->Arg(1000)->Unit(benchmark::kMillisecond);

}  // namespace
