// Concurrent evaluation: the interface and layer evaluation functions are const and documented thread-safe
// (LayeredSurface: one Workspace per thread). Several threads evaluate the same objects at once and must
// reproduce the single-threaded results bit for bit. Run under ThreadSanitizer to check for data races
// (e.g. glibc's std::lgamma writes the global signgam; none of the library's code may call it):
//   cmake -S . -B build/tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++
//         -DCMAKE_CXX_FLAGS=-fsanitize=thread -DSTRATUM_BUILD_BENCHMARKS=OFF -DSTRATUM_BUILD_EXAMPLES=OFF
//   cmake --build build/tsan --target test_concurrency && build/tsan/tests/test_concurrency
#include <doctest/doctest.h>

#include <stratum/interface.hpp>
#include <stratum/layer.hpp>

#include <atomic>
#include <cmath>
#include <cstring>
#include <random>
#include <thread>
#include <vector>

#include "test_util.hpp"

using stratum::LayerOptions;
using stratum::LayerOutput;
using stratum::LayerRequest;
using stratum::RoughDielectric;
using stratum::Shadowing;
using stratum::Slab;
using stratum::Vec3;

namespace {

constexpr int thread_count = 4;
using stratum_test::pi;
using stratum_test::random_direction;
using stratum_test::uniform;

// Bitwise equality of two result vectors (NaN-safe, distinguishes -0 from +0).
bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

// Runs `work` (returning a result vector) on thread_count threads released together; returns their results.
template <class Work>
std::vector<std::vector<double>> run_concurrently(Work work) {
    std::vector<std::vector<double>> results(thread_count);
    std::atomic<int> ready{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < thread_count; ++t)
        threads.emplace_back([&, t] {
            ready.fetch_add(1);
            while (ready.load() < thread_count) std::this_thread::yield();  // start together
            results[static_cast<std::size_t>(t)] = work();
        });
    for (auto& th : threads) th.join();
    return results;
}

// Every evaluation function of one interface on a fixed set of inputs.
std::vector<double> evaluate_interface(const RoughDielectric<double>& rd) {
    std::mt19937_64 rng(11);
    std::vector<double> out;
    for (int i = 0; i < 400; ++i) {
        const Vec3<double> wi = random_direction(rng), wo = random_direction(rng);
        const double u0 = uniform(rng), u1 = uniform(rng), u2 = uniform(rng);
        out.push_back(rd.brdf(wi, wo));
        out.push_back(rd.btdf(wi, wo));
        out.push_back(rd.btdf(wi, {wo.x, wo.y, -wo.z}));
        out.push_back(rd.eval(wi, wo));
        out.push_back(rd.pdf(wi, wo));
        const auto s = rd.sample(wi, u0, u1, u2);
        out.insert(out.end(), {s.wo.x, s.wo.y, s.wo.z, s.value, s.pdf, double(s.reflected), double(s.delta)});
    }
    for (double mu : {0.9, 0.4, 0.05, -0.3, -0.8}) {
        const auto a = rd.hemispherical_totals(mu);
        out.push_back(a.reflectance);
        out.push_back(a.transmittance);
    }
    return out;
}

// Stam's skin layer (README) on 4 ordinates: every evaluation function, from a fresh object or not.
stratum::LayeredSurface<double> skin_layer() {
    const RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    LayerOptions options;
    options.ordinates = 4;
    LayerRequest<double> request;
    request.outputs = LayerOutput::all;
    return stratum::solve_layer(Slab<double>::from_transparency(0.9, 0.8, 0.5), top, bottom, options, request);
}

std::vector<double> evaluate_layer(const stratum::LayeredSurface<double>& layer) {
    std::mt19937_64 rng(12);
    stratum::LayeredSurface<double>::Workspace ws;
    std::vector<double> out;
    for (int i = 0; i < 60; ++i) {
        Vec3<double> wi = random_direction(rng), wo = random_direction(rng);
        wi.z = std::fabs(wi.z);
        wo.z = std::fabs(wo.z);
        out.push_back(layer.brdf(wi, wo, ws));
        out.push_back(layer.subsurface_brdf(wi, wo, ws));
        out.push_back(layer.btdf(wi, {wo.x, wo.y, -wo.z}, ws));
        out.push_back(layer.ambient(wo, ws));
    }
    for (double mu : {1.0, 0.7, 0.3, 0.02, 1e-4}) {  // 1e-4: below the lazy table's first interval
        const auto a = layer.reflectance(mu);
        out.push_back(a.surface);
        out.push_back(a.subsurface);
        out.push_back(layer.transmittance(mu));
        out.push_back(layer.direct_transmittance(mu));
    }
    return out;
}

}  // namespace

