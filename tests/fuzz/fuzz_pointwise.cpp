// libFuzzer target over the pointwise modules: any bytes become parameters (valid or not) and directions.
// Promises checked: a constructor either throws std::invalid_argument or yields an object whose evaluation
// functions return finite, non-negative values for every unit direction and sample in range; samples are
// unit vectors with a positive pdf or are flagged invalid; hemispherical totals lie in [0, 1].
#include <stratum/dipole.hpp>
#include <stratum/fresnel.hpp>
#include <stratum/henyey_greenstein.hpp>
#include <stratum/interface.hpp>
#include <stratum/lambert_w.hpp>

#include <cmath>
#include <stdexcept>

#include "fuzz_input.hpp"

namespace {

using stratum_fuzz::Input;
using stratum_fuzz::direction;
using stratum_fuzz::unit;
using stratum_fuzz::require;
using V = stratum::Vec3<double>;

bool finite_nonnegative(double x) { return std::isfinite(x) && x >= 0; }

void rough_dielectric(Input& in) {
    const double sigma = in.log_in(1e-320, 1e3), eta_a = in.log_in(0.1, 10), eta_b = in.log_in(0.1, 10);
    const auto shadowing = static_cast<stratum::Shadowing>(in.byte() % 3);
    try {
        const stratum::RoughDielectric<double> face(sigma, eta_a, eta_b, shadowing);
        const V wi = direction(in), wo = direction(in);
        require(finite_nonnegative(face.eval(wi, wo)), "RoughDielectric::eval finite and >= 0");
        require(finite_nonnegative(face.pdf(wi, wo)), "RoughDielectric::pdf finite and >= 0");
        const auto s = face.sample(wi, unit(in), unit(in), unit(in));
        if (s.valid()) {
            require(std::isfinite(s.pdf) && s.pdf > 0, "sample pdf finite and > 0");
            require(finite_nonnegative(s.value), "sample value finite and >= 0");
            require(std::fabs(stratum::dot(s.wo, s.wo) - 1) < 1e-9, "sampled direction is a unit vector");
        }
        if ((in.byte() & 15) == 0) {  // the hemispherical integral costs up to a millisecond
            const auto a = face.hemispherical_totals(wi.z);
            require(a.reflectance >= 0 && a.transmittance >= 0 && a.reflectance + a.transmittance <= 1 + 1e-6,
                    "RoughDielectric::hemispherical_totals in [0, 1]");
        }
        // Sampling restricted by a lobe mask (read last, so that earlier corpus inputs keep their meaning).
        const auto mask = static_cast<stratum::Lobe>(in.byte() & 15);
        const auto m = face.sample(wi, unit(in), unit(in), unit(in), stratum::TransportMode::importance, mask);
        require(finite_nonnegative(face.pdf(wi, wo, mask)), "RoughDielectric::pdf with a mask finite and >= 0");
        if (m.valid()) {
            require(std::isfinite(m.pdf) && m.pdf > 0 && finite_nonnegative(m.value), "masked sample finite");
            require(stratum::allows(mask, m.reflected, m.delta), "a masked sample's lobe is allowed");
        }
        // The float instantiation, whose shadowing is computed in float above cosines of 1e-4 (interface.hpp), at the
        // same parameters and directions rounded to float (a parameter float cannot hold throws, as in double).
        const stratum::RoughDielectric<float> narrow(static_cast<float>(sigma), static_cast<float>(eta_a),
                                                     static_cast<float>(eta_b), shadowing);
        const stratum::Vec3<float> wi_f{static_cast<float>(wi.x), static_cast<float>(wi.y), static_cast<float>(wi.z)};
        const stratum::Vec3<float> wo_f{static_cast<float>(wo.x), static_cast<float>(wo.y), static_cast<float>(wo.z)};
        const float f = narrow.eval(wi_f, wo_f);
        require(std::isfinite(f) && f >= 0, "RoughDielectric<float>::eval finite and >= 0");
    } catch (const std::invalid_argument&) {
    }
}

void henyey_greenstein(Input& in) {
    try {
        const stratum::HenyeyGreenstein<double> hg(in.in(-1, 1));
        require(finite_nonnegative(hg.eval(in.in(-1, 1))), "HG eval finite and >= 0");
        const auto s = hg.sample(unit(in), unit(in));
        require(std::fabs(stratum::dot(s.direction, s.direction) - 1) < 1e-9 && finite_nonnegative(s.pdf),
                "HG sample is a unit vector with a finite pdf");
    } catch (const std::invalid_argument&) {
    }
}

void dipole(Input& in) {
    try {
        const stratum::Dipole<double> d(in.log_in(1e-6, 1e3), in.log_in(1e-6, 1e3), in.log_in(0.5, 3));
        const double r = in.log_in(1e-9, 1e3);
        require(finite_nonnegative(d.Rd(r)) || !(r >= 0), "Dipole::Rd finite and >= 0");
        require(finite_nonnegative(d.sample_radius(unit(in))), "Dipole::sample_radius finite and >= 0");
        require(finite_nonnegative(d.pdf_radius(r)), "Dipole::pdf_radius finite and >= 0");
        require(d.total_reflectance() >= 0 && d.total_reflectance() <= 1, "total diffuse reflectance in [0, 1]");
    } catch (const std::invalid_argument&) {
    }
}

void fresnel_and_lambert(Input& in) {
    const double c = in.in(0, 1), eta = in.log_in(1e-3, 1e3);
    if (c >= 0 && c <= 1 && eta > 0 && std::isfinite(eta)) {
        const double f = stratum::fresnel_dielectric(c, eta);
        require(f >= 0 && f <= 1, "fresnel_dielectric in [0, 1]");
    }
    const double x = in.in(-0.36787944117144233, 0);
    if (x >= -0.36787944117144233 && x < 0) {
        const double w = stratum::lambert_wm1(x);
        require(std::isfinite(w) && w <= -1, "lambert_wm1 finite and <= -1");
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    Input in(data, size);
    switch (in.byte() & 3) {
        case 0: rough_dielectric(in); break;
        case 1: henyey_greenstein(in); break;
        case 2: dipole(in); break;
        default: fresnel_and_lambert(in); break;
    }
    return 0;
}
