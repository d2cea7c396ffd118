// The beam source of a bare slab (detail/beam_source.hpp): its response to a beam at any cosine and its radiance
// at any exit cosine, checked against what was not derived from it: the slab's own R and T at the ordinates (the
// boundary solve of slab.hpp, another algorithm), energy conservation at a cosine between the ordinates, the
// continuity through a resonance 1/x = lambda_j (and, in float, double's value beside one near the normal), and
// single scattering in a thin slab (a closed form).
#include <doctest/doctest.h>

#include <stratum/detail/beam_source.hpp>
#include <stratum/henyey_greenstein.hpp>
#include <stratum/quadrature.hpp>
#include <stratum/slab.hpp>

#include <cmath>
#include <vector>

namespace {

using stratum::Quadrature;
using stratum::Slab;
using stratum::detail::BeamResponse;
using stratum::detail::SlabBeam;
using stratum::detail::SlabBeamMode;

const double pi = 3.14159265358979323846;

template <class Real>
struct BasicSetup {
    Quadrature<Real> q;
    int modes;
    std::vector<Real> chi;
    std::vector<stratum::SlabModeOperators<Real>> ops;
    SlabBeam<Real> beam;
};
using Setup = BasicSetup<double>;

// A slab of albedo `albedo`, Henyey-Greenstein g (its first 2M moments, not delta-M scaled), thickness tau, on M
// Gauss ordinates; every mode solved once (in Real), its operators kept for comparison.
template <class Real = double>
BasicSetup<Real> make(int m, double albedo_in, double g_in, double tau_in) {
    const Real albedo = static_cast<Real>(albedo_in), g = static_cast<Real>(g_in), tau = static_cast<Real>(tau_in);
    BasicSetup<Real> s;
    s.q = stratum::gauss_legendre_half<Real>(m);
    s.modes = 2 * m;
    s.chi = stratum::HenyeyGreenstein<Real>(g).legendre_moments(2 * m);
    s.chi.resize(static_cast<std::size_t>(2 * m));
    const stratum::PhaseFourierMatrices<Real> p = stratum::phase_fourier_matrices(s.chi, s.q.nodes, s.modes);
    const Slab<Real> slab(albedo, g, tau);
    s.beam = SlabBeam<Real>(s.q, tau, stratum::detail::PhaseAtOrdinates<Real>(s.chi, s.q.nodes, s.q.weights, s.modes));
    for (int k = 0; k < s.modes; ++k) {
        stratum::detail::SlabModeSolution<Real> sol =
            stratum::detail::slab_mode_solution(slab, s.q, p.same_k(k), p.opposite_k(k), k, false);
        s.ops.push_back(stratum::detail::slab_mode_operators(sol, s.q, tau));
        SlabBeamMode<Real> md;
        md.scatters = sol.scatters;
        md.omega_k = albedo * (k == 0 ? Real(0.5) : Real(0.25));
        md.lambda = sol.eigen.lambda;
        md.n = sol.eigen.n;
        md.y = sol.eigen.y;
        md.r = sol.r_scaled;
        md.t = sol.t_scaled;
        s.beam.add_mode(std::move(md));
    }
    return s;
}

}  // namespace

