#!/usr/bin/env bash
# Where the CPU training step's time goes: `perf record` (software cpu-clock
# sampling, so it works in VMs without hardware counters) over the timed
# steps of one `bench` case alone (bench's --perf-control brackets them),
# then the samples grouped into matrix products, element-wise math and ops,
# reductions, copies, memory management, threading and the rest by
# scripts/profile_categories.py, with the cores kept busy.
#
#   bash scripts/profile-step.sh OUT_DIR [bench flags, default: --backends flex --cases composited --steps 4]
#
# Needs Debian's linux-perf. Writes OUT_DIR/perf.data, OUT_DIR/symbols.txt
# (every symbol's share), OUT_DIR/bench.txt and OUT_DIR/profile.json, and
# prints the table.
set -euo pipefail
out="${1:?usage: profile-step.sh OUT_DIR [bench flags]}"
shift
flags=("$@")
[ ${#flags[@]} -gt 0 ] || flags=(--backends flex --cases composited --steps 4)
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/opennerf-target}"
command -v perf >/dev/null || { echo "profile-step.sh: perf not found (apt-get install linux-perf)" >&2; exit 3; }
cd "$here/.."
cargo build --release -p bench --bin bench
mkdir -p "$out"
fifo="$out/perf.ctl"
rm -f "$fifo"
mkfifo "$fifo"
freq=999
perf record -e cpu-clock -F "$freq" -D -1 --control "fifo:$fifo" -o "$out/perf.data" -- \
  "$CARGO_TARGET_DIR/release/bench" --perf-control "$fifo" "${flags[@]}" | tee "$out/bench.txt"
rm -f "$fifo"
perf report -i "$out/perf.data" --no-children --sort dso,sym --stdio -F overhead,sample,dso,sym \
  --percent-limit 0 2>/dev/null > "$out/symbols.txt"
python3 scripts/profile_categories.py "$out/symbols.txt" "$out/bench.txt" "$freq" > "$out/profile.json"
python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["table"])' "$out/profile.json"
