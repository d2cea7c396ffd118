// Intensities at true angles between specular (index-matched or smooth) faces, where the beam is a source exact at
// its angle (docs/physics.md section 6): against converged DISORT (tests/data/disort_intensity_reference.txt, an
// outside code run outside this repository), its fluxes, reciprocity, and the hard cases of the incidence (on an
// ordinate, at the pole, at grazing and near the critical angle).
#include <doctest/doctest.h>

#include <stratum/layer.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.hpp"

using stratum::Boundary;
using stratum::LayerOptions;
using stratum::LayeredSurface;
using stratum::Slab;
using stratum::SmoothDielectric;
using stratum::Vec3;

namespace {

const double pi = 3.14159265358979323846;

Vec3<double> direction(double mu, double phi) { return stratum_test::direction_at(mu, phi); }

struct Problem {
    double g, albedo, tau, mu0;
};
const std::map<std::string, Problem>& problems() {
    static const std::map<std::string, Problem> p = {{"P1", {0.75, 0.9, 1.0, 0.5}},
                                                     {"P2", {0.75, 0.9, 1.0, 1.0}},
                                                     {"P3", {0.0, 1.0, 2.0, 0.7}},
                                                     {"P4", {0.9, 0.99, 4.0, 0.3}},
                                                     {"P5", {0.5, 0.8, 0.1, 0.6}}};
    return p;
}

struct Intensity {
    std::string problem;
    double umu, phi_deg, reference;
};
struct Flux {
    double up, down, direct;
};

// The lit values (upwelling at the top, downwelling at the bottom) and the fluxes of the reference file.
void read_reference(std::vector<Intensity>& out, std::map<std::string, Flux>& fluxes) {
    std::ifstream in(STRATUM_TEST_DATA_DIR "/disort_intensity_reference.txt");
    REQUIRE(in.good());
    for (std::string line; std::getline(in, line);) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream row(line);
        std::string first;
        row >> first;
        if (first == "flux") {
            std::string name;
            Flux f{};
            row >> name >> f.up >> f.down >> f.direct;
            REQUIRE(!row.fail());
            fluxes[name] = f;
            continue;
        }
        std::string level;
        Intensity x{first, 0, 0, 0};
        double sixteen = 0;
        row >> level >> x.umu >> x.phi_deg >> x.reference >> sixteen;
        REQUIRE(!row.fail());
        if ((level == "top") == (x.umu > 0)) out.push_back(x);
    }
    REQUIRE(out.size() == 5 * 14 * 4);
    REQUIRE(fluxes.size() == 5);
}

// (the incidence requested: its field is solved once, not at every intensity)
LayeredSurface<double> solve(const Problem& p, int m, bool correction) {
    LayerOptions o;
    o.ordinates = m;
    o.single_scattering_correction = correction;
    stratum::LayerRequest<double> request;
    request.incidence = {p.mu0};
    return solve_layer(Slab<double>(p.albedo, p.g, p.tau), Boundary<double>::index_matched(), Boundary<double>::index_matched(),
                       o, request);
}

// DISORT's conventions: the beam travels down at azimuth 0; (umu, phi) is a direction of travel, umu > 0 up.
double intensity(const LayeredSurface<double>& layer, const Problem& p, double umu, double phi_deg) {
    const Vec3<double> wi{-std::sqrt(1 - p.mu0 * p.mu0), 0, p.mu0};
    const double s = std::sqrt(1 - umu * umu), phi = phi_deg * pi / 180;
    const Vec3<double> wo{s * std::cos(phi), s * std::sin(phi), umu};
    return umu > 0 ? layer.subsurface_brdf(wi, wo) : layer.btdf(wi, wo);
}

// Worst relative error over a problem's 56 lit intensities.
double worst_error(const std::vector<Intensity>& ref, const std::string& name, const LayeredSurface<double>& layer) {
    const Problem& p = problems().at(name);
    double worst = 0;
    for (const Intensity& x : ref)
        if (x.problem == name)
            worst = std::fmax(worst, std::fabs(intensity(layer, p, x.umu, x.phi_deg) - x.reference) / x.reference);
    return worst;
}

}  // namespace

