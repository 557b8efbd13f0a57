#!/usr/bin/env bash
# Exact per-call instruction counts (QEMU TCG plugin), stack high-water marks (painting) and
# image sizes of the kernel stages measured by `src/bin/wcet.rs`, on
#   m7-f32  Cortex-M7 (mps2-an500), target-cpu=cortex-m7, f32
#   m7-f64  Cortex-M7 (mps2-an500), target-cpu=cortex-m7 (double-precision FPU), f64
#   m4-f32  Cortex-M4F (mps2-an386), target-cpu=cortex-m4, f32
# and the full step of Justin (`wcet-step`) on each, of the imported Panda (`wcet-step-panda`) on
# m7-f32 (lines "panda-m7-f32").
# Each variant runs twice; the script fails if any count differs between the runs.
# With --callgrind, also counts the same stages on the host (x86-64, valgrind callgrind, one
# process per case and precision; the bench in wcet/host shares wcet/stages with the images).
# With --time (implied by --callgrind), also host wall-clock percentiles of the full step.
# Usage: bash firmware/wcet/measure.sh [--callgrind|--time]   (raw outputs in firmware/target/wcet/)
# Method and its limits: firmware/wcet/README.md.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
fw="$(dirname "$here")"
cd "$fw"
out="$fw/target/wcet"
mkdir -p "$out"

# --- set-up ---------------------------------------------------------------------------------
rustup target add thumbv7em-none-eabihf >/dev/null
if ! command -v qemu-system-arm >/dev/null || ! command -v gcc >/dev/null; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq qemu-system-arm gcc >/dev/null
fi
plugin="$out/wcet_insn.so"
bash "$here/build_plugin.sh" "$plugin"

# --- build and run --------------------------------------------------------------------------
# VARIANTS="m7-f32" limits the run to some variants (default: all three).
read -r -a variants <<< "${VARIANTS:-m7-f32 m7-f64 m4-f32}"
declare -A cpu=([m7-f32]=cortex-m7 [m7-f64]=cortex-m7 [m4-f32]=cortex-m4)
declare -A machine=([m7-f32]=mps2-an500 [m7-f64]=mps2-an500 [m4-f32]=mps2-an386)
declare -A features=([m7-f32]="" [m7-f64]="--features wcet-f64" [m4-f32]="")
stages=(dynamics self_collision projection)
# The imported Panda's full step (`wcet-step-panda`, wcet/stages/src/panda.rs) is measured on
# this variant only; its step lines are the variant "panda-<variant>".
panda_on=m7-f32
step_variants=("${variants[@]}")
if [[ " ${variants[*]} " == *" $panda_on "* ]]; then step_variants+=("panda-$panda_on"); fi

for v in "${variants[@]}"; do
    panda=""; [ "$v" = "$panda_on" ] && panda="--bin wcet-step-panda"
    echo "==> build $v (target-cpu=${cpu[$v]} ${features[$v]})" >&2
    # shellcheck disable=SC2086
    CARGO_TARGET_DIR="$fw/target/wcet-$v" RUSTFLAGS="-C link-arg=-Tlink.x -C target-cpu=${cpu[$v]}" \
        cargo build --locked --release --bin wcet --bin wcet-step ${features[$v]} >&2
    # The Panda's image in a build of its own: its feature would change Justin's images.
    # shellcheck disable=SC2086
    [ -z "$panda" ] || CARGO_TARGET_DIR="$fw/target/wcet-$v" RUSTFLAGS="-C link-arg=-Tlink.x -C target-cpu=${cpu[$v]}" \
        cargo build --locked --release $panda --features wcet-panda ${features[$v]} >&2
    elf="$fw/target/wcet-$v/thumbv7em-none-eabihf/release/wcet"
    cp "$elf" "$out/wcet-$v.elf"
    cp "$elf-step" "$out/wcet-step-$v.elf"
    [ -z "$panda" ] || cp "$elf-step-panda" "$out/wcet-step-panda-$v.elf"
    for run in 1 2; do
        echo "==> run $v on ${machine[$v]} ($run/2)" >&2
        QEMU_MACHINE=${machine[$v]} QEMU_TIMEOUT=600 ./run-qemu.sh "$elf" \
            -plugin "$plugin,out=$out/$v.counts.$run" > "$out/$v.log.$run"
        QEMU_MACHINE=${machine[$v]} QEMU_TIMEOUT=600 ./run-qemu.sh "$elf-step" \
            -plugin "$plugin,out=$out/$v.step-counts.$run" > "$out/$v.step-log.$run"
        [ -z "$panda" ] || QEMU_MACHINE=${machine[$v]} QEMU_TIMEOUT=600 ./run-qemu.sh "$elf-step-panda" \
            -plugin "$plugin,out=$out/panda-$v.step-counts.$run" > "$out/panda-$v.step-log.$run"
    done
    files=("$v.counts" "$v.log" "$v.step-counts" "$v.step-log")
    [ -z "$panda" ] || files+=("panda-$v.step-counts" "panda-$v.step-log")
    for f in "${files[@]}"; do
        if ! cmp -s "$out/$f.1" "$out/$f.2"; then
            echo "error: $f differ between two runs" >&2
            exit 1
        fi
    done
    if ! cmp -s "$out/$v.counts.1" "$out/$v.counts.2" || ! cmp -s "$out/$v.log.1" "$out/$v.log.2"; then
        echo "error: $v counts or outputs differ between two runs" >&2
        diff "$out/$v.counts.1" "$out/$v.counts.2" >&2 || true
        exit 1
    fi
