#!/usr/bin/python3
"""LinuxCNC [DISPLAY] program: switch the machine on, run one program in auto mode while
halsampler records the joint commands, wait until the program is done and the machine is at
rest, then shut down. The program and the output file come from the environment (record.py)."""
import os
import subprocess
import time

import linuxcnc

PROGRAM = os.environ["VCNC_PROGRAM"]
OUT = os.environ["VCNC_SAMPLES"]

stat = linuxcnc.stat()
cmd = linuxcnc.command()


def wait(cond, timeout):
    t0 = time.time()
    while time.time() - t0 < timeout:
        stat.poll()
        if cond():
            return
        time.sleep(0.005)
    raise SystemExit(f"driver: timed out after {timeout} s")


wait(lambda: True, 30)
cmd.state(linuxcnc.STATE_ESTOP_RESET)
wait(lambda: stat.task_state == linuxcnc.STATE_ESTOP_RESET, 30)
cmd.state(linuxcnc.STATE_ON)
wait(lambda: stat.task_state == linuxcnc.STATE_ON, 30)
cmd.mode(linuxcnc.MODE_AUTO)
cmd.wait_complete()
with open(OUT, "w") as out:
    sampler = subprocess.Popen(["halsampler", "-c", "0"], stdout=out)
    time.sleep(0.3)
    cmd.program_open(PROGRAM)
    cmd.wait_complete()
    cmd.auto(linuxcnc.AUTO_RUN, 0)
    wait(lambda: stat.interp_state != linuxcnc.INTERP_IDLE, 10)
    wait(lambda: stat.interp_state == linuxcnc.INTERP_IDLE and stat.queue == 0 and stat.inpos, 900)
    time.sleep(0.3)
    sampler.terminate()
    sampler.wait()
cmd.state(linuxcnc.STATE_OFF)