TEST_CASE("intensities at true angles converge to DISORT's at the method's rate, monotonically") {
    // Five problems (g 0 to 0.9, albedo 0.8 to 1, tau 0.1 to 4, mu0 0.3 to 1), 14 exit cosines from 0.1 to 1 (0.999
    // and 1 included) at 4 azimuths, against DISORT at 256 streams (converged to ~1e-8; its 16-stream values, with
    // TMS and IMS, are off by up to 5.3e-3). Measured worst relative error with the single-scattering correction
    // (LayerOptions::single_scattering_correction), M = 8 / 16 / 24 / 32 / 48:
    //   P1 4.7e-4 / 1.7e-6 / 6.5e-8 / 1.3e-8 / 2.7e-9     P2 4.1e-3 / 1.5e-5 / 6.0e-8 / 7.7e-9 / 7.0e-10
    //   P3 2.9e-6 / 1.1e-7 / 1.0e-8 / 1.9e-9 / 2.9e-10    P4 5.3e-3 / 1.2e-3 / 8.8e-5 / 8.9e-6 / 1.5e-7
    //   P5 6.8e-4 / 6.5e-6 / 6.2e-8 / 3.0e-8 / 7.4e-10
    // (from M = 32 on, P1, P2, P3, P5 are at the reference's own accuracy; P1 and P4 at M = 8 were 1.1e-3 and 1.7e-2
    // with the TMS alone, before the IMS). Before the beam was a source, P1 at
    // M = 16 / 32 / 64 / 96 gave 9.1e-2 / 4.2e-2 / 2.1e-2 / 1.4e-2 (the issue that asked for this). Bounds: the
    // measured x 1.5, and at least 3e-8 (the reference's accuracy).
    std::vector<Intensity> ref;
    std::map<std::string, Flux> fluxes;
    read_reference(ref, fluxes);
    const std::map<std::string, std::vector<double>> bound = {
        {"P1", {7e-4, 2.5e-6, 1e-7, 3e-8, 3e-8}},    {"P2", {6.2e-3, 2.2e-5, 9e-8, 3e-8, 3e-8}},
        {"P3", {4.4e-6, 1.7e-7, 3e-8, 3e-8, 3e-8}},  {"P4", {8e-3, 1.8e-3, 1.4e-4, 1.4e-5, 3e-7}},
        {"P5", {1.1e-3, 1e-5, 1e-7, 4.5e-8, 3e-8}}};
    const int ms[] = {8, 16, 24, 32, 48};
    for (const auto& entry : problems()) {
        const std::string& name = entry.first;
        const Problem& p = entry.second;
        double previous = 1;
        for (std::size_t i = 0; i < 5; ++i) {
            const double e = worst_error(ref, name, solve(p, ms[i], true));
            MESSAGE(name << ", M = " << ms[i] << ": worst relative error " << e);
            CHECK(e < bound.at(name)[i]);
            if (e > 3e-8) CHECK(e < previous);  // (monotone until the reference's accuracy)
            previous = e;
        }
    }
}

TEST_CASE("the single-scattering correction is what puts the forward and backward peaks right at 16 ordinates") {
    // Without it, the truncated phase function misses the peak of single scattering near the beam's directions:
    // measured at M = 16, worst 3.3e-3 (P1, forward), 4.0e-3 (P2), 1.1e-1 (P4, backward glory of g = 0.9), against
    // 1.7e-6, 1.5e-5, 1.2e-3 with it; where no peak is truncated (P3, g = 0) it changes nothing.
    std::vector<Intensity> ref;
    std::map<std::string, Flux> fluxes;
    read_reference(ref, fluxes);
    for (const char* name : {"P1", "P2", "P4"}) {
        const Problem& p = problems().at(name);
        const double without = worst_error(ref, name, solve(p, 16, false)), with = worst_error(ref, name, solve(p, 16, true));
        CHECK(without > 2e-3);
        CHECK(with < without / 3);
    }
    const Problem& p3 = problems().at("P3");
    CHECK(worst_error(ref, "P3", solve(p3, 16, false)) == worst_error(ref, "P3", solve(p3, 16, true)));
}

