#!/usr/bin/env python3
"""Records how Python's built-in `sum` re-averages a track's mean score, for the KITTI evaluator.

AB3DMOT's KITTI evaluation sets every box of a track to `sum(scores) / len(scores)` at each
score threshold, starting from the previous threshold's means. Python's `sum` of floats adds
left to right up to 3.11 and compensates the rounding from 3.12, so the means (and which tracks
a threshold keeps) depend on the interpreter. This script runs that re-averaging on fixed score
lists with the interpreter it runs under and stores the result in a JSON fixture, one entry per
Python minor version, which `probmot`'s evaluator is tested against
(`src/eval/kitti/tests.rs`, `every_pass_means_equal_pythons_sum`).

    python3.11 scripts/python_sum_means.py tests/fixtures/eval/python_sum_means.json
    python3.12 scripts/python_sum_means.py tests/fixtures/eval/python_sum_means.json

The score lists come from a seeded generator (the same on every version), so a second run with
the same interpreter rewrites the same numbers; the fixture's `inputs` are checked, not trusted.
"""

import json
import os
import random
import sys

# The reference re-averages once for its first pass, once per recall point (40) and once for
# the pass at the best threshold.
PASSES = 42
CASES = 160
# Scores are integers over a power of ten: `k / d` is one correctly rounded division in Python
# and in Rust alike, so both read the same doubles from short integers.
DIVISORS = [10**4, 10**6, 10**3, 10**15, 10**15]


def score_lists():
    """Score lists like a tracker's, as (divisor, integers): detector scores printed with a few
    digits (probabilities or logits), one score repeated, and full-precision doubles, over long
    and short tracks."""
    rng = random.Random(20261125)
    lists = []
    for case in range(CASES):
        n = rng.choice([1, 2, 3, 5, 7, 10, 20, 50, 152])
        kind = case % len(DIVISORS)
        d = DIVISORS[kind]
        if kind == 0:
            ks = [rng.randint(0, d) for _ in range(n)]
        elif kind == 1:
            ks = [rng.randint(-2 * d, 12 * d) for _ in range(n)]
        elif kind == 2:
            ks = [rng.randint(0, 10 * d)] * n
        elif kind == 3:
            ks = [rng.randint(-2 * d, 8 * d) for _ in range(n)]
        else:
            ks = [rng.randint(-2 * d, 8 * d)] * n
        lists.append({"d": d, "k": ks})
    return lists


def reaverage(scores):
    """The means after each pass, run-length encoded as [[repr(mean), passes], ...] (`repr`
    is the shortest decimal that reads back as the same double)."""
    current = list(scores)
    runs = []
    for _ in range(PASSES):
        mean = sum(current) / float(len(current))
        current = [mean] * len(current)
        if runs and runs[-1][0] == repr(mean):
            runs[-1][1] += 1
        else:
            runs.append([repr(mean), 1])
    return runs


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: python3.X scripts/python_sum_means.py FIXTURE.json")
    path = sys.argv[1]
    inputs = score_lists()
    try:
        with open(path) as f:
            fixture = json.load(f)
    except FileNotFoundError:
        fixture = {"passes": PASSES, "inputs": inputs, "means": {}}
    if fixture["inputs"] != inputs or fixture["passes"] != PASSES:
        sys.exit(f"{path}: its inputs are not this script's; remove it to start over")
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    scores = [[k / case["d"] for k in case["k"]] for case in inputs]
    fixture["means"][version] = [reaverage(s) for s in scores]
    fixture["means"] = dict(sorted(fixture["means"].items()))
    with open(path + ".tmp", "w") as f:
        json.dump(fixture, f, separators=(",", ":"))
        f.write("\n")
    os.replace(path + ".tmp", path)
    print(f"{path}: wrote the means of Python {version} for {len(inputs)} score lists")


if __name__ == "__main__":
    main()
