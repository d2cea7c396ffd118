// The layer API fed as a new user would feed it: solve_layer and solve_stack with extreme and degenerate
// parameters, options and requests, then every public evaluation function of the result (brdf,
// subsurface_brdf, btdf, reflectance, transmittance, direct_* and forward_peak_*, ambient, with and
// without a Workspace) at extreme and degenerate arguments. Accepted input must give finite values in their
// physical ranges with energy never created (beyond rounding; the two documented limitations, README "Known
// limitations", get their measured bounds); rejected input must throw std::invalid_argument naming the
// parameter; degenerate arguments of an evaluation function (horizon, wrong hemisphere, NaN or infinite
// components, cosines outside (0, 1]) give exactly 0 (the documented, pbrt-style choice).
// Few ordinates (1 - 12, mostly 3 - 4) keep it fast: ~7 s in Release, ~11 s under ASan + UBSan.
#include <doctest/doctest.h>

#include <stratum/layer.hpp>

#include <climits>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

using stratum::Boundary;
using stratum::LayeredSurface;
using stratum::LayerOptions;
using stratum::LayerOutput;
using stratum::LayerRequest;
using stratum::RoughDielectric;
using stratum::Slab;
using stratum::SmoothDielectric;
using stratum::Vec3;
using stratum::solve_layer;
using stratum::solve_stack;