done

# --- table ----------------------------------------------------------------------------------
summary() { # file region -> "min max samples"
    sed -n "s/^wcet SUMMARY region=$2 samples=\([0-9]*\) min=\([0-9]*\) max=\([0-9]*\).*/\2 \3 \1/p" "$1"
}
stack_of() { # log stage -> bytes
    sed -n "s/^wcet-stack.* $2=\([0-9]*\).*/\1/p" "$1"
}
echo
echo "Instructions per call (QEMU TCG plugin; min - max over cases; identical in both runs)"
printf '%-8s %-15s %12s %12s %7s %8s %12s\n' variant stage min max cases spread "stack [B]"
for v in "${variants[@]}"; do
    for r in 0 1 2; do
        read -r mn mx n < <(summary "$out/$v.counts.1" "$r")
        printf '%-8s %-15s %12s %12s %7s %7.2f%% %12s\n' "$v" "${stages[$r]}" "$mn" "$mx" "$n" \
            "$(awk -v a="$mn" -v b="$mx" 'BEGIN { print (b - a) * 100 / b }')" "$(stack_of "$out/$v.log.1" "${stages[$r]}")"
    done
done
echo
echo "Full Controller::step per input class (wcet-step images; insns min / median / max; frames of wcet/stages)"
printf '%-8s %-12s %6s %12s %12s %12s\n' variant class frames min median max
for v in "${step_variants[@]}"; do
    # per-sample counts (plugin: 'wcet region=0 sample=K insns=X fp_div_sqrt=D') joined with the
    # classes of the log: "insns class fp_div_sqrt"
    paste -d' ' <(sed -n 's/^wcet region=0 sample=[0-9]* insns=\([0-9]*\).*/\1/p' "$out/$v.step-counts.1") \
                <(sed -n 's/^step [0-9]* class=\([a-z]*\).*/\1/p' "$out/$v.step-log.1") \
                <(sed -n 's/^wcet region=0 sample=[0-9]* insns=[0-9]* fp_div_sqrt=\([0-9]*\).*/\1/p' "$out/$v.step-counts.1") \
        > "$out/$v.step"
    for class in nominal adversarial fault recovery capacity all; do
        awk -v cl="$class" '$2 == cl || cl == "all" { print $1 }' "$out/$v.step" | sort -n \
            | awk -v v="$v" -v cl="$class" '{ a[NR] = $1 } END { if (NR) printf "%-8s %-12s %6d %12d %12d %12d\n", v, cl, NR, a[1], a[int((NR + 1) / 2)], a[NR] }'
    done
    sed -n 's/^wcet-stack \(step=[0-9]*\).*/  stack: \1/p; s/^wcet-stack \(whole-run.*\)/  stack: \1/p' "$out/$v.step-log.1"
done

# One line per variant for scripts. bound = the most expensive capacity frame (every capacity of
# the step filled, BENCHMARKS.md argues why no input costs more); worst = the most expensive
# sampled frame (nominal, adversarial, fault, recovery), which may not exceed the bound;
# fp_div_sqrt = VDIV/VSQRT in the bound frame; cycles_est = bound + 13 per VDIV/VSQRT (14 cycles
# each on the M4 and M7, one cycle per other instruction: a planning figure, not a measurement).
echo
status=0
for v in "${step_variants[@]}"; do
    median=$(awk '$2 == "nominal" { print $1 }' "$out/$v.step" | sort -n | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }')
    line=$(awk -v v="$v" -v median="$median" '
        $2 != "capacity" && $1 > worst { worst = $1 }
        $2 == "capacity" && $1 > bound { bound = $1; slow = $3 }
        END {
            printf "step %s nominal_median=%d worst=%d bound=%d fp_div_sqrt=%d cycles_est=%d", v, median, worst, bound, slow, bound + 13 * slow
            if (worst > bound) printf " ERROR=worst-exceeds-bound"
        }' "$out/$v.step")
    echo "$line"
    case "$line" in *ERROR*) status=1 ;; esac
done
if [ "$status" -ne 0 ]; then
    echo "error: a sampled frame costs more than the capacity frame (the bound)" >&2
    exit 1
