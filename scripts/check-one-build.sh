#!/usr/bin/env bash
# Every README form of building builds the dependencies once: after any one
# of them (CI runs this after `cargo test --workspace --release`), each
# other form compiles no dependency again, only (at most) the workspace's
# own crates. A dependency compiled again means two forms resolve different
# features for it: `cargo hakari generate && cargo hakari manage-deps`
# puts the union into workspace-hack.
#
#     bash scripts/check-one-build.sh     # exit 1 and the list on a breach
set -euo pipefail
cd "$(dirname "$0")/.."

members="$(cargo metadata --no-deps --format-version 1 |
  python3 -c 'import json, sys; print("|".join(p["name"] for p in json.load(sys.stdin)["packages"]))')"
forms=(
  "-p train --bin train"
  "-p eval --bin eval"
  "-p batch --bin batch"
  "-p train -p eval"
  "-p bench --bins"
  "--workspace --bins"
  "--workspace --all-targets"
)
status=0
for form in "${forms[@]}"; do
  # shellcheck disable=SC2086
  log="$(cargo build --release $form 2>&1)" || { echo "$log"; exit 1; }
  deps="$(grep -E '^ +Compiling ' <<<"$log" | grep -vE "^ +Compiling ($members) v" || true)"
  own="$(grep -cE "^ +Compiling ($members) v" <<<"$log" || true)"
  ndeps="$(grep -c . <<<"$deps" || true)"
  echo "cargo build --release $form: $ndeps dependencies and $own workspace crates compiled"
  if [ -n "$deps" ]; then
    echo "$deps"
    status=1
  fi
done
exit "$status"
