#!/usr/bin/env bash
# Training-step speed against JAX in one run: the bench crate's `bench` binary with
# `--peer`, which first times scripts/peer_step_jax.py (the plain per-sample
# step written in JAX, CPU) with the same sizes and then reports every Burn
# row's step time as a multiple of the JAX step time (see `bench --help`).
#
#   scripts/bench-peer.sh [bench flags, e.g. --quick, --steps 2, --samples 16]
#
# Makes (once) a Python venv next to the Cargo target directory,
# $(dirname ${CARGO_TARGET_DIR:-$HOME/.cache/opennerf-target})/opennerf-jax,
# and installs jax (the CPU wheels, about 100 MB) into it from PyPI. Needs
# python3 with the venv module. Then runs
#   cargo run --release -p bench --bin bench -- --peer VENV/bin/python "$@"
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
target="${CARGO_TARGET_DIR:-$HOME/.cache/opennerf-target}"
export CARGO_TARGET_DIR="$target"
venv="$(dirname "$target")/opennerf-jax"

if ! "$venv/bin/python" -c "import jax" 2>/dev/null; then
    echo "bench-peer: installing jax into $venv (from PyPI)" >&2
    mkdir -p "$(dirname "$venv")"
    [ -x "$venv/bin/python" ] || python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --upgrade pip >&2
    "$venv/bin/python" -m pip install jax >&2
fi

cd "$here/.."
exec cargo run --release -p bench --bin bench -- --peer "$venv/bin/python" "$@"