fi
echo
echo "Image sizes (size: text = flash code+rodata, data = flash+RAM, bss = RAM; stack not included)"
size "$out"/wcet-*.elf   # wcet-step-*: the full-step image (controller in .bss)
echo "smoke image (default bin, f32, generic thumbv7em):"
(cargo build --locked --release --bin firmware >/dev/null 2>&1 && size target/thumbv7em-none-eabihf/release/firmware) || true

# --- host callgrind (optional) --------------------------------------------------------------
if [ "${1:-}" = "--callgrind" ]; then
    if ! command -v valgrind >/dev/null; then
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq && apt-get install -y -qq valgrind >/dev/null
    fi
    cases=$(sed -n 's/^pub const CASES: u32 = \([0-9]*\);/\1/p' "$here/stages/src/lib.rs")
    echo
    echo "Host x86-64 instructions per call (callgrind, $cases cases, min - max)"
    printf '%-8s %-15s %12s %12s\n' variant stage min max
    for prec in f32 f64; do
        feat=""; [ "$prec" = f64 ] && feat="--features wcet-f64"
        # shellcheck disable=SC2086
        (cd "$here/host" && CARGO_TARGET_DIR="$fw/target/wcet-host-$prec" cargo build --locked --release $feat >&2)
        bin="$fw/target/wcet-host-$prec/x86_64-unknown-linux-gnu/release/wcet-host"
        : > "$out/host-$prec.callgrind"
        for ((k = 0; k < cases; k++)); do
            valgrind --tool=callgrind --collect-atstart=no --toggle-collect=wcet_dynamics \
                --toggle-collect=wcet_self_collision --toggle-collect=wcet_projection \
                --callgrind-out-file="$out/cg.out" "$bin" "$k" >/dev/null 2>&1
            # The stage's own line (file wcet/stages/src/lib.rs) carries its inclusive cost.
            for st in "${stages[@]}"; do
                n=$(callgrind_annotate --inclusive=yes "$out/cg.out" 2>/dev/null \
                    | grep -E "lib\.rs:wcet_$st( |\$)" | head -n1 | awk '{ gsub(",", "", $1); print $1 }')
                echo "$st $k $n" >> "$out/host-$prec.callgrind"
            done
        done
        for st in "${stages[@]}"; do
            awk -v st="$st" -v v="x86-$prec" '$1 == st { if (min == "" || $3 < min) min = $3; if ($3 > max) max = $3 }
                END { printf "%-8s %-15s %12s %12s\n", v, st, min, max }' "$out/host-$prec.callgrind"
        done
        # The full step: one process per frame K; frames 0..K-1 run through `warm_step`.
        frames=$("$bin" frames)
        : > "$out/host-$prec.step"
        for ((k = 0; k < frames; k++)); do
            class=$(valgrind --tool=callgrind --collect-atstart=no --toggle-collect=wcet_step \
                --callgrind-out-file="$out/cg.out" "$bin" step "$k" 2>/dev/null | sed -n 's/^frame [0-9]* class=\([a-z]*\).*/\1/p')
            n=$(callgrind_annotate --inclusive=yes "$out/cg.out" 2>/dev/null \
                | grep -E "lib\.rs:wcet_step( |\$)" | head -n1 | awk '{ gsub(",", "", $1); print $1 }')
            echo "$n $class" >> "$out/host-$prec.step"
        done
        for class in nominal adversarial fault recovery all; do
            awk -v cl="$class" '$2 == cl || cl == "all" { print $1 }' "$out/host-$prec.step" | sort -n \
                | awk -v v="x86-$prec" -v cl="$class" '{ a[NR] = $1 } END { if (NR) printf "%-8s step %-12s %4d frames  min %9d  median %9d  max %9d\n", v, cl, NR, a[1], a[int((NR + 1) / 2)], a[NR] }'
        done
    done
fi

# --- host wall clock (optional) ---------------------------------------------------------------
# rdtsc per step, pinned to CPU 1, no ASLR (README.md, "Host"); numbers, not assertions.
if [ "${1:-}" = "--callgrind" ] || [ "${1:-}" = "--time" ]; then
    for prec in f32 f64; do
        feat=""; [ "$prec" = f64 ] && feat="--features wcet-f64"
        # shellcheck disable=SC2086
        (cd "$here/host" && CARGO_TARGET_DIR="$fw/target/wcet-host-$prec" cargo build --locked --release $feat >&2)
        bin="$fw/target/wcet-host-$prec/x86_64-unknown-linux-gnu/release/wcet-host"
        echo
        echo "Host x86-64 $prec wall clock per Controller::step (rdtsc; setarch -R taskset -c 1; 300 passes)"
        setarch x86_64 -R taskset -c 1 "$bin" time 300
    done
fi
