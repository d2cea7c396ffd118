// Evaluates stratum's pointwise modules on the GPU for a grid of inputs and compares with the same
// functions on the host. Built by scripts/gpu-check (nvcc); compiled for device code only in CI
// (tests/CMakeLists.txt, where nvcc is installed).
//
// The inputs are made once on the host and copied to the device, so both sides evaluate the same
// numbers; both are measured against the host's long double evaluation of those numbers. A function
// value's error is counted in eps relative to the reference; a direction's component in eps absolutely
// (a unit vector's components are accurate to eps, not relative to a component near 0). A value can be
// no more accurate than its condition: the Beckmann term far in its tail (1e-97 is exp(-222)) changes by
// thousands of eps when an input changes by one, and the host is off by hundreds of eps there too. So
// each point's allowance is measured: `condition` is the largest change of the reference, in the same
// units, when one input (t or a direction's component) changes by one eps, and every GPU and every host
// value must lie within 2 condition + 8 eps of the reference (8: a few ulp of libm, which differs
// between host and GPU, through a few operations).
// The long double reference instantiates the __host__ __device__ functions with long double, which are
// called on the host only; nvcc's warning that device code would treat it as double does not apply.
#pragma nv_diag_suppress 20208
#include <stratum/dipole.hpp>
#include <stratum/fresnel.hpp>
#include <stratum/henyey_greenstein.hpp>
#include <stratum/interface.hpp>
#include <stratum/lambert_w.hpp>

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

