# Sourced by scripts/setup.sh (and scripts/apt-lock-check.sh, its test).
# apt-get, waiting for the package manager's locks when another apt holds
# them (unattended upgrades often do on a fresh VM) instead of failing at
# once: up to APT_LOCK_WAIT_S seconds in all (default 900), then a clear error.
apt_get() {
  local sudo_="" out deadline=$((SECONDS + ${APT_LOCK_WAIT_S:-900})) said="" inner=$((${APT_LOCK_WAIT_S:-900} < 30 ? ${APT_LOCK_WAIT_S:-900} : 30))
  [ "$(id -u)" -eq 0 ] || sudo_="sudo"
  while :; do
    # DPkg::Lock::Timeout makes install wait for dpkg's lock; update's
    # lists lock is not covered by it, hence the loop.
    if out=$($sudo_ env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout="$inner" "$@" 2>&1); then
      return 0
    fi
    if ! grep -qE 'Could not get lock|Unable to lock' <<<"$out"; then
      echo "$out" >&2
      return 1
    fi
    if [ "$SECONDS" -ge "$deadline" ]; then
      echo "$out" >&2
      echo "setup: apt's lock is still held after ${APT_LOCK_WAIT_S:-900} s (another package manager, e.g. unattended-upgrades, is running): let it finish, or set APT_LOCK_WAIT_S longer" >&2
      return 1
    fi
    [ -n "$said" ] || echo "setup: another package manager holds apt's lock; waiting for it (at most ${APT_LOCK_WAIT_S:-900} s)..." >&2
    said=1
    sleep 5
  done
}
