#!/usr/bin/env bash
# Whole-program measurements that a criterion bench cannot make: peak memory against log length,
# the speed-up of `track --jobs 2` over `--jobs 1` on 8 logs, and `track` (default outputs: tracks
# and the Foxglove SceneUpdate) and `track --no-scene` against the plain copy (`--no-track`) of the
# dense log of benches/pipeline.rs run alternately (on a machine whose speed drifts, alternating
# keeps the drift out of the ratio), with each output's size against the input's. Prints the
# figures that go into BENCHMARKS.md. Usage: scripts/bench.sh [WORKDIR]   (default: a temporary
# directory); `scripts/bench.sh copy [WORKDIR]` runs only the comparison with the copy.
# BENCH_DENSE="FRAMES OBJECTS" changes the dense log (default "600 200"; the size of the
# log of issue #39 is "20000 200"), BENCH_DENSE_REPS the rounds (default 15). BENCH_ISSUE39=1
# runs exactly the measurement of issue #39's acceptance: its log (`simulate --scenario city
# --frames 20000 --objects 200`, default rate and seed), zstd outputs only, 5 rounds unless
# BENCH_DENSE_REPS says otherwise: `BENCH_ISSUE39=1 scripts/bench.sh copy`.
#
# `scripts/bench.sh long [WORKDIR]` measures instead every command that reads a whole log
# (track, eval, eval --protocol kitti, info, fit, plot, export kitti) on long dense logs, side by
# side in one run: wall time and peak RSS (/usr/bin/time), medians of BENCH_REPS runs (default
# 3; a list gives one count per log,
# e.g. "3 1") per log of BENCH_FRAMES frames (default "2000 20000"; the issue's log is
# `simulate --scenario city --frames 20000 --objects 200`, its 10x log 200000 frames: about
# 2.9 GB, 3.8 GB tracked, twice that on disk during its runs), plus the boxes eval holds and its
# bytes per box. Logs are generated in WORKDIR and deleted after their runs (BENCH_KEEP=1 keeps
# them). The issue's run: BENCH_FRAMES="20000 200000" BENCH_REPS="3 1" scripts/bench.sh long.
#
# `scripts/bench.sh bags [WORKDIR]` measures a split rosbag2 bag against the same drive in one
# file (issue #35): an hour-long ROS 2 drive (`simulate --scenario city --rate 10`, converted to
# vision_msgs by scripts/make_ros2_fixture.py) written by rosbags (scripts/split_bag.py) as a bag
# of one file and as a bag split in 60 files, each tracked BENCH_BAG_REPS times (default 5)
# alternately: median wall time and peak RSS of each, and their ratios; and the peak RSS of a
# tenth of the drive split in a tenth of the files (flat memory: the same).
# BENCH_BAG="FRAMES OBJECTS FILES" changes the drive (default "36000 40 60").
#
# `scripts/bench.sh sqlite [WORKDIR]` measures the same hour-long drive as a one-file bag with
# sqlite3 storage (`.db3`, read through SQLite) against the one-file MCAP bag, both written by
# rosbags, each tracked BENCH_BAG_REPS times alternately: median wall time, peak RSS, ratios.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=all
if [ "${1:-}" = long ]; then mode=long; shift; fi
if [ "${1:-}" = copy ]; then mode=copy; shift; fi
if [ "${1:-}" = bags ]; then mode=bags; shift; fi
if [ "${1:-}" = sqlite ]; then mode=sqlite; shift; fi
work="${1:-$(mktemp -d)}"
mkdir -p "$work"
cargo build --release --quiet
bin=target/release/probmot

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
div() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f\n", a / b }'; }
wall() { local s e; s=$(date +%s.%N); "$@" >/dev/null 2>&1; e=$(date +%s.%N); awk -v a="$e" -v b="$s" 'BEGIN { printf "%.3f\n", a - b }'; }
peak_kb() { /usr/bin/time -v "$@" 2>&1 >/dev/null | awk -F: '/Maximum resident set size/ {gsub(/ /,"",$2); print $2}'; }

echo "machine: $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo), $(uname -m), $(rustc --version)"