TEST_CASE("IMS: the beam's aureole is DISORT's at equal streams, and closer to converged DISORT") {
    // tests/data/disort_aureole_reference.txt (gen_disort_aureole.c, an outside code run outside this repository):
    // downwelling radiance at the bottom within 9 degrees of the transmitted beam's polar angle, azimuths 0 to 20
    // degrees, for P4 (A1: g 0.9, albedo 0.99, tau 4, mu0 0.3) and A2 (g 0.95, albedo 0.9, tau 1, mu0 0.8), at 256
    // streams and at 32 and 16 with DISORT's TMS and IMS. Inside DISORT's 10-degree window both codes solve the same
    // discrete equations and apply the same corrections, so stratum at M = 16 and 8 must give DISORT's 32- and
    // 16-stream values: measured within 1.5e-12 (A1, M = 16 and 8) and 1.9e-11 (A2, M = 16) relative; with the TMS
    // alone, as before the IMS, 3.4e-4 and 1.1e-1 off at M = 16. Against 256 streams, worst at M = 16: A1 9.5e-5 (3.6e-4 with
    // TMS alone), A2 1.9e-2.
    std::ifstream in(STRATUM_TEST_DATA_DIR "/disort_aureole_reference.txt");
    REQUIRE(in.good());
    struct Row {
        std::string problem;
        double g, albedo, tau, mu0, umu, phi, reference, s32, s16;
    };
    std::vector<Row> rows;
    for (std::string line; std::getline(in, line);) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream row(line);
        Row r;
        row >> r.problem >> r.g >> r.albedo >> r.tau >> r.mu0 >> r.umu >> r.phi >> r.reference >> r.s32 >> r.s16;
        REQUIRE(!row.fail());
        rows.push_back(r);
    }
    REQUIRE(rows.size() == 2 * 9 * 5);
    for (const std::string name : {"A1", "A2"}) {
        const Row* first = nullptr;
        for (const Row& r : rows)
            if (r.problem == name && !first) first = &r;
        REQUIRE(first);
        const Problem p{first->g, first->albedo, first->tau, first->mu0};
        const LayeredSurface<double> m16 = solve(p, 16, true), m8 = solve(p, 8, true);
        double same16 = 0, same8 = 0, converged16 = 0;
        for (const Row& r : rows) {
            if (r.problem != name) continue;
            const double a = intensity(m16, p, r.umu, r.phi), b = intensity(m8, p, r.umu, r.phi);
            same16 = std::fmax(same16, std::fabs(a - r.s32) / r.s32);
            same8 = std::fmax(same8, std::fabs(b - r.s16) / r.s16);
            converged16 = std::fmax(converged16, std::fabs(a - r.reference) / r.reference);
        }
        MESSAGE(name << ": M = 16 against DISORT's 32 streams " << same16 << ", M = 8 against its 16 " << same8
                     << "; M = 16 against 256 streams " << converged16);
        CHECK(same16 < 1e-10);
        // (A2 at 8 ordinates: the truncated phase function p_0(x, -mu_m) of the beam dips below 0, which stratum
        // clamps (detail/beam_source.hpp: no negative flux) and DISORT keeps; their mode 0 then differs by 6e-6 with
        // or without the corrections, from mu0 = 0.793 up, and agrees to 12 digits below it and for g <= 0.93)
        CHECK(same8 < (name == "A1" ? 1e-10 : 2e-5));
        CHECK(converged16 < (name == "A1" ? 1.4e-4 : 2.9e-2));
    }
    // Continuous where DISORT's window ends (10 degrees from the beam's polar angle), which a windowed correction
    // is not (A2 at M = 16: a jump of 1.1e-2 of the radiance there): a step of 2e-9 rad moves the radiance by O(1e-9).
    const Problem a2{0.95, 0.9, 1.0, 0.8};
    const LayeredSurface<double> layer = solve(a2, 16, true);
    for (const double side : {-1.0, 1.0}) {
        const double theta = std::acos(a2.mu0) + side * pi / 18;
        const double before = intensity(layer, a2, -std::cos(theta - 1e-9), 0.0);
        const double after = intensity(layer, a2, -std::cos(theta + 1e-9), 0.0);
        CHECK(std::fabs(after - before) < 1e-7 * before);
    }
}

