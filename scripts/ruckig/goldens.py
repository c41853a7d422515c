#!/usr/bin/env python3
"""Goldens of Ruckig's time-optimal jerk-limited single moves, for vcnc's seven-phase profile.

For a fixed set of rest-to-rest moves (length L, velocity limit V, acceleration limit A, jerk
limit J) this script asks Ruckig (https://github.com/pantor/ruckig, MIT licence; the PyPI
package `ruckig`) for the time-optimal trajectory and writes its duration and its seven phase
durations to crates/vcnc-gcode/tests/data/ruckig/single_moves.csv, which
crates/vcnc-gcode/tests/ruckig.rs compares with vcnc's profiles (CI needs no Python).

The moves: hand-picked cases of each kind (reaching V and A, reaching A only, reaching V only,
reaching neither) and 60 drawn from a seeded generator (Python's random, seed 31), with L
log-uniform in [1e-4, 500] mm so that many are short moves that reach neither the velocity nor
the acceleration limit.

Usage: pip install ruckig && python3 scripts/ruckig/goldens.py
"""
import math
import os
import random

from ruckig import InputParameter, Result, Ruckig, Trajectory

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "..", "crates", "vcnc-gcode", "tests", "data", "ruckig",
                   "single_moves.csv")


def solve(length, v, a, j):
    inp = InputParameter(1)
    inp.current_position = [0.0]
    inp.current_velocity = [0.0]
    inp.current_acceleration = [0.0]
    inp.target_position = [length]
    inp.target_velocity = [0.0]
    inp.target_acceleration = [0.0]
    inp.max_velocity = [v]
    inp.max_acceleration = [a]
    inp.max_jerk = [j]
    otg = Ruckig(1)
    traj = Trajectory(1)
    result = otg.calculate(inp, traj)
    if result not in (Result.Working, Result.Finished):
        raise SystemExit(f"ruckig failed on {length} {v} {a} {j}: {result}")
    return traj.duration, list(traj.profiles[0][0].t)


def main():
    import ruckig
    moves = [
        (100.0, 50.0, 1000.0, 1.0e5),   # reaches V and A
        (10.0, 200.0, 1000.0, 1.0e5),   # reaches A, not V
        (10.0, 20.0, 1000.0, 1.0e4),    # reaches V, not A
        (0.01, 50.0, 1000.0, 1.0e5),    # reaches neither
        (1.0e-4, 250.0, 2500.0, 5.0e4), # a tiny move
        (350.0, 250.0, 2500.0, 5.0e4),
    ]
    rng = random.Random(31)
    for _ in range(60):
        length = 10.0 ** rng.uniform(-4.0, math.log10(500.0))
        v = rng.uniform(5.0, 500.0)
        a = 10.0 ** rng.uniform(2.0, 4.5)
        j = 10.0 ** rng.uniform(3.0, 6.5)
        moves.append((length, v, a, j))
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    with open(OUT, "w") as f:
        f.write(f"# Ruckig {ruckig.__version__} time-optimal rest-to-rest moves, by "
                "scripts/ruckig/goldens.py; length mm, limits mm/s mm/s2 mm/s3, times s\n")
        f.write("length,v_max,a_max,j_max,duration,t1,t2,t3,t4,t5,t6,t7\n")
        for (length, v, a, j) in moves:
            duration, t = solve(length, v, a, j)
            f.write(",".join(repr(x) for x in [length, v, a, j, duration] + t) + "\n")
    print(f"{len(moves)} moves -> {os.path.relpath(OUT)}")


if __name__ == "__main__":
    main()
