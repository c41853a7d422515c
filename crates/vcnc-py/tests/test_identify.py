"""Identification from Python equals `vcnc identify --trace` (the EMPS benchmark, a real drive)."""

import numpy as np
import pytest

import vcnc
from conftest import EMPS, ROOT


def test_identify_arrays_writes_the_cli_model_toml(cli, emps, tmp_path):
    # Truth: the command line's model.toml of the same data (same calls, bit for bit).
    rel = EMPS.relative_to(ROOT)
    cli("identify", "--trace", rel, "--units", "m", "--xr-col", "qg", "--x-col", "qm", "--out", tmp_path)
    expected = (tmp_path / "model.toml").read_text()
    ident = vcnc.identify(emps["t"], emps["qg"], emps["qm"], units="m", name=str(rel))
    assert ident.to_toml() == expected
    # The file route gives the same model.
    [from_file] = vcnc.identify_trace(rel, units="m", xr_col="qg", x_col="qm")
    assert from_file.to_toml() == expected
    # And the model file reads back to the same model.
    (tmp_path / "py.toml").write_text(ident.to_toml())
    m = vcnc.Model.from_toml(tmp_path / "py.toml")
    assert m.parameters == ident.model.parameters


def test_identification_carries_what_a_user_plots(emps):
    ident = vcnc.identify(emps["t"], emps["qg"], emps["qm"], units="m", structures=["paper"])
    assert ident.axis == "X" and ident.unit == "mm" and ident.structure == "paper"
    m = ident.model
    poles = m.poles
    assert poles is not None and poles["wn_hz"] > 0 and poles["zeta"] > 0
    assert {s["structure"] for s in ident.structures} == {"paper"}
    v = ident.validation
    assert len(v["t"]) == len(v["xr"]) == len(v["x"]) == len(v["x_model"]) == len(emps["t"])
    # The free run of Model.simulate is the model's, in mm: it follows the measured x to well
    # within the tracking error it explains (the summary's fit, an independent computation).
    x_sim = m.simulate(v["xr"], v["t"][1] - v["t"][0])
    assert x_sim.shape == v["x"].shape
    rms = float(np.sqrt(np.mean((x_sim - v["x"]) ** 2)))
    assert rms < float(np.sqrt(np.mean((v["xr"] - v["x"]) ** 2)))
    # Frequency response: unity at DC for a type-1 loop within 1 %, and complex.
    h = m.frf([0.01, 1.0, 10.0])
    assert h.dtype == np.complex128 and abs(abs(h[0]) - 1.0) < 0.01
    # Validation on the same samples equals the identification's own fit.
    fit = m.validate(emps["t"], emps["qg"], emps["qm"], units="m")
    assert fit["fit"]["freerun_rms_um"] == pytest.approx(ident.fit["freerun_rms_um"], rel=1e-9)


def test_bad_input_is_a_value_error_naming_the_sample(emps):
    t = emps["t"].copy()
    t[10] = t[9]  # time stands still at sample 10: line 12 of the arrays' text
    with pytest.raises(ValueError, match="<arrays>:12: time does not increase"):
        vcnc.identify(t, emps["qg"], emps["qm"], units="m")
    x = emps["qm"].copy()
    x[3] = np.nan
    with pytest.raises(ValueError, match="<arrays>:5: x is NaN"):
        vcnc.identify(emps["t"], emps["qg"], x, units="m")
    with pytest.raises(ValueError, match="xr 24840, x 24841"):
        vcnc.identify(emps["t"], emps["qg"][:-1], emps["qm"], units="m")
    with pytest.raises(ValueError, match="units"):
        vcnc.identify(emps["t"], emps["qg"], emps["qm"], units="furlong")
    with pytest.raises(ValueError, match="cannot read"):
        vcnc.identify_trace(ROOT / "no-such-trace.csv")
    with pytest.raises(ValueError, match="unknown trace option 'xr_column'; the options are ts, units"):
        vcnc.read_trace(EMPS, xr_column="qg")
    with pytest.raises(ValueError, match="trace option ts=fast"):
        vcnc.identify_trace(EMPS, ts="fast")


def test_fresh_random_trace_round_trips_through_read_trace(tmp_path):
    seed = int(np.random.SeedSequence().entropy % 2**32)
    print(f"seed {seed}")
    rng = np.random.default_rng(seed)
    n = 500
    t = np.arange(n) * 1e-3
    xr = np.cumsum(rng.normal(size=n))
    x = xr + rng.normal(scale=1e-3, size=n)
    path = tmp_path / "trace.csv"
    np.savetxt(path, np.c_[t, xr, x], delimiter=",", header="t,X_nominal,X_actual", comments="", fmt="%.17g")
    tr = vcnc.read_trace(path, xr_col="X_nominal", x_col="X_actual")
    names = [c.name for c in tr.channels]
    assert names == ["X_nominal", "X_actual"]
    assert np.array_equal(tr.channels[0].samples, xr)
    [a] = tr.pair()
    assert a.axis == "X" and np.array_equal(a.nominal, xr) and np.array_equal(a.actual, x)
    assert a.ts_s == pytest.approx(1e-3, rel=1e-12)
