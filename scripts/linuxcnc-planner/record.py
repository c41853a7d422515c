#!/usr/bin/python3
"""Record LinuxCNC 2.9's trajectory planner on the programs of
crates/vcnc-gcode/tests/data/linuxcnc-planner/programs (see the README there).

For each program `<name>.ngc`, whose first line states the machine's limits as
`(limits X=<v>,<a> Y=<v>,<a> Z=<v>,<a>)` (mm/s, mm/s²), this script writes a LinuxCNC
configuration of a simulated XYZ machine with those joint and axis limits (trivkins, 1 ms servo
period, the joint commands looped back as feedback), runs it headless in its own IPC, mount and
PID namespaces (HAL's shared memory has fixed keys), with driver.py as the [DISPLAY] program,
and keeps the joint commands `joint.N.motor-pos-cmd` that halsampler recorded every servo cycle,
from one sample before the machine first moves to one sample after it last moves, in
`recordings/<name>.txt`. `recordings/cycle_times.csv` lists each program's cycle time.

Usage (as root, with the Debian package linuxcnc-uspace installed):
    /usr/bin/python3 scripts/linuxcnc-planner/record.py [name ...]
    /usr/bin/python3 scripts/linuxcnc-planner/record.py --data DIR --limits "X=v,a Y=v,a Z=v,a" \
        program.ngc ...
The second form records programs from elsewhere (for example LinuxCNC's own ncfiles) into
DIR/programs and DIR/recordings, with the limits line prepended; the comparison test reads DIR
when VCNC_LINUXCNC_PLANNER_DIR names it.
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "..", "crates", "vcnc-gcode", "tests", "data", "linuxcnc-planner")
PROGRAMS = os.path.join(DATA, "programs")
RECORDINGS = os.path.join(DATA, "recordings")
TS = 0.001

INI = """[EMC]
VERSION = 1.1
MACHINE = vcnc-planner-check

[DISPLAY]
DISPLAY = {driver}
MAX_FEED_OVERRIDE = 1.0

[TASK]
TASK = milltask
CYCLE_TIME = 0.001

[RS274NGC]
PARAMETER_FILE = sim.var
RS274NGC_STARTUP_CODE = G21 G90 G94 G17 G40 G49 G80

[EMCMOT]
EMCMOT = motmod
COMM_TIMEOUT = 1.0
SERVO_PERIOD = 1000000

[EMCIO]
EMCIO = io
CYCLE_TIME = 0.100
TOOL_TABLE = sim.tbl

[HAL]
HALFILE = {hal}

[TRAJ]
COORDINATES = XYZ
LINEAR_UNITS = mm
ANGULAR_UNITS = degree
MAX_LINEAR_VELOCITY = 100000
MAX_LINEAR_ACCELERATION = 1000000
NO_FORCE_HOMING = 1

[KINS]
JOINTS = 3
KINEMATICS = trivkins coordinates=XYZ
"""

AXIS = """
[AXIS_{letter}]
MAX_VELOCITY = {vel}
MAX_ACCELERATION = {acc}
MIN_LIMIT = -10000
MAX_LIMIT = 10000

