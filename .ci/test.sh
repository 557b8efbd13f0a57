#!/usr/bin/env bash
# The project's test command (README): sets up a fresh machine and runs every check.
#   1. host tests of the whole workspace (kernel, hal, fixtures, host-sim, thesis tests)
#   2. clippy with the panic-freedom lints as errors
#   3. the firmware image for thumbv7em-none-eabihf, linked WITHOUT a global allocator:
#      the link fails if anything in the kernel's dependency graph pulls in `alloc`
#   4. a QEMU smoke run of that image on Cortex-M7 (mps2-an500) and Cortex-M4F (mps2-an386)
#   5. the link-time panic check: Controller::step and apply_bytes linked with an undefined panic handler;
#      the step images of Justin and the Panda run to their end on the Cortex-M7
#   6. formatting (`cargo fmt --check`), rustdoc with warnings as errors, no import cycle
#      between the kernel's modules (.ci/module_cycles.py)
#   7. processor in the loop: the runtime image under QEMU (Cortex-M7) controls the simulated
#      robot for 300 cycles, and refuses injected bad link frames with the safe output
#   8. the replay page in a real browser: headless Chromium draws replay.html of wbc_phri (Justin)
#      and of projectors_sim1 (the planar arm)
#   9. coverage-guided fuzzing (cargo fuzz): every target for 20 s from the committed seeds
set -euo pipefail
cd "$(dirname "$0")/.."
# Incremental caches double the size of the debug target and a CI build is never incremental.
export CARGO_INCREMENTAL=0

# Each step reports the free disk: the CI machine's disk is small and a full disk fails a
# build with "No space left on device" far from its cause.
step() { printf '\n==> %s   [%s free]\n' "$*" "$(df -h --output=avail . | tail -n 1 | tr -d ' ')"; }

step "toolchain set-up"
rustup target add thumbv7em-none-eabihf >/dev/null
rustup component add clippy rustfmt >/dev/null 2>&1 || true
# gcc builds the QEMU counting plugin of the PIL test (firmware/wcet/build_plugin.sh);
# python3 runs the module-graph check (.ci/module_cycles.py).
if ! command -v qemu-system-arm >/dev/null || ! command -v gcc >/dev/null || ! command -v python3 >/dev/null; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq qemu-system-arm gcc python3 >/dev/null
fi

step "formatting (rustfmt.toml) of the workspace, the firmware and its host bench"
for manifest in Cargo.toml firmware/Cargo.toml firmware/wcet/host/Cargo.toml fuzz/Cargo.toml; do
    cargo fmt --manifest-path "$manifest" --all --check
done

step "kernel and hal build for thumbv7em-none-eabihf (no_std)"
cargo build --locked -p kernel -p hal --target thumbv7em-none-eabihf --release
# ... and with the `defmt::Format` derives of every public kernel and hal type.
cargo build --locked -p kernel -p hal --features kernel/defmt,hal/defmt --target thumbv7em-none-eabihf --release

step "no alloc/std in the kernel's dependency graph"
# Normal edges only: dev-dependencies (proptest, approx/std) never reach the firmware build.
if cargo tree --locked -p kernel --target thumbv7em-none-eabihf -e features,normal --prefix none \
    | grep -E 'feature "(alloc|std)"'; then
    echo "error: the kernel enables alloc/std in a dependency" >&2
    exit 1
fi

step "firmware image (links without a global allocator)"
(cd firmware && cargo build --locked --release)
size_line=$(size -A firmware/target/thumbv7em-none-eabihf/release/firmware 2>/dev/null | grep -E '^\.(text|data|bss)' | tr '\n' ' ' || true)
echo "firmware sections: ${size_line:-n/a}"

step "QEMU smoke run (Cortex-M7, then Cortex-M4F)"
for machine in mps2-an500 mps2-an386; do
    (cd firmware && QEMU_MACHINE=$machine QEMU_TIMEOUT=120 cargo run --locked --release)
done

step "clippy on the firmware (both step images' stages)"
(cd firmware && cargo clippy --locked --features wcet-panda -- -D warnings)

step "no panic path from Controller::step in the release image (link fails on any)"
bash firmware/wcet/panic_check.sh m7-f32 m7-f64 m4-f32

step "the step images run to their end on the Cortex-M7 in f32 (Justin's wcet-step, the Panda's wcet-step-panda)"
# The same build directory and flags as the panic check's m7-f32 variant, so its dependencies are
# reused; an image that fails (a refused command, a controller error) exits non-zero.
mkdir -p firmware/target
for image in "wcet-step" "wcet-step-panda --features wcet-panda"; do
    log="target/${image%% *}.log"
    # shellcheck disable=SC2086
    (cd firmware && CARGO_TARGET_DIR=target/wcet-m7-f32 RUSTFLAGS="-C link-arg=-Tlink.x -C target-cpu=cortex-m7" \
        QEMU_MACHINE=mps2-an500 QEMU_TIMEOUT=600 cargo run --locked --release --bin $image > "$log") \
        || { tail -n 20 "firmware/$log" >&2; exit 1; }
    echo "${image%% *}: ran to its end ($(grep -c . "firmware/$log") lines of output)"
done

# The firmware builds (four release targets with fat LTO, ~1 GB) are done: free the disk for
# the host build.
rm -rf firmware/target

step "clippy (panic-freedom lints are errors)"
cargo clippy --locked --workspace --all-targets -- -D warnings

step "rustdoc (warnings are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --locked --workspace --no-deps

step "no import cycle between the kernel's modules"
python3 .ci/module_cycles.py kernel/src

step "workspace tests"
cargo test --locked --workspace

step "processor in the loop (runtime image on QEMU Cortex-M7: 300 cycles with the defmt log and instruction counts, link-fault injection)"
cargo test --locked -p host-sim --test pil_rig --test pil_link_faults -- --ignored --test-threads 1

step "replay.html in headless Chromium (replay/README.md)"
# Only what is missing: a machine with its own Node.js (not Debian's) cannot take Debian's npm.
missing=()
command -v chromium >/dev/null || missing+=(chromium)
command -v npm >/dev/null || missing+=(nodejs npm)
if [ ${#missing[@]} -gt 0 ]; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
(cd replay && npm ci --no-audit --no-fund && npm run build)
# The committed bundle is the one the lock file's packages build.
git diff --exit-code -- replay/dist/replay.js
cargo run --locked -p host-sim -- run wbc_phri --out out/replay-ci
(cd replay && npm test -- ../out/replay-ci/replay.html 0 1.2 ../out/replay-ci/screenshots)
cargo run --locked -p host-sim -- run projectors_sim1 --out out/replay-ci-planar
(cd replay && npm test -- ../out/replay-ci-planar/replay.html 0 1.5 ../out/replay-ci-planar/screenshots)

# The sanitizer build of the fuzz targets needs ~1.3 GB: on a small disk, free the workspace's
# target first (a developer's machine with room keeps it).
if [ "$(df --output=avail -k . | tail -n 1)" -lt $((8 * 1024 * 1024)) ]; then
    rm -rf target
fi
step "coverage-guided fuzzing, 20 s per target (bash fuzz/run.sh; long runs: bash fuzz/run.sh 3600)"
bash fuzz/run.sh 20
