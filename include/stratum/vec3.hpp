// stratum/vec3.hpp -- the minimal 3-vector that renderer glue needs.
//
// Directions are unit vectors in the local shading frame: z is the macro-surface normal, pointing
// into medium 1 ("above"). Renderer-facing functions take wi (towards the light) and wo (towards
// the viewer), both pointing away from the surface (pbrt's convention).
#pragma once

#include <cmath>

#include "detail/config.hpp"

namespace stratum {

template <class Real = double>
struct Vec3 {
    Real x{}, y{}, z{};
};

template <class Real>
STRATUM_HOST_DEVICE constexpr Vec3<Real> operator+(Vec3<Real> a, Vec3<Real> b) noexcept { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <class Real>
STRATUM_HOST_DEVICE constexpr Vec3<Real> operator-(Vec3<Real> a, Vec3<Real> b) noexcept { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <class Real>
STRATUM_HOST_DEVICE constexpr Vec3<Real> operator-(Vec3<Real> a) noexcept { return {-a.x, -a.y, -a.z}; }
template <class Real>
STRATUM_HOST_DEVICE constexpr Vec3<Real> operator*(Real s, Vec3<Real> a) noexcept { return {s * a.x, s * a.y, s * a.z}; }
template <class Real>
STRATUM_HOST_DEVICE constexpr Vec3<Real> operator*(Vec3<Real> a, Real s) noexcept { return s * a; }

template <class Real>
STRATUM_HOST_DEVICE constexpr Real dot(Vec3<Real> a, Vec3<Real> b) noexcept { return a.x * b.x + a.y * b.y + a.z * b.z; }

template <class Real>
STRATUM_HOST_DEVICE constexpr Vec3<Real> cross(Vec3<Real> a, Vec3<Real> b) noexcept {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

template <class Real>
STRATUM_HOST_DEVICE Real length(Vec3<Real> a) noexcept { return std::sqrt(dot(a, a)); }

/// No component is NaN or infinite.
template <class Real>
STRATUM_HOST_DEVICE bool all_finite(Vec3<Real> a) noexcept {
    return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

/// a / |a|; the zero vector is returned unchanged (no NaN).
template <class Real>
STRATUM_HOST_DEVICE Vec3<Real> normalize(Vec3<Real> a) noexcept {
    const Real len = length(a);
    return len > 0 ? (Real(1) / len) * a : a;
}

/// The unit vector with polar cosine mu (from +z) and azimuth phi.
template <class Real>
STRATUM_HOST_DEVICE Vec3<Real> spherical_direction(Real mu, Real phi) noexcept {
    const Real s = std::sqrt(std::fmax(Real(0), (Real(1) - mu) * (Real(1) + mu)));
    return {s * std::cos(phi), s * std::sin(phi), mu};
}

}  // namespace stratum
