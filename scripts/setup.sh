#!/usr/bin/env bash
# Installs what mpgdrive needs to build and run, then prints the environment the build needs
# as `export` lines on stdout (the Makefile evaluates them). Idempotent; quiet when everything
# is already present. Messages go to stderr.
#
#   eval "$(scripts/setup.sh)"
#
# - Debian packages sumo, sumo-tools, libclang-dev, and xvfb and xauth for the sumo-gui test
#   (apt-get, as root; otherwise the exact command is printed and the script fails).
# - libtorch 2.13.0: $LIBTORCH when it points at one; otherwise a CPU libtorch taken from the
#   PyPI torch wheel, installed once into a per-user cache shared by all clones
#   (${XDG_CACHE_HOME:-$HOME/.cache}/mpgdrive/libtorch-2.13.0), never into the repository.
set -euo pipefail

TORCH_VERSION=2.13.0
PIP_PACKAGES=("torch==${TORCH_VERSION}" "nvidia-cuda-runtime==13.0.96" "nvidia-cuda-cupti==13.0.85")
CACHE_DIR="${XDG_CACHE_HOME:-$HOME/.cache}/mpgdrive/libtorch-${TORCH_VERSION}"

LOG=$(mktemp "${TMPDIR:-/tmp}/mpgdrive-setup.XXXXXX.log")
say() { echo "setup: $*" >&2; }
die() { say "$*"; [ -s "$LOG" ] && { say "last lines of the log:"; tail -n 20 "$LOG" >&2; }; rm -f "$LOG"; exit 1; }
# Installers write to $LOG; it is shown only when something fails.
quietly() { "$@" >>"$LOG" 2>&1; }

# --- Rust ------------------------------------------------------------------------------------
# Edition 2024 needs Rust 1.85 or newer (Cargo.toml's rust-version); Debian 12's rustc is 1.63.
RUST_MIN=1.85
rustc_version=$(rustc --version 2>/dev/null | awk '{print $2}' || true)
if [ -z "$rustc_version" ] || [ "$(printf '%s\n%s\n' "$RUST_MIN" "$rustc_version" | sort -V | head -1)" != "$RUST_MIN" ]; then
  die "Rust ${RUST_MIN} or newer is needed (found: ${rustc_version:-none}). Install it with rustup: \
curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs | sh -s -- -y && . \"\$HOME/.cargo/env\""
fi

# --- system packages -------------------------------------------------------------------------
missing=()
command -v sumo >/dev/null 2>&1 && [ -f /usr/include/libsumo/Simulation.h ] || missing+=(sumo)
[ -d /usr/share/sumo/tools ] || missing+=(sumo-tools)
dpkg-query -W -f='${Status}' libclang-dev 2>/dev/null | grep -q "ok installed" || missing+=(libclang-dev)
# The tests run `cosim --gui` on a virtual display.
command -v xvfb-run >/dev/null 2>&1 || missing+=(xvfb)
# The tests train under QEMU's Intel and AMD processor models (the same weights on both).
command -v qemu-x86_64 >/dev/null 2>&1 || missing+=(qemu-user)
command -v xauth >/dev/null 2>&1 || missing+=(xauth)
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" -ne 0 ]; then
    die "missing system packages: ${missing[*]}. Run: sudo apt-get update && sudo apt-get install -y ${missing[*]}"
  fi
  say "installing ${missing[*]} with apt-get"
  export DEBIAN_FRONTEND=noninteractive
  quietly apt-get update || die "apt-get update failed"
  quietly apt-get install -y --no-install-recommends "${missing[@]}" \
    || die "apt-get install ${missing[*]} failed"
fi

# --- libtorch ----------------------------------------------------------------------------------
# A libtorch directory is accepted when it holds lib/libtorch_cpu.so and names version 2.13.0
# (build-version in the libtorch archive layout, version.py in the PyPI wheel layout).
is_libtorch() {
  local dir=$1
  [ -f "$dir/lib/libtorch_cpu.so" ] || return 1
  if [ -f "$dir/build-version" ]; then
    grep -q "^${TORCH_VERSION}" "$dir/build-version"
  elif [ -f "$dir/version.py" ]; then
    grep -q "__version__ = '${TORCH_VERSION}" "$dir/version.py"
  else
    return 1
  fi
}

if [ -n "${LIBTORCH:-}" ] && is_libtorch "$LIBTORCH"; then
  libtorch=$LIBTORCH
else
  if [ -n "${LIBTORCH:-}" ]; then
    say "ignoring LIBTORCH=$LIBTORCH: not a libtorch ${TORCH_VERSION}; using the per-user cache"
  fi
  libtorch="$CACHE_DIR/torch"
  if ! is_libtorch "$libtorch"; then
    command -v python3 >/dev/null 2>&1 || die "python3 is needed to install libtorch with pip"
    say "installing libtorch ${TORCH_VERSION} (PyPI wheel, about 1.2 GB) into $CACHE_DIR"
    mkdir -p "$(dirname "$CACHE_DIR")"
    tmp=$(mktemp -d "$CACHE_DIR.tmp.XXXXXX")
    trap 'rm -rf "$tmp" "$LOG"' EXIT
    quietly python3 -m pip install -q --disable-pip-version-check --root-user-action=ignore \
      --no-deps --target "$tmp" "${PIP_PACKAGES[@]}" || die "pip install of ${PIP_PACKAGES[*]} failed"
    is_libtorch "$tmp/torch" || die "the torch wheel did not contain a usable libtorch"
    rm -rf "$CACHE_DIR"
    mv "$tmp" "$CACHE_DIR"   # atomic on one file system: a half install is never seen
  fi
fi
rm -f "$LOG"

# --- the environment the build needs -----------------------------------------------------------
echo "export LIBTORCH='$libtorch'"
echo "export LIBTORCH_CXX11_ABI=1"
echo "export SUMO_HOME='${SUMO_HOME:-/usr/share/sumo}'"
