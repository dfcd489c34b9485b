#!/bin/bash
# Builds mpgdrive against the eclipse-sumo wheel's libsumo/libtraci (scripts/sumo_wheel.sh) in
# its own target folder and runs every test that talks to SUMO: the FFI, cosim (library and
# command line, --gui and --attach included), batch, net inspect and a network built at test time.
# Usage (from the repository root): scripts/test_sumo_wheel.sh
set -euo pipefail
cd "$(dirname "$0")/.."
eval "$(scripts/setup.sh)"
SUMO_HOME=$(scripts/sumo_wheel.sh)
export SUMO_HOME PATH=$SUMO_HOME/bin:$PATH CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-target/sumo-wheel}
echo "test_sumo_wheel: $("$SUMO_HOME/bin/sumo" --version | head -1)"
cargo test --test sumo_ffi --test cosim --test cosim_cli --test batch_cli --test net_inspect --test user_network