TEST_CASE("IMS: a medium split into slabs is the same medium; finite for any thickness (found by review)") {
    // The IMS is taken over the column of slabs joined by index-matched faces, with DISORT's averages: a correction per
    // slab took 2 x tau 0.5 5.5% and 4 x tau 0.25 8.4% away from one slab of tau 1 (g 0.95, M = 16, at the beam).
    // Measured: equal to 1.0e-13 relative, with different peaks in the slabs too (Henyey-Greenstein g 0.95 over the
    // same as Legendre moments, which the column sums term by term).
    LayerOptions o;
    o.ordinates = 16;
    o.single_scattering_correction = true;
    stratum::LayerRequest<double> request;
    request.incidence = {0.8};
    const Boundary<double> matched = Boundary<double>::index_matched();
    const auto one = solve_layer(Slab<double>(0.9, 0.95, 1.0), matched, matched, o, request);
    const auto two = stratum::solve_stack(matched, std::vector<Slab<double>>(2, Slab<double>(0.9, 0.95, 0.5)),
                                          std::vector<Boundary<double>>(1, matched), matched, o, request);
    const auto four = stratum::solve_stack(matched, std::vector<Slab<double>>(4, Slab<double>(0.9, 0.95, 0.25)),
                                           std::vector<Boundary<double>>(3, matched), matched, o, request);
    const std::vector<Slab<double>> different = {
        Slab<double>(0.9, 0.95, 0.5),
        Slab<double>::with_phase_moments(0.9, stratum::HenyeyGreenstein<double>(0.95).legendre_moments(1200), 0.5)};
    const auto mixed =
        stratum::solve_stack(matched, different, std::vector<Boundary<double>>(1, matched), matched, o, request);
    const Problem a2{0.95, 0.9, 1.0, 0.8};
    double worst = 0;
    for (const double umu : {-0.8, -0.75, -0.6, 0.3})
        for (const double phi : {0.0, 5.0, 30.0}) {
            const double base = intensity(one, a2, umu, phi);
            for (const LayeredSurface<double>* split : {&two, &four, &mixed})
                worst = std::fmax(worst, std::fabs(intensity(*split, a2, umu, phi) - base) / base);
        }
    MESSAGE("split into slabs: worst relative change " << worst);
    CHECK(worst < 1e-12);
    // Different Henyey-Greenstein peaks in one column sum in closed form (2 sum_j a_j (HG_gj - S) - sum_jk a_j a_k
    // (HG_gjgk - S)); the same slabs as Legendre moments sum term by term: measured equal to 1.9e-13. A slab without a
    // truncated peak (g < 0) adds nothing: counted, its alternating moments cancelled the sum to 0 at tau 0.5 and
    // ended it early, a 3% spike at the beam (found by review); now smooth (second difference 3e-8 relative).
    auto column = [&](double g2, double tau2, bool as_moments) {
        const auto slab = [&](double g, double tau) {
            return as_moments ? Slab<double>::with_phase_moments(0.9, stratum::HenyeyGreenstein<double>(g).legendre_moments(2000), tau)
                              : Slab<double>(0.9, g, tau);
        };
        return stratum::solve_stack(matched, std::vector<Slab<double>>{slab(0.97, 0.5), slab(g2, tau2)},
                                    std::vector<Boundary<double>>(1, matched), matched, o, request);
    };
    const auto closed = column(0.9, 0.5, false), summed = column(0.9, 0.5, true);
    double moments_worst = 0;
    for (const double umu : {-0.8, -0.75, -0.6})
        for (const double phi : {0.0, 5.0, 30.0}) {
            const double c = intensity(closed, a2, umu, phi);
            moments_worst = std::fmax(moments_worst, std::fabs(intensity(summed, a2, umu, phi) - c) / c);
        }
    MESSAGE("closed form against term by term: " << moments_worst);
    CHECK(moments_worst < 1e-12);
    const double below = intensity(column(-0.95, 0.4999, false), a2, -0.8, 0.0);
    const double at = intensity(column(-0.95, 0.5, false), a2, -0.8, 0.0);
    const double above = intensity(column(-0.95, 0.5001, false), a2, -0.8, 0.0);
    CHECK(std::fabs(at - (below + above) / 2) < 1e-6 * at);
    // tau^2 e^{-tau / mu} overflowed to inf x 0 = NaN above tau 1.3e154 (1.8e19 in float)
    for (const double tau : {1e20, 1e160, 1e300}) {
        const auto thick = solve_layer(Slab<double>(0.9, 0.95, tau), SmoothDielectric<double>(1.0, 1.4),
                                       SmoothDielectric<double>(1.4, 1.0), o, request);
        const double r = thick.subsurface_brdf(direction(0.8, 0.0), direction(0.5, 2.0));
        CHECK(std::isfinite(r));
        CHECK(r > 0);
        CHECK(thick.btdf(direction(0.8, 0.0), direction(-0.8, 3.0)) == 0.0);
    }
    stratum::LayerRequest<float> request_f;
    request_f.incidence = {0.8f};
    const auto thick_f = solve_layer(Slab<float>(0.9f, 0.95f, 1e20f), SmoothDielectric<float>(1.0f, 1.4f),
                                     SmoothDielectric<float>(1.4f, 1.0f), o, request_f);
    const float r_f = thick_f.subsurface_brdf({-0.6f, 0.0f, 0.8f}, {0.3f, 0.4f, std::sqrt(0.75f)});
    CHECK(std::isfinite(r_f));
    CHECK(r_f > 0);
}

