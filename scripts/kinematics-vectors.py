#!/usr/bin/env python3
"""Reference vectors for vcnc-kinematics, computed by LinuxCNC's own kinematics functions.

The script reads four LinuxCNC kinematics modules out of a LinuxCNC git repository, cuts the
forward and inverse functions out of their source at generation time, compiles them with a small
harness of our own (types, HAL getters and joint mapping replaced by plain C), runs them on
seeded random machines and joint values, and writes the results as CSV files into
crates/vcnc-kinematics/tests/data/linuxcnc/. No LinuxCNC code is written into the repository:
only the numbers its functions return (and the commit they came from).

    module            file (LinuxCNC)                     functions
    xyzac-trt-kins    src/emc/kinematics/trtfuncs.c       xyzacKinematicsForward / Inverse
    xyzbc-trt-kins    src/emc/kinematics/trtfuncs.c       xyzbcKinematicsForward / Inverse
    5axiskins         src/emc/kinematics/5axiskins.c      fiveaxis_KinematicsForward / Inverse
    maxkins           src/emc/kinematics/maxkins.c        kinematicsForward / Inverse

Each output row holds the module's parameters, the joints in LinuxCNC's units (mm, deg) and the
world position the function returned. The tool axis, which these modules do not return, is
computed from the same functions where the module has a way to move the tool along itself:
table-tilting modules by moving the Z joint (the spindle is along machine Z), 5axiskins and
maxkins by their W joint (tool length). docs/kinematics.md maps every module's parameters and
sign conventions onto vcnc's.

Two sets per module:
  * <module>-forward.csv, <module>-inverse.csv: cross-check vectors (random parameters per row).
  * heldout-<module>.csv: one machine per module with parameters drawn here and *not* written
    into that file: 'fit' rows to identify the offsets from, 'check' rows to predict. The drawn
    parameters go to heldout-answers.csv, which the tests read only after fitting.

Usage:
    scripts/kinematics-vectors.py [--linuxcnc REPO] [--rev REV] [--seed N] [--out DIR]

REPO defaults to $LINUXCNC_REPO; REV to HEAD. Needs python3 and a C compiler (cc).
The same REPO, REV and seed give the same files byte for byte.
"""

import argparse
import os
import random
import re
import subprocess
import sys
import tempfile

MODULES = {
    "trt": ("src/emc/kinematics/trtfuncs.c",
            ["xyzacKinematicsForward", "xyzacKinematicsInverse",
             "xyzbcKinematicsForward", "xyzbcKinematicsInverse"]),
    "fiveaxis": ("src/emc/kinematics/5axiskins.c",
                 ["s2r", "fiveaxis_KinematicsForward", "fiveaxis_KinematicsInverse"]),
    "max": ("src/emc/kinematics/maxkins.c", ["kinematicsForward", "kinematicsInverse"]),
}

# ---- our harness: stand-ins for LinuxCNC's headers, and a driver reading stdin -------------

