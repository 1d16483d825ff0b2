#!/usr/bin/env python3
"""Golden outputs of the probmot binary, to show that a refactor leaves every output byte-identical.

Runs the binary over every sample log (sample_logs/), the ROS 2 and Foxglove fixtures, a simulated
drive in a moving ego frame, the eval fixtures and the MCAP conformance corpus
(../shared/data/mcap-conformance, skipped with a note when absent) with `track` (the tracks channel,
the ego-frame tracks, the SceneUpdate channel, the JSON summary), `info`, `eval`, `fit`, `plot` and
`export`, and records the SHA-256 of every output (and the exit status of every run) in a manifest,
one `NAME SHA256` line per output, sorted.

Volatile fields are removed before hashing: `wall_time_s` of the JSON summaries, and the temporary
directory in printed paths (replaced by `$OUT`), and the places of the checkout and of ../shared
(`$REPO`, `$SHARED`). The numbers of `fit`'s outputs are compared rounded
to 12 significant digits: main's `fit` (at daaba54) summed in HashMap order, so its last bits varied
from run to run.

Usage (from the repository root):
  scripts/golden.py --write scripts/golden.manifest        # record the current binary's outputs
  scripts/golden.py --check scripts/golden.manifest        # compare; exit 1 and list differences
Options: --bin PATH (default target/debug/probmot, built with `cargo build` when missing),
         --keep DIR (write the outputs there instead of a temporary directory).
Also runs scripts/check_layering.py when it exists, its --self-test and then the check (either
failing fails --check).
"""

import argparse
import hashlib
import json
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CONFORMANCE = ROOT.parent / "shared" / "data" / "mcap-conformance"


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


FLOAT = re.compile(r"-?[0-9]+\.[0-9]+(?:[eE][+-]?[0-9]+)?")


def scrub(text: bytes, out: Path, round_floats: bool = False) -> bytes:
    """Removes what changes from run to run: the temporary directory and wall times; with
    `round_floats`, every decimal number is rounded to 12 significant digits."""
    s = text.decode("utf-8", "replace").replace(str(out), "$OUT")
    # The checkout's and the shared data's places (a clone elsewhere gives the same manifest).
    s = s.replace(str(ROOT.parent / "shared"), "$SHARED").replace(str(ROOT), "$REPO")
    s = re.sub(r'"wall_time_s":\s*[0-9.eE+-]+', '"wall_time_s": 0', s)
    if round_floats:
        s = FLOAT.sub(lambda m: "%.12g" % float(m.group(0)), s)
    return s.encode()


class Runner:
    def __init__(self, binary: Path, out: Path):
        self.binary = binary
        self.out = out
        self.results: dict[str, str] = {}

    def run(self, name: str, args: list, files: list = (), round_floats=False) -> None:
        """Runs `probmot ARGS`; records exit status, scrubbed stdout and each output file."""
        p = subprocess.run(
            [str(self.binary)] + [str(a) for a in args],
            cwd=ROOT,
            capture_output=True,
            env={**os.environ, "NO_COLOR": "1"},
        )
        self.results[f"{name}.status"] = str(p.returncode)
        self.results[f"{name}.stdout"] = sha(scrub(p.stdout, self.out, round_floats))
        for f in files:
            f = Path(f)
            key = f"{name}:{f.name}"
            if not f.exists():
                self.results[key] = "missing"
            elif f.suffix == ".json":
                self.results[key] = sha(scrub(f.read_bytes(), self.out, round_floats))
            else:
                self.results[key] = sha(f.read_bytes())


