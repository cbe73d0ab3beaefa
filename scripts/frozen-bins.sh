# Sourced by the measurement scripts: `freeze_bins DIR` builds `train` and
# `eval` and copies them into DIR/bin once, then sets `bin` to that
# directory. A measurement resumed after the code changed still runs the
# same programs, and a build of another checkout into the shared target
# directory cannot swap them mid-way.
freeze_bins() {
  export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/opennerf-target}"
  bin="$1/bin"
  if [ ! -x "$bin/train" ] || [ ! -x "$bin/eval" ]; then
    cargo build --release -q -p train -p eval
    mkdir -p "$bin"
    cp "$CARGO_TARGET_DIR/release/train" "$CARGO_TARGET_DIR/release/eval" "$bin/"
  fi
}
