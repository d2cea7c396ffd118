#!/usr/bin/env python3
"""Reference values for tests/test_fresnel.cpp, in 50-digit arithmetic (mpmath).

F_h(eta) = 2 int_0^1 F(c, eta) c dc for unpolarized Fresnel reflectance with eta = n_t / n_i.
Run: python3 tests/data/gen_fresnel.py
"""
import mpmath as mp

mp.mp.dps = 50


def fresnel(c, eta):
    m2 = c * c + eta * eta - 1
    if m2 <= 0:
        return mp.mpf(1)
    m = mp.sqrt(m2)
    rs = (c - m) / (c + m)
    rp = (eta * eta * c - m) / (eta * eta * c + m)
    return (rs * rs + rp * rp) / 2


def hemispherical(eta):
    eta = mp.mpf(eta)
    pts = [0, 1]
    if eta < 1:
        pts = [0, mp.sqrt(1 - eta * eta), 1]
    return 2 * mp.quad(lambda c: fresnel(c, eta) * c, pts)


if __name__ == "__main__":
    for eta in ["1.3", "1/1.3", "1.4", "1/1.4", "2.5", "1/2.5"]:
        e = mp.mpf(eval(eta.replace("1/", "mp.mpf(1)/")))
        print(f"eta = {eta:6s} F_h = {mp.nstr(hemispherical(e), 20)}")
