#!/usr/bin/env python3
"""How often `dvrk discrepancy` names the effect an independent generator hid (issue #62 item 5).

Every case of tests/python/independent_psm.py (kinematic: a tracker, no efforts) and
tests/python/independent_payload.py (a weight added to a real recording's efforts) x N seeds:
generate the recording, run `dvrk discrepancy --model psm --recording R --marker-topic T
--marker-link L --report r.json --no-tracking` (the effort cases: `--model M`, M identified by
`dvrk identify` on the real recording the weight is added to), compare the report with the truth,
print a markdown table. A payload is named correctly on its body or with its body among the
report's `payload.equivalent` (the recording's gravity cannot tell them apart); its interval is
the first moment's about the pitch's axis (`payload.axis_first_moment_ci95`) against the truth's
mass times the crank or its distance from that axis.

  .venv/bin/python scripts/independent_table.py --bin /tmp/dvrk-base --seeds 20 [--cases a,b]
"""

import argparse
import collections
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "python"))
import independent_psm as gen  # noqa: E402
import independent_payload as pay  # noqa: E402

ALL_CASES = gen.CASES + pay.CASES


def identified_model(binary, workdir):
    """The model `dvrk identify` makes of the real recording the effort cases add a weight to."""
    out = os.path.join(workdir, "base-identified.toml")
    if not os.path.exists(out):
        subprocess.run([binary, "identify", "--recording", pay.BASE, "--format", "wpi-csv",
                        "--model", "psm", "--no-ablation", "-o", out], check=True, capture_output=True)
    return out


def run_one(binary, case, seed, workdir, keep, model=None):
    rec = os.path.join(workdir, f"{case}-{seed}.mcap")
    report = os.path.join(workdir, f"{case}-{seed}.json")
    if case in pay.CASES:
        streams, truth = pay.generate(case, seed)
        gen.write_mcap(rec, streams)
        cmd = [binary, "discrepancy", "--model", model, "--recording", rec, "--report", report,
               "--no-tracking"]
    else:
        streams, truth = gen.generate(case, seed)
        gen.write_mcap(rec, streams)
        cmd = [binary, "discrepancy", "--model", "psm", "--recording", rec,
               "--marker-topic", truth["marker_topic"], "--marker-link", str(truth["marker_link"]),
               "--report", report, "--no-tracking"]
    start = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.monotonic() - start
    out = {"case": case, "seed": seed, "truth": truth, "wall": wall, "rc": p.returncode,
           "cmd": " ".join(cmd)}
    if p.returncode == 0:
        with open(report) as f:
            r = json.load(f)
        out["verdict"] = r.get("verdict")
        out["effects"] = r.get("effects") or []
    else:
        out["error"] = (p.stderr or p.stdout).strip().splitlines()[-1:]
    if not keep:
        for f in (rec, report):
            if os.path.exists(f):
                os.remove(f)
    return out


def matches(e, truth_effect):
    if e.get("name") != truth_effect["name"]:
        return False
    if truth_effect["name"] == "payload_mass":
        equivalent = [q["link"] for q in (e.get("payload") or {}).get("equivalent", [])]
        return truth_effect["link"] in [e.get("link")] + equivalent
    for key in ("joint", "link"):
        if truth_effect.get(key) is not None and e.get(key) != truth_effect[key]:
            return False
    return True


def label(e):
    at = e.get("joint") or e.get("link")
    return f"{e.get('name')}" + (f"[{at}]" if at else "")


def classify(run):
    """(outcome, the truth's effect as named or None); outcome one of correct (the truth among the
    named effects), wrong (named, but not the truth; anything named when nothing was hidden),
    ambiguous, none (verdict none: right when nothing was hidden), error."""
    if run["rc"] != 0:
        return "error", None
    truth = run["truth"]["effect"]
    verdict, effects = run["verdict"], run["effects"]
    if verdict == "ambiguous":
        return "ambiguous", None
    if verdict != "named" or not effects:
        return "none", None
    if truth is None:
        return "wrong", None
    hit = next((e for e in effects if matches(e, truth)), None)
    return ("correct", hit) if hit else ("wrong", None)


