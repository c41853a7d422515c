#!/usr/bin/env bash
# Makes sure Debian's headless-capable `chromium` is installed (the report's browser test needs
# it). Installs it with apt-get when missing; exits non-zero with a message when it cannot.
# Usage: bash crates/vcnc-report/tests/ensure-chromium.sh
set -euo pipefail
if command -v chromium >/dev/null 2>&1; then
  exit 0
fi
if [ "$(id -u)" != "0" ]; then
  echo "ensure-chromium: chromium is missing and installing it needs root (apt-get install -y chromium)" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
start=$(date +%s)
# Another apt process (a parallel install) may hold the lock: wait for it up to 10 minutes.
apt-get -o DPkg::Lock::Timeout=600 update -qq
apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends chromium fonts-dejavu-core >/dev/null
if ! command -v chromium >/dev/null 2>&1; then
  echo "ensure-chromium: apt-get install chromium finished but no chromium is on PATH" >&2
  exit 1
fi
echo "ensure-chromium: installed $(chromium --version 2>/dev/null) in $(( $(date +%s) - start )) s" >&2
