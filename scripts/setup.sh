#!/usr/bin/env bash
# Installs what a fresh machine lacks for echoloc: the thumb targets, rustup
# components, and qemu-system-arm. Idempotent and quiet when all is present.
set -euo pipefail

need_targets=(thumbv7em-none-eabihf thumbv6m-none-eabi)
have_targets=$(rustup target list --installed)
for t in "${need_targets[@]}"; do
  grep -qx "$t" <<<"$have_targets" || rustup target add "$t"
done
have_components=$(rustup component list --installed)
for c in llvm-tools rustfmt clippy; do
  grep -q "^$c" <<<"$have_components" || rustup component add "$c"
done
# flip-link: the STM32 board's linker (the stack below .data/.bss, so an
# overflow faults instead of corrupting them; scripts/thumb-link.sh, issue #30).
command -v flip-link >/dev/null 2>&1 || cargo install --locked -q flip-link
source "$(dirname "$0")/apt-get-wait.sh"
# `ip` (iproute2) and `unshare` (util-linux) put the `link --ros2` tests in a network
# namespace of their own, with only the loopback up.
if ! command -v ip >/dev/null 2>&1; then
  apt_get update -qq
  apt_get install -y -qq iproute2 >/dev/null
fi
if ! command -v qemu-system-arm >/dev/null 2>&1; then
  apt_get update -qq
  apt_get install -y -qq qemu-system-arm >/dev/null
fi
# The independent writer and reader of ROS 2 bags and MCAP recordings the lab's
# tests run (scripts/fixture-bag.py, scripts/mcap-check.py, scripts/live-viewer.py):
# PyPI's rosbags, mcap with its protobuf decoder, websockets, and Cyclone DDS (the
# independent ROS 2 node of the `link --ros2` tests; its wheel bundles the C library),
# installed when absent.
if ! python3 -c "import rosbags, mcap, mcap_protobuf, websockets, cyclonedds" >/dev/null 2>&1; then
  python3 -m pip install -q --disable-pip-version-check rosbags mcap mcap-protobuf-support websockets cyclonedds==11.0.1
fi