HARNESS_HEAD = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
typedef double hal_real_t;
typedef int hal_bool_t;
typedef double rtapi_real;
#define hal_get_real(v) (v)
#define hal_get_bool(v) (v)
#define PM_PI 3.14159265358979323846
#define TO_RAD (PM_PI/180.)
typedef struct { double x, y, z; } PmCartesian;
typedef struct EmcPose { PmCartesian tran; double a, b, c, u, v, w; } EmcPose;
typedef unsigned long KINEMATICS_FORWARD_FLAGS;
typedef unsigned long KINEMATICS_INVERSE_FLAGS;
/* joints 0..8 are X Y Z A B C U V W */
static int JX = 0, JY = 1, JZ = 2, JA = 3, JB = 4, JC = 5, JU = 6, JV = 7, JW = 8;
static int trtfuncs_max_joints = 9, fiveaxis_max_joints = 9;
static int position_to_mapped_joints(int n, const EmcPose *p, double *j) {
    (void)n;
    j[0] = p->tran.x; j[1] = p->tran.y; j[2] = p->tran.z;
    j[3] = p->a; j[4] = p->b; j[5] = p->c; j[6] = p->u; j[7] = p->v; j[8] = p->w;
    return 0;
}
"""

HALDATA = {
    "trt": "struct haldata { hal_real_t x_rot_point, y_rot_point, z_rot_point, x_offset, "
           "y_offset, z_offset, tool_offset; hal_bool_t conventional_directions; };",
    "fiveaxis": "struct haldata { hal_real_t pivot_length; };",
    "max": "struct haldata { hal_real_t pivot_length; hal_bool_t conventional_directions; };",
}

# The driver: each stdin line is "<fn> <params...> | <9 joints or pose values>"; it prints
# 9 numbers (the world pose x y z a b c u v w, or the 9 joints) with %.17g (exact doubles).
HARNESS_MAIN = r"""
static struct haldata hd;
static struct haldata *haldata = &hd;
FUNCTIONS
static void set_params(const char *module, double *p) {
PARAMS
}
int main(void) {
    char line[4096];
    while (fgets(line, sizeof line, stdin)) {
        char fn[64]; double p[16], v[9]; int np = 0, nv = 0; char *s = line, *end;
        if (sscanf(s, "%63s", fn) != 1) continue;
        s = strstr(s, fn) + strlen(fn);
        while (1) { while (*s == ' ') s++; if (*s == '|') { s++; break; }
            p[np++] = strtod(s, &end); if (end == s) return 2; s = end; }
        for (nv = 0; nv < 9; nv++) { v[nv] = strtod(s, &end); if (end == s) return 3; s = end; }
        set_params(fn, p);
        double out[9]; EmcPose pose; memset(&pose, 0, sizeof pose);
        KINEMATICS_FORWARD_FLAGS ff = 0; KINEMATICS_INVERSE_FLAGS fi = 0;
DISPATCH
        for (int i = 0; i < 9; i++) printf(i ? " %.17g" : "%.17g", out[i]);
        printf("\n");
    }
    return 0;
}
"""

PARAMS = {
    "trt": """    hd.x_rot_point = p[0]; hd.y_rot_point = p[1]; hd.z_rot_point = p[2];
    hd.x_offset = p[3]; hd.y_offset = p[4]; hd.z_offset = p[5]; hd.tool_offset = p[6];
    hd.conventional_directions = p[7] != 0.0; (void)module;""",
    "fiveaxis": "    hd.pivot_length = p[0]; (void)module;",
    "max": "    hd.pivot_length = p[0]; hd.conventional_directions = p[1] != 0.0; (void)module;",
}


def dispatch(fwd, inv):
    """C statements calling forward `fwd` (joints v -> pose) or inverse `inv` (pose v -> joints)."""
    return f"""        if (strcmp(fn, "{fwd}") == 0) {{
            {fwd}(v, &pose, &ff, &fi);
            out[0] = pose.tran.x; out[1] = pose.tran.y; out[2] = pose.tran.z;
            out[3] = pose.a; out[4] = pose.b; out[5] = pose.c;
            out[6] = pose.u; out[7] = pose.v; out[8] = pose.w;
        }} else if (strcmp(fn, "{inv}") == 0) {{
            pose.tran.x = v[0]; pose.tran.y = v[1]; pose.tran.z = v[2];
            pose.a = v[3]; pose.b = v[4]; pose.c = v[5]; pose.u = v[6]; pose.v = v[7]; pose.w = v[8];
            for (int i = 0; i < 9; i++) out[i] = 0.0;
            {inv}(&pose, out, &fi, &ff);
        }} else"""


DISPATCH = {
    "trt": dispatch("xyzacKinematicsForward", "xyzacKinematicsInverse")
    + dispatch("xyzbcKinematicsForward", "xyzbcKinematicsInverse") + " return 4;",
    "fiveaxis": dispatch("fiveaxis_KinematicsForward", "fiveaxis_KinematicsInverse")
    + " return 4;",
    "max": dispatch("kinematicsForward", "kinematicsInverse") + " return 4;",
}


def git_show(repo, rev, path):
    return subprocess.run(["git", "-C", repo, "show", f"{rev}:{path}"], check=True,
                          capture_output=True, text=True).stdout


def cut_function(src, name):
    """The text of the C function `name` (from its return type to its closing brace)."""
    m = re.search(r"^[A-Za-z_][\w \t\*]*\b" + re.escape(name) + r"\s*\(", src, re.M)
    if not m:
        sys.exit(f"function {name} not found")
    depth, i = 0, src.index("{", m.end())
    for j in range(i, len(src)):
        if src[j] == "{":
            depth += 1
        elif src[j] == "}":
            depth -= 1
            if depth == 0:
                return src[m.start():j + 1]
    sys.exit(f"function {name} has no end")


def cut_defines(src, names):
    """The one-line #define of each macro in `names` (maxkins's d2r)."""
    out = []
    for n in names:
        m = re.search(r"^#define\s+" + n + r"\b.*$", src, re.M)
        if m:
            out.append(m.group(0))
    return "\n".join(out)


