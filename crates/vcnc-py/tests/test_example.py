"""The example script runs (matplotlib Agg, no window) and writes its figure."""

import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("matplotlib")


def test_identify_emps_example(tmp_path):
    script = pathlib.Path(__file__).resolve().parents[1] / "examples" / "identify_emps.py"
    out = tmp_path / "v.png"
    r = subprocess.run([sys.executable, script, out], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 1000
