#!/usr/bin/env bash
# The merge zoo (issue 62): thirteen merge networks built here with `mpgdrive net build` from
# parameters (nothing committed), spanning freeway speed (20 / 30 / 36 m/s), the merge form
# (junction merge, with and without a traffic light, 60 m / 150 m / 250 m acceleration lane,
# lane drop), straight and curved ramps, 1 and 3 freeway lanes; then the SUMO grid of scripts/traffic_acceptance.sh on every one
# of them (demand 0.8 / 1.0 / 1.2, SUMO seeds 0-2, ego only and the game, against SUMO's
# drivers) with 600 s runs. Writes OUT/nets/<name>/ (the networks), OUT/<name>/ (the runs) and
# OUT/acceptance.md (one table per network, written by scripts/traffic_acceptance.py, with
# issue 62's bounds: ego speed at least 0.9 of SUMO's drivers', SSM conflicts at most theirs plus
# 5 points).
#
#   scripts/zoo_acceptance.sh OUT
#
# Environment: the same as scripts/traffic_acceptance.sh (END defaults to 600 here; SEEDS,
# SCALES, SPEED_MODE, ...), and NETS: a space-separated subset of the names below.
set -euo pipefail
out=${1:?usage: scripts/zoo_acceptance.sh OUT}
bin=${MPGDRIVE:-target/release/mpgdrive}
# name: net build arguments (demand per freeway lane and on the ramp, veh/h, before scaling)
declare -A zoo=(
    [acc60-v20]="--form acceleration --accel-lane 60 --speed 20 --lane-flow 900"
    [acc60-v30]="--form acceleration --accel-lane 60 --speed 30 --lane-flow 900"
    [acc60-v36]="--form acceleration --accel-lane 60 --speed 36 --lane-flow 900"
    [acc250-v20]="--form acceleration --accel-lane 250 --speed 20 --lane-flow 900"
    [acc250-v30-curved]="--form acceleration --accel-lane 250 --speed 30 --lane-flow 900 --curved"
    [acc250-v36]="--form acceleration --accel-lane 250 --speed 36 --lane-flow 900"
    [acc150-v30-l3]="--form acceleration --accel-lane 150 --speed 30 --lanes 3 --lane-flow 700"
    [junction-v20]="--form junction --speed 20 --lane-flow 600"
    [junction-v20-signal]="--form junction --speed 20 --lane-flow 600 --signal"
    [junction-v30-curved]="--form junction --speed 30 --lane-flow 600 --curved"
    [junction-v36]="--form junction --speed 36 --lane-flow 600"
    [junction-v30-l3]="--form junction --speed 30 --lanes 3 --lane-flow 300"
    [lanedrop-v25-l2]="--form lane-drop --speed 25 --lanes 2 --lane-flow 700"
)
names=${NETS:-${!zoo[*]}}
dirs=()
for name in $names; do
    [ -n "${zoo[$name]:-}" ] || { echo "zoo_acceptance: no network named $name" >&2; exit 2; }
    dir="$out/nets/$name"
    # shellcheck disable=SC2086 # the arguments are words
    "$bin" net build ${zoo[$name]} --ramp-flow 400 --duration "${END:-600}" --out "$dir" 2>/dev/null
    dirs+=("$dir")
done
END=${END:-600} SPEED_RATIO=${SPEED_RATIO:-0.9} SSM_POINTS=${SSM_POINTS:-5} \
    "$(dirname "$0")/traffic_acceptance.sh" "$out" "${dirs[@]}"
