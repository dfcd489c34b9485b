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
# SCALES, SPEED_MODE, ...), and NETS: a space-separated subset of the names in scripts/zoo_nets.sh.
set -euo pipefail
out=${1:?usage: scripts/zoo_acceptance.sh OUT}
bin=${MPGDRIVE:-target/release/mpgdrive}
# shellcheck source=scripts/zoo_nets.sh
. "$(dirname "$0")/zoo_nets.sh"
names=${NETS:-${!zoo[*]}}
dirs=()
for name in $names; do
    dir="$out/nets/$name"
    zoo_build "$name" "$dir" "${END:-600}" || exit 2
    dirs+=("$dir")
done
END=${END:-600} SPEED_RATIO=${SPEED_RATIO:-0.9} SSM_POINTS=${SSM_POINTS:-5} \
    "$(dirname "$0")/traffic_acceptance.sh" "$out" "${dirs[@]}"
