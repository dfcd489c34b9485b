#!/bin/bash
# A screenshot of sumo-gui while mpgdrive drives the ramp egos (red; other players the MPG
# policy drives are orange), on a virtual display:
#   1. sumo-gui (from the eclipse-sumo wheel: Debian's sumo-gui 1.15 exits as soon as it loads
#      routes under Xvfb) starts on the network with --remote-port and a view-settings file that
#      names vehicles and takes a snapshot at SNAPSHOT_TIME;
#   2. `mpgdrive cosim --attach PORT` joins it as its TraCI client and drives the run;
#   3. sumo-gui writes the snapshot and quits at the end.
# Usage (from the repository root, after `make build`): scripts/gui_screenshot.sh [OUT.png]
# Environment: SUMOCFG (default the I-80 merge), CONTROLLER (mpg), SNAPSHOT_TIME (80 s),
# VIEW_X, VIEW_Y, ZOOM (the view's centre in network metres and sumo-gui's zoom).
# The wheel is installed by scripts/sumo_wheel.sh when missing.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
out=$(realpath -m "${1:-$repo/docs/images/sumo_gui_i80.png}")
sumocfg=${SUMOCFG:-sumo_nets/i80_merge/i80.sumocfg}
controller=${CONTROLLER:-mpg}
at=${SNAPSHOT_TIME:-80}
bin=$repo/target/release/mpgdrive
die() { echo "gui_screenshot: $*" >&2; exit 1; }

[ -x "$bin" ] || die "no $bin: run \`make build\` first"
command -v xvfb-run >/dev/null || die "xvfb-run is missing: apt-get install -y xvfb"
gui_home=$("$repo/scripts/sumo_wheel.sh")
gui_version=$("$gui_home/bin/sumo" --version | head -1)

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat > "$work/view.xml" <<EOF
<viewsettings>
    <scheme name="mpgdrive">
        <background backgroundColor="white" showGrid="0"/>
        <vehicles vehicleMode="0" vehicleQuality="2" vehicleExaggeration="1.0"
                  vehicleName_show="1" vehicleName_size="55.00" vehicleName_color="cyan" vehicleName_constantSize="1"/>
    </scheme>
    <viewport zoom="${ZOOM:-650}" x="${VIEW_X:-175}" y="${VIEW_Y:--13}"/>
    <delay value="0"/>
    <snapshot file="$work/shot.png" time="$at"/>
</viewsettings>
EOF
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cd "$repo"
SUMO_HOME=$gui_home xvfb-run -a -s "-screen 0 1600x700x24" "$gui_home/bin/sumo-gui" -c "$sumocfg" \
    --remote-port "$port" --num-clients 1 --start --quit-on-end -g "$work/view.xml" \
    --window-size 1600,700 --no-step-log true > "$work/gui.log" 2>&1 &
gui=$!
# mpgdrive retries the connection until sumo-gui listens.
env -u SUMO_HOME "$bin" cosim --sumocfg "$sumocfg" --attach "$port" --controllers "$controller" \
    --end "$((at + 5))" --out "$work/cosim" --no-diagrams > /dev/null
wait "$gui" || die "sumo-gui failed: $(tail -3 "$work/gui.log")"
[ -s "$work/shot.png" ] || die "sumo-gui wrote no snapshot"
mkdir -p "$(dirname "$out")"
mv "$work/shot.png" "$out"
echo "gui_screenshot: $out ($controller controller at t = $at s, $gui_version, $($bin --version))"
