#!/usr/bin/env bash
# The link-time proof that the firmware core cannot panic (issue #14 item 2):
# builds boards/panic-never, whose panic handler calls a symbol defined
# nowhere, so it links only when no panic path is left anywhere in the core
# paths it runs (map validation, ring prediction, the whole loop through the
# driver, the host link).
#
#   bash scripts/panic-never.sh          # must link
#   bash scripts/panic-never.sh --plant  # plants a panic path in the core: must NOT link
#   bash scripts/panic-never.sh --locate # lists where remaining panic calls come from
#   bash scripts/panic-never.sh --overflow # with echoloc's overflow checks on (and
#                                        # LLVM's tail merging off, one call per check):
#                                        # lists the checks the optimiser could not
#                                        # remove, per source line, and fails if any is
#                                        # left (issue #30: none anywhere in the core paths)
#   bash scripts/panic-never.sh --overflow --plant # the same with an overflow planted in
#                                        # the predictor: it must be counted (else fails)
set -euo pipefail
cd "$(dirname "$0")/.."
target=thumbv7em-none-eabihf
build() { cargo build -q -p panic-never --target "$target" --release "$@"; }

# Every branch to a core panic entry point in $1, with its inlined call chain
# (the innermost $2 frames, 8 unless given).
locate() {
  local elf=$1 depth=${2:-8}
  host=$(rustc -vV | sed -n 's/^host: //p')
  objdump="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-objdump"
  dis=$("$objdump" -d --no-show-raw-insn "$elf")
  # Every branch to a core panic entry point, with its inlined call chain.
  targets=$(grep -E '^[0-9a-f]+ <.*(panicking|slice_index_fail|_fail|unwrap_failed|expect_failed).*>:' <<<"$dis" |
    awk '{print $1}' | sed 's/^0*//')
  for t in $targets; do
    grep -E "\s0x$t\b" <<<"$dis" | awk '{print $1}' | tr -d ':' | while read -r a; do
      echo "== call at 0x$a"
      addr2line -e "$elf" -i -f -C "0x$a" | paste - - | head -"$depth"
    done
  done
}

case "${1:-}" in
--locate)
  build --features locate
  locate "${CARGO_TARGET_DIR:-target}/$target/release/panic-never"
  ;;
--overflow)
  # Integer overflow, which a release build would silently wrap: every
  # arithmetic step in the core paths must be proven not to overflow (the
  # bound visible to the compiler), or say in the code that it wraps,
  # saturates or is checked (issue #30).
  export CARGO_TARGET_DIR=target/panic-overflow
  flags="-Cllvm-args=-enable-tail-merge=false"
  if [ "${2:-}" = "--plant" ]; then
    # The count must be able to fail: an unproven sum planted in the predictor.
    export CARGO_TARGET_DIR=target/panic-overflow-plant
    flags="$flags --cfg echoloc_plant_overflow"
  fi
  # On in the board too: echoloc's generic code (the predictor, the
  # localizer, the driver, the link) is compiled in the crate that
  # instantiates it, with that crate's setting.
  RUSTFLAGS="$flags" build --features locate \
    --config 'profile.release.package.echoloc.overflow-checks=true' \
    --config 'profile.release.package.panic-never.overflow-checks=true'
  # Each check at the innermost echoloc (or board) line of its whole call
  # chain; a chain with neither (an outlined library function) is counted too.
  checks=$(locate "$CARGO_TARGET_DIR/$target/release/panic-never" 1000 | sed "s|$PWD/||" |
    awk -F'\t' '
      function flush() { if (open && !found && !inside) print "(no echoloc frame) " first }
      /^== call/ { flush(); open = 1; found = 0; inside = 0; first = ""; n = 0; next }
      { n++; if (n == 1) { first = $1; if ($1 ~ /^core::panicking::/) inside = 1 } }
      !found && ($2 ~ /^src\// || $2 ~ /^boards\//) { print $2; found = 1 }
      END { flush() }' | sort | uniq -c)
  n=$(awk '{ n += $1 } END { print n + 0 }' <<<"$checks")
  if [ "${2:-}" = "--plant" ]; then
    if [ "$n" -ge 1 ] && grep -q 'src/predict/mod.rs' <<<"$checks"; then
      echo "planted overflow: found, as it must be ($(grep 'src/predict/mod.rs' <<<"$checks" | xargs))"
      exit 0
    fi
    echo "$checks"
    echo "FAIL: the planted overflow was not counted: the check cannot fail"
    exit 1
  fi
  if [ "$n" -ne 0 ]; then
    echo "$checks"
    echo "FAIL: $n overflow checks in echoloc the optimiser could not remove (above: count, innermost echoloc line)"
    exit 1
  fi
  echo "0 overflow checks in echoloc the optimiser could not remove: every step in the core paths is proven, or says it wraps, saturates or is checked"
  ;;
--plant)
  # A panic the optimiser cannot remove, in the core, behind a cfg only this run sets.
  set +e
  # Its own target folder, so the normal build's artefacts are not rebuilt.
  out=$(CARGO_TARGET_DIR=target/panic-plant RUSTFLAGS="--cfg echoloc_plant_panic" build 2>&1)
  rc=$?
  set -e
  if [ "$rc" -eq 0 ]; then
    echo "FAIL: a planted panic path linked: the check cannot fail"
    exit 1
  fi
  grep -q "undefined symbol: echoloc_core_panic_path_remains" <<<"$out" || {
    echo "$out"
    echo "FAIL: the build failed for another reason"
    exit 1
  }
  echo "planted panic path: the link fails, as it must (undefined symbol: echoloc_core_panic_path_remains)"
  ;;
"")
  build
  echo "panic-never: the core paths link without any panic path"
  ;;
*)
  echo "usage: $0 [--plant|--locate|--overflow]" >&2
  exit 2
  ;;
esac
