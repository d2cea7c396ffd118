#!/usr/bin/env python3
"""Writes the pbrt-v3 scene files under scenes/: a 200 x 200 square in the z = 0 plane (normal +z by its
counter-clockwise winding), material from a .bsdf file, lit only by a uniform infinite light of radiance 1,
seen by an orthographic camera whose viewing direction makes angle theta with the normal (from above or below)."""
import math, os, sys

RES = int(os.environ.get("RES", 16))
SPP = int(os.environ.get("SPP", 4096))
SAMPLER = os.environ.get("SAMPLER", "random")  # or "stratified" (jittered, SPP = 64 x SPP/64)
ANGLES = [float(a) for a in os.environ.get("ANGLES", "0 30 60 75").split()]
here = os.path.dirname(os.path.abspath(__file__))
os.makedirs(os.path.join(here, "scenes"), exist_ok=True)

def scene(material, theta_deg, below, integrator):
    t = math.radians(theta_deg)
    ex, ez = 10 * math.sin(t), 10 * math.cos(t) * (-1 if below else 1)
    sampler = (f'Sampler "random" "integer pixelsamples" [{SPP}]' if SAMPLER == "random" else
               f'Sampler "stratified" "integer xsamples" [64] "integer ysamples" [{SPP // 64}] "bool jitter" "true"')
    integ = {"direct": 'Integrator "directlighting"',
             "path": 'Integrator "path" "integer maxdepth" [1]'}[integrator]
    return f"""# stratum pbrt-v3 check: square under a uniform white environment, theta_o = {theta_deg:g} deg, viewer {'below' if below else 'above'}
LookAt {ex:.9f} 0 {ez:.9f}  0 0 0  0 1 0
Camera "orthographic"
Film "image" "integer xresolution" [{RES}] "integer yresolution" [{RES}] "string filename" "out.pfm"
{sampler}
PixelFilter "box"
{integ}
WorldBegin
AttributeBegin
LightSource "infinite" "rgb L" [1 1 1]
AttributeEnd
AttributeBegin
{material}
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point P" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]
AttributeEnd
WorldEnd
"""

materials = {
    "skin1": 'Material "fourier" "string bsdffile" "../skin.bsdf"',    # one-sided table (light from above)
    "skin2": 'Material "fourier" "string bsdffile" "../skin2.bsdf"',   # two-sided table (layer + layer turned over)
    # control: pbrt-v3's own test table (layerlab's roughgold_alpha_0.2.bsdf, extracted from pbrt-v3/src/tests/fourierbsdf.cpp)
    "gold": 'Material "fourier" "string bsdffile" "../roughgold.bsdf"',
    "matte": 'Material "matte" "rgb Kd" [0.5 0.5 0.5]',                 # pipeline check: expect 0.5 above, 0 below
}
names = []
for mat in sys.argv[1:] or materials:
    for below in (False, True):
        for th in ANGLES:
            for integ in ("direct", "path"):
                name = f"{mat}_{'below' if below else 'above'}_{th:04.1f}_{integ}" + ("" if SAMPLER == "random" else "_" + SAMPLER) if th != int(th) else f"{mat}_{'below' if below else 'above'}_{int(th):02d}_{integ}" + ("" if SAMPLER == "random" else "_" + SAMPLER)
                with open(os.path.join(here, "scenes", name + ".pbrt"), "w") as f:
                    f.write(scene(materials[mat], th, below, integ))
                names.append(name)
print("\n".join(names))
