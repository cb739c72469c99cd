# Sourced by the scripts that run the lab tool: builds it and sets $LAB.
# The profile is ECHOLOC_LAB_PROFILE's (release by default, for the tables in
# docs/); CI's short cases set dev, the build the host tests have made, so CI
# does not compile the lab and its dependencies a second time (about 6 minutes
# on two cores; the short cases run about 15 % slower, the same answers).
#   lab_build [cargo args]   builds echoloc-lab (and e.g. --example NAME)
#   ECHOLOC_LAB=PATH         runs that binary instead, unbuilt
lab_profile=${ECHOLOC_LAB_PROFILE:-release}
case "$lab_profile" in
  dev) lab_dir=${CARGO_TARGET_DIR:-target}/debug ;;
  *) lab_dir=${CARGO_TARGET_DIR:-target}/$lab_profile ;;
esac
LAB=$lab_dir/echoloc-lab
lab_build() { cargo build -q --profile "$lab_profile" -p echoloc-lab "$@"; }
# ECHOLOC_LAB=PATH: that build of the lab tool instead (another commit's, for
# a before/after table from one script), not rebuilt; examples still are.
if [ -n "${ECHOLOC_LAB:-}" ]; then
  LAB=$ECHOLOC_LAB
  lab_build() { if [ $# -gt 0 ]; then cargo build -q --profile "$lab_profile" -p echoloc-lab "$@"; fi; }
fi
