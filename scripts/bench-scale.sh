#!/usr/bin/env bash
# Stage-by-stage wall time and peak resident memory as the synthetic scene
# grows towards the paper's Replica setting (200 frames at 640x360, 768-D
# feature maps). Per size: train (scene build with feature maps and PCA,
# ray sampler, iterations, novel views), eval segment and eval
# uncertainty, each appending its stages to the run's stages.json; then
# a report (scale.csv, scale.md, scale.png) over the sizes.
#
#   scripts/bench-scale.sh [--sizes bench,paper] [--iters 500] [--novel-views 8]
#                          [--out runs/scale] [--eval-views 10] [--render-scale 0.25]
#                          [--force]
#
# Sizes: ci (20 x 96x54, 512-D maps at 24x13), bench (200 x 320x180, 512-D
# at 80x45), paper (200 x 640x360, 768-D at 160x90), paper-full (200 x
# 640x360, 768-D at 640x360: about 46 M map pixels; it needs well over 10 GB
# of memory and disk for the scene and its novel views, so it only runs
# when asked for).
set -euo pipefail

usage() {
    sed -n '2,17p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
    cat <<'EOF'

Options:
  --sizes LIST         comma-separated sizes of ci, bench, paper, paper-full [bench,paper]
  --iters N            training iterations per size (novel views at N/2) [500]
  --novel-views N      novel views added at N/2 iterations, guided (0: none) [8]
  --out DIR            output directory, one run directory per size [runs/scale]
  --eval-views N       cameras eval segment renders at (evenly spaced) [10]
  --render-scale F     fraction of the camera resolution eval segment renders at [0.25]
  --force              replace run directories left in DIR by an earlier call
  -h, --help           this help
EOF
}

die() {
    echo "bench-scale: $*" >&2
    exit 2
}

is_count() { [[ "$1" =~ ^[0-9]+$ ]]; }

sizes="bench,paper"
iters=500
novel=8
out="runs/scale"
eval_views=10
render_scale=0.25
force=0
while [ $# -gt 0 ]; do
    case "$1" in
    -h | --help)
        usage
        exit 0
        ;;
    --sizes | --iters | --novel-views | --out | --eval-views | --render-scale)
        [ $# -ge 2 ] || die "$1 needs a value"
        case "$1" in
        --sizes) sizes="$2" ;;
        --iters) iters="$2" ;;
        --novel-views) novel="$2" ;;
        --out) out="$2" ;;
        --eval-views) eval_views="$2" ;;
        --render-scale) render_scale="$2" ;;
        esac
        shift 2
        ;;
    --force)
        force=1
        shift
        ;;
    *) die "unknown option $1 (see --help)" ;;
    esac
done

is_count "$iters" && [ "$iters" -ge 2 ] || die "--iters must be an integer >= 2, got '$iters'"
is_count "$novel" || die "--novel-views must be an integer >= 0, got '$novel'"
is_count "$eval_views" && [ "$eval_views" -ge 1 ] || die "--eval-views must be an integer >= 1, got '$eval_views'"
[[ "$render_scale" =~ ^(0?\.[0-9]*[1-9][0-9]*|1(\.0*)?)$ ]] ||
    die "--render-scale must be a number in (0, 1], got '$render_scale'"
[ -n "$out" ] || die "--out must not be empty"
IFS=',' read -r -a size_list <<<"$sizes"
[ "${#size_list[@]}" -gt 0 ] || die "--sizes is empty"
seen=","
for s in "${size_list[@]}"; do
    case "$s" in
    ci | bench | paper | paper-full) ;;
    *) die "unknown size '$s' (expected ci, bench, paper or paper-full)" ;;
    esac
    case "$seen" in *",$s,"*) die "size '$s' given twice" ;; esac
    seen="$seen$s,"
done

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$here/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/opennerf-target}"
bin="$CARGO_TARGET_DIR/release"

for s in "${size_list[@]}"; do
    if [ -e "$out/$s" ]; then
        [ "$force" = 1 ] || die "$out/$s exists (choose another --out, or --force to replace it)"
        rm -rf -- "${out:?}/$s"
    fi
done

echo "bench-scale: building (cargo build --release --workspace)" >&2
cargo build --release --workspace -q
mkdir -p "$out/logs"

for s in "${size_list[@]}"; do
    run="$out/$s"
    novel_flags=(--novel-views "$novel")
    [ "$novel" -gt 0 ] && novel_flags+=(--novel-after "$((iters / 2))")
    echo "bench-scale: $s: train ($iters iterations, $novel novel views)" >&2
    "$bin/train" --scene-size "$s" --iters "$iters" "${novel_flags[@]}" \
        --no-final-render --quiet --out "$run" 2>&1 | tee "$out/logs/$s-train.log"
    echo "bench-scale: $s: eval segment ($eval_views views at $render_scale of the resolution)" >&2
    "$bin/eval" segment --run "$run" --max-views "$eval_views" --render-scale "$render_scale" \
        2>&1 | tee "$out/logs/$s-segment.log" | tail -n 3
    echo "bench-scale: $s: eval uncertainty (no camera proposals)" >&2
    "$bin/eval" uncertainty --run "$run" --views 0 \
        2>&1 | tee "$out/logs/$s-uncertainty.log" | tail -n 3
done

sizes_arg="$(IFS=','; echo "${size_list[*]}")"
"$bin/scale_report" --dir "$out" --sizes "$sizes_arg"
