"""Identify the EMPS drive (a real ball-screw axis, tests/data/emps) and plot the validation.

    python crates/vcnc-py/examples/identify_emps.py [OUT.png]
"""

import pathlib
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no window
import matplotlib.pyplot as plt
import numpy as np

import vcnc

ROOT = pathlib.Path(__file__).resolve().parents[3]
data = np.genfromtxt(ROOT / "tests/data/emps/DATA_EMPS.csv", delimiter=",", names=True, skip_header=3)
ident = vcnc.identify(data["t"], data["qg"], data["qm"], units="m")
m = ident.model
print(f"structure {ident.structure}, poles {m.poles}, dc {m.dc:.1f} mm/s²")
v = ident.validation
fig, (a, b) = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
a.plot(v["t"], v["xr"] - v["x"], label="measured x_r − x")
a.plot(v["t"], v["xr"] - v["x_model"], label="model x_r − x̂")
a.set_ylabel("tracking error [mm]")
a.legend()
b.plot(v["t"], (v["x"] - v["x_model"]) * 1000.0)
b.set_ylabel("x − x̂ [µm]")
b.set_xlabel("t [s]")
fig.suptitle(f"EMPS: fit {ident.fit['fit_percent']:.1f} %")
out = sys.argv[1] if len(sys.argv) > 1 else "emps_validation.png"
fig.savefig(out, dpi=80)
print(f"-> {out}")
