// TabulatedBSDF on Stam's skin layer (n 1 | 1.4 | 1, sigma 0.3 both sides, albedo 0.9, g 0.8, e^-tau 0.5, 16
// ordinates): the table's construction against its tolerance, and eval, pdf and sample per call (double and
// float) beside the direct LayeredSurface evaluation and the top interface alone (RoughDielectric).
#include <benchmark/benchmark.h>

#include <stratum/tabulated_bsdf.hpp>

#include <cmath>
#include <random>
#include <vector>

namespace {

const stratum::LayeredSurface<double>& skin() {
    static const stratum::LayeredSurface<double> layer = [] {
        stratum::LayerOptions options;
        options.ordinates = 16;
        return stratum::solve_layer(stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5),
                                    stratum::RoughDielectric<double>(0.3, 1.0, 1.4),
                                    stratum::RoughDielectric<double>(0.3, 1.4, 1.0), options);
    }();
    return layer;
}

// 1024 pairs of directions (wi above; wo above and below alternately) and uniforms, fixed.
template <class Real>
struct Inputs {
    std::vector<stratum::Vec3<Real>> wi, wo;
    std::vector<Real> u;
    Inputs() {
        std::mt19937_64 rng(1);
        std::uniform_real_distribution<double> uniform(0, 1);
        for (int i = 0; i < 1024; ++i) {
            const auto a = stratum::spherical_direction(uniform(rng), 6.283185307179586 * uniform(rng));
            auto b = stratum::spherical_direction(uniform(rng), 6.283185307179586 * uniform(rng));
            if (i % 2) b.z = -b.z;
            wi.push_back({Real(a.x), Real(a.y), Real(a.z)});
            wo.push_back({Real(b.x), Real(b.y), Real(b.z)});
            for (int k = 0; k < 3; ++k) u.push_back(Real(uniform(rng)));
        }
    }
};

template <class Real>
const stratum::TabulatedBSDF<Real>& table(double tolerance) {
    static const stratum::TabulatedBSDF<Real> t3(skin(), Real(1e-3)), t2(skin(), Real(1e-2));
    return tolerance < 5e-3 ? t3 : t2;
}

// The same layer solved with its faces tabulated (LayerRequest::tabulate_faces).
const stratum::LayeredSurface<double>& skin_tabulated_faces() {
    static const stratum::LayeredSurface<double> layer = [] {
        stratum::LayerOptions options;
        options.ordinates = 16;
        stratum::LayerRequest<double> request;
        request.tabulate_faces = true;
        return stratum::solve_layer(stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5),
                                    stratum::RoughDielectric<double>(0.3, 1.0, 1.4),
                                    stratum::RoughDielectric<double>(0.3, 1.4, 1.0), options, request);
    }();
    return layer;
}

// Building the table from the solved layer, at tolerance 10^-range(0); range(1) = 1: from the layer solved with
// its faces tabulated (the same table).
void BM_tabulated_build(benchmark::State& state) {
    const double tolerance = std::pow(10.0, -static_cast<double>(state.range(0)));
    const stratum::LayeredSurface<double>& layer = state.range(1) == 1 ? skin_tabulated_faces() : skin();
    std::size_t bytes = 0;
    int nodes = 0;
    for (auto _ : state) {
        const stratum::TabulatedBSDF<double> t(layer, tolerance);
        bytes = t.memory_bytes();
        nodes = t.grid_size();
        benchmark::DoNotOptimize(bytes);
    }
    state.counters["kB"] = static_cast<double>(bytes) / 1024;
    state.counters["nodes"] = nodes;
}
BENCHMARK(BM_tabulated_build)->ArgsProduct({{2, 3, 4}, {0, 1}})->Unit(benchmark::kMillisecond);

// The same slab between smooth faces (1 | 1.4 | 1: the beam as a source, exits at the nodes' true angles), 1e-2.
void BM_tabulated_build_smooth(benchmark::State& state) {
    static const stratum::LayeredSurface<double> layer = [] {
        stratum::LayerOptions options;
        options.ordinates = 16;
        return stratum::solve_layer(stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5),
                                    stratum::SmoothDielectric<double>(1.0, 1.4), stratum::SmoothDielectric<double>(1.4, 1.0),
                                    options);
    }();
    int nodes = 0;
    for (auto _ : state) {
        const stratum::TabulatedBSDF<double> t(layer, 1e-2);
        nodes = t.grid_size();
        benchmark::DoNotOptimize(nodes);
    }
    state.counters["nodes"] = nodes;
}
BENCHMARK(BM_tabulated_build_smooth)->Unit(benchmark::kMillisecond);

