#!/usr/bin/env python3
"""Run the README's examples that print or write JSON (and the model files identify writes),
each on real data where the README's example takes a recording, and keep their outputs in one
folder, so that two builds can be compared byte for byte:

    python3 scripts/json_contracts.py --bin OLD/dvrk --out /tmp/a
    python3 scripts/json_contracts.py --bin NEW/dvrk --out /tmp/b
    diff -r /tmp/a /tmp/b && echo identical

A refactor that keeps behaviour leaves the two folders identical. Wall-clock figures (real-time
factors, elapsed seconds) are the only fields taken out: they differ from run to run. Standard
library only.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "data", "external"))
WPI = os.path.join(SHARED, "wpi-dvrk-dynamics")

# Keys whose values are wall-clock measurements.
TIMING_KEYS = {"real_time_factor", "wall_time"}


def strip_timing(value):
    if isinstance(value, dict):
        return {k: strip_timing(v) for k, v in value.items() if k not in TIMING_KEYS}
    if isinstance(value, list):
        return [strip_timing(v) for v in value]
    return value


def run(binary, args, cwd):
    out = subprocess.run([binary, *args], cwd=cwd, capture_output=True, text=True)
    # 3: a check that ran and found problems (its report is the output).
    if out.returncode not in (0, 3):
        sys.exit(f"json_contracts: `dvrk {' '.join(args)}` failed ({out.returncode}): {out.stderr.strip()}")
    return out.stdout


def keep_json(text, path):
    try:
        value = json.loads(text)
    except json.JSONDecodeError as e:
        sys.exit(f"json_contracts: {path}: not JSON ({e})")
    with open(path, "w") as f:
        json.dump(strip_timing(value), f, indent=1, sort_keys=True)
        f.write("\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True, help="the dvrk binary to run")
    ap.add_argument("--out", required=True, help="folder for the outputs (created)")
    a = ap.parse_args()
    binary = os.path.abspath(a.bin)
    os.makedirs(a.out, exist_ok=True)
    one = os.path.join(WPI, "insertion-payload", "one_no_weight_results.csv")
    w205 = os.path.join(WPI, "insertion-payload", "one_results_1.0_scale_205_grams_insertion.csv")
    with tempfile.TemporaryDirectory() as work:
        stdout_cases = {
            "fk.json": ["fk", "psm", "--q", "0.1,-0.2,0.12,0,0,0,0.3", "--json"],
            "model_check.json": ["model", "check", os.path.join(SHARED, "dvrk-config", "PSM.json"), "--tool", os.path.join(SHARED, "dvrk-config", "LARGE_NEEDLE_DRIVER_400006.json"), "--json"],
            "sim_psm.json": ["sim", "--scene", "psm", "--duration", "2", "--json"],
            "sim_full.json": ["sim", "--scene", "full", "--duration", "0.5", "--json"],
            "ik.json": ["ik", "psm", "--pose", "0.011105,-0.463851,-0.110682,0.699167,0.706223,0.105669,-0.035341", "--json"],
        }
        for name, args in stdout_cases.items():
            keep_json(run(binary, args, work), os.path.join(a.out, name))
        model = os.path.join(work, "base.toml")
        run(binary, ["identify", "--recording", one, "--format", "wpi-csv", "--model", "psm", "-o", model], work)
        with open(model) as f, open(os.path.join(a.out, "identified.toml"), "w") as g:
            g.write(f.read().replace(work, "WORK"))
        report = os.path.join(work, "r.json")
        run(binary, ["discrepancy", "--model", model, "--recording", w205, "--format", "wpi-csv", "--report", report, "--no-tracking", "--max-rounds", "1"], work)
        with open(report) as f:
            keep_json(f.read().replace(work, "WORK"), os.path.join(a.out, "discrepancy_205g.json"))
    print(f"json_contracts: outputs in {a.out}")


if __name__ == "__main__":
    main()