namespace {

constexpr int functions = 11;
const char* const names[functions] = {"fresnel_dielectric", "HenyeyGreenstein::eval", "HenyeyGreenstein::sample",
                                      "RoughDielectric::eval", "RoughDielectric::pdf", "RoughDielectric::sample",
                                      "Dipole::Rd", "lambert_wm1", "total_diffuse_reflectance",
                                      "alpha_prime_from_reflectance", "Dipole::sample_radius"};
// Functions whose result is a component of a unit vector (error counted absolutely, in eps).
constexpr bool is_direction[functions] = {false, false, true, false, false, true, false, false, false, false, false};
constexpr int grid = 64;  // inputs per function

template <class Real>
struct Objects {
    stratum::HenyeyGreenstein<Real> hg;
    stratum::RoughDielectric<Real> face;
    stratum::Dipole<Real> dipole;
};

template <class Real>
Objects<Real> make_objects() {
    return {stratum::HenyeyGreenstein<Real>(Real(0.8)), stratum::RoughDielectric<Real>(Real(0.3), Real(1), Real(1.4)),
            stratum::Dipole<Real>(Real(0.032), Real(0.74), Real(1.3))};
}

template <class Real>
struct Input {
    Real t;  // in (0, 1)
    stratum::Vec3<Real> wi, wo;
};

template <class Real>
Input<Real> make_input(int i) {
    const Real t = (Real(i) + Real(0.5)) / Real(grid);
    const Real phi = Real(6.283185307179586) * t * Real(7);
    return {t, stratum::spherical_direction(Real(0.05) + Real(0.9) * t, phi),
            stratum::spherical_direction(Real(0.97) - Real(1.9) * t, Real(0.3) - phi)};
}

template <class To, class From>
Input<To> convert(const Input<From>& in) {
    const auto v = [](stratum::Vec3<From> a) { return stratum::Vec3<To>{To(a.x), To(a.y), To(a.z)}; };
    return {To(in.t), v(in.wi), v(in.wo)};
}

// Result of function f at one input.
template <class Real>
STRATUM_HOST_DEVICE Real evaluate(const Objects<Real>& o, int f, const Input<Real>& in) {
    const Real t = in.t;
    switch (f) {
        case 0: return stratum::fresnel_dielectric(Real(2) * t - Real(1), Real(1.5));
        case 1: return o.hg.eval(Real(2) * t - Real(1));
        case 2: return o.hg.sample(t, Real(1) - t).direction.z;
        case 3: return o.face.eval(in.wi, in.wo);
        case 4: return o.face.pdf(in.wi, in.wo);
        case 5: return o.face.sample(in.wi, t, Real(1) - t, t * t).wo.z;
        case 6: return o.dipole.Rd(Real(4) * t);
        case 7: return stratum::lambert_wm1(-Real(0.36787944117144233) * t);
        case 8: return stratum::total_diffuse_reflectance(t, o.dipole.boundary());
        case 9: return stratum::alpha_prime_from_reflectance(t, o.dipole.boundary());
        default: return o.dipole.sample_radius(t);
    }
}

template <class Real>
__global__ void kernel(Objects<Real> o, const Input<Real>* inputs, Real* out) {
    const int id = blockIdx.x * blockDim.x + threadIdx.x;
    if (id < functions * grid) out[id] = evaluate(o, id / grid, inputs[id % grid]);
}

template <class Real>
long double reference_value(const Objects<long double>& o, int f, const Input<Real>& in) {
    return evaluate(o, f, convert<long double>(in));
}

// Error of `value` against `reference` in eps of Real: relative, or absolute for a direction. A reference
// below Real's normal range counts at the smallest normal's scale (Real cannot hold it more accurately).
template <class Real>
double error(long double value, long double reference, bool direction) {
    const long double smallest = std::numeric_limits<Real>::min();
    const long double scale = direction ? 1 : std::fmax(std::fabs(reference), smallest);
    return double(std::fabs(value - reference) / scale / std::numeric_limits<Real>::epsilon());
}

// The largest error (as above) that a change of one eps in one input causes.
template <class Real>
double condition(const Objects<long double>& o, int f, const Input<Real>& in, long double reference) {
    Input<long double> x = convert<long double>(in);
    long double* const inputs[7] = {&x.t, &x.wi.x, &x.wi.y, &x.wi.z, &x.wo.x, &x.wo.y, &x.wo.z};
    double worst = 0;
    for (long double* p : inputs) {
        const long double kept = *p;
        *p = kept * (1 + (long double)std::numeric_limits<Real>::epsilon());
        worst = std::fmax(worst, error<Real>(evaluate(o, f, x), reference, is_direction[f]));
        *p = kept;
    }
    return worst;
}

// Prints one line per function; returns false when a GPU or host value is outside its allowance.
template <class Real>
bool compare(const char* type, bool* cuda_ok) {
    const Objects<Real> o = make_objects<Real>();
    const Objects<long double> reference = make_objects<long double>();
    std::vector<Input<Real>> inputs(grid);
    for (int i = 0; i < grid; ++i) inputs[i] = make_input<Real>(i);
    const int n = functions * grid;
    Input<Real>* device_inputs = nullptr;
    Real* device = nullptr;
    std::vector<Real> gpu(n);
    *cuda_ok = cudaMalloc(&device_inputs, grid * sizeof(Input<Real>)) == cudaSuccess &&
               cudaMalloc(&device, n * sizeof(Real)) == cudaSuccess &&
               cudaMemcpy(device_inputs, inputs.data(), grid * sizeof(Input<Real>), cudaMemcpyHostToDevice) == cudaSuccess;
    if (*cuda_ok) {
        kernel<Real><<<(n + 127) / 128, 128>>>(o, device_inputs, device);
        *cuda_ok = cudaMemcpy(gpu.data(), device, n * sizeof(Real), cudaMemcpyDeviceToHost) == cudaSuccess;
    }
    cudaFree(device);
    cudaFree(device_inputs);
    if (!*cuda_ok) return false;
    bool pass = true;
    for (int f = 0; f < functions; ++f) {
        double gpu_worst = 0, host_worst = 0, used = 0;  // used: the largest error over its allowance
        for (int i = 0; i < grid; ++i) {
            const long double r = reference_value(reference, f, inputs[i]);
            const double allowed = 2 * condition(reference, f, inputs[i], r) + 8;
            const double e_gpu = error<Real>(gpu[f * grid + i], r, is_direction[f]);
            const double e_host = error<Real>(evaluate(o, f, inputs[i]), r, is_direction[f]);
            gpu_worst = std::fmax(gpu_worst, e_gpu);
            host_worst = std::fmax(host_worst, e_host);
            used = std::fmax(used, std::fmax(e_gpu, e_host) / allowed);
        }
        std::printf("%-28s %-6s GPU %7.1f  host %7.1f eps%-11s  at most %4.2f of the allowance%s\n", names[f], type,
                    gpu_worst, host_worst, is_direction[f] ? " (absolute)" : "", used, used > 1 ? "  FAIL" : "");
        pass = pass && used <= 1;
    }
    return pass;
}

}  // namespace

int main() {
    int count = 0;
    if (cudaGetDeviceCount(&count) != cudaSuccess || count == 0) {
        std::printf("gpu_check: no CUDA device here; the device code compiled, nothing was run\n");
        return 0;
    }
    std::printf("largest error against the host's long double evaluation of the same inputs, in eps:\n");
    bool cuda_ok = true;
    const bool pass_double = compare<double>("double", &cuda_ok);
    if (!cuda_ok) {
        std::printf("gpu_check: a CUDA call failed\n");
        return 1;
    }
    const bool pass_float = compare<float>("float", &cuda_ok);
    if (!cuda_ok) {
        std::printf("gpu_check: a CUDA call failed\n");
        return 1;
    }
    std::printf("%s: every GPU and host value within 2 condition + 8 eps of the reference\n",
                pass_double && pass_float ? "pass" : "FAIL");
    return pass_double && pass_float ? 0 : 1;
}
