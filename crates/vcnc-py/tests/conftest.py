"""Shared fixtures: the repository root, the command-line binary, the EMPS data."""

import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
EMPS = ROOT / "tests" / "data" / "emps" / "DATA_EMPS.csv"


def vcnc_bin():
    """The command line to compare against: $VCNC_BIN, else the workspace's release build."""
    b = os.environ.get("VCNC_BIN") or str(ROOT / "target" / "release" / "vcnc")
    return b if os.path.exists(b) else shutil.which("vcnc")


@pytest.fixture(scope="session")
def cli():
    b = vcnc_bin()
    if b is None:
        pytest.skip("the vcnc binary is not built (cargo build --release)")

    def run(*args):
        r = subprocess.run([b, *map(str, args)], cwd=ROOT, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return r

    return run


@pytest.fixture(scope="session")
def emps():
    """EMPS estimation data: t [s], qg reference [m], qm measured [m] (tests/data/emps)."""
    d = np.loadtxt(EMPS, delimiter=",", comments="#", skiprows=0, dtype=str)
    header = list(d[0])
    v = d[1:].astype(np.float64)
    return {name: np.ascontiguousarray(v[:, i]) for i, name in enumerate(header)}
