// Fluxes at one incidence through a homogeneous slab with black, index-matched faces: stratum (M half-range
// ordinates, LayerOutput::reflectance | transmittance: mode 0 only) against DISORT (cdisort, 2M streams, onlyfl:
// mode 0 only), both with delta-M and the same Henyey-Greenstein moments. Printed per problem and M: the worst of
// |R - R_ref| and |T - T_ref| for each code (reference: DISORT at 256 streams), and the wall time per solve, each
// code timed in turn in this one process (doubling the repetitions until 0.3 s). Problems P1, P3, P4 of
// tests/data/disort_intensity_reference.txt (P3 with albedo 0.999: cdisort's own limit is 1 - 100 eps).
extern "C" {
#include "cdisort.h"
}
#include <stratum/layer.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace {

struct Problem {
    const char* name;
    double g, albedo, tau, mu0;
};

struct Fluxes {
    double reflectance, transmittance;  // diffuse reflectance; transmittance with the direct beam
};

Fluxes disort_fluxes(const Problem& p, int streams) {
    disort_state ds;
    disort_output out;
    std::memset(&ds, 0, sizeof ds);
    std::memset(&out, 0, sizeof out);
    ds.nstr = streams;
    ds.nphase = streams;
    ds.nlyr = 1;
    ds.nmom = streams;  // pmom[nstr] != 0: cdisort applies delta-M
    ds.ntau = 2;
    ds.flag.ibcnd = GENERAL_BC;
    ds.flag.usrtau = TRUE;
    ds.flag.lamber = TRUE;
    ds.flag.onlyfl = TRUE;
    ds.flag.quiet = TRUE;
    ds.flag.brdf_type = BRDF_NONE;
    ds.bc.umu0 = p.mu0;
    ds.bc.fbeam = 1.0 / p.mu0;  // unit flux on a horizontal surface
    ds.bc.temis = 1.0;
    c_disort_state_alloc(&ds);
    c_disort_out_alloc(&ds, &out);
    ds.dtauc[0] = p.tau;
    ds.ssalb[0] = p.albedo;
    for (int l = 0; l <= ds.nmom; ++l) ds.pmom[l] = std::pow(p.g, l);
    ds.utau[0] = 0;
    ds.utau[1] = p.tau;
    c_disort(&ds, &out);
    const Fluxes f{out.rad[0].flup, out.rad[1].rfldn + out.rad[1].rfldir};
    c_disort_out_free(&ds, &out);
    c_disort_state_free(&ds);
    return f;
}

Fluxes stratum_fluxes(const Problem& p, int ordinates) {
    stratum::LayerOptions options;
    options.ordinates = ordinates;
    stratum::LayerRequest<double> request;
    request.outputs = stratum::LayerOutput::reflectance | stratum::LayerOutput::transmittance;
    request.incidence = {p.mu0};
    const stratum::SmoothDielectric<double> matched(1, 1);
    const auto layer = stratum::solve_layer(stratum::Slab<double>(p.albedo, p.g, p.tau), matched, matched, options, request);
    return {layer.reflectance(p.mu0).subsurface, layer.transmittance(p.mu0)};
}

template <class F>
double microseconds_per_call(F f) {
    for (long n = 1;; n *= 2) {
        const auto start = std::chrono::steady_clock::now();
        for (long i = 0; i < n; ++i) f();
        const double t = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
        if (t > 3e5) return t / static_cast<double>(n);
    }
}

double error(const Fluxes& a, const Fluxes& b) {
    return std::fmax(std::fabs(a.reflectance - b.reflectance), std::fabs(a.transmittance - b.transmittance));
}

}  // namespace

int main() {
    const Problem problems[] = {{"P1", 0.75, 0.9, 1.0, 0.5}, {"P3", 0.0, 0.999, 2.0, 0.7}, {"P4", 0.9, 0.99, 4.0, 0.3}};
    std::printf("problem  M  | error: DISORT (2M streams)  stratum (M) | time: DISORT  stratum (us) | ratio\n");
    for (const Problem& p : problems) {
        const Fluxes reference = disort_fluxes(p, 256);
        for (int m : {2, 4, 8, 16, 32}) {
            const double e_disort = error(disort_fluxes(p, 2 * m), reference), e_stratum = error(stratum_fluxes(p, m), reference);
            volatile double sink = 0;
            const double t_disort = microseconds_per_call([&] { sink = disort_fluxes(p, 2 * m).reflectance; });
            const double t_stratum = microseconds_per_call([&] { sink = stratum_fluxes(p, m).reflectance; });
            std::printf("%-7s %3d | %12.2e %12.2e | %9.2f %9.2f | %5.2f\n", p.name, m, e_disort, e_stratum, t_disort,
                        t_stratum, t_stratum / t_disort);
        }
    }
}
