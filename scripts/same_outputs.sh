#!/bin/bash
# Shows that two mpgdrive binaries behave identically: runs the same commands with each
# (eval Tables II/III with the episode CSV, cosim --json on i80_merge, ngsim synth + eval,
# check-mpg, train on the smoke configuration, report) and compares every output file,
# ignoring only wall-clock timings, timestamps, and the binary's and output folder's names.
# Usage: scripts/same_outputs.sh OLD_BINARY NEW_BINARY [WORK_DIR]   (from the repository root)
set -euo pipefail
old=$(realpath "$1"); new=$(realpath "$2"); work=${3:-/tmp/mpgdrive-same-outputs}
rm -rf "$work" && mkdir -p "$work"
run() { # BINARY OUT
  local b=$1 o=$2; mkdir -p "$o"
  "$b" eval --policy policies/mpg --episodes "$o/eval_mpg_episodes.csv" > "$o/eval_mpg.md"
  "$b" eval --policy policies/sarl --ne-policy policies/mpg --json > "$o/eval_sarl.json"
  "$b" cosim --sumocfg sumo_nets/i80_merge/i80.sumocfg --end 200 --seed 7 --json --out "$o/cosim" --no-diagrams > "$o/cosim.json" 2>/dev/null
  "$b" ngsim synth --episodes 100 --out "$o/synth.txt" 2>/dev/null
  "$b" ngsim eval --input "$o/synth.txt" --out "$o/ngsim" > "$o/ngsim.md" 2>/dev/null
  "$b" check-mpg --json --policies 2 --states 4 > "$o/check_mpg.json"
  "$b" train --config configs/smoke.toml --mode mpg --seeds 0,1 --out "$o/train_mpg" > /dev/null
  "$b" train --config configs/smoke.toml --mode sarl --seeds 0 --out "$o/train_sarl" > /dev/null
  "$b" report --cosim "$o/cosim" --ngsim "$o/ngsim" --out "$o/report" > /dev/null
}
run "$old" "$work/a"; run "$new" "$work/b"
norm() {
  sed -E "s#$work/[ab]#OUT#g; s#($old|$new)#BIN#g; s/[0-9.]+ s\)/T s)/; s/\"(sumo|controller)_us_per_step\": [0-9.e+-]+/US/; \
s/generated on [0-9: -]+/GEN/; s/\"wall_seconds\": [0-9.e+-]+/WALL/; s/,[0-9.]+,([-0-9.e+]+)$/,WALL,\1/; s/, [0-9]+ s$/, T s/" "$1"
}
bad=0
while IFS= read -r f; do
  cmp -s <(norm "$work/a/$f") <(norm "$work/b/$f") || { echo "differs: $f"; bad=1; }
done < <(cd "$work/a" && find . -type f | sort)
[ "$(cd "$work/a" && find . -type f | sort)" = "$(cd "$work/b" && find . -type f | sort)" ] || { echo "different file lists"; bad=1; }
[ $bad = 0 ] && echo "same outputs: $(cd "$work/a" && find . -type f | wc -l) files ($work)"
exit $bad
