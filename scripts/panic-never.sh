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
#                                        # counts the checks left, per source line, and
#                                        # fails if one is where hostile bytes arrive
set -euo pipefail
cd "$(dirname "$0")/.."
target=thumbv7em-none-eabihf
build() { cargo build -q -p panic-never --target "$target" --release "$@"; }

# Every branch to a core panic entry point in $1, with its inlined call chain.
locate() {
  local elf=$1
  host=$(rustc -vV | sed -n 's/^host: //p')
  objdump="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-objdump"
  dis=$("$objdump" -d --no-show-raw-insn "$elf")
  # Every branch to a core panic entry point, with its inlined call chain.
  targets=$(grep -E '^[0-9a-f]+ <.*(panicking|slice_index_fail|_fail|unwrap_failed|expect_failed).*>:' <<<"$dis" |
    awk '{print $1}' | sed 's/^0*//')
  for t in $targets; do
    grep -E "\s0x$t\b" <<<"$dis" | awk '{print $1}' | tr -d ':' | while read -r a; do
      echo "== call at 0x$a"
      addr2line -e "$elf" -i -f -C "0x$a" | paste - - | head -8
    done
  done
}

case "${1:-}" in
--locate)
  build --features locate
  locate "${CARGO_TARGET_DIR:-target}/$target/release/panic-never"
  ;;
--overflow)
  # What is left to prove about integer overflow, which a release build
  # wraps instead of panicking on.
  export CARGO_TARGET_DIR=target/panic-overflow
  RUSTFLAGS="-Cllvm-args=-enable-tail-merge=false" build --features locate \
    --config 'profile.release.package.echoloc.overflow-checks=true'
  # Each check at the innermost echoloc line of its call chain.
  checks=$(locate "$CARGO_TARGET_DIR/$target/release/panic-never" | sed "s|$PWD/||" |
    awk -F'\t' '/^== call/ { found = 0; next } !found && $2 ~ /^src\// { print $2; found = 1 }' | sort | uniq -c)
  echo "$checks"
  awk '{ n += $1 } END { printf "%d overflow checks in echoloc the optimiser could not remove\n", n }' <<<"$checks"
  # Where hostile bytes arrive (the compiled-map validator, the scenario
  # reader and bench, the host link) none may be left: that part is a check.
  if grep -E 'src/(map/compiled\.rs|map/field\.rs|map/crc32\.rs|scenario/|link/)' <<<"$checks"; then
    echo "FAIL: overflow checks remain where hostile bytes arrive (above)"
    exit 1
  fi
  echo "none where hostile bytes arrive (the compiled-map validator and its localization field, the scenario reader and bench, the host link)"
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
