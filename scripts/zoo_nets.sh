# The merge zoo's networks, sourced by scripts/zoo_acceptance.sh and scripts/zoo_study.sh.
# shellcheck shell=bash
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

# zoo_build NAME DIR DURATION: builds the zoo network NAME into DIR (DIR/merge.sumocfg), its
# demand running DURATION seconds.
zoo_build() {
    local name=$1 dir=$2 duration=$3
    [ -n "${zoo[$name]:-}" ] || { echo "no zoo network named $name (${!zoo[*]})" >&2; return 2; }
    # shellcheck disable=SC2086 # the arguments are words
    "$bin" net build ${zoo[$name]} --ramp-flow 400 --duration "$duration" --out "$dir" 2>/dev/null
}
