#!/usr/bin/env python3
"""Mean and standard error (pixel-to-pixel spread / sqrt(N)) of the green channel (and of R, B) of PFM files."""
import struct, sys, math
def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        nc = 3 if kind == b"PF" else 1
        data = f.read()
    fmt = ("<" if scale < 0 else ">") + "f" * (w * h * nc)
    v = struct.unpack(fmt, data)
    return [v[c::nc] for c in range(nc)]
import os
for p in sys.argv[1:]:
    if not os.path.exists(p):
        print(p, 'MISSING (render aborted)'); continue
    ch = read_pfm(p)
    out = []
    for c in ch:
        n = len(c); m = sum(c) / n
        sd = math.sqrt(sum((x - m) ** 2 for x in c) / (n - 1))
        out.append((m, sd / math.sqrt(n)))
    print(p, " ".join(f"{m:.8f} {se:.8f}" for m, se in out))
