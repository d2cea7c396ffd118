#!/usr/bin/env python3
"""Rendered vs expected pixel values.
Expected: expect_<file>.txt (./expect_file: E = int f(wi, wo)|wi.z| dw_i from the .bsdf file via stratum's
PbrtBsdfTable::eval) for skin1 = skin.bsdf, skin2 = skin2.bsdf, gold = roughgold.bsdf (per channel R, G, B);
E_table from export_skin.out (TabulatedBSDF::eval integrated; 6 decimals); matte 0.5.
Rendered: renders/results_*.txt (mean and standard error of the 32x32 pixels, per channel)."""
import glob, math, re, sys
def load_expect(path):
    d = {}
    for line in open(path):
        if line.startswith("#"): continue
        v = line.split()
        d[(v[0], float(v[1]))] = [float(x) for x in v[3:7]]  # Y, R, G, B
    return d
EXP = {"skin1": load_expect("expect_skin.txt"), "skin2": load_expect("expect_skin2.txt"),
       "gold": load_expect("expect_roughgold.txt")}
tab = {}
side = None
for line in open("export_skin.out"):
    if line.startswith("viewer ABOVE"): side = "above"
    elif line.startswith("viewer BELOW"): side = "below"
    elif side and re.match(r"^-?[01]\.\d{6} ", line):
        v = line.replace("|", " ").split()
        tab[(side, round(abs(float(v[0])), 6))] = (float(v[7]), float(v[8]))
rows = []
for f in sorted(glob.glob("renders/results_*.txt")):
    for line in open(f):
        v = line.split()
        name = v[0].split("/")[-1][:-4]
        mat, sd, th, integ, smp = re.match(r"(\w+?)_(above|below)_([\d.]+)_(direct|path)(_\w+)?$", name).groups()
        vals = None if v[1] == "MISSING" else [float(x) for x in v[1:7]]
        rows.append((mat, sd, float(th), integ, (smp or "_random")[1:], vals))
print(f"{'material':8} {'viewer':6} {'theta':>5} {'integr.':7} {'sampler':10} {'ch':2} {'rendered':>9} {'s.e.':>8} {'E_file':>9} {'ratio':>8} {'z':>7} {'E_table':>9} {'ratio':>8}")
zs = {}
for mat, sd, th, integ, smp, vals in sorted(set((r[0], r[1], r[2], r[3], r[4], tuple(r[5]) if r[5] else None) for r in rows)):
    chans = [("G", 1)] if mat != "gold" else [("R", 0), ("G", 1), ("B", 2)]
    for cname, c in chans:
        if mat == "matte": ef, et = 0.5, 0.5
        else:
            e = EXP[mat][(sd, th)]
            ef = e[0] if mat != "gold" else e[1 + c]
            t = tab.get((sd, round(math.cos(math.radians(th)), 6)))
            et = (t[0] if mat == "skin1" else t[1]) if t and mat != "gold" else float("nan")
        if vals is None:
            print(f"{mat:8} {sd:6} {th:5g} {integ:7} {smp:10} {cname:2} {'aborted: pbrt CHECK failed on a NaN':>36}   E_file {ef:.6f}")
            continue
        m, se = vals[2 * c], vals[2 * c + 1]
        z = (m - ef) / se if se > 0 else float("nan")
        if th >= 30: zs.setdefault((integ, smp), []).append(z)
        print(f"{mat:8} {sd:6} {th:5g} {integ:7} {smp:10} {cname:2} {m:9.6f} {se:8.6f} {ef:9.6f} {m/ef if ef else float('nan'):8.5f} {z:7.2f} {et:9.6f} {m/et if et == et and et else float('nan'):8.5f}")
print("\nz = (rendered - E_file) / s.e. at theta >= 30, pooled per integrator and sampler (gold: each channel):")
for k, v in sorted(zs.items()):
    v = [x for x in v if x == x]
    print(f"  {k[0]:7} {k[1]:10} n={len(v):2}  mean z {sum(v)/len(v):+.2f}  rms z {math.sqrt(sum(x*x for x in v)/len(v)):.2f}  max |z| {max(abs(x) for x in v):.2f}")
