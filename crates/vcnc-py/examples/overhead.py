"""Time of identify from Python against the command line on a long trace (the issue's < 5 %).

    python crates/vcnc-py/examples/overhead.py VCNC_BIN [REPEATS]

The trace: the EMPS estimation set repeated end to end (26 times: 645 970 samples at 1 ms),
written as CSV. Runs alternate (CLI, Python file, Python arrays) so that load on the machine
hits all three alike.
"""

import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

import vcnc

ROOT = pathlib.Path(__file__).resolve().parents[3]
d = np.genfromtxt(ROOT / "tests/data/emps/DATA_EMPS.csv", delimiter=",", names=True, skip_header=3)
k = 26
n = len(d["t"])
t = np.arange(n * k) * 1e-3
qg = np.concatenate([d["qg"] for _ in range(k)])
qm = np.concatenate([d["qm"] for _ in range(k)])
tmp = pathlib.Path(tempfile.mkdtemp())
path = tmp / "long.csv"
np.savetxt(path, np.c_[t, qg, qm], delimiter=",", header="t,qg,qm", comments="", fmt="%.17g")
print(f"{len(t)} samples -> {path}")
binary, repeats = sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 2
args = ["--units", "m", "--xr-col", "qg", "--x-col", "qm", "--seed", "1"]
times = {"cli": [], "py-file": [], "py-arrays": []}
for r in range(repeats):
    s = time.perf_counter()
    subprocess.run([binary, "--quiet", "identify", "--trace", path, *args, "--out", tmp / "out"], check=True)
    times["cli"].append(time.perf_counter() - s)
    s = time.perf_counter()
    [a] = vcnc.identify_trace(path, units="m", xr_col="qg", x_col="qm", seed=1)
    a.to_toml()
    times["py-file"].append(time.perf_counter() - s)
    s = time.perf_counter()
    b = vcnc.identify(t, qg, qm, units="m", seed=1, name=str(path))
    b.to_toml()
    times["py-arrays"].append(time.perf_counter() - s)
    print({k: round(v[-1], 2) for k, v in times.items()}, flush=True)
same = (tmp / "out" / "model.toml").read_text() == a.to_toml() == b.to_toml()
best = {k: min(v) for k, v in times.items()}
print("best of", repeats, {k: round(v, 2) for k, v in best.items()}, "same model.toml:", same)
for k in ("py-file", "py-arrays"):
    print(f"{k}: {100 * (best[k] / best['cli'] - 1):+.1f} % against the CLI")