class Module:
    """One compiled module: call(fn, params, values) -> 9 numbers."""

    def __init__(self, key, repo, rev, tmp, cc):
        path, functions = MODULES[key]
        src = git_show(repo, rev, path)
        body = cut_defines(src, ["d2r"]) + "\n" + "\n".join(
            ("static " if not f.startswith("static") else "") + f
            for f in (cut_function(src, n) for n in functions))
        code = (HARNESS_HEAD + HALDATA[key] + HARNESS_MAIN.replace("FUNCTIONS", body)
                .replace("PARAMS", PARAMS[key]).replace("DISPATCH", DISPATCH[key]))
        c = os.path.join(tmp, key + ".c")
        exe = os.path.join(tmp, key)
        with open(c, "w") as f:
            f.write(code)
        subprocess.run([cc, "-O0", "-ffp-contract=off", "-w", "-o", exe, c, "-lm"], check=True)
        self.exe = exe
        self.lines = []

    def run(self, calls):
        """calls: list of (fn, params, values) -> list of 9-number results."""
        text = "".join(f"{fn} {' '.join(repr(float(x)) for x in p)} | "
                       f"{' '.join(repr(float(x)) for x in v)}\n" for fn, p, v in calls)
        out = subprocess.run([self.exe], input=text, capture_output=True, text=True, check=True)
        return [[float(x) for x in line.split()] for line in out.stdout.splitlines()]


def fmt(x):
    return repr(float(x))


def write_csv(path, header_lines, columns, rows):
    with open(path, "w") as f:
        for h in header_lines:
            f.write("# " + h + "\n")
        f.write(",".join(columns) + "\n")
        for r in rows:
            f.write(",".join(fmt(x) for x in r) + "\n")


def u(rng, lo, hi):
    return rng.uniform(lo, hi)


def rand_joint(rng, special):
    """X Y Z mm, and a tilt/rotary pair in degrees with some exact special values."""
    x, y, z = u(rng, -500, 500), u(rng, -400, 400), u(rng, -400, 400)
    t = rng.choice([0.0, 90.0, -90.0, 45.0]) if special else u(rng, -120, 120)
    c = rng.choice([0.0, 180.0, -360.0, 30.0]) if special else u(rng, -720, 720)
    return x, y, z, t, c


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--linuxcnc", default=os.environ.get("LINUXCNC_REPO"),
                    help="a LinuxCNC git repository (bare or not)")
    ap.add_argument("--rev", default="HEAD")
    ap.add_argument("--seed", type=int, default=20260828)
    ap.add_argument("--rows", type=int, default=64)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                  "..", "crates", "vcnc-kinematics", "tests",
                                                  "data", "linuxcnc"))
    ap.add_argument("--cc", default="cc")
    a = ap.parse_args()
    if not a.linuxcnc:
        sys.exit("give --linuxcnc REPO (a LinuxCNC git repository) or set LINUXCNC_REPO")
    commit = subprocess.run(["git", "-C", a.linuxcnc, "rev-parse", a.rev], check=True,
                            capture_output=True, text=True).stdout.strip()
    os.makedirs(a.out, exist_ok=True)
    rng = random.Random(a.seed)
    print(f"LinuxCNC {commit}, seed {a.seed}")

    with tempfile.TemporaryDirectory() as tmp:
        mods = {k: Module(k, a.linuxcnc, a.rev, tmp, a.cc) for k in MODULES}
        prov = lambda m, fns: [  # noqa: E731
            f"Computed by LinuxCNC's {m} ({MODULES[m][0]}, functions {', '.join(fns)}) at "
            f"commit {commit},",
            f"compiled out of the LinuxCNC repository by scripts/kinematics-vectors.py "
            f"(seed {a.seed}); LinuxCNC is GPL-2.0, these are its outputs (numbers), no code.",
            "Units: mm and degrees (LinuxCNC's). Column meanings and the mapping onto vcnc: "
            "docs/kinematics.md, 'Cross-checks against LinuxCNC'.",
        ]
        trt_forward(mods["trt"], rng, a, prov)
        fiveaxis_vectors(mods["fiveaxis"], rng, a, prov)
        max_vectors(mods["max"], rng, a, prov)
        heldout(mods, rng, a, prov)


