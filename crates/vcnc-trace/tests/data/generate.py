#!/usr/bin/env python3
"""Writes the vcnc-trace sample files of this folder (all but twincat/tc3_scope_*, which are
third-party, see twincat/README.md).

Every file holds the same kind of motion: per axis a cycloidal move of known length (the nominal
position) and the response of a second-order closed loop to it (the actual position), so the
files look like air-cutting recordings. The layouts follow the public descriptions cited in
README.md. Run from this folder: `python3 generate.py`. The tests check these files against the
motion defined here (see MOVES), so keep the two in step.
"""

import math

T = 1e-3  # s


def move(k, period, start_s, dur_s, dist):
    """Cycloidal move: 0 before start, dist after start + dur."""
    t = k * period - start_s
    if t <= 0:
        return 0.0
    if t >= dur_s:
        return dist
    u = t / dur_s
    return dist * (u - math.sin(2 * math.pi * u) / (2 * math.pi))


def follow(xr, period, wn=2 * math.pi * 40, zeta=0.7):
    """Actual position: x'' = wn^2 (xr - x) - 2 zeta wn x', integrated at period/20."""
    x, v, out = 0.0, 0.0, []
    h = period / 20
    for r in xr:
        out.append(x)
        for _ in range(20):
            a = wn * wn * (r - x) - 2 * zeta * wn * v
            v += h * a
            x += h * v
    return out


# (axis, start s, duration s, distance in axis units)
MOVES = {
    "X": (0.020, 0.150, 25.0),
    "Y": (0.040, 0.120, -12.5),
    "Z": (0.060, 0.100, 5.0),
    "A": (0.030, 0.160, 30.0),
    "B": (0.025, 0.150, 20.0),
    "C": (0.050, 0.140, -45.0),
}


def axis_signals(axis, n, period=T):
    start, dur, dist = MOVES[axis]
    xr = [move(k, period, start, dur, dist) for k in range(n)]
    return xr, follow(xr, period)


def write(path, text, encoding="utf-8"):
    with open(path, "w", encoding=encoding, newline="") as f:
        f.write(text)


def halscope_table():
    # LinuxCNC 2.9+ log of a 5-axis (XYZAC, trivkins coordinates=XYZAC) machine: 5 joints.
    n = 300
    names, cols = [], []
    for j, axis in enumerate("XYZAC"):
        xr, x = axis_signals(axis, n)
        names += [f"joint.{j}.motor-pos-cmd", f"joint.{j}.motor-pos-fb"]
        cols += [xr, x]
    vel = [(cols[0][k + 1] - cols[0][k]) / T if k + 1 < n else 0.0 for k in range(n)]
    ferr = [cols[0][k] - cols[1][k] for k in range(n)]
    names += ["joint.0.vel-cmd", "joint.0.f-error"]
    cols += [vel, ferr]
    lines = ["# Sampling period is 1000000 ns", ";".join(names)]
    lines.append("# Position: " + ";".join("0.500000" for _ in names))
    lines.append("# Scale: " + ";".join(str(s) for s in [2, 2, 2, 2, 2, 2, 5, 5, 5, 5, 8, -6]))
    for k in range(n):
        lines.append(";".join("%.14f" % c[k] for c in cols))
    write("halscope/xyzac-2.9.log", "\n".join(lines) + "\n")


def halscope_pairs():
    # LinuxCNC before 2.8 named joints axis.N; log of the "Save log" of that time.
    n = 200
    xr, x = axis_signals("X", n)
    yr, y = axis_signals("Y", n)
    names = ["axis.0.motor-pos-cmd", "axis.0.motor-pos-fb", "axis.1.motor-pos-cmd", "axis.1.motor-pos-fb"]
    cols = [xr, x, yr, y]
    out = "Sampling period is 1000000 ns \n"
    for k in range(n):
        out += "\n" + "".join("%s %+.14f " % (nm, c[k]) for nm, c in zip(names, cols))
    write("halscope/xy-pre2.9.log", out)