TEST_CASE("beam source: at an ordinate, the response is the slab's own column of R and T (another algorithm)") {
    for (const double tau : {0.05, 1.3, 20.0}) {
        const Setup s = make(8, 0.9, 0.7, tau);
        const std::size_t m = s.q.size();
        BeamResponse<double> at_x, at_y;
        std::vector<double> scratch;
        double worst = 0, worst_exit = 0, scale = 0;
        for (std::size_t j = 0; j < m; ++j) {
            const double x = s.q.nodes[j];
            s.beam.respond(x, s.modes, at_x, scratch);
            for (int k = 0; k < s.modes; ++k) {
                // a beam of unit irradiance at ordinate j is radiance (2 - delta_k0) / (2 pi w_j mu_j) there
                const double beam = (k == 0 ? 1.0 : 2.0) / (2 * pi * s.q.weights[j] * x);
                for (std::size_t n = 0; n < m; ++n) {
                    const auto& op = s.ops[static_cast<std::size_t>(k)];
                    const double r = op.r(n, j) * beam;
                    const double t = (op.t(n, j) - (n == j ? std::exp(-tau / x) : 0.0)) * beam;
                    const std::size_t i = static_cast<std::size_t>(k) * m + n;
                    worst = std::fmax(worst, std::fmax(std::fabs(at_x.up[i] - r), std::fabs(at_x.down[i] - t)));
                    scale = std::fmax(scale, std::fmax(std::fabs(r), std::fabs(t)));
                }
            }
            // the radiance at an exit cosine that is an ordinate, by the source function and reciprocity
            for (std::size_t n = 0; n < m; ++n) {
                s.beam.respond(s.q.nodes[n], s.modes, at_y, scratch);
                std::vector<double> rs(static_cast<std::size_t>(s.modes)), ts(rs.size());
                s.beam.exit(at_x, at_y, s.modes, rs.data(), ts.data());
                for (int k = 0; k < s.modes; ++k) {
                    const double r = rs[static_cast<std::size_t>(k)], t = ts[static_cast<std::size_t>(k)];
                    const std::size_t i = static_cast<std::size_t>(k) * m + n;
                    worst_exit = std::fmax(worst_exit, std::fmax(std::fabs(r - at_x.up[i]), std::fabs(t - at_x.down[i])));
                }
            }
        }
        MESSAGE("tau " << tau << ": response vs R, T " << worst << ", exit at ordinates " << worst_exit << " (scale "
                       << scale << ")");
        CHECK(worst < 1e-12 * scale);
        CHECK(worst_exit < 1e-12 * scale);
    }
}

TEST_CASE("beam source: a conservative slab scatters exactly the energy the beam loses, at any cosine") {
    // Omega = 1: diffuse flux up + down = 1 - e^{-tau/x} (mode 0), for x between the ordinates and at 1.
    const Setup s = make(6, 1.0, 0.5, 0.8);
    BeamResponse<double> r;
    std::vector<double> scratch;
    for (const double x : {0.013, 0.21, 0.5, 0.77, 0.999, 1.0}) {
        s.beam.respond(x, 1, r, scratch);
        double flux = 0;
        for (std::size_t n = 0; n < s.q.size(); ++n) flux += 2 * pi * s.q.weights[n] * s.q.nodes[n] * (r.up[n] + r.down[n]);
        CHECK(flux == doctest::Approx(-std::expm1(-0.8 / x)).epsilon(1e-13));
    }
}

TEST_CASE("beam source: continuous through a resonance 1/x = lambda_j (the secular limit)") {
    // x exactly 1 / lambda_j for an eigenvalue of a strongly scattering mode (k = 0) and of a weak one (k = 9, where
    // lambda ~ 1/mu_n): the value there against the Richardson extrapolation of symmetric neighbours at relative
    // distances h and 2h, (4 A(h) - A(2h)) / 3 = f + O(h^4) (h = 1e-3: ~1e-12 for these smooth responses).
    const int modes = 10;
    const Setup s = make(6, 0.95, 0.3, 2.0);
    const stratum::PhaseFourierMatrices<double> p = stratum::phase_fourier_matrices(s.chi, s.q.nodes, modes);
    for (const int k : {0, 9}) {
        const auto sol =
            stratum::detail::slab_mode_solution(Slab<double>(0.95, 0.3, 2.0), s.q, p.same_k(k), p.opposite_k(k), k, false);
        double lambda = 0;
        for (const double l : sol.eigen.lambda)
            if (l > 1.5 && l < 3) lambda = l;
        REQUIRE(lambda > 0);
        const double x = 1 / lambda;
        BeamResponse<double> at, at_y, near;
        std::vector<double> scratch;
        s.beam.respond(x, modes, at, scratch);
        CHECK(at.points == 2);
        s.beam.respond(0.4, modes, at_y, scratch);
        auto value = [&](const BeamResponse<double>& b, std::size_t i) {  // i < M: up, then down, then the exit
            const std::size_t m = s.q.size(), off = static_cast<std::size_t>(k) * m;
            if (i < m) return b.up[off + i];
            if (i < 2 * m) return b.down[off + i - m];
            std::vector<double> r(static_cast<std::size_t>(k) + 1), t(r.size());
            s.beam.exit(b, at_y, k + 1, r.data(), t.data());
            return i == 2 * m ? r.back() : t.back();
        };
        const double h = 1e-3;
        for (std::size_t i = 0; i < 2 * s.q.size() + 2; ++i) {
            double a[2];
            for (int j = 0; j < 2; ++j) {
                const double d = h * (j + 1);
                s.beam.respond(x * (1 - d), modes, near, scratch);
                const double lo = value(near, i);
                s.beam.respond(x * (1 + d), modes, near, scratch);
                a[j] = (lo + value(near, i)) / 2;
            }
            const double extrapolated = (4 * a[0] - a[1]) / 3;
            CHECK(value(at, i) == doctest::Approx(extrapolated).epsilon(1e-9));
        }
    }
}