TEST_CASE("fluxes against DISORT's, and the intensities integrate to them") {
    // Flux up at the top, diffuse flux down at the bottom and the direct beam, converged DISORT; at M = 24 within
    // 4e-7 (measured 2.7e-7 at most); the direct beam e^{-tau/mu0} to rounding. Without the correction, the intensities at true angles (64 x 64 Gauss per
    // hemisphere) integrate to the solver's own fluxes within 1e-6 (measured 5.2e-7).
    std::vector<Intensity> ref;
    std::map<std::string, Flux> fluxes;
    read_reference(ref, fluxes);
    const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(64);
    for (const auto& entry : problems()) {
        const std::string& name = entry.first;
        const Problem& p = entry.second;
        const LayeredSurface<double> layer = solve(p, 24, false);
        const Flux& f = fluxes.at(name);
        const double direct = layer.direct_transmittance(p.mu0);
        CHECK(std::fabs(direct - f.direct) < 1e-12 * f.direct);
        // DISORT's diffuse flux excludes the delta-M beam's forward peak; stratum's transmittance() includes it
        CHECK(std::fabs(layer.reflectance(p.mu0).total() - f.up) < 4e-7);
        CHECK(std::fabs(layer.transmittance(p.mu0) - direct - f.down) < 4e-7);
        const Vec3<double> wi{-std::sqrt(1 - p.mu0 * p.mu0), 0, p.mu0};
        LayeredSurface<double>::Workspace ws;  // (reused: the exit cosine's work is shared by its azimuths)
        double r = layer.direct_reflectance(p.mu0) + layer.forward_peak_reflectance(p.mu0);
        double t = direct + layer.forward_peak_transmittance(p.mu0);
        for (std::size_t a = 0; a < g.size(); ++a)
            for (std::size_t b = 0; b < g.size(); ++b) {
                const double s = std::sqrt(1 - g.nodes[a] * g.nodes[a]), phi = pi * g.nodes[b];
                const Vec3<double> up{s * std::cos(phi), s * std::sin(phi), g.nodes[a]};
                const double w = 2 * pi * g.weights[a] * g.weights[b] * g.nodes[a];
                r += w * layer.subsurface_brdf(wi, up, ws);
                t += w * layer.btdf(wi, {up.x, up.y, -up.z}, ws);
            }
        INFO(name << ": integrals " << r << ", " << t << "; fluxes " << layer.reflectance(p.mu0).total() << ", "
                  << layer.transmittance(p.mu0));
        CHECK(std::fabs(r - layer.reflectance(p.mu0).total()) < 1e-6);
        CHECK(std::fabs(t - layer.transmittance(p.mu0)) < 1e-6);
    }
}