def halsampler_tagged():
    # halsampler -t of sampler cfg=ffff, pins netted to X and Z command/feedback; the first line
    # names the nets (the sampler_tools convention); 3 samples lost at one overrun.
    n = 260
    xr, x = axis_signals("X", n)
    zr, z = axis_signals("Z", n)
    lines = ["# x-pos-cmd x-pos-fb z-pos-cmd z-pos-fb"]
    lost_at, lost = 180, 3
    for k in range(n):
        if lost_at <= k < lost_at + lost:
            if k == lost_at:
                lines.append("overrun")
            continue
        lines.append("%d " % k + "".join("%f " % c[k] for c in (xr, x, zr, z)))
    write("halsampler/xz-tagged.txt", "\n".join(lines) + "\n")


def halsampler_plain():
    # halsampler without -t or names: two float pins; one overrun of unknown size.
    n = 150
    yr, y = axis_signals("Y", n)
    lines = []
    for k in range(n):
        if 100 <= k < 104:
            if k == 100:
                lines.append("overrun")
            continue
        lines.append("%f %f " % (yr[k], y[k]))
    write("halsampler/plain.txt", "\n".join(lines) + "\n")


def tncscope():
    # TNCscope export of X Y Z and C: positions at 600 us, X nominal at the 3 ms interpolator
    # cycle, Y in micrometres, a feed-rate and a current channel; written in Latin-1 (µ = 0xB5).
    cyc, n = 600, 500
    p = cyc * 1e-6
    curves = []
    for axis in "XYZC":
        xr, x = axis_signals(axis, n, p)
        unit = {"X": "mm", "Y": "\u00b5m", "Z": "mm", "C": "deg"}[axis]
        scale = 1000.0 if axis == "Y" else 1.0
        if axis == "X":
            curves.append(("X s soll", "s soll", "X", unit, 3000, [v * scale for v in xr[::5]]))
        else:
            curves.append((f"{axis} s soll", "s soll", axis, unit, cyc, [v * scale for v in xr]))
        curves.append((f"{axis} s ist", "s ist", axis, unit, cyc, [v * scale for v in x]))
    xr, _ = axis_signals("X", n, p)
    feed = [(xr[min(k + 1, n - 1)] - xr[k]) / p * 60 for k in range(n)]
    curves.append(("X v soll", "v soll", "X", "mm/min", cyc, feed))
    curves.append(("X I ist", "I ist", "X", "Ampere", cyc, [0.02 * f / 60 for f in feed]))
    out = ["%TNCscopeNT data file", "%[GLOBAL]", "CONTROL=TNC 640", "SOFTWARE=340590 10",
           "DATE=2024-03-14 10:21:07", "CURVES=%d" % len(curves)]
    for i, (name, ct, at, dim, cycle, s) in enumerate(curves):
        out += ["%%[CURVE%d]" % (i + 1), "NAME=" + name, "CHANNELTYPE=" + ct, "AXISTYPE=" + at,
                "DIMENSION=" + dim, "COUNT=%d" % len(s), "CYCLETIME=%d" % cycle]
    out.append("%[DATA]")
    for r in range(n):
        row = ["%d" % (r * cyc)]
        for (_, _, _, _, cycle, s) in curves:
            k = cycle // cyc
            row.append(" %.4f" % s[r // k] if r % k == 0 else " ")
        out.append(";".join(row) + ";")
    write("tncscope/xyzc.txt", "\r\n".join(out) + "\r\n", encoding="latin-1")


def sinumerik():
    # Sinumerik Operate servo trace of X1 and Y1 at the 2 ms position-control cycle; Y1's
    # signals only from the 11th record; unchanged values left out of records; one value
    # replaced by the "no value" marker.
    p, n = 2e-3, 150
    xr, x = axis_signals("X", n, p)
    yr, y = axis_signals("Y", n, p)
    sig = [
        ("1", "/Nck/ServoTrace/PositionSetpoint[X1]", "Position setpoint X1", "mm", xr),
        ("2", "/Nck/ServoTrace/PositionActualValue1[X1]", "Position actual value measuring system 1 X1 (64 bit)", "mm", x),
        ("3", "/Nck/ServoTrace/PositionSetpoint[Y1]", "Position setpoint Y1", None, yr),
        ("4", "/Nck/ServoTrace/PositionActualValue1[Y1]", "Position actual value measuring system 1 Y1", None, y),
        ("5", "/Nck/ServoTrace/FollowingError[X1]", "Following error X1", "mm", [a - b for a, b in zip(xr, x)]),
    ]
    out = ['<?xml version="1.0" encoding="UTF-8"?>', '<traceFile version="1.0">',
           '  <traceCaptureSetup machine="vcnc sample" cycle="0.002"/>', "  <traceData>", "    <dataFrame>"]
    for i, name, desc, unit, _ in sig:
        u = ' unit="%s"' % unit if unit else ""
        out.append('      <dataSignal id="%s" name="%s" description="%s"%s/>' % (i, name, desc, u))
    last = {}
    for k in range(n):
        attrs = ['time="%.6f"' % (k * p)]
        for i, _, _, _, s in sig:
            if i in ("3", "4") and k < 10:
                continue
            v = "%.6f" % s[k]
            if last.get(i) == v:
                continue
            if i == "1" and k == 70:
                v = "9.2233720368547758E+18"
            else:
                last[i] = v
            attrs.append('f%s="%s"' % (i, v))
        out.append("      <rec %s/>" % " ".join(attrs))
    out += ["    </dataFrame>", "  </traceData>", "</traceFile>"]
    write("sinumerik/x1-y1.xml", "\n".join(out) + "\n")


def tncscope_itnc530():
    # TNCscope export as an iTNC 530 (NC software 606420 03 SP4) writes it: `% ` separator lines
    # (after the first line, at the end of %[GLOBAL], between curves), %-prefixed keys, every
    # curve recorded at the 3 ms SAMPLING interval while its CYCLETIME is the signal's own control
    # cycle (100 us for the current), NAME "s soll/Y", numeric CHANNELTYPE codes, unknown keys,
    # a PLC bit curve, the actual position in micrometres; Latin-1 (µ = 0xB5, ü), CRLF.
    samp, n = 3000, 200
    p = samp * 1e-6
    yr, y = axis_signals("Y", n, p)
    vel = [(y[min(k + 1, n - 1)] - y[k]) / p * 60 for k in range(n)]
    cur = [0.5 * (yr[min(k + 1, n - 1)] - 2 * yr[k] + yr[max(k - 1, 0)]) / (p * p) / 1000 for k in range(n)]
    bit = [1.0 if 20 <= k < 120 else 0.0 for k in range(n)]
    # (NAME, CHANNELTYPE code, AXISTYPE, DIMENSION, CYCLETIME us, values, format)
    curves = [
        ("s soll/Y", "1", "Y", "mm", 3000, yr, "%.4f"),
        ("s ist/Y", "2", "Y", "\u00b5m", 3000, [v * 1000 for v in y], "%.1f"),
        ("v ist/Y", "4", "Y", "mm/min", 600, vel, "%.3f"),
        ("I ist/Y", "8", "Y", "A", 100, cur, "%.4f"),
        ("PLC M4711", "64", "", "", 3000, bit, "%.0f"),
    ]
    out = ["%TNCscopeNT data file", "% ", "%[GLOBAL]", "%VERSION=3", "%DIAGTYPE=TNCscope",
           "%RECORDEDBY=J. M\u00fcller", "%URL=", "%CONTROL=iTNC 530", "%NCVERSION=606420 03 SP4",
           "%PLCVERSION=BASIS--55-02-4", "%DSPVERSIONS=DSP 1: 0D4 / 07", "%TIME=12.03.2024 09:41:17",
           "%TRIGGERTIME=12.03.2024 09:41:18", "%TRIGGERTIME_US=412000", "%DIFFTIMEUTC=3600",
           "%BUFFER=4096", "%%SAMPLING=%d" % samp, "%TRIGGERMODE=0", "%BGCOLOR=16777215",
           "%CURPOSH=0", "%CURPOSV1=0", "% "]
    for i, (name, ct, at, dim, cyc, s, _) in enumerate(curves):
        out += ["%%[CURVE%d]" % (i + 1), "%NAME=" + name, "%CHANNELTYPE=" + ct,
                "%%CHANNELID=%d" % (100 + i), "%AXISTYPE=" + at, "%DIMENSION=" + dim,
                "%%COUNT=%d" % len(s), "%%SAMPLING=%d" % samp, "%%CYCLETIME=%d" % cyc,
                "%%COLOR=%d" % (255 << (4 * i)), "%TRIGGERCOND=0", "%DRAWOFFS=0.000000",
                "%DRAWMULT=1.000000", "%%LOGIC=%d" % (1 if at == "" else 0),
                "%%DISCRETE=%d" % (1 if at == "" else 0), "%METRIC=1", "%%COLUMN=%d" % i,
                "%%BIT=%d" % (3 if at == "" else 0), "% "]
    out.append("%[DATA]")
    for k in range(n):
        out.append(";".join(["%d" % (k * samp)] + [" " + f % s[k] for (*_, s, f) in curves]) + ";")
    write("tncscope/itnc530-y.txt", "\r\n".join(out) + "\r\n", encoding="latin-1")


def play(m, b, x0):
    """Table position behind a backlash of width b driven by the motor position m (the play
    operator): the table stands until the motor has crossed the gap."""
    x, out = x0, []
    for v in m:
        x = min(max(x, v - b / 2), v + b / 2)
        out.append(x)
    return out


# Lost motion of the Sinumerik V20 sample, mm (the play operator's width).
BACKLASH_MM = 0.005


def reversing_setpoint(n, p, base=-300.0, stroke=0.030, move_s=0.06, hold_s=0.04):
    """Pulses of `stroke` up and down from `base`: a cycloidal move, a hold, the move back."""
    out = []
    for k in range(n):
        t = k * p
        half = move_s + hold_s
        j, tau = int(t // half), t % half
        u = min(tau / move_s, 1.0)
        frac = u - math.sin(2 * math.pi * u) / (2 * math.pi)
        out.append(base + stroke * (frac if j % 2 == 0 else 1.0 - frac))
    return out


def sinumerik_v20():
    # Sinumerik Operate servo trace, traceSession 01.00.03.02 / traceCaptureSetup_V20, of NCK
    # axis 1 with a direct scale: the setpoint is for measuring system 2 (CmdPos2ndEnc64); the
    # motor (measuring system 1, its own zero 800 mm away) follows it (40 Hz, zeta = 1) and
    # drives the table through a 5 um backlash (ActPos2ndEnc64); velocity, deviation, load,
    # current, torque. Records leave out values unchanged since the last record that had them;
    # attributes in no fixed order. UTF-8 with a byte-order mark, CRLF.
    p, n = 2e-3, 600
    xr = reversing_setpoint(n, p)
    m = [v + xr[0] for v in follow([r - xr[0] for r in xr], p, zeta=1.0)]
    x = play(m, BACKLASH_MM, m[0] - BACKLASH_MM / 2)
    motor = [v - 800.0 for v in m]
    d = lambda s: [(s[min(k + 1, n - 1)] - s[k]) / p for k in range(n)]
    vr, vm, vx = d(xr), d(m), d(x)
    acc = d(vm)
    sig = [
        ("s1", "nckServoDataCmdPos2ndEnc64", "Position setpoint (64 bit)", "posn", xr),
        ("s2", "nckServoDataActPos1stEnc64", "Position actual value measuring system 1 (64 bit)", "posn", motor),
        ("s3", "nckServoDataActPos2ndEnc64", "Position actual value measuring system 2 (64 bit)", "posn", x),
        ("s4", "nckServoDataCmdSpeed64", "Speed setpoint (64 bit)", "velo", [v * 60 for v in vr]),
        ("s5", "nckServoDataActVelMot64", "Actual speed motor (64 bit)", "velo", [v * 60 for v in vm]),
        ("s6", "nckServoDataActVel2ndEnc64", "Actual velocity measuring system 2 (64 bit)", "velo", [v * 60 for v in vx]),
        ("s7", "nckServoDataCtrlDev64", "Control deviation (64 bit)", "posn", [a - b for a, b in zip(xr, x)]),
        ("s8", "nckServoDataDrvLoad64", "Load (64 bit)", "percent", [min(abs(a) / 50.0, 100.0) for a in acc]),
        ("s9", "nckServoDataActCurr64", "Torque-generating current actual value i(q) (64 bit)", "current", [a / 400.0 for a in acc]),
        ("s10", "nckServoDataCmdTorque64", "Torque/force setpoint (64 bit)", "torque", [a / 90.0 for a in acc]),
    ]
    nl = "\r\n"
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           '<traceSession version="01.00.03.02" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">',
           "  <traceCaptureSetup_V20>",
           '    <sessionSettings sessionName="BK240_1" comment="reversal test X"/>',
           "    <signalSettings>"]
    for key, nck, desc, ut, _ in sig:
        out.append('      <signal key="%s" unitsType="%s" name="/Nck/!SD/%s [u1, 1]" description="%s" active="true" color="#%06x"/>'
                   % (key, ut, nck, desc, 4321 * int(key[1:])))
    out += ["    </signalSettings>",
            '    <triggerSettings mode="immediate" preTrigger="0"/>',
            "  </traceCaptureSetup_V20>",
            '  <traceData dataFrames="1">',
            "    <dataFrame>",
            '      <frameHeader startTime="2024-05-07T10:11:12.000" stopInc="%.3f" dropOuts="0"/>' % ((n - 1) * p)]
    for key, _, _, ut, _ in sig:
        out.append('      <dataSignal key="%s" id="f%s" unitsType="%s" domain="servo" dataType="double" interval="%.6f" datapointCount="%d"/>'
                   % (key, key[1:], ut, p, n))
    last = {}
    for k in range(n):
        attrs = []
        for key, _, _, _, s in sig:
            v = "%.6f" % s[k]
            if last.get(key) == v:
                continue
            last[key] = v
            attrs.append('f%s="%s"' % (key[1:], v))
        # Attributes in no fixed order: as the control writes them, by its own bookkeeping.
        attrs = attrs[k % max(len(attrs), 1):] + attrs[:k % max(len(attrs), 1)]
        out.append("      <rec %s/>" % " ".join(['time="%.6f"' % (k * p)] + attrs))
    out += ["    </dataFrame>", "  </traceData>", "</traceSession>"]
    with open("sinumerik/v20-x-two-systems.xml", "wb") as f:
        f.write(b"\xef\xbb\xbf" + (nl.join(out) + nl).encode("utf-8"))


def sinumerik_v20_latin1():
    # A V20 trace of NCK axes 1 and 2 with German descriptions, saved as ISO-8859-1 (ß = 0xDF):
    # each axis a setpoint and an actual position of measuring system 1 (no direct scale), and
    # the contour deviation. Axis numbers mapped by the caller (--axis-map 1=X,2=Y).
    p, n = 4e-3, 120
    xr, x = axis_signals("X", n, p)
    yr, y = axis_signals("Y", n, p)
    sig = []
    for ax, r, a in ((1, xr, x), (2, yr, y)):
        sig += [
            ("s%d" % (3 * ax - 2), "nckServoDataCmdPos1stEnc64 [u1, %d]" % ax, "Lagesollwert Me\u00dfsystem 1 (64 bit)", r),
            ("s%d" % (3 * ax - 1), "nckServoDataActPos1stEnc64 [u1, %d]" % ax, "Lageistwert Me\u00dfsystem 1 (64 bit)", a),
            ("s%d" % (3 * ax), "nckServoDataContDev64 [u1, %d]" % ax, "Konturabweichung (64 bit)", [u - v for u, v in zip(r, a)]),
        ]
    out = ['<?xml version="1.0" encoding="ISO-8859-1"?>', '<traceSession version="01.00.03.02">',
           "<traceCaptureSetup_V20>", "<signalSettings>"]
    for key, nck, desc, _ in sig:
        out.append('<signal key="%s" unitsType="posn" name="/Nck/!SD/%s" description="%s"/>' % (key, nck, desc))
    out += ["</signalSettings>", "</traceCaptureSetup_V20>", '<traceData dataFrames="1">', "<dataFrame>",
            '<frameHeader startTime="2024-05-08T08:00:00.000" dropOuts="0"/>']
    for key, *_ in sig:
        out.append('<dataSignal key="%s" id="f%s" unitsType="posn" interval="%.6f" datapointCount="%d"/>' % (key, key[1:], p, n))
    last = {}
    for k in range(n):
        attrs = ['time="%.6f"' % (k * p)]
        for key, _, _, s in sig:
            v = "%.6f" % s[k]
            if last.get(key) != v:
                last[key] = v
                attrs.append('f%s="%s"' % (key[1:], v))
        out.append("<rec %s/>" % " ".join(attrs))
    out += ["</dataFrame>", "</traceData>", "</traceSession>"]
    write("sinumerik/v20-latin1-two-axes.xml", "\n".join(out) + "\n", encoding="latin-1")


def twincat(path, sep, comma, shared):
    # TwinCAT 3 Scope export of two NC axes (PLC symbols of the axis references), in the layout
    # of the sample exports: default (one time column per channel) or with channels of one
    # sample time sharing a time column.
    n = 240
    xr, x = axis_signals("X", n)
    yr, y = axis_signals("Y", n)
    ch = [
        ("SetPos_X", "MAIN.AxisX.NcToPlc.SetPos", "mm (Millimeter)", "REAL64", xr),
        ("ActPos_X", "MAIN.AxisX.NcToPlc.ActPos", "mm (Millimeter)", "REAL64", x),
        ("SetPos_Y", "MAIN.AxisY.NcToPlc.SetPos", "mm (Millimeter)", "REAL64", yr),
        ("ActPos_Y", "MAIN.AxisY.NcToPlc.ActPos", "mm (Millimeter)", "REAL64", y),
        ("bEnable", "MAIN.bEnable", "(None)", "BIT", [1.0] * n),
    ]
    f = (lambda v: ("%g" % v).replace(".", ",")) if comma else (lambda v: "%g" % v)
    num = (lambda v: ("%.6f" % v).replace(".", ",")) if comma else (lambda v: "%.6f" % v)
    rows = ["Name%s%s" % (sep, "vcnc_sample"), "File%sC:\\TwinCAT\\Scope\\vcnc_sample.csv" % sep,
            "Starttime of export%s133521660000000000%sDonnerstag, 14. März 2024%s10:20:00.000" % (sep, sep, sep),
            "Endtime of export%s133521660002400000%sDonnerstag, 14. März 2024%s10:20:00.240" % (sep, sep, sep), "", ""]

    def meta(key, values):
        if shared:
            return sep.join([key] + values)
        return sep.join(x for v in values for x in (key, v))

    rows.append(meta("Name", [c[0] for c in ch]))
    rows.append(meta("SymbolComment", ["" for _ in ch]))
    rows.append(meta("Data-Type", [c[3] for c in ch]))
    rows.append(meta("SampleTime[ms]", [f(1.0) for _ in ch]))
    rows.append(meta("SymbolName", [c[1] for c in ch]))
    rows.append(meta("ScaleFactor", ["1" for _ in ch]))
    rows.append(meta("Unit", [c[2] for c in ch]))
    rows.append("")
    for k in range(n):
        t = f(float(k))
        if shared:
            rows.append(sep.join([t] + [num(c[4][k]) for c in ch]))
        else:
            rows.append(sep.join(x for c in ch for x in (t, num(c[4][k]))))
    write(path, "\r\n".join(rows) + "\r\n")


def delimited():
    n = 250
    xr, x = axis_signals("X", n)
    # The t, xr, x layout of `vcnc identify --trace`, positions in mm.
    write("delimited/t-xr-x.csv", "t,xr,x\n" + "".join("%.3f,%.6f,%.6f\n" % (k * T, xr[k], x[k]) for k in range(n)))
    # A spreadsheet export in German locale: ';' and decimal comma, units in brackets, in µm.
    yr, y = axis_signals("Y", n)
    rows = ["Zeit [ms];X Soll [µm];X Ist [µm];Y Soll [µm];Y Ist [µm]"]
    for k in range(n):
        rows.append(";".join(("%.4f" % v).replace(".", ",") for v in (k * 1.0, xr[k] * 1e3, x[k] * 1e3, yr[k] * 1e3, y[k] * 1e3)))
    write("delimited/semicolon-decimal-comma.csv", "\n".join(rows) + "\n")
    # White-space columns with a header, B axis in radians, a comment line.
    br, b = axis_signals("B", n)
    rows = ["# rotary table test, B axis", "time_s  b_cmd[rad]  b_fb[rad]"]
    for k in range(n):
        rows.append("%.3f  %.9f  %.9f" % (k * T, math.radians(br[k]), math.radians(b[k])))
    write("delimited/whitespace-rad.txt", "\n".join(rows) + "\n")


if __name__ == "__main__":
    halscope_table()
    halscope_pairs()
    halsampler_tagged()
    halsampler_plain()
    tncscope()
    tncscope_itnc530()
    sinumerik()
    sinumerik_v20()
    sinumerik_v20_latin1()
    twincat("twincat/nc-axes_semicolon.csv", ";", False, False)
    twincat("twincat/nc-axes_tab-decimal-comma_shared-time.csv", "\t", True, True)
    delimited()
