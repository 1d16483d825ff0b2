#!/usr/bin/env bash
# Logs per second on one machine: `probmot track --out-dir --jobs 1/2` next to
# `scripts/ray_track.py --num-cpus 1/2` (a local Ray instance on loopback) on the same 8 generated
# logs as scripts/bench.sh. The four configurations run in turn in each of 3 rounds (side by
# side, so that the machine's other load hits them alike); medians of the 3 rounds are printed.
# For Ray: the whole run (starting the local instance included) and the tracking phase alone
# (first task submitted to last log done, from the report's `tracking_s`).
# Needs the Python packages of scripts/requirements.txt (ray, pyarrow).
# Usage: scripts/bench_ray.sh [WORKDIR]   (default: a temporary directory; keep its path short:
# Ray's unix sockets live under it)
set -euo pipefail
cd "$(dirname "$0")/.."
work="${1:-$(mktemp -d)}"
mkdir -p "$work"
cargo build --release --quiet --bin probmot
bin=target/release/probmot

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
rate() { awk -v n="$1" -v t="$2" 'BEGIN { printf "%.2f\n", n / t }'; }
wall() { local s e; s=$(date +%s.%N); "$@" >/dev/null 2>&1; e=$(date +%s.%N); awk -v a="$e" -v b="$s" 'BEGIN { printf "%.3f\n", a - b }'; }
json_field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])" "$1" "$2"; }

echo "machine: $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo), $(uname -m), $(rustc --version), $(python3 -c 'import ray; print("ray", ray.__version__)')"

mkdir -p "$work/many"
for i in 1 2 3 4 5 6 7 8; do
  "$bin" simulate --scenario city --frames 1500 --objects 120 --seed "$i" -o "$work/many/log$i.mcap" >/dev/null
done
n=8

for round in 1 2 3; do
  for j in 1 2; do
    rm -rf "$work/cli$j" && mkdir -p "$work/cli$j"
    wall "$bin" track "$work"/many/*.mcap --out-dir "$work/cli$j" --jobs "$j" --quiet >> "$work/cli$j.s"
  done
  for c in 1 2; do
    rm -rf "$work/ray$c"
    wall python3 scripts/ray_track.py "$work"/many/*.mcap --out "$work/ray$c" --num-cpus "$c" \
      --probmot "$bin" --temp-dir "$work/r" --report "$work/ray$c.json" >> "$work/ray$c.s"
    json_field "$work/ray$c.json" tracking_s >> "$work/ray$c.tracking"
    json_field "$work/ray$c.json" ray_start_s >> "$work/ray$c.start"
    test "$(json_field "$work/ray$c.json" tracked)" = "$n"
  done
done

for j in 1 2; do
  t=$(median < "$work/cli$j.s")
  echo "probmot track --jobs $j: $t s, $(rate $n "$t") logs/s (median of 3)"
done
for c in 1 2; do
  t=$(median < "$work/ray$c.s")
  tr=$(median < "$work/ray$c.tracking")
  st=$(median < "$work/ray$c.start")
  echo "ray_track.py --num-cpus $c: $t s in all, $(rate $n "$t") logs/s; tracking phase $tr s, $(rate $n "$tr") logs/s; starting Ray $st s (medians of 3)"
done
for f in "$work"/many/*.mcap; do
  cmp -s "$work/cli1/$(basename "$f")" "$work/ray2/$(basename "$f")" || { echo "differs: $f"; exit 1; }
done
echo "outputs of ray_track.py and track --jobs 1 are byte-identical"
