#!/usr/bin/env python3
"""Reference values for tests/test_interface_operators.cpp, in 40-digit arithmetic (mpmath).

Von Mises lobe rho(phi) = exp(kappa (cos phi - 1)): its azimuthal Fourier coefficients are
  I_k = int_0^{2 pi} exp(kappa (cos phi - 1)) cos(k phi) dphi = 2 pi exp(-kappa) I_k(kappa)
with I_k the modified Bessel function of the first kind (Abramowitz & Stegun 9.6.19).
A Beckmann lobe is exactly of this shape in phi, with kappa = 1 / width^2.
Run: /usr/bin/python3 tests/data/gen_interface_operators.py > /dev/null  (prints the C++ table)
"""
import mpmath as mp

mp.mp.dps = 40

KAPPAS = ["0.5", "30", "2500", "1e6", "1e8"]
ORDERS = [0, 1, 2, 5, 10, 20, 47]

if __name__ == "__main__":
    for kappa in KAPPAS:
        kap = mp.mpf(kappa)
        for k in ORDERS:
            value = 2 * mp.pi * mp.besseli(k, kap) * mp.exp(-kap)
            # cross-check by direct quadrature for moderate kappa
            if kap <= 2500:
                direct = 2 * mp.quad(lambda p: mp.exp(kap * (mp.cos(p) - 1)) * mp.cos(k * p),
                                     mp.linspace(0, mp.pi, 64))
                assert abs(direct - value) <= mp.mpf("1e-30") * (1 + abs(value)), (kappa, k)
            print("        {%s, %d, %s}," % (kappa, k, mp.nstr(value, 20)))
