# Sourced by the scripts that run the lab tool: builds it and sets $LAB.
# The profile is ECHOLOC_LAB_PROFILE's (release by default, for the tables in
# docs/); CI's short cases set dev, the build the host tests have made, so CI
# does not compile the lab and its dependencies a second time (about 6 minutes
# on two cores; the short cases run about 15 % slower, the same answers).
#   lab_build [cargo args]   builds echoloc-lab (and e.g. --example NAME)
lab_profile=${ECHOLOC_LAB_PROFILE:-release}
case "$lab_profile" in
  dev) lab_dir=${CARGO_TARGET_DIR:-target}/debug ;;
  *) lab_dir=${CARGO_TARGET_DIR:-target}/$lab_profile ;;
esac
LAB=$lab_dir/echoloc-lab
lab_build() { cargo build -q --profile "$lab_profile" -p echoloc-lab "$@"; }
