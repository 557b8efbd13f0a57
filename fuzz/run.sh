#!/usr/bin/env bash
# Coverage-guided fuzzing (cargo fuzz, libFuzzer + AddressSanitizer) of every target in
# fuzz/fuzz_targets/: command_apply (planner bytes into a running controller), step_sequence
# (arbitrary sensor frames and commands, f32 and f64), host_parsers (URDF and states parsers).
#
# Usage: bash fuzz/run.sh [SECONDS_PER_TARGET] [TARGET ...]
#   CI runs each target for 20 s:   bash fuzz/run.sh 20
#   a long local run:               bash fuzz/run.sh 3600
# Each run starts from the committed seeds (fuzz/corpus/<target>/) and writes what it finds
# to a fresh directory under fuzz/out/<target>/ (not committed; copy interesting inputs into
# the seed corpus by hand). A crash leaves its input in fuzz/artifacts/<target>/ and fails.
# The stable toolchain builds the sanitizer flags with RUSTC_BOOTSTRAP=1.
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
cd "$HERE"
SECONDS_PER_TARGET=${1:-20}
shift || true
if ! command -v cargo-fuzz >/dev/null; then
    cargo install cargo-fuzz --version 0.13.2 --locked
fi
export RUSTC_BOOTSTRAP=1
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets < <(cargo fuzz list)
fi
cargo fuzz build
status=0
for target in "${targets[@]}"; do
    out="out/$target"
    rm -rf "$out" "artifacts/$target" && mkdir -p "$out"
    echo "==> fuzz $target for ${SECONDS_PER_TARGET}s"
    if ! cargo fuzz run "$target" "$out" "corpus/$target" -- \
        -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb=4096 -print_final_stats=1 >"out/$target.log" 2>&1; then
        tail -40 "out/$target.log" >&2
        echo "fuzz $target: FAILED, input in fuzz/artifacts/$target/" >&2
        status=1
        continue
    fi
    grep -E "^stat::(number_of_executed_units|peak_rss_mb)|^#[0-9]+ +DONE" "out/$target.log" || true
done
exit $status