TEST_CASE("beam source: in float, the exit for a beam at a resonance near the normal follows double") {
    // 24 ordinates (the top one 0.99759): mode 1 has lambda_j = 1.002875, and x = 1/lambda_j (1 - x = 2.9e-3) is a
    // resonance (docs/physics.md section 6) that float's wide s = 4 sqrt(eps) = 1.4e-3 meets beside the normal, where
    // x (1 + 2s) is within (1 - x) / 2 of 1: the response is extrapolated from x (1 - 2s) and x (1 - 4s) (weights 2
    // and -1), mode k with each point's weight times ratio^{k/2}, ratio = (1 - x^2) / (1 - x_p^2) (0.51 and 0.34
    // here). The exit at y = 0.6, every mode, against double at the same x (whose s = 6e-8 leaves nothing to
    // interpolate), as the sum of the modes' |errors| in R and T over the sum of their |values|: measured 5.4e-5 (g++
    // and clang, -O0 to -march=native); bound 1e-3. The mode weight as ratio^k or as the weight alone, the beam's own
    // Legendre values at x in place of each point's, or exit_mode without the mode weight: 9.7e-3 to 1.9e-2.
    const int m = 24;
    const BasicSetup<double> d = make<double>(m, 0.9, 0.7, 1.0);
    const BasicSetup<float> f = make<float>(m, 0.9, 0.7, 1.0);
    double lambda = 0;
    for (const double l : d.beam.mode(1).lambda)
        if (l > 1 && l < 1.003) lambda = l;
    REQUIRE(lambda > 0);
    const float x = static_cast<float>(1 / lambda), y = 0.6f;
    BeamResponse<double> beam_d, at_y_d;
    BeamResponse<float> beam_f, at_y_f;
    std::vector<double> scratch_d;
    std::vector<float> scratch_f;
    d.beam.respond(static_cast<double>(x), d.modes, beam_d, scratch_d);
    d.beam.respond(static_cast<double>(y), d.modes, at_y_d, scratch_d);
    f.beam.respond(x, f.modes, beam_f, scratch_f);
    f.beam.respond(y, f.modes, at_y_f, scratch_f);
    REQUIRE(beam_f.points == 2);  // (beside the resonance in float)
    const auto kk = static_cast<std::size_t>(d.modes);
    std::vector<double> r_d(kk), t_d(kk);
    std::vector<float> r_f(kk), t_f(kk);
    d.beam.exit(beam_d, at_y_d, d.modes, r_d.data(), t_d.data());
    f.beam.exit(beam_f, at_y_f, f.modes, r_f.data(), t_f.data());
    double error = 0, sum = 0;
    for (std::size_t k = 0; k < kk; ++k) {
        error += std::fabs(static_cast<double>(r_f[k]) - r_d[k]) + std::fabs(static_cast<double>(t_f[k]) - t_d[k]);
        sum += std::fabs(r_d[k]) + std::fabs(t_d[k]);
    }
    MESSAGE("1 - x " << 1 - static_cast<double>(x) << ": float against double " << error / sum << " of the modes' sum "
                     << sum);
    CHECK(error <= 1e-3 * sum);
}

