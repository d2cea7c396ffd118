// stratum/adding.hpp -- the adding equations: the operators of two stacked components (interface over
// slab, slab over slab, ...) combined into the operators of the stack, one Fourier mode at a time.
//
// Convention. A component is described, for one Fourier mode k and M ordinates, by four M x M row-major
// operators of the kind of docs/physics.md section 5 (row n = outgoing ordinate, column m = incoming
// ordinate, radiance coefficients in propagation directions, out = L in):
//   reflection_down   light arriving from above (travelling down), reflected back up, out of the top;
//   transmission_down light arriving from above, transmitted down, out of the bottom;
//   reflection_up     light arriving from below (travelling up), reflected back down, out of the bottom;
//   transmission_up   light arriving from below, transmitted up, out of the top.
// Both components must use the same ordinates for the medium between them.
//
// Derivation (component 1 on top of component 2). Light from above with coefficients x: let D be the
// downward and U the upward radiance between the two. Then D = T1d x + R1u U and U = R2d D, so
//     D = (I - R1u R2d)^{-1} T1d x,
//     R_d = R1d + T1u R2d (I - R1u R2d)^{-1} T1d,        T_d = T2d (I - R1u R2d)^{-1} T1d,
// and from below, with U = T2u x + R2d D, D = R1u U:
//     R_u = R2u + T2d R1u (I - R2d R1u)^{-1} T2u,        T_u = T1u (I - R2d R1u)^{-1} T2u.
// (I - R1u R2d)^{-1} is the sum of the multiple reflections between the components. It exists whenever
// light between them is eventually lost (absorbed or transmitted out); for two lossless, totally
// reflecting components trapping light at some ordinate it is singular: the LU then replaces the zero
// pivot by a tiny number (results stay finite but that trapped ordinate is meaningless).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <utility>
#include <vector>

#include "detail/linalg.hpp"
#include "detail/validate.hpp"

namespace stratum {

/// The four operators of one component for one Fourier mode (see the header comment), each size x size.
template <class Real = double>
struct ComponentOperators {
    std::size_t size = 0;
    std::vector<Real> reflection_down, transmission_down, reflection_up, transmission_up;
};

namespace detail {

template <class Real>
Matrix<Real> as_matrix(std::size_t n, const std::vector<Real>& v) {
    if (v.size() != n * n) detail::fail_invalid_argument("stratum: component operator is not size x size");
    Matrix<Real> m(n, n);
    m.data = v;
    return m;
}

/// (I - A B)
template <class Real>
Matrix<Real> one_minus_product(const Matrix<Real>& a, const Matrix<Real>& b) {
    Matrix<Real> m = multiply(a, b);
    for (Real& x : m.data) x = -x;
    for (std::size_t i = 0; i < m.rows; ++i) m(i, i) += Real(1);
    return m;
}

}  // namespace detail

namespace detail {

/// The half of the adding for light from above (out.reflection_down, out.transmission_down); x receives
/// (I - R1u R2d)^{-1} T1d, the down-going light between the components per unit coming in. Without `transmission`
/// out.transmission_down = T2d x is left empty (a caller that needs only x, or applies T2d x to fewer columns).
template <class Real>
void add_from_above(const ComponentOperators<Real>& top, const ComponentOperators<Real>& bottom, Matrix<Real>& x,
                    ComponentOperators<Real>& out, bool transmission = true) {
    const std::size_t n = top.size;
    x = as_matrix(n, top.transmission_down);
    const Matrix<Real> r2d = as_matrix(n, bottom.reflection_down);
    lu_solve(lu_factor(one_minus_product(as_matrix(n, top.reflection_up), r2d)), x);
    Matrix<Real> rd = multiply(as_matrix(n, top.transmission_up), multiply(r2d, x));
    const Matrix<Real> r1d = as_matrix(n, top.reflection_down);
    for (std::size_t i = 0; i < n * n; ++i) rd.data[i] += r1d.data[i];
    out.size = n;
    out.reflection_down = std::move(rd.data);
    if (transmission) out.transmission_down = multiply(as_matrix(n, bottom.transmission_down), x).data;
}

/// The half of the adding for light from below (out.reflection_up, out.transmission_up): the half from above
/// for the stack turned over (each component's up and down exchanged, bottom on top).
template <class Real>
void add_from_below(const ComponentOperators<Real>& top, const ComponentOperators<Real>& bottom,
                    ComponentOperators<Real>& out) {
    auto turned = [](const ComponentOperators<Real>& c) {
        return ComponentOperators<Real>{c.size, c.reflection_up, c.transmission_up, c.reflection_down, c.transmission_down};
    };
    ComponentOperators<Real> half;
    Matrix<Real> y;
    add_from_above(turned(bottom), turned(top), y, half);
    out.size = top.size;
    out.reflection_up = std::move(half.reflection_down);
    out.transmission_up = std::move(half.transmission_down);
}

}  // namespace detail

/// The operators of `top` stacked on `bottom` (same size). ~ 14 M^3 flops.
/// Throws std::invalid_argument if the sizes differ.
template <class Real>
ComponentOperators<Real> add_components(const ComponentOperators<Real>& top, const ComponentOperators<Real>& bottom) {
    if (top.size != bottom.size) detail::fail_invalid_argument("stratum: adding components of different sizes");
    ComponentOperators<Real> out;
    detail::Matrix<Real> x;
    detail::add_from_above(top, bottom, x, out);
    detail::add_from_below(top, bottom, out);
    return out;
}

/// Doubling: 2^doublings identical copies of `c` stacked (c itself for doublings = 0).
template <class Real>
ComponentOperators<Real> double_component(ComponentOperators<Real> c, int doublings) {
    detail::require_count("doublings", doublings, 0);
    for (int i = 0; i < doublings; ++i) c = add_components(c, c);
    return c;
}

}  // namespace stratum
