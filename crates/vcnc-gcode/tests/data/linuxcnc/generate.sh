#!/bin/sh
# Regenerate the canonical outputs of LinuxCNC's stand-alone interpreter for every program in
# programs/ (see README.md). Needs the Debian package linuxcnc-uspace (it provides rs274).
# rs274 rewrites the parameter file it reads, so it gets a scratch copy.
set -eu
cd "$(dirname "$0")"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for p in programs/*.ngc; do
    name=$(basename "$p" .ngc)
    cp params.var "$tmp/params.var"
    cp tools.tbl "$tmp/tools.tbl"
    # -g: run to the end without stopping; the exit status is that of the program.
    rs274 -g -t "$tmp/tools.tbl" -v "$tmp/params.var" "$p" > "canon/$name.canon" 2>&1 || true
done
