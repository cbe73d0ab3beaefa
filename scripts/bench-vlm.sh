#!/usr/bin/env bash
# Dense CLIP feature extraction speed: the Burn backends against PyTorch in
# one run (the `bench-vlm` binary of the bench crate; see its --help).
#
#   scripts/bench-vlm.sh [bench-vlm flags, e.g. --frames 2 --backend flex]
#
# Makes (once) a Python venv next to the Cargo target directory,
# $(dirname ${CARGO_TARGET_DIR:-$HOME/.cache/opennerf-target})/opennerf-torch,
# and installs torch and transformers into it from PyPI. That download is a
# few GB (torch's default Linux wheels bring the CUDA libraries along); set
# TORCH_INDEX_URL=https://download.pytorch.org/whl/cpu for the CPU-only wheel
# (about 200 MB). Needs python3 with the venv module. Then runs
#   cargo run --release -p bench --bin bench-vlm -- --python VENV/bin/python "$@"
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
target="${CARGO_TARGET_DIR:-$HOME/.cache/opennerf-target}"
export CARGO_TARGET_DIR="$target"
venv="$(dirname "$target")/opennerf-torch"

if ! "$venv/bin/python" -c "import torch, transformers" 2>/dev/null; then
    echo "bench-vlm: installing torch + transformers into $venv (a few GB from PyPI)" >&2
    mkdir -p "$(dirname "$venv")"
    [ -x "$venv/bin/python" ] || python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --upgrade pip >&2
    if [ -n "${TORCH_INDEX_URL:-}" ]; then
        "$venv/bin/python" -m pip install --index-url "$TORCH_INDEX_URL" torch >&2
    fi
    "$venv/bin/python" -m pip install torch transformers >&2
fi

cd "$here/.."
exec cargo run --release -p bench --bin bench-vlm -- --python "$venv/bin/python" "$@"
