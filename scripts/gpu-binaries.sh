# Sourced by the GPU scripts (scripts/gpu-measure.sh,
# scripts/gpu-fast-field.sh) from the repository root, with `$out` set:
# sets `$bin`, the directory of the release binaries `train` and `bench`,
# and writes where they came from to `$out/binaries.txt`; sets wgpu's
# environment (minimal autotuning, a runtime directory).
#
export CUBECL_AUTOTUNE_LEVEL="${CUBECL_AUTOTUNE_LEVEL:-minimal}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"

# The binaries: unpacked from gpu-pack/ (scripts/gpu-pack.sh) where it
# exists, as on a lent GPU machine, which reaches no registry to build
# from; built here otherwise.
if [ -f gpu-pack/train.xz ] && [ -f gpu-pack/bench.xz ]; then
  echo "== unpacking gpu-pack/, built from $(cat gpu-pack/COMMIT 2>/dev/null || echo 'an unknown commit')"
  if [ -d .git ] && [ "$(git rev-parse HEAD 2>/dev/null)" != "$(cut -d' ' -f1 gpu-pack/COMMIT 2>/dev/null)" ]; then
    echo "warning: gpu-pack/ was built from another commit than this checkout's" >&2
  fi
  bin=$(mktemp -d)
  for b in train bench; do
    # Python's lzma where xz is not installed.
    if command -v xz >/dev/null 2>&1; then
      xz -dc "gpu-pack/$b.xz" > "$bin/$b"
    else
      python3 -c 'import lzma, shutil, sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
        "gpu-pack/$b.xz" "$bin/$b"
    fi
    chmod +x "$bin/$b"
  done
  cp gpu-pack/COMMIT "$out/binaries.txt" 2>/dev/null || true
else
  echo "== building"
  cargo build --release -p train --bin train -p bench --bin bench
  target=${CARGO_TARGET_DIR:-target}
  bin=$target/release
  git rev-parse HEAD > "$out/binaries.txt" 2>/dev/null || true
fi
