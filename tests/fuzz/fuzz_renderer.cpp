// libFuzzer target over the renderer-facing objects built from solved layers and the dipole: TabulatedBSDF
// (one side, two sides, three channels, smooth faces with deltas) and DipoleBSSRDF. The tables are built once;
// the bytes choose directions (unit, grazing, along the normal, or raw doubles: NaN, infinities, non-unit),
// uniforms, transport modes and lobe masks. Promises checked: eval, pdf and every channel's value are finite
// and >= 0 for any direction; a sample is either invalid (pdf 0, value 0) or has a finite pdf > 0 and finite values
// >= 0 and a finite direction (a unit vector when wi is one, and for a glossy sample its pdf is then pdf() there); a BSSRDF probe has a finite origin
// and a unit axis, and its density is finite and >= 0 anywhere.
#include <stratum/bssrdf.hpp>
#include <stratum/tabulated_bsdf.hpp>

#include <cmath>
#include <vector>

#include "fuzz_input.hpp"

namespace {

using stratum_fuzz::Input;
using stratum_fuzz::require;
using stratum_fuzz::unit;
using V = stratum::Vec3<double>;

bool finite_nonnegative(double x) { return std::isfinite(x) && x >= 0; }

struct Tables {
    std::vector<stratum::TabulatedBSDF<double>> all;
    stratum::DipoleBSSRDF<double, 3> bssrdf{stratum::make_dipoles<double, 3>({0.032, 0.17, 0.48}, {0.74, 0.88, 1.01}, 1.3)};
    Tables() {
        stratum::LayerOptions o;
        o.ordinates = 6;
        const stratum::Slab<double> slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
        const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.5, 1.4, 1.2);
        const stratum::RoughDielectric<double> top_turned(0.5, 1.2, 1.4), bottom_turned(0.3, 1.4, 1.0);
        const auto above = stratum::solve_layer(slab, top, bottom, o), below = stratum::solve_layer(slab, top_turned, bottom_turned, o);
        all.emplace_back(above, 3e-2);
        all.emplace_back(above, below, 3e-2);
        std::vector<stratum::Slab<double>> rgb;
        for (double a : {0.95, 0.8, 0.5}) rgb.push_back(stratum::Slab<double>(a, 0.5, 1.0));
        all.emplace_back(stratum::solve_spectral(rgb, stratum::SmoothDielectric<double>(1.0, 1.5),
                                                 stratum::SmoothDielectric<double>(1.5, 1.0), o),
                         3e-2, std::vector<double>{0.2126, 0.7152, 0.0722});
        all.emplace_back(stratum::solve_layer(stratum::Slab<double>(0.9, 0.0, 0.05), stratum::SmoothDielectric<double>(1.0, 1.5),
                                              stratum::Boundary<double>::lambertian(0.6, 1.5), o),
                         3e-2);
    }
};

const Tables& tables() {
    static const Tables t;
    return t;
}

// Any vector (raw doubles: NaN, infinities, non-unit), or one of fuzz_input.hpp's unit directions.
V any_direction(Input& in) {
    if ((in.byte() & 3) == 0) return {in.raw(), in.raw(), in.raw()};
    return stratum_fuzz::direction(in);
}

void tabulated(Input& in) {
    const auto& t = tables().all[in.byte() % tables().all.size()];
    const V wi = any_direction(in), wo = any_direction(in);
    const auto mode = (in.byte() & 1) ? stratum::TransportMode::radiance : stratum::TransportMode::importance;
    const auto mask = static_cast<stratum::Lobe>(in.byte() & 15);
    require(finite_nonnegative(t.eval(wi, wo, mode)), "TabulatedBSDF::eval finite and >= 0");
    require(finite_nonnegative(t.pdf(wi, wo, mode, mask)), "TabulatedBSDF::pdf finite and >= 0");
    double values[3] = {0, 0, 0};
    t.eval(wi, wo, values, mode);
    for (int c = 0; c < t.channels(); ++c) require(finite_nonnegative(values[c]), "channel values finite and >= 0");
    const auto s = t.sample(wi, unit(in), unit(in), unit(in), values, mode, mask);
    if (!s.valid()) {
        require(s.pdf == 0 && s.value == 0, "an invalid sample has pdf 0 and value 0");
        return;
    }
    require(std::isfinite(s.pdf) && s.pdf > 0, "sample pdf finite and > 0");
    require(finite_nonnegative(s.value), "sample value finite and >= 0");
    for (int c = 0; c < t.channels(); ++c) require(finite_nonnegative(values[c]), "sampled channel values finite and >= 0");
    require(stratum::all_finite(s.wo), "a valid sample's direction is finite");
    // Directions are expected to be unit vectors and are not normalized (class comment): a unit wi gives a unit wo,
    // and the density it reports is pdf() there. (For a non-unit wi both are undefined: with subnormal components
    // the sampler and pdf() read its azimuth to different digits, 1e-3 apart; found by fuzz_renderer.)
    const bool unit_wi = std::fabs(stratum::dot(wi, wi) - 1) < 1e-12;
    if (unit_wi) require(std::fabs(stratum::dot(s.wo, s.wo) - 1) < 1e-9, "sampled direction is a unit vector");
    require(stratum::allows(mask, s.reflected, s.delta), "the sample's lobe is allowed");
    if (!s.delta && unit_wi) {
        const double p = t.pdf(wi, s.wo, mode, mask);
        require(std::fabs(p - s.pdf) <= 1e-9 * s.pdf, "a glossy sample's pdf is pdf() there");
    }
}

void bssrdf(Input& in) {
    const auto& b = tables().bssrdf;
    const auto p = b.sample_probe(unit(in), unit(in), unit(in));
    require(p.valid() && std::isfinite(p.half_length), "a probe has a finite half length > 0");
    require(std::isfinite(p.origin.x) && std::isfinite(p.origin.y) && std::isfinite(p.origin.z), "probe origin finite");
    require(std::fabs(stratum::dot(p.axis, p.axis) - 1) < 1e-12, "probe axis a unit vector");
    const V d{in.in(-100, 100), in.in(-100, 100), in.in(-100, 100)};
    V n = any_direction(in);
    if (!(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z) && stratum::dot(n, n) > 0.5 && stratum::dot(n, n) < 2))
        n = {0, 0, 1};
    if (std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z))
        require(finite_nonnegative(b.pdf(d, n)), "BSSRDF pdf finite and >= 0");
    double sp[3];
    const double r = in.in(0, 1e3);
    b.Sp(r, sp);
    for (double x : sp) require(finite_nonnegative(x) || !(r >= 0), "S_p finite and >= 0");
    require(finite_nonnegative(b.Sw(n)), "S_w finite and >= 0");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    Input in(data, size);
    if ((in.byte() & 3) == 0) bssrdf(in);
    else tabulated(in);
    return 0;
}