TEST_CASE("smooth Fresnel faces: the BRDF at true angles is reciprocal") {
    // Air | 1.4 | air: f(wi, wo) = f(wo, wi). The solution is not symmetric in its construction (the beam is a
    // source, the exit a source-function integral), so this is a check: measured within 2e-12 relative at M = 16
    // (the discrete equations are reciprocal: docs/physics.md section 6).
    LayerOptions o;
    o.ordinates = 16;
    for (const bool correction : {false, true}) {
        o.single_scattering_correction = correction;
        const auto layer = solve_layer(Slab<double>(0.9, 0.7, 1.5), SmoothDielectric<double>(1.0, 1.4),
                                       SmoothDielectric<double>(1.4, 1.0), o);
        double worst = 0;
        for (const double a : {0.05, 0.3, 0.7, 1.0})
            for (const double b : {0.1, 0.5, 0.9, 0.999})
                for (const double phi : {0.0, 1.0, 3.0}) {
                    const Vec3<double> wi = direction(a, 0.0), wo = direction(b, phi);
                    const double f = layer.subsurface_brdf(wi, wo), f_reversed = layer.subsurface_brdf(wo, wi);
                    worst = std::fmax(worst, std::fabs(f - f_reversed) / f);
                }
        MESSAGE("correction " << correction << ": worst relative asymmetry " << worst);
        CHECK(worst < 1e-10);
    }
}

TEST_CASE("hard incidences: on an ordinate, at the pole, at grazing, at the critical angle: finite and continuous") {
    LayerOptions o;
    o.ordinates = 12;
    const auto layer = solve_layer(Slab<double>(0.95, 0.8, 2.0), SmoothDielectric<double>(1.0, 1.33),
                                   SmoothDielectric<double>(1.33, 1.0), o);
    const Vec3<double> wo = direction(0.6, 2.0), wt = direction(-0.4, 0.5);
    // Values at mu and at a neighbour at relative distance h differ by O(h) (by O(sqrt(h)) at the pole, where the
    // modes k > 0 vanish as sin^k); near grazing the BRDF and BTDF are proportional to mu (T_12 is). Bounds 1e-6
    // (was 1e-5).
    auto close = [&](double mu, double nearby, double ratio, double tolerance) {
        const Vec3<double> a = direction(mu, 0.0), b = direction(nearby, 0.0);
        const double fa = layer.subsurface_brdf(a, wo), fb = layer.subsurface_brdf(b, wo) * ratio;
        const double ta = layer.btdf(a, wt), tb = layer.btdf(b, wt) * ratio;
        INFO("mu " << mu << ": " << fa << " / " << fb << ", " << ta << " / " << tb);
        CHECK(fa > 0);
        CHECK(ta > 0);
        CHECK(std::fabs(fa - fb) <= tolerance * fa);
        CHECK(std::fabs(ta - tb) <= tolerance * ta);
    };
    // the refracted beam exactly on an ordinate (where the weakly scattering modes have lambda ~ 1/mu_m)
    for (const double node : layer.quadrature().nodes) {
        const double mu = std::sqrt(1 - 1.33 * 1.33 * (1 - node * node));  // Snell, outside
        // (near the pole the modes k > 0 scale as sin(theta): a relative step h moves them by ~h / sin; measured
        // 1.7e-6 at mu = 0.998, h = 1e-7)
        if (mu > 0 && mu <= 1) close(mu, mu * (1 - 1e-7), 1, std::fmax(1e-6, 2e-7 / std::sqrt((1 - mu) * (1 + mu))));
    }
    close(1.0, 1 - 1e-13, 1, 1e-6);  // the pole
    close(1e-9, 2e-9, 0.5, 1e-6);    // grazing: the refracted beam at the critical cosine
    CHECK(layer.subsurface_brdf(direction(1e-300, 0.0), wo) >= 0);
}