# --- long logs: every whole-log command next to track, wall time and peak RSS
timed() { # timed NAME CMD...: appends "wall_s peak_kB" of one run to $work/NAME.tm
  local name=$1; shift
  /usr/bin/time -f "%e %M" -o "$work/time.tmp" "$@" >/dev/null 2>&1
  cat "$work/time.tmp" >> "$work/$name.tm"
}
med() { awk -v c="$2" '{print $c}' "$work/$1.tm" | median; }
boxes_of() { # truth + track boxes of a tracked log (what eval holds)
  "$bin" info "$1" --json --quiet | python3 -c '
import json, sys
info = json.load(sys.stdin)
print(sum(sum(c["per_label"].values()) for c in info["channels"]
          if c["topic"] in ("/ground_truth", "/tracks")))'
}
long_logs() {
  local all_reps=(${BENCH_REPS:-3}) k=0
  for n in ${BENCH_FRAMES:-2000 20000}; do
    # BENCH_REPS is one count per log (the last one for every further log).
    local reps=${all_reps[$(( k < ${#all_reps[@]} ? k : ${#all_reps[@]} - 1 ))]}; k=$((k + 1))
    local log="$work/city$n.mcap" out="$work/city$n.tracked.mcap"
    "$bin" simulate --scenario city --frames "$n" --objects 200 -o "$log" >/dev/null
    "$bin" track "$log" -o "$out" --quiet
    local boxes; boxes=$(boxes_of "$out")
    for c in track eval kitti info fit plot export; do : > "$work/$n-$c.tm"; done
    for _ in $(seq "$reps"); do
      timed "$n-track" "$bin" track "$log" -o "$work/city$n.again.mcap" --quiet
      timed "$n-eval" "$bin" eval --truth "$out" --quiet
      timed "$n-kitti" "$bin" eval --protocol kitti --truth "$out" --quiet
      timed "$n-info" "$bin" info "$out" --quiet
      timed "$n-fit" "$bin" fit "$log" -o "$work/fit$n.json" --quiet
      timed "$n-plot" "$bin" plot "$out" --class car --from 0 --to 30 -o "$work/plot$n.png"
      timed "$n-export" "$bin" export kitti "$out" -o "$work/export$n.txt" --quiet
    done
    echo "log of $n frames x 200 objects ($(du -h "$log" | cut -f1), tracked $(du -h "$out" | cut -f1), eval holds $boxes boxes), medians of $reps:"
    for c in track eval kitti info fit plot export; do
      echo "  $c: $(med "$n-$c" 1) s, peak RSS $(med "$n-$c" 2) kB ($(div "$(med "$n-$c" 1)" "$(med "$n-track" 1)")x track's time)"
    done
    echo "  eval: $(div "$(( $(med "$n-eval" 2) * 1024 ))" "$boxes") bytes of peak RSS per box"
    echo "  kitti (eval --protocol kitti): $(div "$(( $(med "$n-kitti" 2) * 1024 ))" "$boxes") bytes of peak RSS per box"
    echo "$n $boxes $(med "$n-eval" 2)" >> "$work/eval-rss.txt"
    [ "${BENCH_KEEP:-0}" = 1 ] || rm -f "$log" "$out" "$work/city$n.again.mcap" "$work/export$n.txt"
  done
  # The growth between the logs: peak RSS added per box added (what a longer log costs).
  if [ "$(wc -l < "$work/eval-rss.txt")" -ge 2 ]; then
    awk 'NR==1 {n0=$1; b0=$2; r0=$3} END {printf "eval: %.1f bytes of peak RSS per added box (%s -> %s frames)\n", ($3-r0)*1024/($2-b0), n0, $1}' "$work/eval-rss.txt"
  fi
}
if [ "$mode" = long ]; then
  : > "$work/eval-rss.txt"
  long_logs
  exit 0
fi

# --- a split bag against the same drive in one file: wall time and peak RSS, alternating
split_bags() {
  local frames objects parts reps=${BENCH_BAG_REPS:-5}
  read -r frames objects parts <<< "${BENCH_BAG:-36000 40 60}"
  "$bin" simulate --scenario city --frames "$frames" --objects "$objects" --rate 10 -o "$work/drive.mcap" --quiet
  python3 scripts/make_ros2_fixture.py "$work/drive.mcap" -o "$work/drive_ros2.mcap" >/dev/null
  rm -rf "$work/one" "$work/split"
  python3 scripts/split_bag.py "$work/drive_ros2.mcap" "$work/one" --parts 1 >/dev/null
  python3 scripts/split_bag.py "$work/drive_ros2.mcap" "$work/split" --parts "$parts" >/dev/null
  # A tenth of the drive in a tenth of the files (files of the same length): flat memory is
  # the same peak RSS for the whole drive.
  "$bin" simulate --scenario city --frames "$((frames / 10))" --objects "$objects" --rate 10 -o "$work/tenth.mcap" --quiet
  python3 scripts/make_ros2_fixture.py "$work/tenth.mcap" -o "$work/tenth_ros2.mcap" >/dev/null
  rm -rf "$work/tenth"
  python3 scripts/split_bag.py "$work/tenth_ros2.mcap" "$work/tenth" --parts "$((parts / 10 > 0 ? parts / 10 : 1))" >/dev/null
  : > "$work/one.tm"; : > "$work/split.tm"; : > "$work/tenth.tm"
  for _ in $(seq "$reps"); do
    for b in one split tenth; do
      rm -rf "$work/$b.out"
      timed "$b" "$bin" track "$work/$b" -o "$work/$b.out" --quiet
    done
  done
  echo "drive of $frames frames at 10 Hz x $objects objects, ROS 2 vision_msgs ($(du -sh "$work/one" | cut -f1)), medians of $reps alternating runs:"
  echo "  one file:  $(med one 1) s, peak RSS $(med one 2) kB"
  echo "  $parts files: $(med split 1) s, peak RSS $(med split 2) kB"
  echo "  split / one: time $(div "$(med split 1)" "$(med one 1)")x, peak RSS $(div "$(med split 2)" "$(med one 2)")x"
  echo "  a tenth of the drive in $((parts / 10 > 0 ? parts / 10 : 1)) files: peak RSS $(med tenth 2) kB (whole drive / tenth: $(div "$(med split 2)" "$(med tenth 2)")x)"
  [ "${BENCH_KEEP:-0}" = 1 ] || rm -rf "$work"/{drive,drive_ros2,tenth,tenth_ros2}.mcap "$work"/{one,split,tenth}{,.out}
}
if [ "$mode" = bags ]; then
  split_bags
  exit 0
fi

# --- a sqlite3 bag against the same drive as an MCAP bag: wall time and peak RSS, alternating
sqlite_bag() {
  local frames objects reps=${BENCH_BAG_REPS:-5}
  read -r frames objects _ <<< "${BENCH_BAG:-36000 40 60}"
  "$bin" simulate --scenario city --frames "$frames" --objects "$objects" --rate 10 -o "$work/drive.mcap" --quiet
  python3 scripts/make_ros2_fixture.py "$work/drive.mcap" -o "$work/drive_ros2.mcap" >/dev/null
  rm -rf "$work/mcap_bag" "$work/db3_bag"
  python3 scripts/split_bag.py "$work/drive_ros2.mcap" "$work/mcap_bag" --parts 1 >/dev/null
  python3 scripts/split_bag.py "$work/drive_ros2.mcap" "$work/db3_bag" --parts 1 --storage sqlite3 >/dev/null
  : > "$work/mcap_bag.tm"; : > "$work/db3_bag.tm"
  for _ in $(seq "$reps"); do
    for b in mcap_bag db3_bag; do
      rm -rf "$work/$b.out"
      timed "$b" "$bin" track "$work/$b" -o "$work/$b.out" --quiet
    done
  done
  echo "drive of $frames frames at 10 Hz x $objects objects, ROS 2 vision_msgs, one file (MCAP $(du -sh "$work/mcap_bag" | cut -f1), sqlite3 $(du -sh "$work/db3_bag" | cut -f1)), medians of $reps alternating runs:"
  echo "  MCAP bag:    $(med mcap_bag 1) s, peak RSS $(med mcap_bag 2) kB"
  echo "  sqlite3 bag: $(med db3_bag 1) s, peak RSS $(med db3_bag 2) kB"
  echo "  sqlite3 / MCAP: time $(div "$(med db3_bag 1)" "$(med mcap_bag 1)")x, peak RSS $(div "$(med db3_bag 2)" "$(med mcap_bag 2)")x"
  [ "${BENCH_KEEP:-0}" = 1 ] || rm -rf "$work"/{drive,drive_ros2}.mcap "$work"/{mcap_bag,db3_bag}{,.out}
}
if [ "$mode" = sqlite ]; then
  sqlite_bag
  exit 0
fi

# --- peak memory: a log 10x as long must not need more than 1.2x the memory
if [ "$mode" = all ]; then
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
fi

# --- track vs the plain copy, alternating, 15 runs each (the dense log of benches/pipeline.rs).
# Each run prints its wall time and its CPU time (user + system, all threads); the runs with
# `--compression none` separate compressing the output from everything else. Three outputs:
# the copy (`--no-track`), `--no-scene` (the tracks channel only) and the default outputs.
read -r dense_frames dense_objects <<< "${BENCH_DENSE:-600 200}"
sim_args=(--rate 2 --seed 3)
compressions=(zstd none)
if [ "${BENCH_ISSUE39:-0}" = 1 ]; then
  dense_frames=20000 dense_objects=200 sim_args=() compressions=(zstd)
  : "${BENCH_DENSE_REPS:=5}"
fi
"$bin" simulate --scenario city --frames "$dense_frames" --objects "$dense_objects" "${sim_args[@]}" -o "$work/dense.mcap" >/dev/null
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
outputs=(copy noscene track)
declare -A flags=([copy]=--no-track [noscene]=--no-scene [track]=)
for c in "${compressions[@]}"; do for o in "${outputs[@]}"; do : > "$work/$o-$c.s"; done; done
for i in $(seq "${BENCH_DENSE_REPS:-15}"); do
  for c in "${compressions[@]}"; do
    for o in "${outputs[@]}"; do
      # shellcheck disable=SC2086 # an empty flag is no argument
      run "$o-$c" "$bin" track "$work/dense.mcap" -o "$work/dense.$o.$c.mcap" ${flags[$o]} --quiet --compression "$c"
    done
  done
done
size() { stat -c %s "$1"; }
echo "dense log ($dense_frames frames x $dense_objects objects, $(size "$work/dense.mcap") bytes), medians of ${BENCH_DENSE_REPS:-15} alternating runs (wall s / cpu s):"
for c in "${compressions[@]}"; do
  echo "  --compression $c: copy (--no-track) $(col 1 "copy-$c") / $(col 2 "copy-$c"), --no-scene $(col 1 "noscene-$c") / $(col 2 "noscene-$c"), track $(col 1 "track-$c") / $(col 2 "track-$c")"
done
for o in track noscene; do
  name=$([ "$o" = track ] && echo "track (default outputs)" || echo "track --no-scene")
  echo "$name:"
  echo "  ratio to copy (wall): $(div "$(col 1 "$o-zstd")" "$(col 1 copy-zstd)")x"
  echo "  ratio to copy (cpu):  $(div "$(col 2 "$o-zstd")" "$(col 2 copy-zstd)")x"
  echo "  output / input size:  $(div "$(size "$work/dense.$o.zstd.mcap")" "$(size "$work/dense.mcap")")x ($(size "$work/dense.$o.zstd.mcap") bytes)"
done

# --- issue #39: the compression floor. zstd alone, at the output's level and chunk size, on the
# uncompressed records of the copy and of the default output: the default's ratio to the copy
# cannot go below this one while both write these bytes at this level (the zstd command line
# tool, not installed by the project; the same library as the crate, version may differ).
if [ "${BENCH_ISSUE39:-0}" = 1 ]; then
  if command -v zstd >/dev/null; then
    for o in copy track; do
      # shellcheck disable=SC2086 # an empty flag is no argument
      "$bin" track "$work/dense.mcap" -o "$work/dense.$o.none.mcap" ${flags[$o]} --quiet --compression none
    done
    zstd_mbs() { # zstd_mbs FILE: compression speed (MB/s) of level 2 in 1 MiB blocks, best of 5
      zstd -2 -B1M -i5 -b "$1" 2>&1 | tr '\r' '\n' | grep 'MB/s' | tail -1 | sed -E 's/.*\), *([0-9.]+) MB\/s.*/\1/'
    }
    c_mbs=$(zstd_mbs "$work/dense.copy.none.mcap"); d_mbs=$(zstd_mbs "$work/dense.track.none.mcap")
    c_s=$(div "$(size "$work/dense.copy.none.mcap")" "${c_mbs}e6"); d_s=$(div "$(size "$work/dense.track.none.mcap")" "${d_mbs}e6")
    echo "compression floor (zstd -2 -B1M -b on the uncompressed outputs, $(zstd --version | grep -o 'v[0-9.]*')):"
    echo "  copy $(size "$work/dense.copy.none.mcap") bytes in ${c_s} s, default $(size "$work/dense.track.none.mcap") bytes in ${d_s} s: $(div "$d_s" "$c_s")x"
    rm -f "$work"/dense.*.none.mcap
  else
    echo "compression floor: SKIPPED (no zstd command line tool)"
  fi
fi