[JOINT_{joint}]
TYPE = LINEAR
MAX_VELOCITY = {vel}
MAX_ACCELERATION = {acc}
MIN_LIMIT = -10000
MAX_LIMIT = 10000
FERROR = 10000
MIN_FERROR = 10000
HOME_SEQUENCE = 0
"""


def limits_of(path):
    with open(path) as f:
        first = f.readline()
    m = re.match(r"\(limits X=([\d.]+),([\d.]+) Y=([\d.]+),([\d.]+) Z=([\d.]+),([\d.]+)\)", first)
    if not m:
        raise SystemExit(f"{path}:1: the first line must be (limits X=v,a Y=v,a Z=v,a)")
    v = [float(x) for x in m.groups()]
    return [(v[0], v[1]), (v[2], v[3]), (v[4], v[5])]


def version():
    out = subprocess.run(["dpkg-query", "-W", "-f", "${Version}", "linuxcnc-uspace"],
                         capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


def record(name, programs=None, recordings=None):
    programs = programs or PROGRAMS
    recordings = recordings or RECORDINGS
    program = os.path.join(programs, name + ".ngc")
    limits = limits_of(program)
    work = tempfile.mkdtemp(prefix="vcnc-lcnc-")
    os.chmod(work, 0o1777)  # rtapi_app runs as RTAPI_UID and makes its socket here
    try:
        ini = INI.format(driver=os.path.join(HERE, "driver.py"), hal=os.path.join(HERE, "sim.hal"))
        for j, (letter, (vel, acc)) in enumerate(zip("XYZ", limits)):
            ini += AXIS.format(letter=letter, joint=j, vel=vel, acc=acc)
        with open(os.path.join(work, "sim.ini"), "w") as f:
            f.write(ini)
        open(os.path.join(work, "sim.var"), "w").close()
        with open(os.path.join(work, "sim.tbl"), "w") as f:
            f.write("T1 P1 D0 Z0 ;\n")
        samples = os.path.join(work, "samples.txt")
        env = dict(os.environ, RTAPI_UID="65534", RTAPI_FIFO_PATH=os.path.join(work, "rtapi_fifo"),
                   VCNC_PROGRAM=program, VCNC_SAMPLES=samples)
        run = subprocess.run(["unshare", "--ipc", "--mount", "--pid", "--fork", "linuxcnc", "sim.ini"],
                             cwd=work, env=env, capture_output=True, text=True, timeout=1200)
        if run.returncode != 0 or not os.path.exists(samples):
            raise SystemExit(f"{name}: linuxcnc failed ({run.returncode}):\n{run.stdout}\n{run.stderr}")
        rows = []
        with open(samples) as f:
            for line in f:
                parts = line.split()
                if len(parts) >= 3:
                    rows.append(parts[:3])
        pos = [[float(x) for x in r] for r in rows]
        moving = [i for i in range(len(pos) - 1) if pos[i + 1] != pos[i]]
        if not moving:
            raise SystemExit(f"{name}: the machine did not move")
        first, last = moving[0], moving[-1] + 1
        # The joint commands pass LinuxCNC's cubic interpolator, which smooths the planner's
        # points with the weights (1, 4, 1)/6: a rest-to-rest motion starts one sample earlier
        # and ends one sample later than the planner's. The cycle time is the planner's.
        cycle = (last - first - 2) * TS
        out = os.path.join(recordings, name + ".txt")
        with open(out, "w") as f:
            f.write(f"# LinuxCNC {version()} planner, program {name}.ngc, recorded by "
                    "scripts/linuxcnc-planner/record.py\n")
            f.write("# limits " + " ".join(f"{l}={v:g},{a:g}" for l, (v, a) in zip("XYZ", limits)) + "\n")
            f.write(f"# joint.0..2.motor-pos-cmd (mm) every 1 ms from the sample before the first "
                    f"motion; cycle_time_s {cycle:.3f}\n")
            for r in rows[first:last + 1]:
                f.write(" ".join(r) + "\n")
        return cycle
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    args = sys.argv[1:]
    programs, recordings = PROGRAMS, RECORDINGS
    if args[:1] == ["--data"]:
        data, limits, paths = args[1], args[3], args[4:]
        if args[2] != "--limits":
            raise SystemExit("usage: record.py --data DIR --limits 'X=v,a Y=v,a Z=v,a' program.ngc ...")
        programs, recordings = os.path.join(data, "programs"), os.path.join(data, "recordings")
        os.makedirs(programs, exist_ok=True)
        args = []
        for p in paths:
            name = os.path.splitext(os.path.basename(p))[0]
            with open(p) as f:
                text = f.read()
            with open(os.path.join(programs, name + ".ngc"), "w") as f:
                f.write(f"(limits {limits})\n" + text)
            args.append(name)
    names = args or sorted(p[:-4] for p in os.listdir(programs) if p.endswith(".ngc"))
    os.makedirs(recordings, exist_ok=True)
    table = os.path.join(recordings, "cycle_times.csv")
    times = {}
    if os.path.exists(table):
        with open(table) as f:
            for line in f.readlines()[1:]:
                n, t = line.strip().split(",")
                times[n] = t
    for name in names:
        cycle = record(name, programs, recordings)
        times[name] = f"{cycle:.3f}"
        print(f"{name}: {cycle:.3f} s")
    with open(table, "w") as f:
        f.write("program,cycle_time_s\n")
        for n in sorted(times):
            f.write(f"{n},{times[n]}\n")


if __name__ == "__main__":
    main()