namespace {

constexpr double inf = std::numeric_limits<double>::infinity();
constexpr double not_a_number = std::numeric_limits<double>::quiet_NaN();
constexpr double huge = std::numeric_limits<double>::max();
constexpr double denormal = std::numeric_limits<double>::denorm_min();

// Energy slack for albedo + transmittance <= 1. Every flux the solver reports is rescaled to exact totals
// (Gauss sums to T_12(mu_0) and the exit weights to (n_out/n_in)^2 T(mu), the rough operators to their
// hemispherical totals, the specular beam's scattered part to exactly the energy the true beam loses), so
// what remains is rounding: ~100 operations on O(1) numbers at M <= 12, the 1e-12 that test_layer.cpp's
// energy tests and randomized sweeps use for rough and specular faces alike. No discretization error enters a
// bound here, so none is allowed for.
constexpr double slack = 1e-12;

LayerOptions with_ordinates(int m, int modes = 0, bool delta_m = true) {
    LayerOptions o;
    o.ordinates = m;
    o.modes = modes;
    o.delta_m = delta_m;
    return o;
}

Vec3<double> direction(double mu, double phi) { return stratum::spherical_direction(mu, phi); }
Vec3<double> flip(Vec3<double> v) { return {v.x, v.y, -v.z}; }
Vec3<double> scaled(double s, Vec3<double> v) { return {s * v.x, s * v.y, s * v.z}; }

std::string fmt(double x) {
    std::ostringstream out;
    out.precision(17);
    out << x;
    return out.str();
}
std::string fmt(Vec3<double> v) { return "(" + fmt(v.x) + ", " + fmt(v.y) + ", " + fmt(v.z) + ")"; }

// In [0, 1] up to `tolerance` above 1 (a total of 1 computed as a sum can round to 1 + 2e-16); false for NaN.
bool in01(double x, double tolerance) { return x >= 0 && x <= 1 + tolerance; }
bool finite_nonnegative(double x) { return std::isfinite(x) && x >= 0; }

// Collects the failures of one surface so that a defect prints once, with its input, instead of as hundreds
// of CHECKs.
struct Findings {
    std::string label;
    std::vector<std::string> failures;
    void expect(bool ok, const std::string& what) {
        if (!ok) failures.push_back(what);
    }
    std::string summary() const {
        std::string s = label + ": " + std::to_string(failures.size()) + " failure(s)";
        for (std::size_t i = 0; i < failures.size() && i < 8; ++i) s += "\n    " + failures[i];
        return s;
    }
};

// Unit directions above the surface: the normal, two oblique ones, grazing (z = 1e-9) and grazing to rounding.
const std::vector<Vec3<double>>& up_directions() {
    static const std::vector<Vec3<double>> v = {{0, 0, 1}, direction(0.8, 0.3), direction(0.3, 2.0), direction(1e-9, 1.0),
                                                {1, 0, 1e-300}};
    return v;
}

// Degenerate arguments: on the horizon, the zero vector, NaN and infinite components. Documented result: 0.
const std::vector<Vec3<double>>& degenerate_directions() {
    static const std::vector<Vec3<double>> v = {
        {1, 0, 0},     {0, 1, -0.0},   {0, 0, 0},    {0, 0, -0.0},  {not_a_number, 0, 0.8}, {0, not_a_number, 0.8}, {0.6, 0, not_a_number},
        {not_a_number, not_a_number, not_a_number}, {inf, 0, 0.8}, {0.6, -inf, 0.8}, {0, 0, inf}, {-inf, 0, inf}, {not_a_number, 0, -0.8}, {0.6, 0, -inf}};
    return v;
}

// Finite, non-unit vectors (the functions expect unit vectors; these must still give finite values >= 0).
const std::vector<Vec3<double>>& non_unit_directions() {
    static const std::vector<Vec3<double>> v = {
        {0, 0, 2},
        scaled(3, direction(0.8, 0.3)),
        scaled(1e-3, direction(0.8, 0.3)),
        scaled(1e200, direction(0.8, 0.3)),
        scaled(1e-200, direction(0.3, 2.0)),
        {1e-300, 0, 1e-300},
        {1e300, 1e300, 1e300},
        {huge, huge, huge},
        {denormal, 0, denormal},
        {0, 0, denormal},
    };
    return v;
}

// Every public evaluation function of `s` at regular, extreme and degenerate arguments. Energy: albedo +
// transmittance <= 1 + energy_slack.
void check_surface(const LayeredSurface<double>& s, const std::string& label, double energy_slack = slack) {
    Findings f{label, {}};
    typename LayeredSurface<double>::Workspace ws;

    // Cosines in (0, 1]: every component in [0, 1], the direct parts inside their totals, energy not created.
    for (double mu : {denormal, 1e-300, 1e-9, 0.3, 0.7, 1.0}) {
        const auto a = s.reflectance(mu);
        const double t = s.transmittance(mu), dt = s.direct_transmittance(mu), dr = s.direct_reflectance(mu);
        const double pt = s.forward_peak_transmittance(mu), pr = s.forward_peak_reflectance(mu);
        const std::string at = " at mu = " + fmt(mu) + ": R = " + fmt(a.surface) + " + " + fmt(a.subsurface) +
                               ", T = " + fmt(t) + ", direct T = " + fmt(dt) + ", direct R = " + fmt(dr) +
                               ", forward peak T = " + fmt(pt) + ", R = " + fmt(pr);
        f.expect(in01(a.surface, energy_slack) && in01(a.subsurface, energy_slack) && in01(t, energy_slack) &&
                     in01(dt, energy_slack) && in01(dr, energy_slack) && in01(pt, energy_slack) && in01(pr, energy_slack),
                 "outside [0, 1]" + at);
        // (dt + pt rounds delta-M's beam, which the totals contain: 1e-15 relative slack)
        f.expect(dt + pt <= t * (1 + 1e-15) && dr + pr <= a.subsurface * (1 + 1e-15), "direct part exceeds its total" + at);
        f.expect(a.total() + t <= 1 + energy_slack, "energy created (R + T - 1 = " + fmt(a.total() + t - 1) + ")" + at);
    }
    // Cosines outside (0, 1]: documented 0.
    for (double mu : {0.0, -0.0, -denormal, -0.5, -1.0, std::nextafter(1.0, 2.0), 1 + 1e-12, 2.0, inf, -inf, not_a_number}) {
        const auto a = s.reflectance(mu);
        f.expect(a.surface == 0 && a.subsurface == 0 && s.transmittance(mu) == 0 && s.direct_transmittance(mu) == 0 &&
                     s.direct_reflectance(mu) == 0 && s.forward_peak_transmittance(mu) == 0 &&
                     s.forward_peak_reflectance(mu) == 0,
                 "not 0 outside (0, 1] at mu = " + fmt(mu));
    }

    // Regular directions: every incidence against the normal, an oblique and a grazing outgoing direction.
    for (const Vec3<double>& wi : up_directions()) {
        for (const Vec3<double>& wo : {up_directions()[0], up_directions()[2], up_directions()[3]}) {
            const double r = s.brdf(wi, wo), rs = s.subsurface_brdf(wi, wo), t = s.btdf(wi, flip(wo));
            const std::string at = " at wi = " + fmt(wi) + ", wo = " + fmt(wo) + ": brdf " + fmt(r) + ", subsurface " +
                                   fmt(rs) + ", btdf(wi, -wo) " + fmt(t);
            f.expect(finite_nonnegative(r) && finite_nonnegative(rs) && finite_nonnegative(t), "not finite >= 0" + at);
            f.expect(rs <= r, "subsurface_brdf > brdf" + at);
            if (wi.z == wo.z)  // (one pair is enough: the same code)
                f.expect(s.brdf(wi, wo, ws) == r && s.subsurface_brdf(wi, wo, ws) == rs && s.btdf(wi, flip(wo), ws) == t,
                         "Workspace overload differs" + at);
            // The wrong hemispheres: 0.
            f.expect(s.brdf(wi, flip(wo)) == 0 && s.brdf(flip(wi), wo) == 0 && s.subsurface_brdf(wi, flip(wo)) == 0 &&
                         s.btdf(wi, wo) == 0 && s.btdf(flip(wi), flip(wo)) == 0 && s.btdf(flip(wi), wo) == 0,
                     "not 0 for the wrong hemisphere" + at);
        }
        const double a = s.ambient(wi);
        f.expect(finite_nonnegative(a) && a <= 1 + energy_slack && s.ambient(wi, ws) == a,
                 "ambient " + fmt(a) + " at wo = " + fmt(wi));
        f.expect(s.ambient(flip(wi)) == 0, "ambient not 0 below at wo = " + fmt(flip(wi)));
    }

    // Degenerate directions, in either argument: documented 0.
    const Vec3<double> partner = direction(0.8, 0.3), partner_down = direction(-0.6, 2.0);
    for (const Vec3<double>& d : degenerate_directions()) {
        const double values[] = {s.brdf(d, partner),         s.brdf(partner, d),      s.subsurface_brdf(d, partner),
                                 s.subsurface_brdf(partner, d), s.btdf(d, partner_down), s.btdf(partner, d),
                                 s.btdf(partner, flip(d)),   s.ambient(d),           s.brdf(d, d)};
        std::string list;
        bool zero = true;
        for (double v : values) {
            list += " " + fmt(v);
            zero = zero && v == 0;
        }
        f.expect(zero, "not 0 for the degenerate direction " + fmt(d) + ":" + list);
    }

    // Non-unit directions: finite and >= 0.
    for (const Vec3<double>& d : non_unit_directions()) {
        const double values[] = {s.brdf(d, partner), s.brdf(partner, d), s.btdf(d, partner_down),
                                 s.btdf(partner, flip(d)), s.ambient(d), s.btdf(d, flip(d))};
        std::string list;
        bool ok = true;
        for (double v : values) {
            list += " " + fmt(v);
            ok = ok && finite_nonnegative(v);
        }
        f.expect(ok, "not finite >= 0 for the non-unit direction " + fmt(d) + ":" + list);
    }

    // The per-mode operators, when requested, are finite, and the flux of each mode-0 column (light arriving at
    // one ordinate, from above or from below) is bounded. Not by 1: under the default automatic transmission a
    // smooth face's pointwise interpolation rows do not conserve flux per column (interface_operators.hpp; up
    // to 4.0 measured at M = 12); the bound 8 catches unbounded growth (before the fix of ordinates totally
    // reflected at both faces, a smooth | smooth layer with tau <= 1e-6 gave column fluxes of 1e5 to 5e291).
    bool finite_operators = true;
    for (const auto& c : s.mode_operators())
        for (const std::vector<double>* m : {&c.reflection_down, &c.transmission_down, &c.reflection_up, &c.transmission_up})
            for (double x : *m) finite_operators = finite_operators && std::isfinite(x);
    f.expect(finite_operators, "mode_operators() not finite");
    if (!s.mode_operators().empty()) {
        const auto& c = s.mode_operators()[0];
        const auto& q = s.quadrature();
        const std::size_t n_size = q.size();
        double largest = 0;
        for (std::size_t m = 0; m < n_size; ++m) {
            double down = 0, up = 0;
            for (std::size_t n = 0; n < n_size; ++n) {
                const double w = q.weights[n] * q.nodes[n];
                down += w * (c.reflection_down[n * n_size + m] + c.transmission_down[n * n_size + m]);
                up += w * (c.reflection_up[n * n_size + m] + c.transmission_up[n * n_size + m]);
            }
            largest = std::fmax(largest, std::fmax(down, up) / (q.weights[m] * q.nodes[m]));
        }
        f.expect(largest <= 8, "mode_operators() column flux " + fmt(largest));
    }
    f.expect(s.modes() >= 0 && s.ordinates() >= 1, "modes() " + std::to_string(s.modes()) + ", ordinates() " +
                                                        std::to_string(s.ordinates()));

    CHECK_MESSAGE(f.failures.empty(), f.summary());
}

// The boundary pairs every parameter sweep runs through (air | n = 1.4 | air unless stated).
// A layer with a rough face costs up to ~50 ms at M = 4 (its transmittance table: up to 65 hemispherical integrals
// per face, as evaluations need them), a specular one ~1 ms: the sweeps visit fewer values with rough faces.
struct Faces {
    const char* name;
    Boundary<double> top, bottom;
    bool rough() const { return top.rough() || bottom.rough(); }
};
std::vector<Faces> face_kinds() {
    return {
        {"smooth | smooth", SmoothDielectric<double>(1.0, 1.4), SmoothDielectric<double>(1.4, 1.0)},
        {"rough | rough", RoughDielectric<double>(0.3, 1.0, 1.4), RoughDielectric<double>(0.3, 1.4, 1.0)},
        {"rough | index matched", RoughDielectric<double>(0.3, 1.0, 1.4), Boundary<double>::index_matched(1.4)},
        {"index matched | index matched", Boundary<double>::index_matched(), Boundary<double>::index_matched()},
        {"smooth | white Lambertian floor", SmoothDielectric<double>(1.0, 1.4), Boundary<double>::lambertian(1.0, 1.4)},
        {"rough | black Lambertian floor", RoughDielectric<double>(0.3, 1.0, 1.4), Boundary<double>::lambertian(0.0, 1.4)},
    };
}

template <class F>
std::string thrown_message(F&& f) {
    try {
        f();
    } catch (const std::invalid_argument& e) {
        return e.what();
    } catch (const std::exception& e) {
        return std::string("<wrong exception type> ") + e.what();
    }
    return "<nothing thrown>";
}

// `f` throws std::invalid_argument whose what() contains `name` (the parameter).
#define CHECK_REJECTS(expression, name)                                                                    \
    do {                                                                                                   \
        const std::string message_ = thrown_message([&] { static_cast<void>(expression); });              \
        CHECK_MESSAGE(message_.find(name) != std::string::npos,                                            \
                      #expression " should throw std::invalid_argument naming " name ", got: " << message_); \
    } while (false)

// The BTDF's largest difference from `fine` at 18 exits (wi at cosine mu_i), relative to fine's largest value there.
double btdf_difference(const LayeredSurface<double>& layer, const LayeredSurface<double>& fine, double mu_i) {
    const Vec3<double> wi{std::sqrt(1 - mu_i * mu_i), 0, mu_i};
    double worst = 0, largest = 0;
    for (const double mu_o : {0.99, 0.9, 0.7, 0.5, 0.3, 0.1})
        for (const double phi : {0.0, 1.5, 3.1}) {
            const double s = std::sqrt(1 - mu_o * mu_o);
            const Vec3<double> wo{s * std::cos(phi), s * std::sin(phi), -mu_o};
            worst = std::fmax(worst, std::fabs(layer.btdf(wi, wo) - fine.btdf(wi, wo)));
            largest = std::fmax(largest, fine.btdf(wi, wo));
        }
    return worst / largest;
}

// The BTDF's integral over the exits for each incidence: mode 0 of fourier_coefficients on the Gauss cosines g.
std::vector<double> btdf_integrals(const LayeredSurface<double>& layer, const std::vector<double>& incidence,
                                   const stratum::Quadrature<double>& g) {
    const std::vector<double> a = layer.fourier_coefficients(LayerOutput::transmission, incidence, g.nodes);
    std::vector<double> out(incidence.size(), 0.0);
    for (std::size_t i = 0; i < incidence.size(); ++i)
        for (std::size_t j = 0; j < g.size(); ++j)
            out[i] += g.weights[j] * 2 * 3.141592653589793 * a[(i * g.size() + j) * static_cast<std::size_t>(layer.modes())];
    return out;
}

}  // namespace

TEST_CASE("optical thickness 0, 1e-300, 1e-12, huge and +infinity are accepted; negative and NaN rejected") {
    // +infinity is the documented semi-infinite slab (slab.hpp: tau in [0, +inf]).
    for (const Faces& faces : face_kinds())
        for (double albedo : {0.0, 0.5, 1.0})
            for (double tau : {0.0, 1e-300, denormal, 1e-12, 1e6, 1e300, huge, inf}) {
                if (faces.rough() && (albedo == 0.5 || tau == denormal || tau == 1e6 || tau == 1e300)) continue;
                const auto layer = solve_layer(Slab<double>(albedo, 0.5, tau), faces.top, faces.bottom, with_ordinates(4));
                check_surface(layer, std::string(faces.name) + ", albedo " + fmt(albedo) + ", tau " + fmt(tau));
            }
    // Continuity at both ends.
    for (const Faces& faces : face_kinds())
        for (double albedo : {0.0, 1.0}) {
            if (faces.rough() && albedo == 0) continue;
            auto at = [&](double tau) {
                const auto l = solve_layer(Slab<double>(albedo, 0.5, tau), faces.top, faces.bottom, with_ordinates(4));
                return std::vector<double>{l.reflectance(0.6).total(), l.transmittance(0.6), l.reflectance(0.2).total(),
                                           l.transmittance(0.2)};
            };
            const std::vector<double> zero = at(0.0), thin = at(1e-12), thick = at(1e300), semi = at(inf);
            INFO(std::string(faces.name) << ", albedo " << albedo);
            for (std::size_t i = 0; i < zero.size(); ++i) {
                CHECK(std::fabs(zero[i] - thin[i]) < 1e-9);
                CHECK(std::fabs(thick[i] - semi[i]) < 1e-12);
            }
        }
    for (double tau : {-1.0, -1e-300, -inf, not_a_number}) CHECK_REJECTS(Slab<double>(0.5, 0.5, tau), "optical_thickness");
    for (double tau : {-1.0, not_a_number}) CHECK_REJECTS(Slab<double>::from_one_minus_albedo(0.5, 0.5, tau), "optical_thickness");
    for (double x : {-0.1, 1.1, not_a_number, inf}) CHECK_REJECTS(Slab<double>::from_transparency(0.5, 0.5, x), "transparency");
    // The transparency's ends are the two ends of tau.
    CHECK(Slab<double>::from_transparency(0.5, 0.5, 0.0).optical_thickness() == inf);
    CHECK(Slab<double>::from_transparency(0.5, 0.5, 1.0).optical_thickness() == 0);
    CHECK(std::isfinite(Slab<double>::from_transparency(0.5, 0.5, denormal).optical_thickness()));
}

// Nearly empty lossless slabs between smooth faces that trap light (total internal reflection at both faces below
// the critical cosine): the trapped ordinates' losses are O(tau / mu), and a slab's eigen-solution carries absolute
// errors ~eps, so below some thickness rounding decides their sign. Found by review: R + T = 3.8e17 at tau = 1e-14,
// g = 0.999999 (delta-M scales tau to 3e-19; 16 ordinates), NaN on one half-range rule, 1.42 at tau = 5.6e-18, g = 0,
// 207 at tau = 3.2e-11, g = 0.999999, 3 ordinates, where slabs were solved as films only below eps mu_min on the
// unscaled thickness (1711 of 118800 such solves above 1 + 1e-9, against none now). Films below 1e5 eps mu_min
// of the scaled thickness (detail::film_limit): R + T = 1 to rounding, and a thinner slab is the film to O(tau).
TEST_CASE("nearly empty lossless slabs between faces that trap light conserve energy (found by review)") {
    const auto fluxes = [](int m, double g, double tau, bool split) {
        LayerOptions o = with_ordinates(m);
        o.critical_split = split;
        LayerRequest<double> r;
        r.outputs = LayerOutput::reflectance | LayerOutput::transmittance | LayerOutput::surface_reflection;
        return solve_layer(Slab<double>(1.0, g, tau), SmoothDielectric<double>(1.0, 1.5), SmoothDielectric<double>(1.5, 1.0), o, r);
    };
    for (int m : {3, 8, 13, 16})
        for (double g : {0.0, 0.999999})
            for (double tau : {5.62341325190349e-18, 1e-16, 1e-14, 3.16228e-13, 1e-12, 3.16228e-11, 1e-9, 1e-6})
                for (bool split : {true, false}) {
                    const auto layer = fluxes(m, g, tau, split), film = fluxes(m, g, 0.0, split);
                    for (double mu : {1.0, 0.8, 0.5, 0.2}) {
                        INFO("M = " << m << ", g = " << g << ", tau = " << tau << (split ? ", split" : ", one rule") << ", mu = " << mu);
                        const double r = layer.reflectance(mu).total(), t = layer.transmittance(mu);
                        REQUIRE(std::isfinite(r + t));
                        CHECK(std::fabs(r + t - 1) < 1e-12);
                        CHECK(std::fabs(r - film.reflectance(mu).total()) <= 2 * tau / 0.1 + 1e-14);  // (O(tau / mu))
                    }
                }
    // Above the film limit a thin slab keeps the light it traps: its fluence is O(1) as tau -> 0 (4.8096 at
    // tau = 1e-9, 16 ordinates; a film has 1.2247). At tau = 1e-11 (4e4 times the rounding it must beat) within
    // 2e-5 (measured 6e-6).
    const auto fluence = [](double tau) {
        LayerRequest<double> r;
        r.depths = {tau / 2};
        return solve_layer(Slab<double>(1.0, 0.0, tau), SmoothDielectric<double>(1.0, 1.5), SmoothDielectric<double>(1.5, 1.0),
                           with_ordinates(16), r)
            .depth_profile(0.5)[0]
            .fluence;
    };
    const double converged = fluence(1e-9);
    CHECK(converged > 4);
    CHECK(fluence(1e-11) == doctest::Approx(converged).epsilon(2e-5));
}

TEST_CASE("nearly specular rough faces lit at the normal: the BTDF integrates to the transmittance within the discretization (renderer sweep)") {
    // Faces of RMS slope 0.05: the refracted beam lies beyond the last ordinate. The specular spread extrapolated
    // there (4 points), which put negative shares on the ordinates below the last: the BTDF read them back negative
    // between 8 and 12 degrees, returned 0 there, and integrated to 0.92 (16 ordinates) and 0.91 (32) where the
    // transmittance is 0.743. Then the extrapolation carried only the share of the lobe the ordinates resolve (small
    // here) and the last ordinate the rest: 0.793 against 0.741 (+7.0%) and 0.766 against 0.742 (+3.2%), the linear
    // spread's cell at the pole not carrying the Gauss weight (the last ordinate read flat from it to mu = 1). Now the
    // spread above the last ordinate but one is linear to the last ordinate's value at mu = 1, at entry and exit alike:
    // +1.7% and +1.4% (README, known limitations; TabulatedBSDF::energy_error reports it).
    const double pi = 3.141592653589793;
    const stratum::Quadrature<double> g = stratum::gauss_legendre<double>(24);  // per band of mu_o, and in dphi
    const double bands[] = {0, 0.5, 0.8, 0.95, 0.99, 1};
    for (int m : {16, 32}) {
        LayerOptions o;
        o.ordinates = m;
        const LayeredSurface<double> layer = solve_layer(Slab<double>(1.0, 0.5, 1.0), RoughDielectric<double>(0.05, 1, 1.4),
                                                         RoughDielectric<double>(0.05, 1.4, 1), o);
        const Vec3<double> wi{0, 0, 1};
        double integral = 0, smallest = 1;
        for (int band = 0; band < 5; ++band)  // mu_o in (0, 1), dphi in (0, pi), doubled
            for (std::size_t a = 0; a < g.size(); ++a) {
                const double width = bands[band + 1] - bands[band];
                const double mu = bands[band] + width * (g.nodes[a] + 1) / 2, s = std::sqrt((1 - mu) * (1 + mu));
                for (std::size_t b = 0; b < g.size(); ++b) {
                    const double phi = pi * (g.nodes[b] + 1) / 2;
                    integral += width * g.weights[a] / 2 * pi * g.weights[b] / 2 * 2 * mu *
                                layer.btdf(wi, Vec3<double>{s * std::cos(phi), s * std::sin(phi), -mu});
                }
            }
        for (double degrees = 0; degrees <= 20; degrees += 1) {
            const double t = degrees * pi / 180;
            smallest = std::fmin(smallest, layer.btdf(wi, Vec3<double>{std::sin(t), 0, -std::cos(t)}));
        }
        CAPTURE(m);
        CHECK(smallest > 0);
        CHECK(integral / layer.transmittance(1) - 1 <= 0.02);
    }
}

TEST_CASE("one face rough, the other specular: the BTDF's unscattered first pass is exact at its angle (found by review)") {
    // The light let in that crosses the slab unscattered once leaves as the rough face's lobe: the discrete solution
    // held it on the ordinates and read it out by the exit's spread, and a lobe narrower than the ordinate spacing near
    // the normal came out inflated. Lit at the normal (albedo 0.9, g 0.5, tau 1, 16 ordinates), the BTDF integrated
    // (its mode 0 on 400 Gauss cosines: the azimuth exactly) to 1.25, 1.67, 1.61 times the transmittance for a rough
    // 0.3 top over a smooth bottom, a rough 0.1 top over an index-matched bottom and a smooth top over a rough 0.05
    // bottom; now to 1 + 1.7e-3, 1.2e-3, 1.5e-3 (and at mu = 0.87: 2.7e-3, 5.3e-3, 1.2e-3, where it was 2.4e-2,
    // 1.5e-2, 2.2e-2). Bounds 8e-3. And pointwise: at M = 16 within 6e-3 of the largest value of M = 64's BTDF at
    // 18 exit directions for the first two (measured 3.2e-4 and 3.9e-3 at the normal, 2.1e-3 and 3.3e-3 at mu 0.7;
    // against M = 96: 3.1e-4, 4.2e-3, 1.9e-3, 3.3e-3, and 7.8e-2 and 1.5 before; M = 64 solved for the BTDF alone
    // costs a fifth of M = 96's, which took 26 s of the sanitized suite); the exact pass itself integrates to
    // T_12 e^{-tau'/mu_t} T_23 (smooth top), checked.
    using B = Boundary<double>;
    struct Case {
        B top, bottom;
    };
    const Case cases[] = {{RoughDielectric<double>(0.3, 1.0, 1.4), SmoothDielectric<double>(1.4, 1.0)},
                          {RoughDielectric<double>(0.1, 1.0, 1.4), B::index_matched(1.4)},
                          {SmoothDielectric<double>(1.0, 1.4), RoughDielectric<double>(0.05, 1.4, 1.0)}};
    const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(400);
    const std::vector<double> incidence{1.0, 0.87};
    for (std::size_t c = 0; c < 3; ++c) {
        LayerOptions o;
        o.ordinates = 16;
        const auto layer = solve_layer(Slab<double>(0.9, 0.5, 1.0), cases[c].top, cases[c].bottom, o);
        const std::vector<double> integral = btdf_integrals(layer, incidence, g);
        for (std::size_t i = 0; i < incidence.size(); ++i) {
            const double mu = incidence[i];
            const double t = layer.transmittance(mu) - layer.direct_transmittance(mu) - layer.forward_peak_transmittance(mu);
            INFO("case " << c << ", mu " << mu << ": " << integral[i] << " against " << t);
            CHECK(std::fabs(integral[i] / t - 1) <= 8e-3);
        }
        if (c == 2) continue;
        o.ordinates = 64;
        LayerRequest<double> btdf_only;
        btdf_only.outputs = LayerOutput::transmission;
        const auto fine = solve_layer(Slab<double>(0.9, 0.5, 1.0), cases[c].top, cases[c].bottom, o, btdf_only);
        for (const double mu_i : {1.0, 0.7}) {
            INFO("case " << c << ", mu_i " << mu_i);
            CHECK(btdf_difference(layer, fine, mu_i) <= 6e-3);
        }
    }
}

TEST_CASE("the BTDF's unscattered first pass is exact across joints that refract (stacks of slabs of different indices)") {
    // As above, through air | 1.5 | 1.4 | air (slabs of tau 0.1 and 0.15, albedo 0.5: the first pass is most of the
    // BTDF): the pass crossed the joint through its operator on the ordinates (each ordinate's beam split over the two
    // around its Snell image) and came out spread: at M = 16 the BTDF was up to 6.2 times the largest value of M = 96's
    // off it (a smooth top over a rough 0.1 bottom at the normal), 0.23 (a rough 0.3 top over a smooth bottom), 0.43 (a
    // smooth top over a rough 0.3 bottom), and the first integrated to 1.37 times the transmittance at the normal. Now
    // the pass is taken out of the modes through the same operators and added along the Snell chain: measured
    // pointwise against M = 48 (solved for the BTDF alone; M = 96 gives as much) 2.6e-2, 2.9e-4, 5.6e-3; integrals
    // within 3.4e-3. Bounds: the measured x 1.5, integrals 8e-3.
    using B = Boundary<double>;
    struct Case {
        B top, bottom;
        double pointwise;
    };
    const Case cases[] = {{SmoothDielectric<double>(1.0, 1.5), RoughDielectric<double>(0.1, 1.4, 1.0), 4e-2},
                          {RoughDielectric<double>(0.3, 1.0, 1.5), SmoothDielectric<double>(1.4, 1.0), 4.5e-4},
                          {SmoothDielectric<double>(1.0, 1.5), RoughDielectric<double>(0.3, 1.4, 1.0), 8.5e-3}};
    const std::vector<Slab<double>> slabs{Slab<double>(0.5, 0.5, 0.1), Slab<double>(0.5, 0.3, 0.15)};
    const std::vector<B> joints{SmoothDielectric<double>(1.5, 1.4)};
    const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(400);
    const std::vector<double> incidence{1.0, 0.87};
    for (std::size_t c = 0; c < 3; ++c) {
        const auto layer = stratum::solve_stack(cases[c].top, slabs, joints, cases[c].bottom, with_ordinates(16));
        const std::vector<double> integral = btdf_integrals(layer, incidence, g);
        for (std::size_t i = 0; i < incidence.size(); ++i) {
            const double t = layer.transmittance(incidence[i]);
            INFO("case " << c << ", mu " << incidence[i] << ": " << integral[i] << " against " << t);
            CHECK(std::fabs(integral[i] / t - 1) <= 8e-3);
        }
        LayerRequest<double> btdf_only;
        btdf_only.outputs = LayerOutput::transmission;
        const auto fine = stratum::solve_stack(cases[c].top, slabs, joints, cases[c].bottom, with_ordinates(48), btdf_only);
        for (const double mu_i : {1.0, 0.7}) {
            INFO("case " << c << ", mu_i " << mu_i);
            CHECK(btdf_difference(layer, fine, mu_i) <= cases[c].pointwise);
        }
    }
}

TEST_CASE("the exact pass: a lobe narrow in azimuth does not ring, and a reused Workspace gives what a fresh one gives") {
    // A rough 0.1 top at 1 | 1.05 (a lobe nearly a delta) over a smooth bottom, lit at mu 0.7: taken as a Fourier series
    // cut to the solve's 32 modes the exact pass rang, 3.2 and 4.3 at 16 ordinates away from the lobe where the BTDF at
    // 96 ordinates is 0.07 and 0.09 (found by review); as a value, 0.0699 and 0.0983 against 0.0655 and 0.0940 (96
    // ordinates) and 0.0658 and 0.0944 (64, solved for the BTDF alone: the reference here, a fifth of 96's time).
    // A Workspace reused after ambient(), or for another layer, handed the pass a stale entry (25% off; found by review).
    using B = Boundary<double>;
    const auto make = [](int m, stratum::LayerRequest<double> request = {}) {
        LayerOptions o;
        o.ordinates = m;
        return solve_layer(Slab<double>(0.9, 0.5, 1.0), RoughDielectric<double>(0.1, 1.0, 1.05),
                           SmoothDielectric<double>(1.05, 1.0), o, request);
    };
    stratum::LayerRequest<double> btdf_only;
    btdf_only.outputs = LayerOutput::transmission;
    const auto coarse = make(16), fine = make(64, btdf_only);
    const double mu = 0.7;
    const Vec3<double> wi{std::sqrt(1 - mu * mu), 0, mu};
    for (const double phi : {0.3, 1.5}) {  // (the lobe is at phi = pi)
        const double s = std::sqrt(1 - mu * mu);
        const Vec3<double> wo{s * std::cos(phi), s * std::sin(phi), -mu};
        INFO("phi " << phi << ": " << coarse.btdf(wi, wo) << " against " << fine.btdf(wi, wo));
        CHECK(std::fabs(coarse.btdf(wi, wo) - fine.btdf(wi, wo)) <= 0.1 * fine.btdf(wi, wo));
    }
    stratum::LayerRequest<double> request;
    request.incidence = {mu};  // (a cached field: no entry computed with it)
    const auto a = make(16, request);
    const auto b = solve_layer(Slab<double>(0.5, 0.2, 2.0), RoughDielectric<double>(0.3, 1.0, 1.4), B::index_matched(1.4),
                               LayerOptions{}, request);
    for (const double mu_o : {0.95, 0.7, 0.3}) {
        const Vec3<double> wo{std::sqrt(1 - mu_o * mu_o), 0, -mu_o};
        const double fresh_a = a.btdf(wi, wo), fresh_b = b.btdf(wi, wo);
        LayeredSurface<double>::Workspace ws;
        (void)a.btdf(wi, wo, ws);
        (void)a.ambient(Vec3<double>{0, 0, 1}, ws);
        CHECK(a.btdf(wi, wo, ws) == fresh_a);
        CHECK(b.btdf(wi, wo, ws) == fresh_b);
        CHECK(a.btdf(wi, wo, ws) == fresh_a);
    }
}

TEST_CASE("a Workspace reuses an incidence's entry (and field) only for its own layer and incidence") {
    // What an incidence computed on the fly lets into the layer (the entry: the top's couplings to the ordinates) is
    // kept in the Workspace, and between specular faces the incidence's field, so that calls at one incidence share
    // them (a 64 x 64 integral of the BRDF and BTDF at three incidences between smooth faces: 1.7 s -> 0.08 s). Each
    // value below must be the fresh Workspace's: the keys hold the layer and the incidence (and the modes: ambient()
    // at an exit cosine equal to the next incidence leaves a field of mode 0 alone, which the BRDF must not take;
    // found by review, 23 times the value in a stack). Rough, smooth and index-matched faces; the exact pass (a rough
    // top over a smooth bottom); stacks with refracting joints (a specular top over them: the joints' mirror); a layer
    // and its copy.
    LayerOptions o;
    o.ordinates = 8;
    const Slab<double> slab(0.9, 0.5, 1.0);
    std::vector<LayeredSurface<double>> layers;
    layers.push_back(solve_layer(slab, SmoothDielectric<double>(1.0, 1.4), SmoothDielectric<double>(1.4, 1.0), o));
    layers.push_back(solve_layer(Slab<double>(0.5, 0.2, 2.0), SmoothDielectric<double>(1.0, 1.5),
                                 stratum::Boundary<double>::index_matched(1.5), o));
    layers.push_back(solve_layer(slab, RoughDielectric<double>(0.3, 1.0, 1.4), RoughDielectric<double>(0.3, 1.4, 1.0), o));
    layers.push_back(solve_layer(Slab<double>(0.5, 0.2, 2.0), RoughDielectric<double>(0.2, 1.0, 1.5),
                                 SmoothDielectric<double>(1.5, 1.0), o));
    layers.push_back(layers[2]);
    const std::vector<Slab<double>> two{Slab<double>(0.5, 0.5, 0.1), Slab<double>(0.5, 0.3, 0.15)};
    const std::vector<stratum::Boundary<double>> joint{SmoothDielectric<double>(1.5, 1.4)};
    layers.push_back(stratum::solve_stack(SmoothDielectric<double>(1.0, 1.5), two, joint, RoughDielectric<double>(0.3, 1.4, 1.0), o));
    layers.push_back(stratum::solve_stack(SmoothDielectric<double>(1.0, 1.5), two, joint, SmoothDielectric<double>(1.4, 1.0), o));
    const Vec3<double> wo_up{0.3, 0.2, std::sqrt(0.87)}, wo_down{0.3, -0.4, -std::sqrt(0.75)};
    LayeredSurface<double>::Workspace ws;
    int checked = 0;
    for (const double mu : {0.6, 0.6, 0.9, 0.6})
        for (const std::size_t i : {0u, 1u, 0u, 2u, 3u, 2u, 4u, 2u, 5u, 6u, 5u}) {
            const LayeredSurface<double>& layer = layers[i];
            const Vec3<double> wi{-std::sqrt(1 - mu * mu), 0, mu}, sky{0, std::sqrt(1 - mu * mu), mu};
            INFO("mu " << mu << ", layer " << i);
            CHECK(layer.ambient(sky, ws) == layer.ambient(sky));
            CHECK(layer.subsurface_brdf(wi, wo_up, ws) == layer.subsurface_brdf(wi, wo_up));
            CHECK(layer.btdf(wi, wo_down, ws) == layer.btdf(wi, wo_down));
            checked += layer.subsurface_brdf(wi, wo_up) > 0 && layer.btdf(wi, wo_down) > 0;
        }
    CHECK(checked == 44);
}

TEST_CASE("a specular top over a rough bottom: the BRDF's pass reflected once by the bottom is exact at its angles") {
    // The beam let in, reflected once by a nearly specular rough bottom (RMS slope 0.05) and leaving unscattered: read
    // out between the ordinates the BRDF was 18% (mu_i 0.7) off the largest value of the BRDF at 96 ordinates at 16
    // ordinates and 7.3% at 32; taken at its true angles (the bottom's lobe, attenuated both ways and refracted out
    // through the top), 1.7e-2 / 1.6e-2 / 7.0e-3 at 16 and 1.2e-3 / 2.4e-3 / 1.1e-3 at 32 (mu_i 1 / 0.7 / 0.3;
    // the reference taken the same way; read out between the ordinates the 96 ordinates' BRDF itself was 3.2% off).
    // Bounds: the measured x 1.5.
    // (The reference solved for the subsurface BRDF alone. At 64 ordinates it is too coarse for the check at 32:
    // 4.3e-3 at mu_i 0.7.)
    const Boundary<double> top = SmoothDielectric<double>(1.0, 1.4), bottom = RoughDielectric<double>(0.05, 1.4, 1.0);
    LayerOptions o;
    o.ordinates = 96;
    LayerRequest<double> brdf_only;
    brdf_only.outputs = LayerOutput::subsurface_reflection;
    const auto fine = solve_layer(Slab<double>(0.9, 0.5, 1.0), top, bottom, o, brdf_only);
    for (const int m : {16, 32}) {
        o.ordinates = m;
        const auto layer = solve_layer(Slab<double>(0.9, 0.5, 1.0), top, bottom, o);
        for (const double mu_i : {1.0, 0.7, 0.3}) {
            const Vec3<double> wi{std::sqrt(1 - mu_i * mu_i), 0, mu_i};
            double worst = 0, largest = 0;
            for (const double mu_o : {0.99, 0.9, 0.7, 0.5, 0.3, 0.1})
                for (const double phi : {0.0, 1.5, 3.1}) {
                    const double s = std::sqrt(1 - mu_o * mu_o);
                    const Vec3<double> wo{s * std::cos(phi), s * std::sin(phi), mu_o};
                    worst = std::fmax(worst, std::fabs(layer.subsurface_brdf(wi, wo) - fine.subsurface_brdf(wi, wo)));
                    largest = std::fmax(largest, fine.subsurface_brdf(wi, wo));
                }
            INFO("M " << m << ", mu_i " << mu_i << ": " << worst / largest);
            CHECK(worst <= (m == 16 ? 2.6e-2 : 3.6e-3) * largest);
        }
    }
}

TEST_CASE("a beam at normal incidence through a specular top is extrapolated to beyond the last ordinate (found by review)") {
    // A specular top (index matched or 1 | 1.4) over a rough 1.4 | 1 bottom: the beam is spread over the ordinates.
    // Placed on the last ordinate instead of beyond it, T at normal incidence (RMS slope 0.3, index-matched top) was
    // off by 4.4e-3 at 8 ordinates and 3.7e-4 at 16 from 64 ordinates'. Extrapolated from the last two ordinates: over
    // these 12 layers the worst error in T or R_sub measured 6.5e-4 at 8 ordinates and 3.0e-4 at 16 (from 4 points, as
    // before a review sweep found the next test's defect: 1.7e-3 at 8, from RMS slopes 0.03 and 0.05), and T of the
    // first case 7.8e-6 off at 16 (1.7e-5 from 4 points).
    double worst8 = 0, worst16 = 0;
    for (double sigma : {0.03, 0.05, 0.1, 0.2, 0.3, 0.5})
        for (bool smooth_top : {false, true}) {
            const auto solve = [&](int m) {
                LayerOptions o;
                o.ordinates = m;
                LayerRequest<double> r;
                r.incidence = {1.0};
                r.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
                const Boundary<double> top = smooth_top ? Boundary<double>(SmoothDielectric<double>(1, 1.4))
                                                        : Boundary<double>::index_matched(1.4);
                return solve_layer(Slab<double>(0.9, 0.8, std::log(2.0)), top, RoughDielectric<double>(sigma, 1.4, 1), o, r);
            };
            const LayeredSurface<double> reference = solve(64);
            const auto error = [&](const LayeredSurface<double>& l) {
                return std::fmax(std::fabs(l.transmittance(1) - reference.transmittance(1)),
                                 std::fabs(l.reflectance(1).subsurface - reference.reflectance(1).subsurface));
            };
            worst8 = std::fmax(worst8, error(solve(8)));
            const LayeredSurface<double> sixteen = solve(16);
            worst16 = std::fmax(worst16, error(sixteen));
            if (sigma == 0.3 && !smooth_top) CHECK(std::fabs(sixteen.transmittance(1) - reference.transmittance(1)) <= 5e-5);
        }
    CHECK(worst8 <= 7e-4);
    CHECK(worst16 <= 3.5e-4);
}

TEST_CASE("a beam extrapolated beyond the last ordinate reflects no negative light from a nearly specular bottom (found by review)") {
    // 1 | 1.1 over a rough 1.1 | 1 bottom of RMS slope 0.03 around an empty or thin slab, normal incidence: the
    // 4-point extrapolation reached the ordinate at 54 degrees at 8 ordinates, where the bottom's reflectance (critical
    // angle 65 degrees) is ten times its value at the normal; its negative share there made R_sub -2.3e-3, returned as
    // 0, and R + T = 1.0017 (1 + 1.2e-6 at 9 and 10 ordinates). Linear from the last two ordinates: R + T = 1 - 1.6e-11
    // at tau 0 and R_sub within 2.4e-5 of 32 ordinates'.
    for (double tau : {0.0, 1e-4, 1e-3})
        for (double albedo : {0.0, 1.0})
            for (int m : {8, 9, 10}) {
                const auto solve = [&](int ordinates) {
                    return solve_layer(Slab<double>(albedo, 0.5, tau), SmoothDielectric<double>(1, 1.1),
                                       RoughDielectric<double>(0.03, 1.1, 1), with_ordinates(ordinates));
                };
                const LayeredSurface<double> layer = solve(m);
                const auto r = layer.reflectance(1);
                CAPTURE(tau);
                CAPTURE(albedo);
                CAPTURE(m);
                CHECK(r.total() + layer.transmittance(1) <= 1 + 1e-9);
                CHECK(r.subsurface == doctest::Approx(solve(32).reflectance(1).subsurface).epsilon(0.02));
            }
}

TEST_CASE("single-scattering albedo 0 and 1 and asymmetry 0, +-(1 - 1e-12) are accepted; g = +-1 rejected") {
    for (const Faces& faces : face_kinds())
        for (double albedo : {0.0, 1.0})
            for (double g : {0.0, 1 - 1e-12, -(1 - 1e-12), 0.5, -0.5})
                for (bool delta_m : {true, false})
                    for (double tau : {1.0, inf}) {
                        if (faces.rough() && (tau == inf || std::fabs(g) == 0.5)) continue;
                        const auto layer = solve_layer(Slab<double>(albedo, g, tau), faces.top, faces.bottom,
                                                       with_ordinates(4, 0, delta_m));
                        // Documented limitation (README, known limitations): a phase function too peaked for the
                        // ordinates and not delta-M scaled (|g| > 0.9 with delta-M off, or g < -0.9, whose
                        // backward peak delta-M cannot remove) has a truncated expansion that is negative in
                        // places; the slab solver regularizes it, and the negative (Gibbs) reflectance that
                        // remains is returned as 0, which creates energy. Measured here: 2.9e-4 (rough | index
                        // matched, g = 1 - 1e-12 without delta-M, albedo 1, tau 1, mu = 1); elsewhere up to 16%.
                        const bool aliased = std::fabs(g) > 0.9 && (!delta_m || g < 0);
                        check_surface(layer,
                                      std::string(faces.name) + ", albedo " + fmt(albedo) + ", g " + fmt(g) + ", delta-M " +
                                          (delta_m ? "on" : "off") + ", tau " + fmt(tau),
                                      aliased ? 1e-3 : slack);
                    }
    // Albedo 1 - 1e-300 rounds to 1; from_one_minus_albedo keeps tiny absorptions.
    for (double om : {0.0, denormal, 1e-300, 1e-17, 1.0})
        check_surface(solve_layer(Slab<double>::from_one_minus_albedo(om, 0.5, 3.0), SmoothDielectric<double>(1.0, 1.4),
                                  SmoothDielectric<double>(1.4, 1.0), with_ordinates(4)),
                      "1 - albedo " + fmt(om));
    for (double g : {1.0, -1.0, 1 + 1e-12, -1.5, inf, -inf, not_a_number}) CHECK_REJECTS(Slab<double>(0.5, g, 1.0), "g =");
    for (double albedo : {-1e-300, -0.1, 1 + 1e-12, inf, not_a_number}) CHECK_REJECTS(Slab<double>(albedo, 0.5, 1.0), "stratum: albedo =");
    for (double om : {-1e-300, 1.1, not_a_number}) CHECK_REJECTS(Slab<double>::from_one_minus_albedo(om, 0.5, 1.0), "one_minus_albedo");
    CHECK_REJECTS(Slab<double>::from_transparency(not_a_number, 0.5, 0.5), "stratum: albedo =");
}

TEST_CASE("boundaries: roughness from 1e-300 to 1e10, index ratios 1 and 1 +- 1e-12, smooth and index matched") {
    const Slab<double> slab(0.9, 0.5, 1.0);
    for (double sigma : {1e-8, 1e-30, 1e-300, 10.0, 1e3, 1e10}) {
        if (sigma < 1)  // (huge sigma: ~0.5 s a face for the transmittance table; one face below is enough)
            check_surface(solve_layer(slab, RoughDielectric<double>(sigma, 1.0, 1.4),
                                      RoughDielectric<double>(sigma, 1.4, 1.0), with_ordinates(4)),
                          "rough | rough, sigma " + fmt(sigma));
        check_surface(solve_layer(slab, RoughDielectric<double>(sigma, 1.0, 1.4), SmoothDielectric<double>(1.4, 1.0),
                                  with_ordinates(3)),
                      "rough | smooth, sigma " + fmt(sigma));
    }
    // sigma = 0: the smooth limit, once RoughDielectric accepts it.
    bool sigma_zero = true;
    try {
        static_cast<void>(RoughDielectric<double>(0.0, 1.0, 1.4));
    } catch (const std::invalid_argument& e) {
        sigma_zero = false;
        MESSAGE("skipped: RoughDielectric<double>(0.0, 1.0, 1.4) throws (" << e.what() << ")");
    }
    if (sigma_zero) {
        const auto rough0 = solve_layer(slab, RoughDielectric<double>(0.0, 1.0, 1.4), RoughDielectric<double>(0.0, 1.4, 1.0),
                                        with_ordinates(4));
        const auto smooth = solve_layer(slab, SmoothDielectric<double>(1.0, 1.4), SmoothDielectric<double>(1.4, 1.0),
                                        with_ordinates(4));
        check_surface(rough0, "rough | rough, sigma 0");
        // ... and it is exactly the smooth layer.
        for (double mu : {1.0, 0.5, 0.1}) {
            CHECK(rough0.reflectance(mu).total() == doctest::Approx(smooth.reflectance(mu).total()).epsilon(1e-14));
            CHECK(rough0.transmittance(mu) == doctest::Approx(smooth.transmittance(mu)).epsilon(1e-14));
        }
    }
    // Index ratios 1 and 1 +- 1e-12 on either face, rough and smooth; the layer's index n2 = eta.
    for (double eta : {1.0, 1 + 1e-12, 1 - 1e-12}) {
        check_surface(solve_layer(slab, RoughDielectric<double>(0.3, 1.0, eta), RoughDielectric<double>(0.3, eta, 1.0),
                                  with_ordinates(4)),
                      "rough | rough, n2 = " + fmt(eta));
        check_surface(solve_layer(slab, SmoothDielectric<double>(1.0, eta), SmoothDielectric<double>(eta, 1.0),
                                  with_ordinates(4)),
                      "smooth | smooth, n2 = " + fmt(eta));
        check_surface(solve_layer(slab, RoughDielectric<double>(0.3, 1.0, 1.4), RoughDielectric<double>(0.3, 1.4, 1.4 * eta),
                                  with_ordinates(4)),
                      "rough | rough, n3 / n2 = " + fmt(eta));
        check_surface(solve_layer(slab, SmoothDielectric<double>(1.4, 1.4 * eta), Boundary<double>::index_matched(1.4 * eta),
                                  with_ordinates(4)),
                      "smooth | index matched, n2 / n1 = " + fmt(eta));
    }
    // Index matched, and the mixed pairs; a layer less dense than the medium above (total internal reflection
    // of light from above is impossible, but the layer's own escape cone is the whole hemisphere).
    check_surface(solve_layer(slab, Boundary<double>::index_matched(1.4), RoughDielectric<double>(0.3, 1.4, 1.0),
                              with_ordinates(4)),
                  "index matched | rough");
    check_surface(solve_layer(slab, SmoothDielectric<double>(1.0, 1.4), RoughDielectric<double>(0.3, 1.4, 1.0),
                              with_ordinates(4)),
                  "smooth | rough");
    check_surface(solve_layer(slab, SmoothDielectric<double>(1.4, 1.0), SmoothDielectric<double>(1.0, 1.4),
                              with_ordinates(4)),
                  "smooth 1.4 | 1.0 | 1.4");
    check_surface(solve_layer(slab, RoughDielectric<double>(0.3, 1.4, 1.0), RoughDielectric<double>(0.3, 1.0, 2.5),
                              with_ordinates(4)),
                  "rough 1.4 | 1.0 | 2.5");
    // Rejected: NaN, negative, zero and infinite indices, NaN, negative and infinite roughness.
    for (double eta : {0.0, -1.0, inf, not_a_number}) {
        CHECK_REJECTS(SmoothDielectric<double>(eta, 1.4), "eta_above");
        CHECK_REJECTS(SmoothDielectric<double>(1.0, eta), "eta_below");
        CHECK_REJECTS(RoughDielectric<double>(0.3, eta, 1.4), "eta_above");
        CHECK_REJECTS(RoughDielectric<double>(0.3, 1.0, eta), "eta_below");
        CHECK_REJECTS(Boundary<double>::index_matched(eta), "eta_above");
    }
    for (double sigma : {-1.0, -1e-300, inf, not_a_number}) CHECK_REJECTS(RoughDielectric<double>(sigma, 1.0, 1.4), "sigma");
}

TEST_CASE("a nearly matched face's critical cosine too close to 0 for the ordinates is not a cut (found by review)") {
    // A bottom face 1.4 | 1.4 (1 - 1e-12) has its critical cosine at 1.4e-6: as a cut it took 4 of 16 ordinates
    // (the lower panels' share) for a cone that holds no light, and a semi-infinite layer's BRDF, which the bottom
    // cannot touch, came out 0.5245 instead of 0.2739 (wi mu 0.3, M = 16; the BTDF at tau 1 integrated to 15% more
    // than the transmittance). Now the layer equals the one with an index-matched bottom to rounding, at any
    // thickness, and so does the same face as the top.
    const double e = 1 - 1e-12;
    const Vec3<double> wi = {std::sqrt(1 - 0.09), 0, 0.3}, wo = {-0.3, 0.1, std::sqrt(1 - 0.1)};
    for (const double tau : {inf, 1.0})
        for (const int m : {8, 16, 24}) {
            const auto near = solve_layer(Slab<double>(1.0, 0.9, tau), SmoothDielectric<double>(1.0, 1.4),
                                          SmoothDielectric<double>(1.4, 1.4 * e), with_ordinates(m));
            const auto matched = solve_layer(Slab<double>(1.0, 0.9, tau), SmoothDielectric<double>(1.0, 1.4),
                                             Boundary<double>::index_matched(1.4), with_ordinates(m));
            INFO("tau " << tau << ", M = " << m);
            CHECK(near.quadrature().nodes == matched.quadrature().nodes);
            CHECK(near.subsurface_brdf(wi, wo) == doctest::Approx(matched.subsurface_brdf(wi, wo)).epsilon(1e-9));
            if (tau == 1.0) {
                const Vec3<double> down{wo.x, wo.y, -wo.z};
                CHECK(near.btdf(wi, down) == doctest::Approx(matched.btdf(wi, down)).epsilon(1e-9));
            }
        }
    const auto top = solve_layer(Slab<double>(0.9, 0.5, 1.0), SmoothDielectric<double>(1.4 / e, 1.4),
                                 SmoothDielectric<double>(1.4, 1.0), with_ordinates(16));
    const auto top_matched = solve_layer(Slab<double>(0.9, 0.5, 1.0), Boundary<double>::index_matched(1.4),
                                         SmoothDielectric<double>(1.4, 1.0), with_ordinates(16));
    CHECK(top.quadrature().nodes == top_matched.quadrature().nodes);
}

TEST_CASE("one ordinate inside a smooth face's trapped cone is refused (found by review)") {
    // A 1 | 1.4 top traps cosines below 0.7, where the single ordinate (0.5) lies: no scattered light left the layer
    // (a lossless slab: R_sub 0 and R + T 0.072 at tau = inf, a fluence of 2.2e16 inside at tau 1 between Fresnel
    // faces). Refused with the reason; two ordinates (split at the critical cosine) solve it, and so does one under
    // faces that let it leave (index ratio up to 1.155: critical cosine up to 0.5; rough faces), or where only the
    // top face's own reflection is asked for (no scattered light).
    const Slab<double> lossless(1.0, 0.0, inf);
    CHECK_REJECTS(solve_layer(lossless, SmoothDielectric<double>(1.0, 1.4), Boundary<double>::index_matched(1.4),
                              with_ordinates(1)),
                  "options.ordinates = 1");
    CHECK_REJECTS(solve_layer(Slab<double>(0.9, 0.5, 1.0), Boundary<double>::index_matched(1.4),
                              SmoothDielectric<double>(1.4, 1.0), with_ordinates(1)),
                  "bottom face");
    // A joint traps the denser slab's light as well: 1 | 1.1 | 1.4 | 1.1 | 1 (the middle slab's joints at critical
    // cosine 0.62) lost 87% of the light, R + T = 0.135 (found by review).
    const std::vector<Slab<double>> three = {Slab<double>(1.0, 0.0, 0.1), Slab<double>(1.0, 0.0, 1.0), Slab<double>(1.0, 0.0, 0.1)};
    const std::vector<Boundary<double>> joints = {SmoothDielectric<double>(1.1, 1.4), SmoothDielectric<double>(1.4, 1.1)};
    CHECK_REJECTS(stratum::solve_stack(SmoothDielectric<double>(1.0, 1.1), three, joints, SmoothDielectric<double>(1.1, 1.0),
                                       with_ordinates(1)),
                  "interior[0] face");
    const auto two = solve_layer(lossless, SmoothDielectric<double>(1.0, 1.4), Boundary<double>::index_matched(1.4),
                                 with_ordinates(2));
    CHECK(two.reflectance(0.5).total() == doctest::Approx(1.0).epsilon(1e-12));
    const auto mild = solve_layer(lossless, SmoothDielectric<double>(1.0, 1.15), Boundary<double>::index_matched(1.15),
                                  with_ordinates(1));
    CHECK(mild.reflectance(0.5).total() == doctest::Approx(1.0).epsilon(1e-12));
    LayerRequest<double> surface;
    surface.outputs = LayerOutput::surface_reflection;
    CHECK(solve_layer(lossless, SmoothDielectric<double>(1.0, 1.4), Boundary<double>::index_matched(1.4),
                      with_ordinates(1), surface)
              .reflectance(0.5)
              .surface == doctest::Approx(SmoothDielectric<double>(1.0, 1.4).reflectance(0.5)));
}

TEST_CASE("options: ordinates 1, 2, 3 and one mode are accepted; 0 and negative counts rejected") {
    const Slab<double> slab(0.9, 0.5, 1.0);
    for (const Faces& faces : face_kinds())
        for (int m : {1, 2, 3})
            for (int modes : {0, 1})
                for (double tau : {1.0, inf})
                    if ((!faces.rough() || tau == 1.0) &&
                        !(m == 1 && std::string(faces.name).rfind("smooth", 0) == 0))  // (refused: the case above)
                        check_surface(solve_layer(Slab<double>(0.9, 0.5, tau), faces.top, faces.bottom, with_ordinates(m, modes)),
                                  std::string(faces.name) + ", M = " + std::to_string(m) + ", modes " +
                                      std::to_string(modes) + ", tau " + fmt(tau));
    // Non-default discretization choices.
    for (const Faces& faces : face_kinds()) {
        LayerOptions o = with_ordinates(3, 0, false);
        o.renormalization = stratum::Renormalization::none;
        o.specular_transmission = stratum::SpecularTransmission::pointwise;
        check_surface(solve_layer(slab, faces.top, faces.bottom, o), std::string(faces.name) + ", no renormalization");
    }
    const Boundary<double> top = RoughDielectric<double>(0.3, 1.0, 1.4), bottom = SmoothDielectric<double>(1.4, 1.0);
    // (4097 and 2^30: 2^30 threw std::length_error from an allocation; found by a review sweep)
    for (int m : {0, -1, INT_MIN, 4097, 1 << 30}) CHECK_REJECTS(solve_layer(slab, top, bottom, with_ordinates(m)), "options.ordinates");
    for (int k : {-1, INT_MIN, 8193, 1 << 30}) CHECK_REJECTS(solve_layer(slab, top, bottom, with_ordinates(3, k)), "options.modes");
    {  // enumerations from out-of-range integers (used silently: Renormalization(99) changed R from 0.1407 to 0.1179)
        LayerOptions o = with_ordinates(3);
        o.renormalization = static_cast<stratum::Renormalization>(99);
        CHECK_REJECTS(solve_layer(slab, top, bottom, o), "options.renormalization");
        o = with_ordinates(3);
        o.specular_transmission = static_cast<stratum::SpecularTransmission>(99);
        CHECK_REJECTS(solve_layer(slab, top, bottom, o), "options.specular_transmission");
    }
    {  // a depth of inf in a semi-infinite layer (refused naming an internal thickness, "optical_thickness = -nan")
        LayerRequest<double> r;
        r.depths = {1.0, std::numeric_limits<double>::infinity()};
        CHECK_REJECTS(solve_layer(Slab<double>(0.9, 0.5, std::numeric_limits<double>::infinity()), top, bottom,
                                  with_ordinates(4), r),
                      "request.depths[1]");
    }
    for (int n : {1, 33, INT_MIN}) {
        LayerOptions o = with_ordinates(3);
        o.hemispherical_nodes = n;
        CHECK_REJECTS(solve_layer(slab, top, bottom, o), "options.hemispherical_nodes");
    }
    for (int n : {1, 0, INT_MIN, 1025, 1 << 30}) {
        LayerOptions o = with_ordinates(3);
        o.azimuthal_points = n;
        CHECK_REJECTS(solve_layer(slab, top, bottom, o), "options.azimuthal_points");
    }
}

TEST_CASE("cheaper integrals for rough faces: hemispherical_nodes and azimuthal_points change the result within their stated error") {
    // Stam's skin layer at 16 ordinates; the fluxes and the BRDF with the renormalization's integrals at 10 nodes
    // (5.8e-7, LayerOptions) and the azimuthal rule at 12 points (~5e-7), against the defaults (16 and 24).
    const Slab<double> slab(0.9, 0.8, std::log(2.0));
    const Boundary<double> top = RoughDielectric<double>(0.3, 1.0, 1.4), bottom = RoughDielectric<double>(0.3, 1.4, 1.0);
    LayerRequest<double> r;
    r.incidence = {0.3, 0.8};
    const auto exact = solve_layer(slab, top, bottom, with_ordinates(16), r);
    LayerOptions cheap = with_ordinates(16);
    cheap.hemispherical_nodes = 10;
    cheap.azimuthal_points = 12;
    const auto fast = solve_layer(slab, top, bottom, cheap, r);
    double worst = 0;
    for (const double mu : r.incidence) {
        worst = std::max({worst, std::fabs(fast.reflectance(mu).subsurface - exact.reflectance(mu).subsurface),
                          std::fabs(fast.transmittance(mu) - exact.transmittance(mu))});
        const stratum::Vec3<double> wi{std::sqrt(1 - mu * mu), 0.0, mu}, wo{0.0, 0.6, 0.8};
        worst = std::max(worst, std::fabs(fast.subsurface_brdf(wi, wo) - exact.subsurface_brdf(wi, wo)) * mu * wo.z);
    }
    INFO("worst difference " << worst);
    CHECK(worst > 0);       // (the knobs are used)
    CHECK(worst < 1e-6);    // (within their stated errors; measured 6.6e-8)
}

TEST_CASE("requests: incidences 1, 1e-300 and denormal are accepted and cached; 0, > 1, NaN and negative rejected") {
    const Slab<double> slab(0.9, 0.5, 1.0);
    for (const Faces& faces : face_kinds()) {
        if (faces.rough() && faces.bottom.rough_interface() == std::nullopt) continue;  // rough | index matched
        const auto plain = solve_layer(slab, faces.top, faces.bottom, with_ordinates(4));
        LayerRequest<double> r;
        r.incidence = {1.0, 1e-300, denormal, 0.5, 0.5};
        const auto cached = solve_layer(slab, faces.top, faces.bottom, with_ordinates(4), r);
        check_surface(cached, std::string(faces.name) + ", cached incidences");
        for (double mu : r.incidence) {
            INFO(std::string(faces.name) << ", mu = " << mu);
            CHECK(cached.reflectance(mu).total() == doctest::Approx(plain.reflectance(mu).total()).epsilon(1e-14));
            CHECK(cached.transmittance(mu) == doctest::Approx(plain.transmittance(mu)).epsilon(1e-14));
            const Vec3<double> wi{std::sqrt((1 - mu) * (1 + mu)), 0, mu}, wo = direction(0.5, 1.0);
            CHECK(cached.brdf(wi, wo) == doctest::Approx(plain.brdf(wi, wo)).epsilon(1e-14));
            CHECK(cached.btdf(wi, flip(wo)) == doctest::Approx(plain.btdf(wi, flip(wo))).epsilon(1e-14));
        }
        // A tolerance and a mode cap at their extremes; the outputs one at a time and none at all.
        for (double tol : {denormal, 1e-300, 0.5, 1 - 1e-16}) {
            if (faces.rough() && (tol == 1e-300 || tol == 1 - 1e-16)) continue;
            LayerRequest<double> t;
            t.tolerance = tol;
            check_surface(solve_layer(slab, faces.top, faces.bottom, with_ordinates(4), t),
                          std::string(faces.name) + ", tolerance " + fmt(tol));
            t.outputs = LayerOutput::subsurface_reflection;  // lets a thick slab be solved as semi-infinite
            check_surface(solve_layer(Slab<double>(0.9, 0.5, 40.0), faces.top, faces.bottom, with_ordinates(4), t),
                          std::string(faces.name) + ", reflection only, tau 40, tolerance " + fmt(tol));
        }
        LayerRequest<double> cap;
        cap.max_modes = 1;
        check_surface(solve_layer(slab, faces.top, faces.bottom, with_ordinates(4), cap),
                      std::string(faces.name) + ", max_modes 1");
        for (LayerOutput o : {LayerOutput::surface_reflection, LayerOutput::subsurface_reflection, LayerOutput::transmission,
                              LayerOutput::ambient, LayerOutput::operators, static_cast<LayerOutput>(0)}) {
            LayerRequest<double> one;
            one.outputs = o;
            const auto layer = solve_layer(slab, faces.top, faces.bottom, with_ordinates(3), one);
            check_surface(layer, std::string(faces.name) + ", outputs " + std::to_string(static_cast<unsigned>(o)));
            // What was not requested evaluates to 0.
            const Vec3<double> wi = direction(0.8, 0.3), wo = direction(0.5, 1.0);
            if (!includes(o, LayerOutput::subsurface_reflection)) {
                CHECK(layer.subsurface_brdf(wi, wo) == 0);
                CHECK(layer.reflectance(0.5).subsurface == 0);
            }
            if (!includes(o, LayerOutput::transmission)) {
                CHECK(layer.btdf(wi, flip(wo)) == 0);
                CHECK(layer.transmittance(0.5) == 0);
            }
            if (!includes(o, LayerOutput::ambient)) CHECK(layer.ambient(wo) == 0);
        }
    }
    const Boundary<double> top = RoughDielectric<double>(0.3, 1.0, 1.4), bottom = SmoothDielectric<double>(1.4, 1.0);
    for (double mu : {0.0, -0.0, -denormal, -0.5, std::nextafter(1.0, 2.0), 2.0, inf, -inf, not_a_number}) {
        LayerRequest<double> r;
        r.incidence = {0.5, mu};
        CHECK_REJECTS(solve_layer(slab, top, bottom, with_ordinates(3), r), "request.incidence[1]");
    }
    for (double tol : {-denormal, -1.0, 1.0, inf, not_a_number}) {
        LayerRequest<double> r;
        r.tolerance = tol;
        CHECK_REJECTS(solve_layer(slab, top, bottom, with_ordinates(3), r), "request.tolerance");
    }
    for (int k : {-1, INT_MIN}) {
        LayerRequest<double> r;
        r.max_modes = k;
        CHECK_REJECTS(solve_layer(slab, top, bottom, with_ordinates(3), r), "request.max_modes");
    }
}

TEST_CASE("solve_stack: extreme slabs and every kind of interior boundary; inconsistent stacks rejected") {
    const Boundary<double> top = RoughDielectric<double>(0.3, 1.0, 1.4), bottom = RoughDielectric<double>(0.3, 1.33, 1.0);
    const Boundary<double> smooth_top = SmoothDielectric<double>(1.0, 1.4), smooth_bottom = SmoothDielectric<double>(1.33, 1.0);
    const std::vector<Boundary<double>> interiors = {RoughDielectric<double>(0.2, 1.4, 1.33), SmoothDielectric<double>(1.4, 1.33),
                                                     RoughDielectric<double>(1e3, 1.4, 1.33),
                                                     RoughDielectric<double>(1e-30, 1.4, 1.33)};
    for (const Boundary<double>& inner : interiors)
        for (double tau : {0.0, 1e-300, 1.0, huge, inf})
            for (double albedo : {0.0, 1.0}) {
                const std::vector<Slab<double>> slabs = {Slab<double>(albedo, 0.5, tau), Slab<double>(0.9, -0.3, 2.0)};
                const std::string name = "albedo " + fmt(albedo) + ", tau " + fmt(tau) + " over tau 2, interior " +
                                         (inner.rough() ? "rough" : "smooth");
                // (5 ordinates where the interior face refracts smoothly: detail::require_ordinates_for_joints)
                const int m = inner.rough() ? 3 : 5;
                if (albedo == 1 && (tau == 0 || tau == inf))
                    check_surface(solve_stack(top, slabs, {inner}, bottom, with_ordinates(m)), "rough stack, " + name);
                check_surface(solve_stack(smooth_top, slabs, {inner}, smooth_bottom, with_ordinates(m)), "smooth stack, " + name);
            }
    // Three slabs, the middle one semi-infinite or empty, index-matched interior faces.
    for (double tau : {0.0, inf})
        check_surface(solve_stack<double>(top, {Slab<double>(0.9, 0.5, 1.0), Slab<double>(1.0, 0.5, tau), Slab<double>(0.5, 0.0, 1.0)},
                                  {Boundary<double>::index_matched(1.4), Boundary<double>::index_matched(1.4)},
                                  RoughDielectric<double>(0.3, 1.4, 1.0), with_ordinates(3)),
                      "three slabs, middle tau " + fmt(tau));
    // A thin slab between smooth faces in a stack: with the default options energy is never created, for any
    // ordinate count. Before: ordinates below the critical cosine (totally reflected at both faces) received light
    // from the interior face's beam splitting and leaked it back out through its pointwise interpolation, without
    // bound at tau -> 0 (R + T = 1102 at M = 12, tau = 0; 1.19 at M = 8, tau = 1e-3, albedo 1), and pointwise
    // interior faces alone created up to 26% (M = 4).
    // (From 5 ordinates, which slabs joined by a refracting face need: detail::require_ordinates_for_joints.)
    for (int m = 2; m <= 12; ++m)
        for (double tau : {0.0, 1e-3, 1.0})
            for (bool rough_top : {false, true}) {
                if (rough_top && m != 2 && m != 5 && m != 7) continue;  // (rough: slower; the worst cases measured)
                const auto solve = [&] {
                    return solve_stack<double>(rough_top ? top : smooth_top, {Slab<double>(0.0, 0.5, tau), Slab<double>(1.0, -0.3, 2.0)},
                                               {SmoothDielectric<double>(1.4, 1.33)}, smooth_bottom, with_ordinates(m));
                };
                if (m < 5) {
                    CHECK_REJECTS(solve(), "options.ordinates");
                    continue;
                }
                const auto stack = solve();
                for (double mu : {0.05, 0.3, 0.7, 1.0}) {
                    INFO("M = " << m << ", tau " << tau << (rough_top ? ", rough top" : ", smooth top") << ", mu " << mu);
                    const double r = stack.reflectance(mu).total(), t = stack.transmittance(mu);
                    CHECK(r >= 0);
                    CHECK(t >= 0);
                    CHECK(r + t <= 1 + slack);
                }
            }
    // An explicit SpecularTransmission::pointwise keeps the interior faces radiance-accurate but not energy-
    // conserving (documented: README, known limitations; R + T up to 1.9 measured for a zero-thickness slab
    // between smooth faces, M = 2..16): values stay finite and >= 0.
    {
        LayerOptions pointwise = with_ordinates(5);
        pointwise.specular_transmission = stratum::SpecularTransmission::pointwise;
        for (double tau : {0.0, 1.0})
            check_surface(solve_stack<double>(smooth_top, {Slab<double>(0.0, 0.5, tau), Slab<double>(1.0, -0.3, 2.0)},
                                              {SmoothDielectric<double>(1.4, 1.33)}, smooth_bottom, pointwise),
                          "smooth stack, pointwise interior face, tau " + fmt(tau), 1.0);
    }
    // A semi-infinite top slab hides everything below it.
    {
        const auto stack = solve_stack<double>(top, {Slab<double>(0.9, 0.5, inf), Slab<double>(1.0, 0.0, 1.0)},
                                       {SmoothDielectric<double>(1.4, 1.33)}, bottom, with_ordinates(5));
        CHECK(stack.transmittance(0.5) == 0);
        CHECK(stack.btdf(direction(0.8, 0.3), direction(-0.5, 1.0)) == 0);
    }
    const Slab<double> slab(0.9, 0.5, 1.0);
    CHECK_REJECTS((solve_stack<double>(top, {}, {}, bottom, with_ordinates(3))), "slabs.size()");
    CHECK_REJECTS((solve_stack<double>(top, {slab, slab}, {}, bottom, with_ordinates(3))), "interior.size()");
    CHECK_REJECTS(solve_stack<double>(top, {slab}, {interiors[0]}, bottom, with_ordinates(3)), "interior.size()");
    CHECK_REJECTS((solve_stack<double>(top, {slab, slab}, {SmoothDielectric<double>(1.33, 1.4)}, bottom, with_ordinates(3))), "disagree");
    CHECK_REJECTS(solve_layer(slab, top, bottom, with_ordinates(3)), "disagree");
    CHECK_REJECTS((solve_stack<double>(top, {slab, slab}, {interiors[0]}, bottom, with_ordinates(0))), "options.ordinates");
}

TEST_CASE("a rough top under a denser medium creates no energy at small sigma (found by fuzz_layer)") {
    // n 1.877 | 0.501 | 0.5, sigma 7e-5: the transmittance of the top from above rises from 0 to 0.67 within
    // ~sigma of the critical cosine 0.964. Interpolating it from the 64-interval table gave T = 0.745 at
    // mu = 0.996 against 0.665 entering (R + T - 1 = 0.08); it is now computed exactly there. The smooth top
    // is the reference where the refracted light travels steeply inside (mu >= 0.97: internal cosine >= 0.4):
    // for a nearly transparent slab the two then agree to the rough lobe's effect (< 1e-4). Closer to the
    // critical cosine the light enters near grazing, where 4 ordinates put part of it below the bottom face's
    // critical cosine (0.075): energy is still conserved, but the rough layer reflects more than the exact
    // smooth one (R 0.57 against 0.38 at mu = 0.966; the known discretization limit of a lobe narrower than
    // the ordinates, README).
    const Slab<double> slab(0.6, 0.22, 1e-9);
    LayerOptions options;
    options.ordinates = 4;
    const auto rough = solve_layer(slab, RoughDielectric<double>(7e-5, 1.8774, 0.5014), SmoothDielectric<double>(0.5014, 0.5),
                                   options);
    const auto smooth = solve_layer(slab, SmoothDielectric<double>(1.8774, 0.5014), SmoothDielectric<double>(0.5014, 0.5),
                                    options);
    for (double mu : {0.996, 0.99, 0.97, 0.965, 0.9, 0.5}) {
        INFO("mu = " << mu);
        const double r = rough.reflectance(mu).total(), t = rough.transmittance(mu);
        CHECK(r + t <= 1 + 1e-9);
        if (mu >= 0.97) CHECK(std::fabs(t - smooth.transmittance(mu)) < 1e-4);
    }
}

// Light nearly trapped between a nearly specular rough top and a smooth bottom, both totally reflecting near the
// direction it travels, in a nearly transparent slab (found by a random sweep after fuzz_layer): the beam refracted
// into the slab at 0.566 lies between the top's critical cosine (0.548) and the bottom's (0.733), so it never leaves
// through the bottom (T = 0) and, the slab absorbing almost nothing, R + T = 1. The spread of the beam over the
// ordinates crossed the bottom's critical cosine (a negative share on trapped ordinates, a positive one on
// ordinates the bottom transmits) and the layer created energy: R + T = 1.547 at 7 ordinates, 2.11 at 16, with T up
// to 1.8. The spread now stays on x's side of a sharp critical cosine (layer.hpp, specular_spread). Measured after:
// R + T - 1 within -1.1e-4 (the slab's absorption over the trapped light's many passes) and 0, T <= 3.3e-7.
TEST_CASE("nearly trapped light between a nearly specular rough top and a smooth bottom conserves energy") {
    const Slab<double> slab(0.482, 0.139, 5.81e-7);
    for (int m : {7, 8, 12, 16, 24}) {
        LayerOptions options;
        options.ordinates = m;
        const auto layer = solve_layer(slab, RoughDielectric<double>(0.00789, 0.898, 1.074),
                                       SmoothDielectric<double>(1.074, 0.730), options);
        for (double mu : {0.1, 0.13, 0.168, 0.2, 0.3, 0.6, 1.0}) {
            INFO("M = " << m << ", mu = " << mu);
            const double sum = layer.reflectance(mu).total() + layer.transmittance(mu);
            CHECK(sum <= 1 + 1e-9);
            CHECK(sum >= 1 - 2e-4);
            if (mu <= 0.3) CHECK(layer.transmittance(mu) <= 1e-6);  // (internal cosine 0.555 to 0.603: trapped)
        }
    }
}

// A second case of the sweep: light from a slightly denser medium (1.37) through a rough top (slope 0.042) into a
// slab of 1.351 over a smooth bottom to 1.298, whose critical cosine inside is 0.277. At mu = 0.3 the internal
// cosine is 0.253: trapped by the bottom, but above every ordinate below 0.277 at M = 7 (0.025, 0.129), so the
// spread extrapolated from those two (weights -1.19 and 2.19) and R + T came out 1.296; at M = 8 and 16 it is 0.94.
// The nearest ordinate below the cut now takes the beam (measured: 0.877 at M = 7). A third case: through a rough
// top of slope 0.0026 from 1.371 into 1.415, over a rough bottom (slope 0.071) to 1.14; internal cosines 0.252 to
// 0.382 lie between the top's own critical cosine inside (0.247) and the first ordinate above it (0.408 at M = 8),
// and the stencil extrapolated from 0.408 and 0.592 (weights 1.85, -0.85): R + T = 1.19; now at most 1 + 9e-5
// (M = 16, mu = 0.7: the discretization's own energy error with two rough faces, not this defect).
// From the random sweep of docs/accuracy.md (layer_energy_sweep): a nearly transparent slab (tau 1.6e-5, n 1.178)
// under a rough top (slope 0.117, from 1.291) over a smooth face to 1.070, its ordinates split at the bottom's critical
// cosine (0.418). At mu = 0.7 the beam enters at 0.62, between ordinates; a 4-point stencil there put negative
// shares on ordinates whose light, nearly trapped, leaves only in part (shadowing losses over many bounces):
// R + T = 1.108 at 9 and 10 ordinates. The stencil between ordinates is now linear (layer.hpp, spread_points).
TEST_CASE("the beam's spread between ordinates has non-negative weights: no energy from nearly trapped light") {
    for (int m : {9, 10, 12, 16}) {
        LayerOptions options;
        options.ordinates = m;
        const auto layer = solve_layer(Slab<double>(0.140, -0.34, 1.64e-5), RoughDielectric<double>(0.1174, 1.291, 1.178),
                                       SmoothDielectric<double>(1.178, 1.070), options);
        for (double mu : {0.05, 0.168, 0.3, 0.5, 0.7, 0.9, 1.0}) {
            INFO("M = " << m << ", mu = " << mu);
            CHECK(layer.reflectance(mu).total() + layer.transmittance(mu) <= 1 + 1e-9);
        }
    }
}

TEST_CASE("a beam next to a critical cosine is not extrapolated onto the ordinates") {
    for (int m : {7, 8, 9, 16}) {
        LayerOptions options;
        options.ordinates = m;
        const auto layer = solve_layer(Slab<double>(0.836, -0.117, 2.12e-6), RoughDielectric<double>(0.0026, 1.371, 1.415),
                                       RoughDielectric<double>(0.0708, 1.415, 1.140), options);
        for (double mu : {0.05, 0.168, 0.3, 0.5, 0.7, 1.0}) {
            INFO("M = " << m << ", mu = " << mu);
            CHECK(layer.reflectance(mu).total() + layer.transmittance(mu) <= 1 + 2e-4);
        }
    }
    for (int m : {5, 6, 7, 8, 16}) {
        LayerOptions options;
        options.ordinates = m;
        const auto layer = solve_layer(Slab<double>(0.335, 0.136, 1.12e-2), RoughDielectric<double>(0.0417, 1.370, 1.351),
                                       SmoothDielectric<double>(1.351, 1.298), options);
        for (double mu : {0.05, 0.168, 0.25, 0.3, 0.35, 0.5, 1.0}) {
            INFO("M = " << m << ", mu = " << mu);
            CHECK(layer.reflectance(mu).total() + layer.transmittance(mu) <= 1 + 1e-9);
        }
    }
}