// Per call, cycling through the fixed inputs; range(0) = -log10(tolerance).
template <class Real>
void BM_tabulated_eval(benchmark::State& state) {
    static const Inputs<Real> in;
    const stratum::TabulatedBSDF<Real>& t = table<Real>(std::pow(10.0, -static_cast<double>(state.range(0))));
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(t.eval(in.wi[i], in.wo[i]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_tabulated_eval, double)->Arg(2)->Arg(3);
BENCHMARK_TEMPLATE(BM_tabulated_eval, float)->Arg(2)->Arg(3);

template <class Real>
void BM_tabulated_pdf(benchmark::State& state) {
    static const Inputs<Real> in;
    const stratum::TabulatedBSDF<Real>& t = table<Real>(std::pow(10.0, -static_cast<double>(state.range(0))));
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(t.pdf(in.wi[i], in.wo[i]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_tabulated_pdf, double)->Arg(2)->Arg(3);

template <class Real>
void BM_tabulated_sample(benchmark::State& state) {
    static const Inputs<Real> in;
    const stratum::TabulatedBSDF<Real>& t = table<Real>(std::pow(10.0, -static_cast<double>(state.range(0))));
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(t.sample(in.wi[i], in.u[3 * i], in.u[3 * i + 1], in.u[3 * i + 2]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK_TEMPLATE(BM_tabulated_sample, double)->Arg(2)->Arg(3);
BENCHMARK_TEMPLATE(BM_tabulated_sample, float)->Arg(2)->Arg(3);

// The peers in this library: the layer evaluated directly, and the top interface's own BSDF.
void BM_tabulated_peer_layer_eval(benchmark::State& state) {
    static const Inputs<double> in;
    stratum::LayeredSurface<double>::Workspace ws;
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& wo = in.wo[i];
        benchmark::DoNotOptimize(wo.z > 0 ? skin().brdf(in.wi[i], wo, ws) : skin().btdf(in.wi[i], wo, ws));
        i = (i + 1) & 1023;
    }
}
BENCHMARK(BM_tabulated_peer_layer_eval)->Unit(benchmark::kMicrosecond);

void BM_tabulated_peer_rough_interface(benchmark::State& state) {
    static const Inputs<double> in;
    const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4);
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(top.eval(in.wi[i], in.wo[i]));
        benchmark::DoNotOptimize(top.sample(in.wi[i], in.u[3 * i], in.u[3 * i + 1], in.u[3 * i + 2]));
        i = (i + 1) & 1023;
    }
}
BENCHMARK(BM_tabulated_peer_rough_interface);

}  // namespace

namespace {

// Three channels on one grid (Stam's skin layer with albedo 0.95 / 0.88 / 0.80, tolerance 1e-2): every channel's
// value per call, and sampling the luminance with every channel's value at the sample.
const stratum::TabulatedBSDF<double>& rgb_table() {
    static const stratum::TabulatedBSDF<double> t = [] {
        stratum::LayerOptions options;
        options.ordinates = 16;
        std::vector<stratum::Slab<double>> slabs;
        for (double albedo : {0.95, 0.88, 0.80}) slabs.push_back(stratum::Slab<double>::from_transparency(albedo, 0.8, 0.5));
        return stratum::TabulatedBSDF<double>(
            stratum::solve_spectral(slabs, stratum::RoughDielectric<double>(0.3, 1.0, 1.4),
                                    stratum::RoughDielectric<double>(0.3, 1.4, 1.0), options),
            1e-2, {0.2126, 0.7152, 0.0722});
    }();
    return t;
}

void BM_tabulated_eval_rgb(benchmark::State& state) {
    static const Inputs<double> in;
    const auto& t = rgb_table();
    double v[3];
    std::size_t i = 0;
    for (auto _ : state) {
        t.eval(in.wi[i], in.wo[i], v);
        benchmark::DoNotOptimize(v);
        i = (i + 1) & 1023;
    }
    state.counters["kB"] = static_cast<double>(t.memory_bytes()) / 1024;
}
BENCHMARK(BM_tabulated_eval_rgb);

// sample() with every channel's value, in importance transport and in radiance transport (a path tracer from the
// camera, as examples/render_sphere.cpp: the arguments exchanged, so the values are evaluated anew, with the
// luminance, in one pass).
void sample_rgb(benchmark::State& state, stratum::TransportMode mode) {
    static const Inputs<double> in;
    const auto& t = rgb_table();
    double v[3];
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(t.sample(in.wi[i], in.u[3 * i], in.u[3 * i + 1], in.u[3 * i + 2], v, mode));
        i = (i + 1) & 1023;
    }
}
void BM_tabulated_sample_rgb(benchmark::State& state) { sample_rgb(state, stratum::TransportMode::importance); }
BENCHMARK(BM_tabulated_sample_rgb);
void BM_tabulated_sample_rgb_radiance(benchmark::State& state) { sample_rgb(state, stratum::TransportMode::radiance); }
BENCHMARK(BM_tabulated_sample_rgb_radiance);

}  // namespace