def ci_and_ratio(hit, truth):
    """Whether the named effect's 95% interval covers the truth, and fitted / true."""
    (param, true), = [(k, v) for k, v in truth["parameters"].items()][:1]
    if param == "axis_first_moment":
        fitted = (hit.get("payload") or {}).get("axis_first_moment")
        ci = (hit.get("payload") or {}).get("axis_first_moment_ci95")
    else:
        fitted = (hit.get("parameters") or {}).get(param)
        ci = (hit.get("ci95") or {}).get(param)
    covers = None
    if ci is not None and len(ci) == 2:
        lo = -float("inf") if ci[0] is None else ci[0]
        hi = float("inf") if ci[1] is None else ci[1]
        covers = lo <= true <= hi
    ratio = fitted / true if fitted is not None and true else None
    return covers, ratio


def table(runs):
    by_case = collections.defaultdict(list)
    for r in runs:
        by_case[r["case"]].append(r)
    lines = ["| case | runs | named correctly | named wrong | ambiguous | none | errors | CI covers truth "
             "| median fitted/true | wall s/run (median, max) | what was named |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for case in ALL_CASES:
        rs = by_case.get(case)
        if not rs:
            continue
        counts = collections.Counter()
        covers, ratios, named = [], [], collections.Counter()
        for r in rs:
            outcome, hit = classify(r)
            counts[outcome] += 1
            for e in r.get("effects") or []:
                named[label(e)] += 1
            if hit is not None:
                c, q = ci_and_ratio(hit, r["truth"]["effect"])
                if c is not None:
                    covers.append(c)
                if q is not None:
                    ratios.append(q)
        walls = [r["wall"] for r in rs]
        truth = rs[0]["truth"]["effect"]
        correct = "-" if truth is None else counts["correct"]
        cov = f"{sum(covers)}/{len(covers)}" if covers else "-"
        med = f"{statistics.median(ratios):.3f}" if ratios else "-"
        what = ", ".join(f"{k} x{v}" for k, v in named.most_common(4)) or "-"
        lines.append(f"| {case} | {len(rs)} | {correct} | {counts['wrong']} | {counts['ambiguous']} | "
                     f"{counts['none']} | {counts['error']} | "
                     f"{cov} | {med} | {statistics.median(walls):.2f}, {max(walls):.2f} | {what} |")
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bin", default=os.environ.get("DVRK_BIN", "target/release/dvrk"))
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--first-seed", type=int, default=1)
    p.add_argument("--cases", default=",".join(ALL_CASES))
    p.add_argument("--jobs", type=int, default=2, help="parallel runs (at most 2)")
    p.add_argument("--workdir", help="keep the recordings and reports here")
    p.add_argument("--json", help="write every run (truth, verdict, effects, wall) here")
    a = p.parse_args()
    binary = os.path.abspath(a.bin)
    if not os.access(binary, os.X_OK):
        sys.exit(f"no dvrk binary at {binary} (--bin)")
    cases = [c for c in a.cases.split(",") if c]
    for c in cases:
        if c not in ALL_CASES:
            sys.exit(f"unknown case {c}; cases: {', '.join(ALL_CASES)}")
    workdir = a.workdir or tempfile.mkdtemp(prefix="independent-")
    os.makedirs(workdir, exist_ok=True)
    model = identified_model(binary, workdir) if any(c in pay.CASES for c in cases) else None
    jobs = [(binary, c, s, workdir, bool(a.workdir), model) for c in cases
            for s in range(a.first_seed, a.first_seed + a.seeds)]
    start = time.monotonic()
    with ProcessPoolExecutor(max_workers=max(1, min(a.jobs, 2))) as pool:
        runs = list(pool.map(run_one, *zip(*jobs)))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(runs, f, indent=1)
    print(f"{binary}, {a.seeds} seeds per case from {a.first_seed}, "
          f"{time.monotonic() - start:.0f} s in all\n")
    print(table(runs))
    errors = [r for r in runs if r["rc"] != 0]
    for r in errors[:5]:
        print(f"\nerror: {r['case']} seed {r['seed']}: {' '.join(r['error'])}")
    if not a.workdir:
        try:
            if model:
                os.remove(model)
            os.rmdir(workdir)
        except OSError:
            pass


if __name__ == "__main__":
    main()