TEST_CASE("a phase function given by its Legendre moments gets the same intensities and correction as the closed form") {
    // Henyey-Greenstein g = 0.75 as 300 moments (Slab::with_phase_moments): delta-M truncates at chi_2M as for the
    // closed form, and the single-scattering correction sums the moments given where it would use the closed form
    // (g^300 ~ 3e-38: the same function).
    const std::vector<double> chi = stratum::HenyeyGreenstein<double>(0.75).legendre_moments(300);
    LayerOptions o;
    o.ordinates = 12;
    o.single_scattering_correction = true;
    const auto closed = solve_layer(Slab<double>(0.9, 0.75, 1.0), Boundary<double>::index_matched(),
                                    Boundary<double>::index_matched(), o);
    const auto given = solve_layer(Slab<double>::with_phase_moments(0.9, chi, 1.0), Boundary<double>::index_matched(),
                                   Boundary<double>::index_matched(), o);
    const Vec3<double> wi = direction(0.5, 0.0);
    for (const double mu : {0.1, 0.5, 0.999})
        for (const double phi : {0.0, 1.0, 3.14159}) {
            const Vec3<double> up = direction(mu, phi), down = direction(-mu, phi);
            CHECK(given.subsurface_brdf(wi, up) == doctest::Approx(closed.subsurface_brdf(wi, up)).epsilon(1e-12));
            CHECK(given.btdf(wi, down) == doctest::Approx(closed.btdf(wi, down)).epsilon(1e-12));
        }
}

TEST_CASE("float: beside a resonance near the normal the modes k >= 1 vanish there, and nothing is NaN (found by review)") {
    // Beside a resonance 1/x = lambda_j the beam's response is interpolated between two cosines at a relative
    // s = 4 sqrt(eps) from x (1.4e-3 in float). The modes k >= 1, which vary as sin^k(theta), were extrapolated across
    // sqrt(1 - x) and did not vanish at the normal: g 0.95, albedo 0.9, tau 1 at 8 ordinates (lambda = 1.00086) gave a
    // BTDF a milliradian from the normal of 0 / 0.013 / 0.094 at azimuths 0, 90 and 180 degrees (0.0088 / 0.0089 /
    // 0.0090 in double). Now mode k is interpolated divided by sin^k(theta). (Mode 0 there stays 0.0152 against
    // double's 0.0089: README, known limitations.) Scaling back by ((1 - x^2) / (1 - x2^2))^{k/2} overflowed where
    // x2 = x (1 + 2s) lay a few ulp below 1, and inf x 0 made the BRDF NaN for 45 of 1001 albedos at M = 16: that x2
    // is no longer taken.
    LayerOptions o;
    o.ordinates = 8;
    const auto f = stratum::solve_layer(Slab<float>(0.9f, 0.95f, 1.0f), Boundary<float>::index_matched(),
                                        Boundary<float>::index_matched(), o);
    const Vec3<float> wi{0.71414284f, 0, 0.7f};
    const float along = f.btdf(wi, {0, 0, -1});
    for (float phi : {0.0f, 1.5707964f, 3.1415927f}) {
        const float e = 1e-3f;
        CHECK(f.btdf(wi, {e * std::cos(phi), e * std::sin(phi), -std::sqrt(1 - e * e)}) == doctest::Approx(along).epsilon(0.02));
    }
    o.ordinates = 16;
    int nan = 0;
    for (int i = 0; i <= 200; ++i) {
        const float albedo = 0.5f + 0.5f * float(i) / 200.0f;
        const auto l = stratum::solve_layer(Slab<float>(albedo, 0.8f, 1.0f), Boundary<float>::index_matched(),
                                            Boundary<float>::index_matched(), o);
        for (float x : {0.99979943f, 0.99979967f, 0.99979985f, 0.99979997f}) {
            const Vec3<float> w{std::sqrt(1 - x * x), 0, x}, wo{-0.6f, 0.1f, std::sqrt(1 - 0.37f)};
            nan += !std::isfinite(l.brdf(w, wo)) || !std::isfinite(l.btdf(w, {wo.x, wo.y, -wo.z}));
        }
    }
    CHECK(nan == 0);
}