def track_all(r: Runner, name: str, src: Path, extra=(), eval_it=False, plot=False):
    """track (plain, with SceneUpdate) + info of the output, optionally eval/plot/export."""
    o = r.out
    out = o / f"{name}.tracked.mcap"
    r.run(f"track/{name}", ["track", src, "-o", out, "--json", *extra], [out])
    scene = o / f"{name}.scene.mcap"
    r.run(
        f"track-scene/{name}",
        ["track", src, "-o", scene, "--json", "--quiet", "--scene-topic", "/tracks/scene", *extra],
        [scene],
    )
    r.run(f"info/{name}", ["info", src])
    r.run(f"info-json/{name}", ["info", "--json", src])
    r.run(f"info-tracked/{name}", ["info", "--json", out])
    if eval_it:
        r.run(f"eval/{name}", ["eval", "--truth", out, "--json"])
        r.run(f"eval-kitti/{name}", ["eval", "--protocol", "kitti", "--truth", out, "--json"])
        r.run(f"eval-base/{name}", ["eval", "--truth", out, "--baseline", scene, "--json"])
        kitti = o / f"{name}.kitti.txt"
        r.run(f"export-kitti/{name}", ["export", "kitti", out, "-o", kitti], [kitti])
    if plot:
        png = o / f"{name}.png"
        r.run(f"plot/{name}", ["plot", out, "-o", png, "--quiet"], [png])
        png2 = o / f"{name}.window.png"
        r.run(
            f"plot-window/{name}",
            ["plot", out, "-o", png2, "--quiet", "--from", "2", "--to", "8", "--class", "car,pedestrian",
             "--width", "900", "--height", "400"],
            [png2],
        )
    return out