def trt_params(rng, bc):
    """x/y/z-rot-point, x-offset, y-offset, z-offset, tool-offset, conventional-directions."""
    r = [u(rng, -200, 200) for _ in range(3)]
    xo = u(rng, -150, 150) if bc else 0.0
    yo = 0.0 if bc else u(rng, -150, 150)
    zo = u(rng, -300, 300)
    tool = rng.choice([0.0, u(rng, 0, 150)])
    conv = float(rng.random() < 0.5)
    return r + [xo, yo, zo, tool, conv]


def trt_forward(mod, rng, a, prov):
    for name, bc, fwd, inv in [("xyzac-trt", False, "xyzacKinematicsForward",
                                "xyzacKinematicsInverse"),
                               ("xyzbc-trt", True, "xyzbcKinematicsForward",
                                "xyzbcKinematicsInverse")]:
        tilt = 4 if bc else 3  # joint index of B or A
        f_calls, i_calls = [], []
        for k in range(a.rows):
            p = trt_params(rng, bc)
            x, y, z, t, c = rand_joint(rng, k < 8)
            j = [x, y, z, 0, 0, c, 0, 0, 0]
            j[tilt] = t
            f_calls += [(fwd, p, j), (fwd, p, j[:2] + [z + 1.0] + j[3:])]
            pose = [u(rng, -300, 300), u(rng, -300, 300), u(rng, -300, 300), 0, 0, c, 0, 0, 0]
            pose[tilt] = t
            i_calls.append((inv, p, pose))
        f_out, i_out = mod.run(f_calls), mod.run(i_calls)
        letter = "b" if bc else "a"
        cols_p = ["x_rot_point", "y_rot_point", "z_rot_point", "x_offset", "y_offset",
                  "z_offset", "tool_offset", "conventional"]
        rows = []
        for k in range(a.rows):
            _, p, j = f_calls[2 * k]
            w0, w1 = f_out[2 * k], f_out[2 * k + 1]
            o = [w1[i] - w0[i] for i in range(3)]  # the tool axis: the Z joint moved by 1 mm
            rows.append(p + [j[0], j[1], j[2], j[tilt], j[5]] + w0[:3] + o)
        write_csv(os.path.join(a.out, f"{name}-forward.csv"),
                  prov("trt", [fwd]) + [
                      "Forward: joints jx jy jz (mm) j" + letter + " jc (deg) -> tool tip px py pz "
                      "(mm) in the workpiece frame; ox oy oz = forward(jz + 1 mm) - forward(jz)."],
                  cols_p + ["jx", "jy", "jz", "j" + letter, "jc", "px", "py", "pz", "ox", "oy",
                            "oz"], rows)
        rows = []
        for (fn, p, pose), out in zip(i_calls, i_out):
            rows.append(p + [pose[0], pose[1], pose[2], pose[tilt], pose[5]] + out[:3])
        write_csv(os.path.join(a.out, f"{name}-inverse.csv"),
                  prov("trt", [inv]) + [
                      "Inverse: tool tip px py pz (mm, workpiece frame) and " + letter +
                      " c (deg) -> joints jx jy jz (mm)."],
                  cols_p + ["px", "py", "pz", letter, "c", "jx", "jy", "jz"], rows)
        # LinuxCNC's own round trip, printed for the record.
        back = mod.run([(fwd, p, o[:3] + ([pose[3], 0] if not bc else [0, pose[4]]) + [pose[5],
                        0, 0, 0]) for (_, p, pose), o in zip(i_calls, i_out)])
        for conv in (0.0, 1.0):
            err = max(max(abs(b[i] - c[2][i]) for i in range(3))
                      for b, c in zip(back, i_calls) if c[1][7] == conv)
            print(f"{name}, conventional-directions {conv:.0f}: forward(inverse(pose)) - pose, "
                  f"max {err:.3g} mm (LinuxCNC's own round trip)")


