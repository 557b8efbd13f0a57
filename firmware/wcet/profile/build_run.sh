#!/usr/bin/env bash
# Build the M7 f32 wcet-step image from this checkout and profile it with wcet_prof.so.
# usage: profile/build_run.sh TAG [samples]   -> profile/out/TAG/{sample-K.txt,nodes.txt,disas.txt,log.txt,wcet-step.elf}
# BIN=wcet-step-panda profiles the imported Panda's step image instead (-> out/TAG/wcet-step-panda.elf).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"; tag=$1; samples=${2:-all}; bin=${BIN:-wcet-step}
features=""; [ "$bin" = wcet-step-panda ] && features="--features wcet-panda"
cd "$here/../.."
CARGO_TARGET_DIR="$PWD/target/wcet-m7-f32" RUSTFLAGS="-C link-arg=-Tlink.x -C target-cpu=cortex-m7" \
    cargo build ${CARGO_LOCKED---locked} --release --bin "$bin" $features >&2
[ -f "$here/wcet_prof.so" ] || gcc -O2 -shared -fPIC -fvisibility=hidden -o "$here/wcet_prof.so" "$here/wcet_prof.c"
out="$here/out/$tag"; mkdir -p "$out"
elf=target/wcet-m7-f32/thumbv7em-none-eabihf/release/$bin
cp "$elf" "$out/$bin.elf"
QEMU_MACHINE=mps2-an500 QEMU_TIMEOUT=600 ./run-qemu.sh "$elf" -plugin "$here/wcet_prof.so,dir=$out,samples=$samples" > "$out/log.txt"
# per-sample totals with classes (nominal median = sample 13, worst adversarial = sample 24 in the base build)
frames=$(ls "$out"/sample-*.txt | wc -l)
paste -d' ' <(for k in $(seq 0 $((frames - 1))); do head -1 "$out/sample-$k.txt" | awk '{print $3}'; done) \
            <(sed -n 's/^step [0-9]* class=\([a-z]*\).*/\1/p' "$out/log.txt") > "$out/step.txt"
for class in nominal adversarial capacity; do
  awk -v cl="$class" '$2 == cl { print $1 }' "$out/step.txt" | sort -n \
    | awk -v cl="$class" '{ a[NR] = $1 } END { printf "%-12s min %9d  median %9d  max %9d\n", cl, a[1], a[int((NR + 1) / 2)], a[NR] }'
done
echo "sample13 $(head -1 $out/sample-13.txt)  sample24 $(head -1 $out/sample-24.txt)"
grep -o 'torque_sum=[^ ]*' "$out/log.txt" | md5sum | sed 's/^/torque checksums md5: /'
