#!/usr/bin/env bash
# The paper's ablation on real KITTI data: 2-fold cross-validation over the ten KITTI tracking
# train sequences in ../shared/data/kitti-tracking-train (PointRCNN detections). Noise is fitted
# on one fold and the other fold is tracked and evaluated, then the folds swap; the metrics are
# computed over all ten tracked sequences together.
#
# Usage: scripts/kitti_benchmark.sh [WORKDIR]
set -euo pipefail
cd "$(dirname "$0")/.."
data="${KITTI_DATA:-../shared/data/kitti-tracking-train}"
[ -d "$data" ] || { echo "no KITTI data at $data" >&2; exit 2; }
work="${1:-$(mktemp -d)}"
mkdir -p "$work/logs"
cargo build --release --quiet
bin=target/release/probmot
fold_a=(0000 0002 0003 0004 0005)
fold_b=(0007 0009 0011 0017 0020)

for s in "${fold_a[@]}" "${fold_b[@]}"; do
  [ -f "$work/logs/$s.mcap" ] || "$bin" import kitti --labels "$data/label_02/$s.txt" \
    --detections "$data/pointrcnn" -o "$work/logs/$s.mcap" >/dev/null
done

fit() { # fit FOLD_NAME SEQ... -> $work/noise_FOLD.json (fitted on those sequences)
  local name=$1; shift
  local files=(); for s in "$@"; do files+=("$work/logs/$s.mcap"); done
  "$bin" fit "${files[@]}" -o "$work/noise_$name.json" --dt-nominal 0.1 --fold-yaw \
    --base-preset "${BASE_PRESET:-nuscenes-chiu2019}" >/dev/null
}
fit a "${fold_a[@]}"
fit b "${fold_b[@]}"

declare -A rows=(
  [1_paper_fitted]="--config {noise}"
  [2_default_covariance]="--config {noise} --covariance default"
  [3_iou3d]="--config {noise} --distance iou3d"
  [4_hungarian]="--config {noise} --matcher hungarian"
  [5_no_angular_velocity]="--config {noise} --no-angular-velocity"
  # AB3DMOT exactly as its code runs on KITTI (docs/ab3dmot.md); its settings were chosen by
  # its authors on the other eleven train sequences, so this row is held out too.
  [6_ab3dmot_kitti_preset]="--preset ab3dmot-kitti"
  # Tuned on all ten sequences, so this row is in-sample (not cross-validated).
  [7_kitti_pointrcnn_preset]="--preset kitti-pointrcnn"
)
printf '%-24s %8s %8s %8s %8s %6s %6s | %8s %8s %6s\n' row sAMOTA MOTA MOTP AMOTA IDS FRAG nuAMOTA nuMOTA nuIDS
for row in $(printf '%s\n' "${!rows[@]}" | sort); do
  out="$work/$row"; mkdir -p "$out"
  for fold in a b; do
    # Tracked with the noise fitted on the *other* fold.
    if [ $fold = a ]; then seqs=("${fold_a[@]}"); noise="$work/noise_b.json"; else seqs=("${fold_b[@]}"); noise="$work/noise_a.json"; fi
    args=${rows[$row]//\{noise\}/$noise}
    for s in "${seqs[@]}"; do
      # shellcheck disable=SC2086
      "$bin" track "$work/logs/$s.mcap" -o "$out/$s.mcap" --quiet $args 2>/dev/null
    done
  done
  k=$("$bin" eval --protocol kitti --iou 0.25 --truth "$out" --json)
  n=$("$bin" eval --classes car,pedestrian,cyclist --truth "$out" --json)
  python3 - "$row" "$k" "$n" <<'PY'
import json, sys
row, k, n = sys.argv[1], json.loads(sys.argv[2])["result"]["overall"], json.loads(sys.argv[3])["result"]["overall"]
f = lambda v: "-" if v is None else f"{v:.4f}"
print(f"{row:<24} {f(k['sAMOTA']):>8} {f(k['MOTA']):>8} {f(k['MOTP']):>8} {f(k['AMOTA']):>8} {k['IDS']:>6.0f} {k['FRAG']:>6.0f} | {f(n['amota']):>8} {f(n['mota']):>8} {n['ids']:>6.0f}")
PY
done
