// stratum/detail/config.hpp -- compiler and platform switches used by every header.
//
// STRATUM_HOST_DEVICE marks the pointwise evaluation functions (Fresnel, Beckmann, RoughDielectric
// evaluation and sampling, Henyey-Greenstein, the dipole, Lambert W, Vec3) so that CUDA and HIP compile
// them for the GPU as well as the host. Constructors, which validate, stay host-only: build the objects
// on the host and copy them to the device (they are trivially copyable). nvcc also needs
// --expt-relaxed-constexpr (std::numeric_limits is constexpr, not __device__).
//
// STRATUM_EXCEPTIONS is 1 when the compiler has exceptions enabled. Without them (-fno-exceptions) a
// rejected parameter is reported through stratum::invalid_parameter_handler (detail/validate.hpp), which
// by default prints the message and aborts.
#pragma once

#if defined(__CUDACC__) || defined(__HIPCC__)
#define STRATUM_HOST_DEVICE __host__ __device__
#else
#define STRATUM_HOST_DEVICE
#endif

#if defined(__cpp_exceptions) || defined(__EXCEPTIONS) || defined(_CPPUNWIND)
#define STRATUM_EXCEPTIONS 1
#else
#define STRATUM_EXCEPTIONS 0
#endif
