#!/usr/bin/env bash
# The penetration study (`mpgdrive study`) on one network of the merge zoo, built here with
# `mpgdrive net build` (scripts/zoo_nets.sh): writes OUT/net/ (the network), OUT/zoo.txt (its
# name and build arguments) and OUT/study/ (the study; `scripts/results.py study-zoo OUT` puts
# it into docs/results/study-zoo.md, `scripts/results.py study-junction OUT` a junction merge's
# into docs/results/study-junction.md).
#
#   scripts/zoo_study.sh NAME OUT [mpgdrive study arguments...]
#
# END (default 600) is the duration of the network's demand and of every run.
set -euo pipefail
name=${1:?usage: scripts/zoo_study.sh NAME OUT [study arguments]}
out=${2:?usage: scripts/zoo_study.sh NAME OUT [study arguments]}
shift 2
bin=${MPGDRIVE:-target/release/mpgdrive}
# shellcheck source=scripts/zoo_nets.sh
. "$(dirname "$0")/zoo_nets.sh"
end=${END:-600}
zoo_build "$name" "$out/net" "$end" || exit 2
echo "$name: ${zoo[$name]} --ramp-flow 400 --duration $end" > "$out/zoo.txt"
"$bin" study --sumocfg "$out/net/merge.sumocfg" --end "$end" --out "$out/study" "$@"