def run_all(r: Runner) -> list:
    notes = []
    o = r.out
    samples = sorted((ROOT / "sample_logs").glob("*.mcap"))
    for s in samples:
        track_all(r, f"sample-{s.stem}", s, eval_it=True, plot=True)
        hung = o / f"sample-{s.stem}.ab3dmot.mcap"
        r.run(
            f"track-ab3dmot/{s.stem}",
            ["track", s, "-o", hung, "--quiet", "--preset", "ab3dmot", "--distance", "iou3d",
             "--matcher", "hungarian"],
            [hung],
        )
        noise = o / f"fit-{s.stem}.json"
        r.run(f"fit/{s.stem}", ["fit", s, "-o", noise, "--min-samples", "5"], [noise], True)
        noise2 = o / f"fit-json-{s.stem}.json"
        r.run(f"fit-json/{s.stem}", ["fit", s, "-o", noise2, "--json", "--fold-yaw"], [noise2], True)
    allfit = o / "fit-all.json"
    r.run("fit/all", ["fit", *samples, "-o", allfit, "--json"], [allfit], True)
    outdir = o / "many"
    outdir.mkdir()
    r.run("track-many", ["track", *samples, "--out-dir", outdir, "--jobs", "2", "--quiet"],
          [outdir / s.name for s in samples])
    tracked = sorted(o.glob("sample-*.tracked.mcap"))
    r.run("eval-many", ["eval", "--truth", *tracked, "--json"])
    # nuScenes tables -> MCAP -> track -> eval with the range filter -> submission JSON.
    # Relative (runs start in ROOT): the imported recordings name their source file, and a
    # relative name keeps them the same in every clone.
    fixtures = Path("tests") / "fixtures"
    nin = o / "nuscenes-in"
    r.run("import-nuscenes", ["import", "nuscenes", "--detections", fixtures / "nuscenes" / "results.json",
                              "--meta", fixtures / "nuscenes", "-o", nin],
          [nin / "scene-0001.mcap", nin / "scene-0002.mcap"])
    ntracked = []
    for scene in ["scene-0001", "scene-0002"]:
        t = o / f"nuscenes-{scene}.tracked.mcap"
        r.run(f"track-nuscenes/{scene}", ["track", nin / f"{scene}.mcap", "-o", t, "--json"], [t])
        r.run(f"eval-range/{scene}", ["eval", "--truth", t, "--max-range", "--json"])
        ntracked.append(t)
    nus = o / "nuscenes.json"
    r.run("export-nuscenes", ["export", "nuscenes", *ntracked, "--meta", fixtures / "nuscenes", "-o", nus],
          [nus])

    # Detections in a moving ego frame: tracks in the fixed frame, the ego frame and SceneUpdate.
    ego = o / "ego.mcap"
    r.run("simulate-ego", ["simulate", "--scenario", "city", "--seed", "1", "--frames", "40",
                           "--objects", "40", "--ego-frame", "-o", ego], [ego])
    ego_out = track_all(r, "ego", ego, extra=["--tracks-frame", "ego"], eval_it=True, plot=True)
    eo = o / "ego.base.mcap"
    r.run("track-ego-fixed", ["track", ego, "-o", eo, "--quiet", "--fixed-frame", "map",
                              "--tracks-frame", "ego", "--scene-topic", "/s"], [eo])
    r.run("eval-ego-frame", ["eval", "--truth", ego_out, "--tracks-topic", "/tracks/ego", "--json"])

    fixtures = ROOT / "tests" / "fixtures"
    for f in sorted((fixtures / "ros2").glob("*.mcap")) + sorted((fixtures / "foxglove").glob("*.mcap")):
        track_all(r, f"{f.parent.name}-{f.stem}", f, plot=True)
    track_all(r, "ros2_tf", fixtures / "ros2_tf" / "tf.mcap")
    for f in sorted((fixtures / "eval").glob("*.mcap")):
        r.run(f"eval-fixture/{f.stem}", ["eval", "--truth", f, "--json"])
        r.run(f"eval-fixture-kitti/{f.stem}", ["eval", "--protocol", "kitti", "--truth", f, "--json"])
        r.run(f"info-fixture/{f.stem}", ["info", "--json", f])
    for f in sorted((fixtures / "fuzz").glob("*.mcap")):
        r.run(f"track-fuzz/{f.stem}", ["track", f, "-o", o / f"fuzz-{f.name}", "--quiet"])

    if CONFORMANCE.is_dir():
        conf = sorted(CONFORMANCE.rglob("*.mcap"))
        cdir = o / "conformance"
        cdir.mkdir(exist_ok=True)
        def one(f):
            rel = f.relative_to(CONFORMANCE)
            dst = cdir / (str(rel).replace("/", "__"))
            r.run(f"conformance/{rel}", ["track", f, "-o", dst, "--quiet"], [dst])

        with ThreadPoolExecutor(max_workers=2) as pool:
            list(pool.map(one, conf))
        r.run("conformance-info", ["info", "--json", conf[0]])
    else:
        notes.append(f"conformance corpus not found at {CONFORMANCE}: skipped")
    return notes


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--write", metavar="MANIFEST")
    g.add_argument("--check", metavar="MANIFEST")
    ap.add_argument("--bin", default=str(ROOT / "target" / "debug" / "probmot"))
    ap.add_argument("--keep", metavar="DIR")
    a = ap.parse_args()
    binary = Path(a.bin)
    if not binary.exists():
        subprocess.run(["cargo", "build", "--quiet"], cwd=ROOT, check=True)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(a.keep) if a.keep else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        r = Runner(binary, out.resolve())
        notes = run_all(r)
    for n in notes:
        print("note:", n, file=sys.stderr)
    lines = [f"{k} {v}" for k, v in sorted(r.results.items())]
    if a.write:
        Path(a.write).write_text("\n".join(lines) + "\n")
        print(f"wrote {len(lines)} entries to {a.write}")
        return 0
    want = dict(l.split(" ", 1) for l in Path(a.check).read_text().splitlines() if l)
    bad = [k for k in sorted(set(want) | set(r.results)) if want.get(k) != r.results.get(k)]
    if notes:
        bad = [k for k in bad if not k.startswith("conformance")]
    for k in bad:
        print(f"DIFF {k}: manifest {want.get(k)} now {r.results.get(k)}")
    layering = ROOT / "scripts" / "check_layering.py"
    ok_layers = True
    if layering.exists():
        # The checker's own self-test first, then the check of src/.
        ok_layers = all(
            subprocess.run([sys.executable, str(layering), *args], cwd=ROOT).returncode == 0
            for args in (["--self-test"], [])
        )
    print(f"golden: {len(r.results)} outputs, {len(bad)} differ" + ("" if ok_layers else "; layering check failed"))
    return 0 if not bad and ok_layers else 1


if __name__ == "__main__":
    sys.exit(main())
