#!/usr/bin/env bash
# Whole-program measurements that a criterion bench cannot make: peak memory against log length,
# the speed-up of `track --jobs 2` over `--jobs 1` on 8 logs, and `track` against the plain copy
# (`--no-track`) of the dense log of benches/pipeline.rs run alternately (on a machine whose speed
# drifts, alternating keeps the drift out of the ratio). Prints the figures that go into
# BENCHMARKS.md. Usage: scripts/bench.sh [WORKDIR]   (default: a temporary directory)
set -euo pipefail
cd "$(dirname "$0")/.."
work="${1:-$(mktemp -d)}"
mkdir -p "$work"
cargo build --release --quiet
bin=target/release/probmot

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
div() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f\n", a / b }'; }
wall() { local s e; s=$(date +%s.%N); "$@" >/dev/null 2>&1; e=$(date +%s.%N); awk -v a="$e" -v b="$s" 'BEGIN { printf "%.3f\n", a - b }'; }
peak_kb() { /usr/bin/time -v "$@" 2>&1 >/dev/null | awk -F: '/Maximum resident set size/ {gsub(/ /,"",$2); print $2}'; }

echo "machine: $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo), $(uname -m), $(rustc --version)"

# --- peak memory: a log 10x as long must not need more than 1.2x the memory
"$bin" simulate --scenario city --frames 1000 --objects 100 --rate 10 --seed 5 -o "$work/short.mcap" >/dev/null
"$bin" simulate --scenario city --frames 10000 --objects 100 --rate 10 --seed 5 -o "$work/long.mcap" >/dev/null
for f in short long; do
  runs=()
  for i in 1 2 3; do runs+=("$(peak_kb "$bin" track "$work/$f.mcap" -o "$work/$f.out.mcap" --quiet --dt-nominal 0.1)"); done
  printf '%s\n' "${runs[@]}" | median > "$work/$f.rss"
  echo "peak RSS $f ($(du -h "$work/$f.mcap" | cut -f1)): $(cat "$work/$f.rss") kB (median of 3)"
done
echo "peak RSS ratio long/short: $(div "$(cat "$work/long.rss")" "$(cat "$work/short.rss")")"

# --- many logs: 8 logs, --jobs 1 vs --jobs 2
mkdir -p "$work/many" "$work/out1" "$work/out2"
for i in 1 2 3 4 5 6 7 8; do
  "$bin" simulate --scenario city --frames 1500 --objects 120 --seed "$i" -o "$work/many/log$i.mcap" >/dev/null
done
# Alternating --jobs 1 and --jobs 2, 5 rounds.
: > "$work/jobs1.all"; : > "$work/jobs2.all"
for i in 1 2 3 4 5; do
  for j in 1 2; do
    wall "$bin" track "$work"/many/*.mcap --out-dir "$work/out$j" --jobs "$j" --quiet >> "$work/jobs$j.all"
  done
done
for j in 1 2; do
  median < "$work/jobs$j.all" > "$work/jobs$j.s"
  echo "8 logs with --jobs $j: $(cat "$work/jobs$j.s") s (median of 5, alternating)"
done
echo "speed-up --jobs 2 over --jobs 1: $(div "$(cat "$work/jobs1.s")" "$(cat "$work/jobs2.s")")x"

# --- track vs the plain copy, alternating, 15 runs each (the dense log of benches/pipeline.rs).
# Each run prints its wall time and its CPU time (user + system, all threads); the runs with
# `--compression none` separate compressing the output from everything else.
"$bin" simulate --scenario city --frames 600 --objects 200 --rate 2 --seed 3 -o "$work/dense.mcap" >/dev/null
run() { # run NAME ARGS...: appends "wall cpu" (seconds) of one run to $work/NAME.s
  local name=$1; shift
  python3 - "$@" >> "$work/$name.s" <<'PY'
import resource, subprocess, sys, time
r0 = resource.getrusage(resource.RUSAGE_CHILDREN)  # not zero: Python's start-up can spawn
t = time.perf_counter()
subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
wall = time.perf_counter() - t
ru = resource.getrusage(resource.RUSAGE_CHILDREN)
cpu = ru.ru_utime + ru.ru_stime - r0.ru_utime - r0.ru_stime
print(f"{wall:.4f} {cpu:.4f}")
PY
}
col() { awk -v c="$1" '{print $c}' "$work/$2.s" | median; }
for c in zstd none; do : > "$work/copy-$c.s"; : > "$work/track-$c.s"; done
for i in $(seq 15); do
  for c in zstd none; do
    run "copy-$c" "$bin" track "$work/dense.mcap" -o "$work/dense.copy.mcap" --no-track --quiet --compression "$c"
    run "track-$c" "$bin" track "$work/dense.mcap" -o "$work/dense.track.mcap" --quiet --compression "$c"
  done
done
echo "dense log ($(du -h "$work/dense.mcap" | cut -f1)), medians of 15 alternating runs (wall s / cpu s):"
for c in zstd none; do
  echo "  --compression $c: copy (--no-track) $(col 1 "copy-$c") / $(col 2 "copy-$c"), track $(col 1 "track-$c") / $(col 2 "track-$c")"
done
echo "ratio track / copy (wall): $(div "$(col 1 track-zstd)" "$(col 1 copy-zstd)")x"
echo "ratio track / copy (cpu):  $(div "$(col 2 track-zstd)" "$(col 2 copy-zstd)")x"
