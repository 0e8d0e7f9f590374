"""Trial tables: many independent trials (simulation runs, discrepancy detections, identifications)
run on Ray, locally or on a cluster, gathered into one table.

    python -m dvrk_twin.sweep SPEC.toml [--address ray://HOST:10001 | auto] [--serial] [--out FILE]

A spec names a trial kind and its parameters; every combination of the listed values (and of the
``seeds``) is one trial::

    kind = "detection"          # run_scene | detection | identify
    out = "detections.csv"      # .csv or .parquet (pyarrow)
    seeds = [1, 2, 3]           # or { start = 1, count = 20 }
    [parameters]
    effect = ["spring", "payload_mass", "none"]
    duration = [12.0]

- ``run_scene``: ``dvrk_twin.run_scene`` (parameters scene, duration, trajectory, engine); its
  figures (tracking RMS per joint, closure and RCM gaps; no wall-clock figures, so that the table
  is the same wherever it runs).
- ``detection``: ``synth_hidden_effect`` (effect, seed, duration, engine: the truth, reduced by
  default) then ``discrepancy`` on it: the hidden effects, the verdict, the named effects and
  whether the first hidden one was named.
- ``identify``: ``dvrk_twin.identify`` (recording, model, format, validate), without its
  ablation (a row holds none of it; it is most of an identification's time): the
  relative torque errors per channel, on the recording and on ``validate``.

Ray (PyPI ``ray``) is the engine: ``ray.init()`` on this machine by default, ``--address`` for a
cluster. Ray retries a trial whose worker died (``max_retries``); a trial that raises is recorded
with its error and the others go on. Rows come back in trial order, so the table is identical to
a serial run's (``--serial``, or without Ray, which it says). Progress goes to stderr; a summary
follows the table.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import os
import sys
import tempfile
import time
from typing import Any, Callable, Dict, List, Optional

KINDS = ("run_scene", "detection", "identify")
RETRIES = 3


def load_spec(path: str) -> Dict[str, Any]:
    try:
        import tomllib  # Python 3.11+
    except ImportError:  # pragma: no cover
        import tomli as tomllib  # type: ignore[no-redef]
    with open(path, "rb") as f:
        try:
            spec = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise ValueError(f"{path}: {e}") from None
    spec.setdefault("source", path)
    return spec


def trials(spec: Dict[str, Any]) -> List[Dict[str, Any]]:
    """Every trial of ``spec``: the product of its parameter lists and seeds, in a fixed order."""
    where = spec.get("source", "spec")
    kind = spec.get("kind")
    if kind not in KINDS:
        raise ValueError(f"{where}: kind = {kind!r}: expected one of {', '.join(KINDS)}")
    params = spec.get("parameters", {})
    if not isinstance(params, dict):
        raise ValueError(f"{where}: parameters: expected a table of lists")
    seeds = spec.get("seeds", [None])
    if isinstance(seeds, dict):
        seeds = list(range(int(seeds.get("start", 0)), int(seeds.get("start", 0)) + int(seeds["count"])))
    names = sorted(params)
    values = [v if isinstance(v, list) else [v] for v in (params[n] for n in names)]
    out = []
    for combo in itertools.product(*values):
        for seed in seeds:
            t = dict(zip(names, combo))
            if seed is not None:
                t["seed"] = seed
            out.append({"trial": len(out), "kind": kind, **t})
    return out


def run_trial(trial: Dict[str, Any]) -> Dict[str, Any]:
    """One trial's row: its parameters and results, or its error (never raises)."""
    import dvrk_twin

    row = dict(trial)
    p = {k: v for k, v in trial.items() if k not in ("trial", "kind")}
    try:
        if trial["kind"] == "run_scene":
            s = dvrk_twin.run_scene(p.get("scene", "psm"), float(p.get("duration", 2.0)), trajectory=p.get("trajectory", "sine"), engine=p.get("engine", "reduced"))
            row.update(max_closure_error_m=s["max_closure_error"], max_rcm_error_m=s.get("max_rcm_error"))
            for j in s["joints"]:
                row[f"rms_{j['joint']}"] = j["rms_error"]
        elif trial["kind"] == "detection":
            with tempfile.TemporaryDirectory() as tmp:
                rec = os.path.join(tmp, "trial.mcap")
                truth = dvrk_twin.synth_hidden_effect(rec, effect=p.get("effect", "random"), seed=int(p.get("seed", 1)), duration=float(p.get("duration", 12.0)), engine=p.get("engine", "reduced"))
                report = dvrk_twin.discrepancy(rec, model=p.get("model", "psm"), tracking=bool(p.get("tracking", False)), max_rounds=int(p.get("max_rounds", 1)))
            hidden = [e["name"] + (f" on {e.get('joint') or e.get('link') or e.get('actuator')}" if e.get("joint") or e.get("link") or e.get("actuator") else "") for e in truth.get("effects", [])]
            named = [e["name"] + (f" on {e.get('joint') or e.get('link') or e.get('actuator')}" if e.get("joint") or e.get("link") or e.get("actuator") else "") for e in report.get("effects", [])]
            row.update(hidden="; ".join(hidden) or "none", verdict=report["verdict"], named="; ".join(named) or "none")
            row["correct"] = (named[:1] == hidden[:1]) if hidden else report["verdict"] == "none"
        elif trial["kind"] == "identify":
            r = dvrk_twin.identify(p["recording"], model=p.get("model", "psm"), format=p.get("format", "wpi-csv"), validate=p.get("validate"), ablation=False)
            for c, e in zip(r["channels"], r["relative_error"]):
                row[f"relative_error_{c}"] = e
            for c, e in zip(r["channels"], (r.get("validation") or {}).get("relative_error", [])):
                row[f"validation_relative_error_{c}"] = e
        row["error"] = ""
    except Exception as e:  # a failed trial is a row, not the end of the table
        row["error"] = f"{type(e).__name__}: {e}"
    return row


