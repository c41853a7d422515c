"""Machine runs from Python equal the command line's (the embedded spiral, machines/nmv5000.toml)."""

import csv

import numpy as np
import pytest

import vcnc
from conftest import ROOT

MACHINE = ROOT / "machines" / "nmv5000.toml"
SPIRAL = ROOT / "gcode" / "spiral.ngc"


@pytest.fixture(scope="module")
def models(emps, tmp_path_factory):
    """A model file for the five axes: the EMPS drive's model on each (units per axis)."""
    ident = vcnc.identify(emps["t"], emps["qg"], emps["qm"], units="m", structures=["paper"])
    x = ident.model.to_toml(machine="NMV5000").split("[axes.X]", 1)
    head, body = x[0], x[1]
    text = head
    for a, unit in [("X", "mm"), ("Y", "mm"), ("Z", "mm"), ("A", "deg"), ("C", "deg")]:
        text += f"[axes.{a}]" + body.replace('unit = "mm"', f'unit = "{unit}"')
    p = tmp_path_factory.mktemp("models") / "model.toml"
    p.write_text(text)
    return p


def test_predict_spiral_equals_cli_contour_errors(cli, models, tmp_path):
    cli("predict", MACHINE, SPIRAL, "--model", models, "--out", tmp_path)
    with open(tmp_path / "contour.csv") as f:
        rows = list(csv.reader(f))
    header, values = rows[0], np.array(rows[1:], dtype=np.float64)
    cols, summary = vcnc.Machine(MACHINE).predict(SPIRAL, models)
    assert list(cols) == header
    for i, name in enumerate(header):
        # The CSV holds Rust's shortest exact text of each number: equal bit for bit.
        assert np.array_equal(cols[name], values[:, i]), name
    import json

    cli_summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["contour_um"] == cli_summary["contour_um"]


def test_interpolate_simulate_and_kinematics(models):
    m = vcnc.Machine(MACHINE)
    assert m.axes == ["X", "Y", "Z", "A", "C"]
    ref, s = m.interpolate(SPIRAL)
    assert s["samples"] == len(ref["t"]) if "samples" in s else True
    trace, s2 = m.simulate(SPIRAL, models)
    assert set(trace) >= {"t", "X_ref", "X_act", "X_model"}
    assert np.array_equal(trace["X_ref"], ref["X"])
    # FK then IK returns the axes (the kinematics' own round trip, within 1e-9 mm / deg).
    axes = np.c_[ref["X"], ref["Y"], ref["Z"], ref["A"], ref["C"]][::500]
    poses = m.kinematics.forward(axes)
    assert poses.shape == (len(axes), 6)
    back = m.kinematics.inverse(poses)
    assert np.max(np.abs(back - axes)) < 1e-6
    # A program as text.
    cols, _ = m.interpolate("G21 G90\nG1 X10 F600\nM2\n")
    assert cols["X"][-1] == pytest.approx(10.0)
    with pytest.raises(ValueError):
        m.interpolate("G1 X1e9 F600\nM2\n")


def _models_only(models, tmp_path):
    """The NMV5000's machine file with every plant, controller and encoder removed and
    `models` named as the machine's own (a machine known only by identified models)."""
    out = []
    for line in MACHINE.read_text().splitlines():
        if line.startswith(("plant =", "controller =", "encoder =")):
            continue
        if line.startswith("urdf ="):
            line = f'urdf = "{ROOT / "machines" / "nmv5000.urdf"}"'
        out.append(line)
        if line.startswith("sample_period_s"):
            out.append(f'model = "{models}"')
    p = tmp_path / "models-only.toml"
    p.write_text("\n".join(out) + "\n")
    return p


def test_a_models_only_machine_predicts_what_the_full_machine_predicts(models, tmp_path):
    # Truth: the full NMV5000 predicting with the same model file. The models-only machine's
    # true machine is those models, so its prediction equals the full machine's bit for bit
    # and its "true" columns equal its predicted ones.
    full, full_summary = vcnc.Machine(MACHINE).predict(SPIRAL, models)
    only, only_summary = vcnc.Machine(_models_only(models, tmp_path)).predict(SPIRAL)
    assert list(only) == list(full)
    true_cols = [n for n in only if "true" in n]
    assert len(true_cols) == 5 + 6 + 2
    for name in only:
        if name in true_cols:
            assert np.array_equal(only[name], only[name.replace("true", "pred")]), name
        else:
            assert np.array_equal(only[name], full[name]), name
    predicted = full_summary["contour_um"]
    assert only_summary["contour_um"]["predicted_max"] == predicted["predicted_max"]
    assert only_summary["contour_um"]["true_max"] == predicted["predicted_max"]
    assert only_summary["contour_um"]["discrepancy_max"] == 0.0