TEST_CASE("threads evaluating one RoughDielectric reproduce the single-threaded results bit for bit") {
    for (auto form : {Shadowing::height_correlated, Shadowing::separable}) {
        const RoughDielectric<double> rd(0.3, 1.0, 1.4, form);
        const std::vector<double> reference = evaluate_interface(rd);
        const auto results = run_concurrently([&] { return evaluate_interface(rd); });
        for (const auto& r : results) CHECK(same_bits(r, reference));
    }
}

TEST_CASE("threads evaluating one smooth-limit RoughDielectric (sigma = 0) reproduce the single-threaded results") {
    const RoughDielectric<double> smooth(0.0, 1.0, 1.4);
    const std::vector<double> reference = evaluate_interface(smooth);
    const auto results = run_concurrently([&] { return evaluate_interface(smooth); });
    for (const auto& r : results) CHECK(same_bits(r, reference));
}

TEST_CASE("threads evaluating one LayeredSurface (lazy tables included) reproduce the single-threaded results") {
    const std::vector<double> reference = evaluate_layer(skin_layer());
    // A fresh layer, so that the threads race to build its lazily tabulated transmittances.
    const auto fresh = skin_layer();
    const auto results = run_concurrently([&] { return evaluate_layer(fresh); });
    for (const auto& r : results) CHECK(same_bits(r, reference));
}

TEST_CASE("threads solving layers at once get the single-threaded solution") {
    const std::vector<double> reference = evaluate_layer(skin_layer());
    const auto results = run_concurrently([] { return evaluate_layer(skin_layer()); });
    for (const auto& r : results) CHECK(same_bits(r, reference));
}

TEST_CASE("threads solving and evaluating layers from one pair of PreparedBoundary share it safely") {
    const std::vector<double> reference = evaluate_layer(skin_layer());
    LayerOptions options;
    options.ordinates = 4;
    // Fresh prepared faces: the threads race to build the shared lazily tabulated transmittance.
    const stratum::PreparedBoundary<double> top(RoughDielectric<double>(0.3, 1.0, 1.4), options);
    const stratum::PreparedBoundary<double> bottom(RoughDielectric<double>(0.3, 1.4, 1.0), options);
    const auto results = run_concurrently([&] {
        return evaluate_layer(stratum::solve_layer(Slab<double>::from_transparency(0.9, 0.8, 0.5), top, bottom));
    });
    for (const auto& r : results) CHECK(same_bits(r, reference));
}

TEST_CASE("threads solving a rough coat over a smooth base from one PreparedBoundary build its split rule once, safely") {
    // A rough top over a smooth bottom is solved on ordinates split at the critical cosines (detail::layer_quadrature):
    // the prepared top builds its operators on that rule at the first solve that needs it, under a lock, and every
    // thread must get the plain solve's values.
    LayerOptions options;
    options.ordinates = 6;
    const RoughDielectric<double> coat(0.3, 1.0, 1.4);
    const stratum::SmoothDielectric<double> base(1.4, 1.0);
    const Slab<double> slab = Slab<double>::from_transparency(0.9, 0.8, 0.5);
    const std::vector<double> reference = evaluate_layer(stratum::solve_layer(slab, coat, base, options));
    const stratum::PreparedBoundary<double> top(coat, options), bottom(base, options);
    const auto results = run_concurrently([&] { return evaluate_layer(stratum::solve_layer(slab, top, bottom)); });
    for (const auto& r : results) CHECK(same_bits(r, reference));
}

TEST_CASE("the layer's shared Gauss rules are computed once, from several threads at once, and equal the fresh rules") {
    // detail::shared_gauss_legendre_half caches gauss_legendre_half(n) for n <= 256 (std::call_once per n): threads
    // asking for the same rules at the same time must all get the fresh rule, bit for bit (and 257, past the
    // cache, too).
    std::vector<std::vector<double>> fresh;
    for (int n = 1; n <= 257; n += 16) {
        const auto q = stratum::gauss_legendre_half<double>(n);
        std::vector<double> v(q.nodes);
        v.insert(v.end(), q.weights.begin(), q.weights.end());
        fresh.push_back(v);
    }
    std::atomic<int> mismatches{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < thread_count; ++t)
        threads.emplace_back([&] {
            for (int n = 1, i = 0; n <= 257; n += 16, ++i) {
                const auto q = stratum::detail::shared_gauss_legendre_half<double>(n);
                std::vector<double> v(q.nodes);
                v.insert(v.end(), q.weights.begin(), q.weights.end());
                if (!same_bits(v, fresh[static_cast<std::size_t>(i)])) ++mismatches;
            }
        });
    for (auto& th : threads) th.join();
    CHECK(mismatches.load() == 0);
}