TEST_CASE("beam source: a thin slab's radiance at any exit cosine is single scattering (closed form)") {
    // tau = 1e-5: to first order in tau, mode k of the radiance leaving at y per unit irradiance is
    // Omega p_k(-+x, y) tau / (4 pi x y), up at the top and down at the bottom (Omega_k beta = Omega / (4 pi x) for
    // every k; detail/beam_source.hpp); the next order is O(tau / x), O(tau / y).
    const double tau = 1e-5, omega = 0.8;
    const Setup s = make(8, omega, 0.6, tau);
    BeamResponse<double> at_x, at_y;
    std::vector<double> scratch;
    for (const double x : {0.3, 0.77, 1.0})
        for (const double y : {0.15, 0.5, 0.91}) {
            s.beam.respond(x, s.modes, at_x, scratch);
            s.beam.respond(y, s.modes, at_y, scratch);
            double rs[4], ts[4];
            s.beam.exit(at_x, at_y, 4, rs, ts);
            for (int k = 0; k < 4; ++k) {
                const double r = rs[k], t = ts[k];
                const double f = omega * tau / (4 * pi * x * y);
                const double r_single = f * stratum::phase_fourier_coefficient(s.chi, -x, y, k);
                const double t_single = f * stratum::phase_fourier_coefficient(s.chi, x, y, k);
                CHECK(std::fabs(r - r_single) < 1e-4 * f);
                CHECK(std::fabs(t - t_single) < 1e-4 * f);
            }
        }
}

TEST_CASE("beam source: the exit's phase coefficients from stored Legendre values are phase_fourier_coefficient's") {
    // PhaseAtOrdinates::between sums the products of the Legendre values at() stored at x and at y; checked against
    // the recurrences of phase_fourier_coefficient (henyey_greenstein.hpp), at +x and -x, every mode of a table built
    // for all 2M moments' modes and of one built for fewer, the normal and grazing cosines included. Tolerance: 16 ulp
    // of the larger of 1 and the coefficient (measured within 8 ulp, not within 2).
    const int m = 12;
    const std::vector<double> chi = stratum::HenyeyGreenstein<double>(0.85).legendre_moments(2 * m);
    const Quadrature<double> q = stratum::gauss_legendre_half<double>(m);
    for (const int modes : {2 * m, 7}) {
        const stratum::detail::PhaseAtOrdinates<double> phase(chi, q.nodes, q.weights, modes);
        std::vector<double> same(static_cast<std::size_t>(modes * m)), opposite(same.size()), scratch;
        std::vector<double> lx(static_cast<std::size_t>(modes) * phase.row_length()), ly(lx.size());
        for (const double x : {1.0, 0.61, 1e-3})
            for (const double y : {1.0, 0.37, 2e-3}) {
                phase.at(x, same.data(), opposite.data(), modes, scratch, lx.data());
                phase.at(y, same.data(), opposite.data(), modes, scratch, ly.data());
                for (int k = 0; k < modes; ++k) {
                    CAPTURE(modes);
                    CAPTURE(k);
                    double plus = -1, minus = -1;
                    phase.between(lx.data(), ly.data(), k, &plus, &minus);
                    const double ref_plus = stratum::phase_fourier_coefficient(chi, x, y, k);
                    const double ref_minus = stratum::phase_fourier_coefficient(chi, -x, y, k);
                    const double scale = std::fmax(1.0, std::fmax(std::fabs(ref_plus), std::fabs(ref_minus)));
                    CHECK(std::fabs(plus - ref_plus) <= 16 * 2.2e-16 * scale);
                    CHECK(std::fabs(minus - ref_minus) <= 16 * 2.2e-16 * scale);
                }
            }
    }
}
