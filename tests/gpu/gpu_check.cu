// Evaluates stratum's pointwise modules on the GPU for a grid of inputs and compares with the same
// functions on the host. Built by scripts/gpu-check (nvcc); compiled for device code only in CI
// (tests/CMakeLists.txt, where nvcc is installed). Prints, per function and type, the largest difference
// in ulp of the host value, and exits 1 when a double result differs by more than `double_ulp_limit`
// (GPU and host libm differ by a few ulp in exp, erfc, log, sqrt is exact).
#include <stratum/dipole.hpp>
#include <stratum/fresnel.hpp>
#include <stratum/henyey_greenstein.hpp>
#include <stratum/interface.hpp>
#include <stratum/lambert_w.hpp>

#include <cmath>
#include <cstdio>
#include <vector>

namespace {

constexpr int functions = 8;
const char* const names[functions] = {"fresnel_dielectric", "HenyeyGreenstein::eval", "HenyeyGreenstein::sample",
                                      "RoughDielectric::eval", "RoughDielectric::pdf", "RoughDielectric::sample",
                                      "Dipole::Rd", "lambert_wm1"};
constexpr int grid = 64;  // inputs per function

template <class Real>
struct Objects {
    stratum::HenyeyGreenstein<Real> hg;
    stratum::RoughDielectric<Real> face;
    stratum::Dipole<Real> dipole;
};

// Result j of function f at grid point i: every function maps i to its own input.
template <class Real>
STRATUM_HOST_DEVICE Real evaluate(const Objects<Real>& o, int f, int i) {
    const Real t = (Real(i) + Real(0.5)) / Real(grid);  // in (0, 1)
    const Real phi = Real(6.283185307179586) * t * Real(7);
    const stratum::Vec3<Real> wi = stratum::spherical_direction(Real(0.05) + Real(0.9) * t, phi);
    const stratum::Vec3<Real> wo = stratum::spherical_direction(Real(0.97) - Real(1.9) * t, Real(0.3) - phi);
    switch (f) {
        case 0: return stratum::fresnel_dielectric(Real(2) * t - Real(1), Real(1.5));
        case 1: return o.hg.eval(Real(2) * t - Real(1));
        case 2: return o.hg.sample(t, Real(1) - t).direction.z;
        case 3: return o.face.eval(wi, wo);
        case 4: return o.face.pdf(wi, wo);
        case 5: return o.face.sample(wi, t, Real(1) - t, t * t).wo.z;
        case 6: return o.dipole.Rd(Real(4) * t);
        default: return stratum::lambert_wm1(-Real(0.36787944117144233) * t);
    }
}

template <class Real>
__global__ void kernel(Objects<Real> o, Real* out) {
    const int id = blockIdx.x * blockDim.x + threadIdx.x;
    if (id < functions * grid) out[id] = evaluate(o, id / grid, id % grid);
}

template <class Real>
double ulp_difference(Real a, Real b) {
    if (a == b) return 0;
    const Real ulp = std::nextafter(std::fabs(b), Real(INFINITY)) - std::fabs(b);
    return std::fabs(double(a) - double(b)) / double(ulp);
}

// Returns the largest ulp difference over all functions; prints one line per function.
template <class Real>
double compare(const char* type) {
    const Objects<Real> o{stratum::HenyeyGreenstein<Real>(Real(0.8)),
                          stratum::RoughDielectric<Real>(Real(0.3), Real(1), Real(1.4)),
                          stratum::Dipole<Real>(Real(0.032), Real(0.74), Real(1.3))};
    const int n = functions * grid;
    Real* device = nullptr;
    if (cudaMalloc(&device, n * sizeof(Real)) != cudaSuccess) return -1;
    kernel<Real><<<(n + 127) / 128, 128>>>(o, device);
    std::vector<Real> gpu(n);
    const bool ok = cudaMemcpy(gpu.data(), device, n * sizeof(Real), cudaMemcpyDeviceToHost) == cudaSuccess;
    cudaFree(device);
    if (!ok) return -1;
    double worst = 0;
    for (int f = 0; f < functions; ++f) {
        double max_ulp = 0;
        for (int i = 0; i < grid; ++i) max_ulp = std::fmax(max_ulp, ulp_difference(gpu[f * grid + i], evaluate(o, f, i)));
        std::printf("%-26s %-6s max %8.1f ulp\n", names[f], type, max_ulp);
        worst = std::fmax(worst, max_ulp);
    }
    return worst;
}

}  // namespace

int main() {
    int count = 0;
    if (cudaGetDeviceCount(&count) != cudaSuccess || count == 0) {
        std::printf("gpu_check: no CUDA device here; the device code compiled, nothing was run\n");
        return 0;
    }
    const double double_ulp_limit = 8;
    const double worst_double = compare<double>("double");
    const double worst_float = compare<float>("float");
    if (worst_double < 0 || worst_float < 0) {
        std::printf("gpu_check: a CUDA call failed\n");
        return 1;
    }
    std::printf("worst: double %.1f ulp (limit %.0f), float %.1f ulp\n", worst_double, double_ulp_limit, worst_float);
    return worst_double <= double_ulp_limit ? 0 : 1;
}
