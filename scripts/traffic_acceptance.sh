#!/usr/bin/env bash
# The SUMO acceptance of the traffic policy (issue 15), on the bundled networks or others:
# demand 0.8 / 1.0 / 1.2 (`mpgdrive routes`), SUMO seeds 0-2, 900 s, the policy deploying
# ego-only (`players = "controllable"`) and as the game (`players = "all"`), against SUMO's
# own drivers; and, at demand 1.2, 30% of the freeway vehicles controllable and playing the
# game, the time loss of every vehicle (tripinfo) against SUMO's drivers alone.
#
#   scripts/traffic_acceptance.sh OUT [NET_DIR ...]    (default: both bundled networks)
#
# Environment: GATE=true|false (the merge gate as a shield; default as cosim's: off for
# traffic policies), SPEED_MODE and LANE_CHANGE_MODE (default cosim's 0 and 257: the policy
# alone; SPEED_MODE=25 adds SUMO's safe speed as a shield, 0 and 0 no SUMO check at all), PLAYER_LANE_CHANGE_MODE (default
# cosim's 1621: target-lane players keep SUMO's lane changes), CONFIG (default configs/traffic.toml), POLICY (default its shipped set),
# ENSEMBLE=median|mean (how the policy's seeds combine; default cosim's, the median),
# SEEDS (default "0 1 2"), SCALES (default "0.8,1.0,1.2"), END (default 900), JOBS (default
# the number of cores). Writes OUT/acceptance.md and one cosim folder per run.
set -euo pipefail
out=${1:?usage: scripts/traffic_acceptance.sh OUT [NET_DIR ...]}
shift
nets=("$@")
[ ${#nets[@]} -gt 0 ] || nets=(sumo_nets/i80_merge sumo_nets/single_lane_merge)
config=${CONFIG:-configs/traffic.toml}
seeds=${SEEDS:-0 1 2}
scales=${SCALES:-0.8,1.0,1.2}
end=${END:-900}
jobs=${JOBS:-$(nproc)}
bin=${MPGDRIVE:-target/release/mpgdrive}
mkdir -p "$out"
runs="$out/runs.txt"
: >"$runs"

for net in "${nets[@]}"; do
    name=$(basename "$net")
    cfg=$(ls "$net"/*.sumocfg | head -1)
    base=$(sed -n 's/.*<route-files value="\([^"]*\)".*/\1/p' "$cfg" | head -1)
    base="$net/$(basename "$base")"
    dir="$out/$name"
    mkdir -p "$dir"
    "$bin" routes --base "$base" --merge "$net/merge.toml" --scales "$scales" --seeds 0 \
        --duration "$end" --out "$dir/routes" >/dev/null
    "$bin" routes --base "$base" --merge "$net/merge.toml" --scales 1.2 --seeds 0 \
        --duration "$end" --mainline-controllable-share 0.3 --out "$dir/routes_m30" >/dev/null
    for players in controllable all; do
        sed "s/^players = .*/players = \"$players\"/" "$net/merge.toml" >"$dir/merge_$players.toml"
    done
    for route in "$dir"/routes/*.rou.xml; do
        stem=$(basename "$route" .rou.xml)
        for seed in $seeds; do
            echo "$cfg $route $dir/merge_controllable.toml mpg,sumo $seed $dir/${stem}_seed${seed}_ego" >>"$runs"
            echo "$cfg $route $dir/merge_all.toml mpg $seed $dir/${stem}_seed${seed}_game" >>"$runs"
        done
    done
    for route in "$dir"/routes_m30/*.rou.xml; do
        stem=$(basename "$route" .rou.xml)
        for seed in $seeds; do
            echo "$cfg $route $dir/merge_controllable.toml mpg,sumo $seed $dir/${stem}_seed${seed}_mainline30" >>"$runs"
        done
    done
done

run_one() {
    read -r cfg route merge controllers seed folder <<<"$1"
    "$bin" cosim --config "$config" ${POLICY:+--policy "$POLICY"} ${ENSEMBLE:+--ensemble "$ENSEMBLE"} \
        --sumocfg "$cfg" --route-files "$route" \
        --merge "$merge" --controllers "$controllers" --seed "$seed" --end "$end" \
        ${GATE:+--gate "$GATE"} --speed-mode "${SPEED_MODE:-0}" --lane-change-mode "${LANE_CHANGE_MODE:-257}" \
        --player-lane-change-mode "${PLAYER_LANE_CHANGE_MODE:-1621}" --no-diagrams --json --out "$folder" >"$folder.json" 2>"$folder.log"
}
export -f run_one
export bin config end POLICY ENSEMBLE GATE SPEED_MODE LANE_CHANGE_MODE PLAYER_LANE_CHANGE_MODE
start=$(date +%s)
tr '\n' '\0' <"$runs" | xargs -0 -P "$jobs" -I{} bash -c 'run_one "$@"' _ {}
echo "$(wc -l <"$runs") cosim runs in $(($(date +%s) - start)) s ($jobs at a time)" >&2
python3 "$(dirname "$0")/traffic_acceptance.py" "$out" >"$out/acceptance.md"
cat "$out/acceptance.md"