def fiveaxis_vectors(mod, rng, a, prov):
    fwd, inv = "fiveaxis_KinematicsForward", "fiveaxis_KinematicsInverse"
    f_calls, i_calls = [], []
    for k in range(a.rows):
        p = [u(rng, 50, 400)]
        x, y, z, t, c = rand_joint(rng, k < 8)
        j = [x, y, z, 0, t, c, 0, 0, 0]
        f_calls += [(fwd, p, j), (fwd, p, j[:8] + [1.0])]
        i_calls.append((inv, p, [u(rng, -300, 300), u(rng, -300, 300), u(rng, -300, 300), 0, t,
                                 c, 0, 0, 0]))
    f_out, i_out = mod.run(f_calls), mod.run(i_calls)
    rows = []
    for k in range(a.rows):
        _, p, j = f_calls[2 * k]
        w0, w1 = f_out[2 * k], f_out[2 * k + 1]
        o = [w0[i] - w1[i] for i in range(3)]  # W = 1 lengthens the tool by 1 mm
        rows.append(p + [j[0], j[1], j[2], j[4], j[5]] + w0[:3] + o)
    write_csv(os.path.join(a.out, "5axiskins-forward.csv"), prov("fiveaxis", [fwd]) + [
        "Forward: joints jx jy jz (mm) jb jc (deg), W = 0 -> tool tip px py pz (mm); "
        "ox oy oz = forward(W = 0) - forward(W = 1 mm)."],
        ["pivot_length", "jx", "jy", "jz", "jb", "jc", "px", "py", "pz", "ox", "oy", "oz"], rows)
    rows = [p + [q[0], q[1], q[2], q[4], q[5]] + out[:3] for (_, p, q), out in zip(i_calls, i_out)]
    write_csv(os.path.join(a.out, "5axiskins-inverse.csv"), prov("fiveaxis", [inv]) + [
        "Inverse: tool tip px py pz (mm) and b c (deg), W = 0 -> joints jx jy jz (mm)."],
        ["pivot_length", "px", "py", "pz", "b", "c", "jx", "jy", "jz"], rows)


def max_vectors(mod, rng, a, prov):
    fwd, inv = "kinematicsForward", "kinematicsInverse"
    f_calls, i_calls = [], []
    for k in range(a.rows):
        p = [u(rng, 20, 300), float(rng.random() < 0.25)]
        x, y, z, t, c = rand_joint(rng, k < 8)
        if k < 16:  # where LinuxCNC's maxkins forward agrees with its inverse (docs/kinematics.md)
            if k % 2:
                t = 0.0
            else:
                c = 0.0
        f_calls.append((fwd, p, [x, y, z, 0, t, c, 0, 0, 0]))
        pose = [u(rng, -300, 300), u(rng, -300, 300), u(rng, -300, 300), 0, t, c, 0, 0, 0]
        i_calls += [(inv, p, pose), (inv, p, pose[:8] + [1.0])]
    f_out, i_out = mod.run(f_calls), mod.run(i_calls)
    rows = [p + [j[0], j[1], j[2], j[4], j[5]] + w[:3] for (_, p, j), w in zip(f_calls, f_out)]
    write_csv(os.path.join(a.out, "maxkins-forward.csv"), prov("max", [fwd]) + [
        "Forward: joints jx jy jz (mm) jb jc (deg) -> tool tip px py pz (mm). LinuxCNC's maxkins "
        "forward is not the inverse of its inverse when B and C are both nonzero "
        "(docs/kinematics.md); rows 0-15 have B = 0 or C = 0."],
        ["pivot_length", "conventional", "jx", "jy", "jz", "jb", "jc", "px", "py", "pz"], rows)
    rows = []
    for k in range(a.rows):
        _, p, q = i_calls[2 * k]
        j0, j1 = i_out[2 * k], i_out[2 * k + 1]
        om = [j1[i] - j0[i] for i in range(3)]  # the slides' shift for 1 mm more tool
        rows.append(p + [q[0], q[1], q[2], q[4], q[5]] + j0[:3] + om)
    write_csv(os.path.join(a.out, "maxkins-inverse.csv"), prov("max", [inv]) + [
        "Inverse: tool tip px py pz (mm) and b c (deg), U = V = W = 0 -> joints jx jy jz (mm); "
        "mx my mz = inverse(W = 1 mm) - inverse(W = 0): the tool axis in the machine frame."],
        ["pivot_length", "conventional", "px", "py", "pz", "b", "c", "jx", "jy", "jz", "mx", "my",
         "mz"], rows)
    # LinuxCNC's own round trip, printed for the record.
    back = mod.run([(fwd, p, out[:3] + [0, q[4], q[5], 0, 0, 0])
                    for (_, p, q), out in zip(i_calls[::2], i_out[::2])])
    err = max(max(abs(b[i] - q[i]) for i in range(3)) for b, (_, _, q) in zip(back, i_calls[::2]))
    print(f"maxkins: forward(inverse(pose)) - pose, max {err:.3g} mm (LinuxCNC's own)")


