#!/bin/sh
# Records pid-loop.txt: a genuine LinuxCNC halsampler recording (LinuxCNC 2.9, uspace,
# POSIX non-realtime) of a simulated servo loop on a 1 ms thread. siggen.0 gives a 2 Hz sine
# of 5 mm as the position command; pid.0 (Pgain 60, nothing else) closes the loop on an integ
# component that stands for the velocity-controlled drive (its output, the position, is the
# integral of the pid output). sampler.0 records the command and the position (cfg=ff), and
# halsampler writes them as LinuxCNC does: no names, no period, no sample numbers.
#
# The loop's law, from LinuxCNC's integ.comp (out += in * period) and pid.c (output = Pgain *
# error, the error taken against the command of the period before, as the recording shows of
# this LinuxCNC 2.9 build): fb[k] = fb[k-1] + T * Pgain * (cmd[k-1] - fb[k-1]), T = 1 ms.
# tests/fixtures.rs checks the recording against it (within the 1e-6 of halsampler's %f).
# Run from this folder: sh record-pid-loop.sh (needs linuxcnc-uspace: halrun, halsampler).
set -e
out="$(pwd)/pid-loop.txt"
work="$(mktemp -d)"
chmod 777 "$work"
cat > "$work/loop.hal" <<HAL
loadrt threads name1=servo period1=1000000
loadrt siggen num_chan=1
loadrt pid num_chan=1
loadrt integ count=1
loadrt sampler depth=4000 cfg=ff
addf siggen.0.update servo
addf pid.0.do-pid-calcs servo
addf integ.0 servo
addf sampler.0 servo
setp siggen.0.frequency 2.0
setp siggen.0.amplitude 5.0
setp pid.0.Pgain 60
setp pid.0.maxoutput 0
setp pid.0.enable 1
net cmd siggen.0.sine => pid.0.command sampler.0.pin.0
net fb integ.0.out => pid.0.feedback sampler.0.pin.1
net out pid.0.output => integ.0.in
start
loadusr -w halsampler -n 1500 $out
HAL
if [ "$(id -u)" = 0 ]; then
    # rtapi_app refuses to run as root without an unprivileged uid to fall back to.
    RTAPI_UID="${RTAPI_UID:-$(awk -F: '$3 >= 1000 && $3 < 65534 {print $3; exit}' /etc/passwd)}"
    export RTAPI_UID="${RTAPI_UID:-65534}"
fi
export RTAPI_FIFO_PATH="$work/fifo"
halrun -f "$work/loop.hal"
halrun -U || true
rm -rf "$work"
echo "wrote $out ($(wc -l < "$out") samples)"
