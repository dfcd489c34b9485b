#!/usr/bin/env bash
# Regenerates the .net.xml files of sumo_nets/ from their plain XML sources (make nets).
# i80_merge and single_lane_merge are straight along +x with zero-radius junctions and no
# internal links, so a vehicle's network x is its distance along the road (as in the internal
# simulator; tests/cosim.rs compares the two); curved_ramp_merge keeps netconvert's defaults
# (junction shapes and internal lanes), as a user's network would. mpgdrive measures positions
# along the lanes in all three. --offset.disable-normalization keeps the sources' coordinates.
set -euo pipefail
cd "$(dirname "$0")"
export SUMO_HOME="${SUMO_HOME:-/usr/share/sumo}"
build() { # dir prefix
    (cd "$1" && netconvert --node-files "$2.nod.xml" --edge-files "$2.edg.xml" \
        --connection-files "$2.con.xml" --output-file "$2.net.xml" \
        --no-turnarounds true --offset.disable-normalization true \
        --default.junctions.radius 0 --no-internal-links true --output.street-names false \
        --no-warnings true)
}
build single_lane_merge merge
build i80_merge i80
(cd curved_ramp_merge && netconvert --node-files curved.nod.xml --edge-files curved.edg.xml \
    --connection-files curved.con.xml --output-file curved.net.xml --no-turnarounds true \
    --offset.disable-normalization true --output.street-names false --no-warnings true)
