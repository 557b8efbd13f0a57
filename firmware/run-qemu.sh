#!/bin/sh
# Cargo runner: boots the ELF given as $1 in QEMU with semihosting (output on stdout, exit code
# from the guest). QEMU_MACHINE: mps2-an500 (Cortex-M7, default) or mps2-an386 (Cortex-M4F).
set -e
elf="$1"; shift
exec timeout "${QEMU_TIMEOUT:-300}" qemu-system-arm -machine "${QEMU_MACHINE:-mps2-an500}" \
    -display none -monitor none -serial none \
    -semihosting-config enable=on,target=native -kernel "$elf" "$@"
