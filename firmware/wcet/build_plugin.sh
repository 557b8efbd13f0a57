#!/usr/bin/env bash
# Builds the counting plugin `wcet_insn.c` for the installed qemu-system-arm into FILE (needs gcc).
# The plugin declares the QEMU plugin API itself: no glib or qemu headers needed.
# Usage: bash firmware/wcet/build_plugin.sh FILE.so
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
qemu_major=$(qemu-system-arm --version | sed -n 's/.*version \([0-9]*\)\..*/\1/p' | head -n1)
api=""
if [ "${qemu_major:-7}" -ge 9 ]; then api="-DQEMU_PLUGIN_API_VERSION=3"; fi
# shellcheck disable=SC2086
gcc -O2 -shared -fPIC -fvisibility=hidden $api -o "$1" "$here/wcet_insn.c"
