#!/usr/bin/env bash
# Panic-freedom evidence for `Controller::step`, `Controller::apply_bytes` (command decoding
# and `apply`) and the runtime's setup (`ControllerSlot::configure`: assembling, decoding, building
# the controller) in the release firmware (issues 8, 14 and 16).
#
# Links `src/bin/panic_check.rs` (main calls only `wcet_step` = the Justin controller's full
# `step`, `wcet_step_panda` = the imported Panda's, `apply_bytes` and the setup path, on opaque inputs) with a panic handler that calls an undefined
# function: the link succeeds only if no panic path from either survives optimisation (release profile: opt 3, fat
# LTO, 1 CGU, panic = abort). Variants: Cortex-M7 f32, Cortex-M7 f64 (DP FPU), Cortex-M4F f32.
# On a failure it rebuilds with a defined handler and lists the functions that still call a
# panic function (core::panicking::*, core::option::expect_failed, slice index failures, ...).
# Usage: bash firmware/wcet/panic_check.sh [m7-f32|m7-f64|m4-f32 ...]   (default: all three)
# Exit status: 0 = no panic path in any variant, 1 = some remain (listed), 2 = build error.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
fw="$(dirname "$here")"
cd "$fw"
rustup target add thumbv7em-none-eabihf >/dev/null

declare -A cpu=([m7-f32]=cortex-m7 [m7-f64]=cortex-m7 [m4-f32]=cortex-m4)
declare -A features=([m7-f32]="" [m7-f64]=",wcet-f64" [m4-f32]="")
variants=("$@")
[ ${#variants[@]} -eq 0 ] && variants=(m7-f32 m7-f64 m4-f32)
objdump=$(command -v llvm-objdump || command -v arm-none-eabi-objdump || true)
status=0
for v in "${variants[@]}"; do
    [ -n "${cpu[$v]:-}" ] || { echo "unknown variant $v" >&2; exit 2; }
    dir="$fw/target/wcet-$v"
    flags="-C link-arg=-Tlink.x -C target-cpu=${cpu[$v]}"
    log="$fw/target/panic-check-$v.log"
    mkdir -p "$fw/target"
    if CARGO_TARGET_DIR="$dir" RUSTFLAGS="$flags" cargo build --locked --release --bin panic-check \
        --features "panic-check${features[$v]}" >"$log" 2>&1; then
        elf="$dir/thumbv7em-none-eabihf/release/panic-check"
        for symbol in wcet_step wcet_step_panda; do
            if ! nm -C "$elf" | grep -q " $symbol\$"; then
                echo "panic-check $v: FAILED ($symbol missing from the image: the check proves nothing)" >&2
                exit 2
            fi
        done
        echo "panic-check $v: OK (no panic path reachable from Controller::step (Justin, Panda), apply_bytes or the setup; $(size "$elf" | awk 'NR == 2 { print "text " $1 " B" }'))"
        continue
    fi
    if ! grep -q 'step_has_a_panic_path' "$log"; then
        echo "panic-check $v: build error (not a panic path):" >&2
        tail -n 30 "$log" >&2
        exit 2
    fi
    status=1
    echo "panic-check $v: FAILED, panic paths remain; call sites:"
    CARGO_TARGET_DIR="$dir" RUSTFLAGS="$flags" cargo build --locked --release --bin panic-check \
        --features "panic-check-report${features[$v]}" >>"$log" 2>&1
    elf="$dir/thumbv7em-none-eabihf/release/panic-check"
    # The panic entry points present in the image ...
    nm -C "$elf" | grep -E ' [tT] (core::panicking::|core::option::(expect|unwrap)_failed|core::result::unwrap_failed|core::slice::index::|core::cell::panic_|core::str::slice_error_fail|rust_begin_unwind)' \
        | sed 's/^/  entry: /' || true
    # ... and the functions that call them (disassembly, demangled).
    if [ -n "$objdump" ]; then
        "$objdump" -d -C --no-show-raw-insn "$elf" | awk '
            /^[0-9a-f]+ <.*>:$/ { fn = substr($0, index($0, "<") + 1); sub(/>:$/, "", fn); next }
            /\tbl?x?\t|\tb\.w\t|\tbl\t/ && /<(core::panicking::|core::option::(expect|unwrap)_failed|core::result::unwrap_failed|core::slice::index::|core::cell::panic_|rust_begin_unwind)/ {
                t = substr($0, index($0, "<") + 1); sub(/>.*/, "", t); print "  caller: " fn "  ->  " t }' | sort | uniq -c | sort -rn
    fi
done
exit $status
