#!/bin/bash
# Prints the SUMO_HOME of the eclipse-sumo wheel (current SUMO, with sumo-gui, the C++ headers
# and libsumo/libtraci), installing it into ~/.cache/mpgdrive when missing (about 150 MB).
# Debian's SUMO 1.15 stays what `make test` and `make demo` use.
set -euo pipefail
version=${SUMO_WHEEL_VERSION:-1.28.0}
dir=${XDG_CACHE_HOME:-$HOME/.cache}/mpgdrive/eclipse-sumo-$version
if [ ! -x "$dir/sumo/bin/sumo-gui" ]; then
    echo "sumo_wheel: installing eclipse-sumo $version into $dir" >&2
    python3 -m pip install --quiet --no-deps --target "$dir" "eclipse-sumo==$version" >&2
fi
echo "$dir/sumo"
