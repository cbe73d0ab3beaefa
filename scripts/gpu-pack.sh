#!/usr/bin/env bash
# The release binaries `train` and `bench`, stripped and xz-compressed into
# gpu-pack/ (about 45 MB), for scripts/gpu-measure.sh on a lent GPU machine:
# that machine reaches no package registry, so it cannot build, and a
# device call carries at most 64 MiB of ignored files (docs/guide/gpu.md).
#
#     bash scripts/gpu-pack.sh
#
# gpu-pack/COMMIT names the commit the binaries were built from.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p train --bin train -p bench --bin bench
target=${CARGO_TARGET_DIR:-target}
rm -rf gpu-pack
mkdir gpu-pack
for b in train bench; do
  strip -o "gpu-pack/$b" "$target/release/$b"
  xz -T0 -6 "gpu-pack/$b"
done
commit=$(git rev-parse HEAD)
if [ -n "$(git status --porcelain --untracked-files=no)" ]; then
  commit="$commit (with uncommitted changes)"
fi
echo "$commit" > gpu-pack/COMMIT
du -sh gpu-pack