TEST_CASE("float between smooth Fresnel faces: the fluxes against double's") {
    // README, known limitations: measured up to 7.2e-5 from double's (and R + T - 1 up to 8e-5 at albedo 1) over
    // n 1.33 and 1.5, g 0 to 0.95, albedo 0.9 and 1, tau 1 to 20, 8 and 16 ordinates (this said 1e-6; found by
    // review). Here a subset of that sweep; bound 1e-4.
    double worst = 0, excess = 0;
    for (const double n : {1.33, 1.5})
        for (const double g : {0.0, 0.8, 0.95})
            for (const double tau : {1.0, 20.0})
                for (const int m : {8, 16}) {
                    LayerOptions o;
                    o.ordinates = m;
                    const auto f = stratum::solve_layer(Slab<float>(1.0f, float(g), float(tau)), stratum::SmoothDielectric<float>(1.0f, float(n)),
                                                        stratum::SmoothDielectric<float>(float(n), 1.0f), o);
                    const auto d = stratum::solve_layer(Slab<double>(1.0, g, tau), stratum::SmoothDielectric<double>(1.0, n),
                                                        stratum::SmoothDielectric<double>(n, 1.0), o);
                    for (const double mu : {1.0, 0.5, 0.1}) {
                        const double rf = f.reflectance(float(mu)).total(), tf = f.transmittance(float(mu));
                        worst = std::fmax(worst, std::fmax(std::fabs(rf - d.reflectance(mu).total()), std::fabs(tf - d.transmittance(mu))));
                        excess = std::fmax(excess, rf + tf - 1);
                    }
                }
    MESSAGE("float against double between smooth faces: " << worst << "; R + T - 1 up to " << excess);
    CHECK(worst <= 1e-4);
    CHECK(excess <= 1e-4);
}

TEST_CASE("one Workspace for layer after layer: no values of a freed layer (found by review)") {
    // The Workspace caches the slabs' responses at an exit cosine, keyed by the layer's beam source. Keyed by its
    // address, the next layer solved where the freed one had been (the allocator's choice: not under ASan) took the
    // freed layer's responses: brdf(ws) 0 where brdf() is 0.0035 (albedo 0.3 after 0.9), btdf likewise.
    LayerOptions o;
    o.ordinates = 8;
    const stratum::SmoothDielectric<double> top(1.0, 1.4), bottom(1.4, 1.0);
    const Vec3<double> wi{0.8, 0, 0.6}, wo{-0.5, 0.5, std::sqrt(0.5)}, down{-0.5, 0.5, -std::sqrt(0.5)};
    stratum::LayeredSurface<double>::Workspace ws;
    for (const double albedo : {0.9, 0.3, 0.6, 0.1}) {
        const auto layer = stratum::solve_layer(Slab<double>(albedo, 0.5, 2.0), top, bottom, o);
        INFO("albedo " << albedo);
        CHECK(layer.brdf(wi, wo, ws) == layer.brdf(wi, wo));
        CHECK(layer.btdf(wi, down, ws) == layer.btdf(wi, down));
    }
}

TEST_CASE("the beam's scattering into the ordinates near the normal: continuous, and its first moment kept (found by review)") {
    // The beam's phase at the ordinates is clamped at 0 and rescaled to conserve energy and its first moment; where
    // that made a factor negative it fell back to energy alone, a jump: g 0.99 between index-matched faces, M = 16,
    // R 0.0016 at mu 0.99978 and 0.0049 at 0.99979, 0.0052 at the normal where M = 64 gives 0.0020 (Fresnel faces:
    // 7% high). Now the factors stop at the edge (alpha = |beta|): continuous, and 0.00172 at the normal (15% low:
    // the discretization's).
    LayerOptions o16, o64;
    o16.ordinates = 16;
    o64.ordinates = 64;
    const Slab<double> peaked(1.0, 0.99, 1.0);
    const auto l16 = stratum::solve_layer(peaked, Boundary<double>::index_matched(), Boundary<double>::index_matched(), o16);
    const auto l64 = stratum::solve_layer(peaked, Boundary<double>::index_matched(), Boundary<double>::index_matched(), o64);
    CHECK(std::fabs(l16.reflectance(0.99979).subsurface - l16.reflectance(0.99978).subsurface) < 1e-5);
    const double at_normal = l16.reflectance(1.0).subsurface, converged = l64.reflectance(1.0).subsurface;
    CHECK(std::fabs(at_normal - converged) < 0.2 * converged);
}
