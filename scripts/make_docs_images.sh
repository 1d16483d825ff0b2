#!/usr/bin/env bash
# Regenerates the `probmot plot` pictures of the docs from the shipped samples:
#   docs/turning-car-bev.png    the turning-car sample, tracked (README, docs/viewing.md)
#   docs/pedestrian-switch.png  the pedestrian crossing with the evaluation's events (README,
#                               docs/viewing.md)
# The docs' examples write their pictures elsewhere; this script is the only writer of these.
# tests/it/plot_layout.rs runs it into a temporary directory and compares with the committed files,
# so a change to what `plot` draws shows up as stale pictures until this is run again.
#
# Usage (from anywhere):  scripts/make_docs_images.sh [OUT_DIR]     (default: docs/)
# Environment: PROBMOT=path/to/probmot (default: target/debug/probmot, built with `cargo build`).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/docs}
mkdir -p "$out"
out=$(cd "$out" && pwd)
if [[ -z "${PROBMOT:-}" ]]; then
    (cd "$root" && cargo build --quiet)
    PROBMOT=$root/target/debug/probmot
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

# The turning car: every frame, cars, the three layers.
"$PROBMOT" track "$root/sample_logs/turning-car.mcap" -o turning-car.tracked.mcap --quiet
"$PROBMOT" plot turning-car.tracked.mcap -o "$out/turning-car-bev.png" --class car \
    --layers detections,tracks,ground_truth --quiet

# The pedestrian crossing: the two seconds around the switches `eval --events` lists at 11.5 and
# 12 s, tracks beside the ground truth, the view framing the window's switches and fragmentations.
"$PROBMOT" track "$root/sample_logs/pedestrians.mcap" -o pedestrians.tracked.mcap --quiet
"$PROBMOT" eval --truth pedestrians.tracked.mcap --events pedestrians.events.mcap --quiet \
    > /dev/null
"$PROBMOT" plot pedestrians.tracked.mcap -o "$out/pedestrian-switch.png" --class pedestrian \
    --from 10.5 --to 12.5 --layers tracks,ground_truth --events pedestrians.events.mcap \
    --width 1300 --height 620 --quiet

echo "wrote $out/turning-car-bev.png and $out/pedestrian-switch.png"
