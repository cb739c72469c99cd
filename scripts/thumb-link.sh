#!/usr/bin/env bash
# The linker of every thumbv7em-none-eabihf build run from the workspace root
# (.cargo/config.toml): rustc calls it as it would call rust-lld, and it
# hands the arguments on unchanged. Only the STM32 board (the one link that
# names its linker script `stm32f4-sonar.x`) goes through flip-link instead
# (issue #30 item 3): the stack is placed below .data/.bss, so an overflow
# faults instead of overwriting the statics. Every other image (the QEMU
# board, panic-never) is linked by rust-lld exactly as without this script.
# rustc puts its own tools folder (rust-lld) on PATH for the linker.
set -euo pipefail
flip=0
for a in "$@"; do
  case "$a" in
    -Tstm32f4-sonar.x) flip=1 ;;
    @*) grep -qx -- '-Tstm32f4-sonar.x' "${a#@}" 2>/dev/null && flip=1 ;;
  esac
done
if [ "$flip" = 1 ]; then
  if ! command -v flip-link >/dev/null; then
    echo "thumb-link.sh: the STM32 board links with flip-link, which is not installed: cargo install flip-link (scripts/setup.sh does)" >&2
    exit 1
  fi
  exec flip-link "$@"
fi
exec rust-lld "$@"
