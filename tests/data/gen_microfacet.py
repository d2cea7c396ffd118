#!/usr/bin/env python3
"""Reference values for tests/test_microfacet.cpp, in 40-digit arithmetic (mpmath).

Smith's Lambda for a Gaussian (Beckmann) surface, van Ginneken et al. 1998:
  Lambda(a) = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2,  a = cot(theta) / alpha,  G1 = 1 / (1 + Lambda).
Each value is checked against the integral form Lambda(a) = (1/2) int_a^inf exp(-t^2) / (sqrt(pi) t^2) dt
as a check that the closed form is typed correctly.
Run: /usr/bin/python3 tests/data/gen_microfacet.py
"""
import mpmath as mp

mp.mp.dps = 40


def lam(a):
    a = mp.mpf(a)
    return (mp.exp(-a * a) / (a * mp.sqrt(mp.pi)) - mp.erfc(a)) / 2


def lam_integral(a):
    # t = a + u: exp(-t^2) = exp(-a^2) exp(-2 a u - u^2), with the exp(-a^2) scale taken out of the quadrature.
    a = mp.mpf(a)
    f = lambda u: mp.exp(-2 * a * u - u * u) / (mp.sqrt(mp.pi) * (a + u) ** 2)
    return mp.exp(-a * a) * mp.quad(f, [0, 1 / a, 4 / a, 16 / a, 64 / a, mp.inf]) / 2


if __name__ == "__main__":
    print("// G1 at a = 0.1, 0.5, 1")
    for a in ["0.1", "0.5", "1"]:
        assert abs(lam(a) - lam_integral(a)) < mp.mpf(10) ** -30
        print("{%s, %s}," % (a, mp.nstr(1 / (1 + lam(a)), 20)))
    print("// Lambda at sigma = 0.5 (alpha = sqrt(2)/2 exactly) for exactly representable mu: {mu, Lambda}, a in comment")
    alpha = mp.sqrt(2) / 2
    for mu in ["0.0007", "0.035", "0.2", "0.58", "0.817", "0.927", "0.9622", "0.9623", "0.98", "0.9966", "0.9985"]:
        m = mp.mpf(float(mu))  # the double nearest to mu, exactly
        a = m / (alpha * mp.sqrt(1 - m * m))
        assert abs(lam(a) / lam_integral(a) - 1) < mp.mpf(10) ** -25
        print("{%s, %s},  // a = %s" % (mu, mp.nstr(lam(a), 20), mp.nstr(a, 6)))