def _progress(done: int, total: int, failed: int, start: float) -> None:
    print(f"\rsweep: {done}/{total} trials ({failed} failed), {time.monotonic() - start:.0f} s", end="" if done < total else "\n", file=sys.stderr, flush=True)


def run(spec: Dict[str, Any], address: Optional[str] = None, serial: bool = False, on_result: Optional[Callable[[Dict[str, Any]], None]] = None) -> List[Dict[str, Any]]:
    """Run every trial of ``spec``; rows in trial order. On Ray unless ``serial`` or Ray is not
    installed (said on stderr). ``on_result`` sees each row as it arrives (any order)."""
    todo = trials(spec)
    start = time.monotonic()
    rows: List[Optional[Dict[str, Any]]] = [None] * len(todo)
    failed = 0
    ray = None
    if not serial:
        try:
            import ray  # type: ignore[no-redef]
        except ImportError:
            print("sweep: ray is not installed (pip install ray): running the trials serially on this machine", file=sys.stderr)
    if ray is None:
        for i, t in enumerate(todo):
            rows[i] = run_trial(t)
            failed += bool(rows[i]["error"])
            if on_result:
                on_result(rows[i])
            _progress(i + 1, len(todo), failed, start)
        return rows  # type: ignore[return-value]
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray.remote(max_retries=RETRIES, retry_exceptions=False)(run_trial)
        pending = {remote.remote(t): t["trial"] for t in todo}
        done = 0
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                i = pending.pop(ref)
                try:
                    row = ray.get(ref)
                except Exception as e:  # the worker died more often than Ray retries
                    row = dict(todo[i], error=f"{type(e).__name__}: {e}")
                rows[i] = row
                failed += bool(row["error"])
                done += 1
                if on_result:
                    on_result(row)
                _progress(done, len(todo), failed, start)
    finally:
        if started_here:
            ray.shutdown()
    return rows  # type: ignore[return-value]


def write_table(rows: List[Dict[str, Any]], path: str) -> None:
    """The rows as CSV or Parquet (by extension), all or nothing (a temporary file renamed)."""
    columns: List[str] = []
    for r in rows:
        columns.extend(k for k in r if k not in columns)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".sweep-", suffix=os.path.splitext(path)[1])
    os.close(fd)
    try:
        if path.endswith(".parquet"):
            import pyarrow as pa
            import pyarrow.parquet as pq

            pq.write_table(pa.table({c: [r.get(c) for r in rows] for c in columns}), tmp)
        else:
            with open(tmp, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=columns)
                w.writeheader()
                w.writerows(rows)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def summary(rows: List[Dict[str, Any]]) -> str:
    failed = [r for r in rows if r.get("error")]
    lines = [f"{len(rows)} trials, {len(failed)} failed"]
    for r in failed[:5]:
        lines.append(f"  trial {r['trial']}: {r['error']}")
    if rows and rows[0].get("kind") == "detection":
        by: Dict[str, List[bool]] = {}
        for r in rows:
            if not r.get("error"):
                by.setdefault(r.get("effect", "?"), []).append(bool(r["correct"]))
        for effect, ok in sorted(by.items()):
            lines.append(f"  {effect}: named right in {sum(ok)}/{len(ok)}")
    return "\n".join(lines)


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dvrk_twin.sweep", description=__doc__.split("\n\n")[0])
    ap.add_argument("spec", help="the sweep's TOML file")
    ap.add_argument("--address", help="a Ray cluster's address (ray://HOST:10001, or auto); default: ray.init() here")
    ap.add_argument("--serial", action="store_true", help="no Ray: one trial after another here")
    ap.add_argument("--out", help="the table (.csv or .parquet); default: the spec's `out`")
    args = ap.parse_args(argv)
    try:
        spec = load_spec(args.spec)
        out = args.out or spec.get("out")
        if not out:
            raise ValueError(f"{args.spec}: out: missing (or give --out)")
        if os.path.abspath(out) == os.path.abspath(args.spec):
            raise ValueError(f"--out {out}: is the spec itself")
        rows = run(spec, address=args.address, serial=args.serial)
        write_table(rows, out)
    except (ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(summary(rows))
    print(f"table: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
