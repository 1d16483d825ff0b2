#!/usr/bin/env python3
"""Track a fleet's logs on a Ray cluster: one `probmot track` per log, as Ray tasks of one CPU.

Usage:
  python3 scripts/ray_track.py INPUT... --out PREFIX [options] [-- TRACK_ARGS...]

INPUT: MCAP files, directories (their *.mcap), glob patterns, or URIs that pyarrow.fs understands
(s3://bucket/logs/*.mcap, gs://..., file:///abs/path.mcap; a glob only in the last component).
Each output is PREFIX/<input file name>, the name `probmot track --out-dir` would give it.
Everything after `--` is passed to `probmot track` unchanged (e.g. `-- --preset ab3dmot-kitti`).

Local paths are used in place, so on a cluster they must name the same file on every node (a
shared mount); URIs are copied to a temporary file on the worker, tracked there, and the output is
copied back. With --eval each log is also scored by `probmot eval` (truth: the /ground_truth
channel carried through to the tracked output, or PREFIX/<name> of --truth-prefix), and the
per-class metrics over all logs come from one many-logs `probmot eval --json` over every output.

Retries: a task is retried once when its worker dies (Ray's max_retries=1) and once when it fails
for a reason that can pass: an I/O error while copying to or from the store, or probmot killed by
a signal (out of memory, preempted node). A non-zero exit status of probmot (bad input, invalid
option) is not retried: it gives the same error on the same bytes, so it is reported at once.

The probmot binary must be on each worker: either installed in the worker image (then --probmot
names its path there, default `probmot` on PATH), or shipped by Ray with --ship-probmot, which
puts the local binary given by --probmot in the job's runtime_env working_dir.

Examples:
  python3 scripts/ray_track.py sample_logs/*.mcap --out tracked/ --num-cpus 2
  python3 scripts/ray_track.py 's3://fleet/2026-11-22/*.mcap' --out s3://fleet/tracked \\
      --address ray://head:10001 --ship-probmot --probmot target/release/probmot \\
      --eval --report report.json -- --preset nuscenes-chiu2019

Exit status: 0 every log tracked (and evaluated), 1 a log or the evaluation failed, 2 bad usage.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import pyarrow.fs as pafs

GLOB_CHARS = "*?["
# Lines of probmot's stderr kept in an error message.
ERROR_TAIL_LINES = 20
COPY_CHUNK = 8 << 20


class TransientError(Exception):
    """A failure that may pass on a second try (I/O with the store, probmot killed by a signal)."""


# --------------------------------------------------------------------------------------------
# Locations: a local path or a URI understood by pyarrow.fs.


def is_uri(location: str) -> bool:
    """Whether `location` is a URI (copied through pyarrow.fs) rather than a local path."""
    return "://" in location


def filesystem(location: str) -> tuple[pafs.FileSystem, str]:
    """The pyarrow file system and the path inside it."""
    if is_uri(location):
        return pafs.FileSystem.from_uri(location)
    return pafs.LocalFileSystem(), os.path.abspath(location)


def join(prefix: str, name: str) -> str:
    """`prefix/name` for a URI, an absolute path for a local prefix."""
    if is_uri(prefix):
        return prefix.rstrip("/") + "/" + name
    return os.path.join(os.path.abspath(prefix), name)


def base_name(location: str) -> str:
    """The file name of a path or URI."""
    return location.rstrip("/").rsplit("/", 1)[-1]




def expand(inputs: list[str]) -> list[str]:
    """Files, directories (their *.mcap, sorted) and glob patterns, as paths or URIs."""
    out: list[str] = []
    for loc in inputs:
        fs, path = filesystem(loc)
        info = fs.get_file_info(path)
        # Listed files are named as `parent/name`, with `parent` spelled as given.
        parent_loc = loc.rstrip("/")
        if info.type == pafs.FileType.Directory:
            found = sorted(
                i.path
                for i in fs.get_file_info(pafs.FileSelector(path))
                if i.type == pafs.FileType.File and i.path.endswith(".mcap")
            )
            if not found:
                raise SystemExit(f"error: {loc}: no .mcap file in this directory")
        elif info.type == pafs.FileType.NotFound and any(c in base_name(loc) for c in GLOB_CHARS):
            parent, pattern = path.rsplit("/", 1)
            parent_loc = loc.rsplit("/", 1)[0]
            if any(c in parent for c in GLOB_CHARS):
                raise SystemExit(f"error: {loc}: only the last component may be a pattern")
            try:
                listing = fs.get_file_info(pafs.FileSelector(parent))
            except (FileNotFoundError, OSError) as e:
                raise SystemExit(f"error: {loc}: cannot list {parent}: {e}") from e
            found = sorted(
                i.path
                for i in listing
                if i.type == pafs.FileType.File and fnmatch.fnmatchcase(base_name(i.path), pattern)
            )
            if not found:
                raise SystemExit(f"error: {loc}: the pattern matches no file")
        else:
            # A missing file is left to probmot, which reports it as that log's failure.
            out.append(loc if is_uri(loc) else path)
            continue
        out.extend(join(parent_loc, base_name(p)) for p in found)
    return out


def copy_file(src: str, dst: str) -> None:
    """Copies one file between locations; local destinations are written atomically."""
    sfs, spath = filesystem(src)
    dfs, dpath = filesystem(dst)
    local_dst = dfs.type_name == "local"
    if local_dst:
        os.makedirs(os.path.dirname(dpath), exist_ok=True)
        target = dpath + ".partial"
    else:
        target = dpath
    with sfs.open_input_stream(spath, compression=None) as r, dfs.open_output_stream(
        target, compression=None
    ) as w:
        while True:
            chunk = r.read(COPY_CHUNK)
            if not chunk:
                break
            w.write(chunk)
    if local_dst:
        os.replace(target, dpath)


def fetch(src: str, dst_path: str) -> None:
    """Copies `src` to the local file `dst_path`; a missing file is final, other errors may pass."""
    try:
        copy_file(src, dst_path)
    except FileNotFoundError:
        raise
    except OSError as e:
        raise TransientError(f"copying {src} to the worker: {e}") from e


def local_copy(location: str, directory: str) -> str:
    """A local path for `location`: itself if local, else a copy in `directory`."""
    if not is_uri(location):
        return location
    dst = os.path.join(directory, base_name(location))
    fetch(location, dst)
    return dst


# --------------------------------------------------------------------------------------------
# Work done on the workers.


def run_probmot(cmd: list[str]) -> tuple[subprocess.CompletedProcess | None, str | None]:
    """Runs probmot; returns the process (None if it could not start) and an error message (None
    on success). A binary that is missing or cannot run is reported, not retried.

    Raises TransientError when probmot was killed by a signal."""
    try:
        p = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        return None, f"cannot run {cmd[0]}: {e}"
    if p.returncode < 0:
        raise TransientError(f"{' '.join(cmd[:2])} was killed by signal {-p.returncode}")
    if p.returncode != 0:
        tail = "\n".join(p.stderr.strip().splitlines()[-ERROR_TAIL_LINES:])
        return p, f"exit status {p.returncode}: {tail}"
    return p, None


def probmot_path(job: dict) -> str:
    """The binary to run: the shipped copy in the working directory, or the given path."""
    if job["shipped"]:
        return os.path.join(os.getcwd(), "probmot")
    return job["probmot"]


def track_one(job: dict) -> dict:
    """Tracks (and optionally evaluates) one log; the body of a Ray task."""
    started = time.time()
    result = {
        "input": job["input"],
        "output": job["output"],
        "ok": False,
        "stage": None,
        "error": None,
        "summary": None,
        "eval": None,
        "warnings": [],
        "node": os.uname().nodename,
    }
    work = tempfile.mkdtemp(prefix="probmot-ray-")
    try:
        binary = probmot_path(job)
        try:
            local_in = local_copy(job["input"], os.path.join(work, "in"))
        except FileNotFoundError as e:
            result.update(stage="fetch", error=f"{job['input']}: no such file ({e})")
            return result
        remote_out = is_uri(job["output"])
        local_out = (
            os.path.join(work, "out", base_name(job["output"])) if remote_out else job["output"]
        )
        os.makedirs(os.path.dirname(local_out), exist_ok=True)
        cmd = [binary, "track", local_in, "-o", local_out, "--json", *job["track_args"]]
        p, err = run_probmot(cmd)
        if err is not None:
            result.update(stage="track", error=f"{job['input']}: probmot track: {err}")
            return result
        result["warnings"] = [
            line[len("warning: ") :] for line in p.stderr.splitlines() if line.startswith("warning: ")
        ]
        summary = json.loads(p.stdout)
        summary["input"], summary["output"] = job["input"], job["output"]
        result["summary"] = summary
        if job["eval"]:
            if job["truth"] is None:
                truth = local_out
            else:
                try:
                    truth = local_copy(job["truth"], os.path.join(work, "truth"))
                except FileNotFoundError as e:
                    result.update(stage="eval", error=f"{job['truth']}: no such file ({e})")
                    return result
            cmd = [binary, "eval", "--truth", truth, "--tracks", local_out, "--json"]
            p, err = run_probmot(cmd + job["eval_args"])
            if err is not None:
                result.update(stage="eval", error=f"{job['input']}: probmot eval: {err}")
                return result
            result["eval"] = json.loads(p.stdout)["result"]
        if remote_out:
            try:
                copy_file(local_out, job["output"])
            except OSError as e:
                raise TransientError(f"copying the output to {job['output']}: {e}") from e
        result["ok"] = True
        return result
    finally:
        result["seconds"] = round(time.time() - started, 3)
        shutil.rmtree(work, ignore_errors=True)


def evaluate_all(jobs: list[dict]) -> dict:
    """One many-logs `probmot eval --json` over the given tracked logs; the body of a Ray task."""
    work = tempfile.mkdtemp(prefix="probmot-ray-eval-")
    try:
        tracks = [local_copy(j["output"], os.path.join(work, "tracks")) for j in jobs]
        cmd = [probmot_path(jobs[0]), "eval", "--json", "--truth"]
        if jobs[0]["truth"] is None:
            cmd += tracks
        else:
            cmd += [local_copy(j["truth"], os.path.join(work, "truth")) for j in jobs]
            cmd += ["--tracks", *tracks]
        p, err = run_probmot(cmd + jobs[0]["eval_args"])
        if err is not None:
            raise RuntimeError(f"probmot eval over {len(jobs)} logs: {err}")
        return json.loads(p.stdout)
    finally:
        shutil.rmtree(work, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# The driver.


def parse_args(argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    """Options before `--`, and the `probmot track` arguments after it."""
    track_args: list[str] = []
    if "--" in argv:
        i = argv.index("--")
        argv, track_args = argv[:i], argv[i + 1 :]
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="Everything after `--` is passed to `probmot track`. See the module docstring.",
    )
    ap.add_argument("inputs", nargs="+", metavar="INPUT", help="files, directories, globs, URIs")
    ap.add_argument("--out", required=True, metavar="PREFIX", help="output directory or URI prefix")
    ap.add_argument("--eval", action="store_true", help="also run probmot eval per log and overall")
    ap.add_argument(
        "--truth-prefix",
        metavar="PREFIX",
        help="with --eval: truth files PREFIX/<name> (default: the truth channel in the output)",
    )
    ap.add_argument(
        "--eval-arg",
        action="append",
        default=[],
        metavar="ARG",
        help="argument for probmot eval (repeatable), e.g. --eval-arg=--tracks-topic --eval-arg=/t",
    )
    ap.add_argument(
        "--address",
        help="existing Ray cluster (host:6379, ray://host:10001 or auto); default: start a local "
        "instance on loopback",
    )
    ap.add_argument("--num-cpus", type=int, help="CPUs of the local instance (default: all)")
    ap.add_argument("--probmot", default="probmot", help="probmot binary (default: probmot on PATH)")
    ap.add_argument(
        "--ship-probmot",
        action="store_true",
        help="ship the local binary given by --probmot to the workers in the runtime_env "
        "working_dir",
    )
    ap.add_argument("--report", metavar="OUT.json", help="write the report as JSON")
    ap.add_argument("--temp-dir", help="Ray's temporary directory for a local instance")
    a = ap.parse_args(argv)
    if a.truth_prefix and not a.eval:
        ap.error("--truth-prefix needs --eval")
    if a.address and a.num_cpus is not None:
        ap.error("--num-cpus is for a local instance; a cluster has its own")
    if a.num_cpus is not None and a.num_cpus < 1:
        ap.error("--num-cpus must be at least 1")
    return a, track_args


def make_jobs(a: argparse.Namespace, track_args: list[str]) -> list[dict]:
    """One job description per input log."""
    inputs = expand(a.inputs)
    seen: dict[str, str] = {}
    for i in inputs:
        name = base_name(i)
        if name in seen:
            raise SystemExit(f"error: {seen[name]} and {i} would both be written to {name}")
        seen[name] = i
    if not is_uri(a.out):
        os.makedirs(a.out, exist_ok=True)
    probmot = a.probmot
    if not a.ship_probmot and os.sep in probmot:
        probmot = os.path.abspath(probmot)
    return [
        {
            "input": i,
            "output": join(a.out, base_name(i)),
            "truth": join(a.truth_prefix, base_name(i)) if a.truth_prefix else None,
            "probmot": probmot,
            "shipped": a.ship_probmot,
            "track_args": track_args,
            "eval": a.eval,
            "eval_args": a.eval_arg,
        }
        for i in inputs
    ]


def start_ray(a: argparse.Namespace, ship_dir: str | None):
    """Connects to --address or starts a local instance on loopback without a dashboard."""
    if not a.address:
        # Ray maps 127.0.0.1 given as _node_ip_address to the machine's routable address and
        # then listens on every interface; with this switch (read when ray is imported, and
        # inherited by the processes it starts) the node's address is the loopback one and every
        # server of the instance listens on 127.0.0.1 only (ray 2.60.0:
        # ray/_private/services.py get_node_ip_address).
        os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    import ray

    runtime_env = {"working_dir": ship_dir} if ship_dir else None
    common = dict(
        runtime_env=runtime_env, include_dashboard=False, log_to_driver=False, logging_level="WARNING"
    )
    if a.address:
        ray.init(address=a.address, **common)
    else:
        ray.init(
            address="local",
            num_cpus=a.num_cpus or os.cpu_count(),
            _temp_dir=os.path.abspath(a.temp_dir) if a.temp_dir else None,
            # Only small results pass through the object store.
            object_store_memory=128 << 20,
            **common,
        )
    return ray


def describe_ok(r: dict) -> str:
    s = r["summary"]
    dets = sum(s["detections"]["per_label"].values())
    text = (
        f"{s['frames']} frames, {dets} detections, {s['tracks_confirmed']} tracks confirmed, "
        f"{r['seconds']:.2f} s"
    )
    if r["eval"] is not None:
        text += f", AMOTA {r['eval']['overall']['amota']:.4f}"
    return text


def table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    lines = [
        "  ".join(str(x).ljust(w) for x, w in zip(row, widths)).rstrip() for row in [header, *rows]
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


COUNT_COLUMNS = {"ids", "frag", "fp", "fn", "mt", "ml", "tp", "gt"}


def fmt(v, column: str = "") -> str:
    """A metric for the table: counts as integers, ratios with four decimals, None as '-'."""
    if v is None:
        return "-"
    if isinstance(v, float):
        if v != v:
            return "nan"
        if column in COUNT_COLUMNS and v.is_integer():
            return str(int(v))
        return f"{v:.4f}"
    return str(v)


def main(argv: list[str]) -> int:
    a, track_args = parse_args(argv)
    started = time.time()
    jobs = make_jobs(a, track_args)
    ship_dir = None
    if a.ship_probmot:
        ship_dir = tempfile.mkdtemp(prefix="probmot-ship-")
        src = a.probmot if os.sep in a.probmot else shutil.which(a.probmot)
        if not src or not os.path.isfile(src):
            raise SystemExit(f"error: --ship-probmot: no binary {a.probmot}")
        shutil.copy2(src, os.path.join(ship_dir, "probmot"))
    ray = None
    try:
        try:
            ray = start_ray(a, ship_dir)
        except Exception as e:
            where = a.address or "a local instance"
            raise SystemExit(f"error: cannot start or reach Ray ({where}): {e}") from e
        ray_started = time.time()
        task = ray.remote(num_cpus=1, max_retries=1, retry_exceptions=[TransientError])(track_one)
        pending = {task.remote(j): k for k, j in enumerate(jobs)}
        results: list[dict | None] = [None] * len(jobs)
        done = 0
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            k = pending.pop(ready[0])
            try:
                r = ray.get(ready[0])
            except Exception as e:  # the task failed twice, or its worker died twice
                r = {
                    "input": jobs[k]["input"],
                    "output": jobs[k]["output"],
                    "ok": False,
                    "stage": "task",
                    "error": f"{jobs[k]['input']}: {type(e).__name__}: {e}",
                    "summary": None,
                    "eval": None,
                    "warnings": [],
                }
            results[k] = r
            done += 1
            status = describe_ok(r) if r["ok"] else f"FAILED ({r['stage']}): {r['error']}"
            print(f"[{done}/{len(jobs)}] {base_name(r['input'])}: {status}", flush=True)

        tracking_s = time.time() - ray_started
        ok_jobs = [j for j, r in zip(jobs, results) if r["ok"]]
        metrics, metrics_error = None, None
        if a.eval and ok_jobs:
            ev = ray.remote(num_cpus=1, max_retries=1, retry_exceptions=[TransientError])(
                evaluate_all
            )
            try:
                metrics = ray.get(ev.remote(ok_jobs))
            except Exception as e:
                metrics_error = f"{type(e).__name__}: {e}"
    finally:
        if "ray" in sys.modules:  # also after a failed start: stops what it started
            sys.modules["ray"].shutdown()
        if ship_dir:
            shutil.rmtree(ship_dir, ignore_errors=True)

    failures = [
        {"input": r["input"], "stage": r["stage"], "error": r["error"]} for r in results if not r["ok"]
    ]
    report = {
        "logs": len(jobs),
        "tracked": len(jobs) - len(failures),
        "failed": len(failures),
        "failures": failures,
        "metrics": metrics,
        "metrics_error": metrics_error,
        "per_log": results,
        "track_args": track_args,
        # Listing the inputs and starting (or connecting to) Ray; from the first task submitted to the last log done;
        # the whole run, with the evaluation over all logs and shutting Ray down.
        "ray_start_s": round(ray_started - started, 3),
        "tracking_s": round(tracking_s, 3),
        "wall_time_s": round(time.time() - started, 3),
    }

    # The final table.
    rows = []
    for r in results:
        if r["ok"]:
            s = r["summary"]
            rows.append(
                [
                    base_name(r["input"]),
                    "ok",
                    s["frames"],
                    sum(s["detections"]["per_label"].values()),
                    s["tracks_confirmed"],
                    f"{r['seconds']:.2f}",
                    fmt(r["eval"]["overall"]["amota"]) if r["eval"] else "-",
                ]
            )
        else:
            rows.append([base_name(r["input"]), f"FAILED ({r['stage']})", "-", "-", "-", "-", "-"])
    print()
    print(table(["log", "status", "frames", "detections", "tracks", "seconds", "AMOTA"], rows))
    print(
        f"\n{len(jobs)} logs: {report['tracked']} tracked, {report['failed']} failed, "
        f"{report['tracking_s']:.1f} s tracking ({len(jobs) / max(tracking_s, 1e-9):.2f} logs/s), "
        f"{report['wall_time_s']:.1f} s in all with {report['ray_start_s']:.1f} s starting Ray"
    )
    if metrics is not None:
        res = metrics["result"]
        cols = ["amota", "amotp", "recall", "mota", "motp", "ids", "frag", "fp", "fn"]
        mrows = [
            [c, *[fmt(m.get(k), k) for k in cols]]
            for c, m in res["classes"].items()
            if m.get("gt") is not None  # classes with ground truth (NaN, written null, otherwise)
        ]
        mrows.append(["overall", *[fmt(res["overall"].get(k), k) for k in cols]])
        print(f"\nnuScenes tracking metrics over {len(ok_jobs)} logs:")
        print(table(["class", *cols], mrows))
    if metrics_error:
        print(f"\nerror: the evaluation over all logs failed: {metrics_error}", file=sys.stderr)
    for f in failures:
        print(f"error: {f['error']}", file=sys.stderr)

    if a.report:
        tmp = a.report + ".partial"
        with open(tmp, "w") as fh:
            json.dump(report, fh, indent=2, allow_nan=True)
            fh.write("\n")
        os.replace(tmp, a.report)
    return 1 if failures or metrics_error else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