def heldout(mods, rng, a, prov):
    """One machine per module, parameters drawn here: 'fit' rows and 'check' rows."""
    answers = []
    n = 24
    specs = [
        ("xyzac-trt", "trt", "xyzacKinematicsForward", 3, trt_params(rng, False)[:7] + [0.0]),
        ("xyzbc-trt", "trt", "xyzbcKinematicsForward", 4, trt_params(rng, True)[:7] + [0.0]),
        ("5axiskins", "fiveaxis", "fiveaxis_KinematicsForward", 4, [u(rng, 100, 400)]),
    ]
    for name, key, fwd, tilt, p in specs:
        calls = []
        for k in range(2 * n):
            x, y, z, t, c = rand_joint(rng, False)
            j = [x, y, z, 0, 0, c, 0, 0, 0]
            j[tilt] = t
            calls += [(fwd, p, j), (fwd, p, j[:2] + [z + 1.0] + j[3:] if key == "trt"
                                    else j[:8] + [1.0])]
        out = mods[key].run(calls)
        rows = []
        for k in range(2 * n):
            _, _, j = calls[2 * k]
            w0, w1 = out[2 * k], out[2 * k + 1]
            o = [w1[i] - w0[i] for i in range(3)] if key == "trt" else \
                [w0[i] - w1[i] for i in range(3)]
            rows.append([0.0 if k < n else 1.0, j[0], j[1], j[2], j[tilt], j[5]] + w0[:3] + o)
        letter = "jb" if tilt == 4 else "ja"
        write_csv(os.path.join(a.out, f"heldout-{name}.csv"), prov(key, [fwd]) + [
            "Held out: one machine whose parameters are in heldout-answers.csv. set 0 = rows to "
            "fit the offsets from, set 1 = rows to predict. Forward samples as in the "
            f"{name}-forward.csv file, conventional directions off."],
            ["set", "jx", "jy", "jz", letter, "jc", "px", "py", "pz", "ox", "oy", "oz"], rows)
        answers.append([name] + p)
    # maxkins: its inverse (its forward disagrees with it; docs/kinematics.md).
    p = [u(rng, 50, 300), 0.0]
    calls, poses = [], []
    for k in range(2 * n):
        _, _, _, t, c = rand_joint(rng, False)
        pose = [u(rng, -300, 300), u(rng, -300, 300), u(rng, -300, 300), 0, t, c, 0, 0, 0]
        calls += [("kinematicsInverse", p, pose), ("kinematicsInverse", p, pose[:8] + [1.0])]
        poses.append(pose)
    out = mods["max"].run(calls)
    rows = []
    for k in range(2 * n):
        j0, j1 = out[2 * k], out[2 * k + 1]
        om = [j1[i] - j0[i] for i in range(3)]
        rows.append([0.0 if k < n else 1.0] + j0[:3] + [poses[k][4], poses[k][5]] + poses[k][:3]
                    + om)
    write_csv(os.path.join(a.out, "heldout-maxkins.csv"), prov("max", ["kinematicsInverse"]) + [
        "Held out: one machine whose parameters are in heldout-answers.csv. set 0 = rows to fit "
        "the offsets from, set 1 = rows to predict. Rows of the maxkins inverse: joints jx jy jz "
        "(mm) jb jc (deg) and the tool tip px py pz (mm) they reach; mx my mz the tool axis in the "
        "machine frame, conventional directions off."],
        ["set", "jx", "jy", "jz", "jb", "jc", "px", "py", "pz", "mx", "my", "mz"], rows)
    answers.append(["maxkins"] + p)
    with open(os.path.join(a.out, "heldout-answers.csv"), "w") as f:
        for h in prov("trt", ["(all four modules)"])[:2] + [
                "The parameters of the held-out machines, in each module's parameter order:",
                "trt: x/y/z-rot-point, x-offset, y-offset, z-offset, tool-offset, conventional; "
                "5axiskins: pivot-length; maxkins: pivot-length, conventional.",
                "Read only after the offsets are fitted from the 'fit' rows."]:
            f.write("# " + h + "\n")
        for r in answers:
            f.write(",".join([r[0]] + [fmt(x) for x in r[1:]]) + "\n")


if __name__ == "__main__":
    main()
