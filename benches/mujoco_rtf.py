"""Real-time factor of every Table 9 scene: ours (both engines: rapier and the reduced one) against
MuJoCo on our own exported MJCF, measured in the same run, since absolute times on shared machines
vary by a third between runs.

For each scene (psm, ecm, 2psm-ecm, 3psm, full): export the MJCF (``dvrk_twin.export_mjcf``, as
``dvrk export mjcf``), time MuJoCo on the section 4.3 tracking test, time ours on the same test
(``dvrk_twin.run_scene``: the ``dvrk sim --json`` figures, the same Rust code and release build),
and print scene, our RTF on each engine, MuJoCo's RTF, the reduced engine's ratio to MuJoCo and
the loop-closure gaps.

MuJoCo method: a C rollout (``benches/mujoco_rollout.c``, compiled here against the headers and
library the ``mujoco`` wheel ships) stepping ``mj_step`` with our PID computed in C between steps,
the fastest honest way, since the PID's anti-windup cannot be expressed inside MuJoCo for
``mujoco.rollout``. Without a C compiler it falls back to the Python step loop
(``dvrk_twin.mujoco_run``) and says so: that measures Python more than MuJoCo. Both timings
cover the step loop with controller and statistics only, as ``dvrk sim`` times its own.

Usage (after ``bash scripts/test.sh`` or building and installing the wheel, with ``mujoco``)::

    .venv/bin/python benches/mujoco_rtf.py [--duration 10] [--repeat 3] [--scenes psm,ecm]

Each figure is the best of ``--repeat`` runs (the least disturbed by other load).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import dvrk_twin

HERE = Path(__file__).resolve().parent
SCENES = ["psm", "ecm", "2psm-ecm", "3psm", "full"]


def build_rollout(workdir: Path):
    """Compile the C rollout against the mujoco wheel; None (with a note) when that fails."""
    import mujoco

    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    lib_dir = Path(mujoco.__file__).parent
    libs = sorted(lib_dir.glob("libmujoco.so*")) + sorted(lib_dir.glob("libmujoco*.dylib"))
    if not cc or not libs or not (lib_dir / "include" / "mujoco" / "mujoco.h").exists():
        print(f"note: no C compiler or no MuJoCo headers/library in {lib_dir}: Python step loop instead", file=sys.stderr)
        return None
    exe = workdir / "mujoco_rollout"
    cmd = [cc, "-O2", "-o", str(exe), str(HERE / "mujoco_rollout.c"), f"-I{lib_dir / 'include'}", str(libs[0]), f"-Wl,-rpath,{lib_dir}", "-lm"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        print(f"note: compiling the C rollout failed ({r.stderr.strip()[:300]}): Python step loop instead", file=sys.stderr)
        return None
    return exe


def mujoco_run(exe, xml_path: Path, duration: float) -> dict:
    """RTF and closure gap of MuJoCo on the exported scene."""
    if exe is None:
        from dvrk_twin import mujoco_run as mr

        r = mr.run_tracking(xml_path.read_text(), duration)
        return {"real_time_factor": r["real_time_factor"], "max_closure_error": r["max_closure_error"]}
    out = subprocess.run([str(exe), str(xml_path), str(duration)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=10.0, help="simulated time per run (s)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure; the best is kept")
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated scene names")
    args = ap.parse_args()
    try:
        import mujoco
    except ImportError:
        sys.exit("error: the MuJoCo comparison needs the PyPI package `mujoco` (pip install mujoco)")
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        exe = build_rollout(workdir)
        method = "C rollout (mj_step, PID in C)" if exe else "Python step loop (mj_step, PID in numpy)"
        print(f"MuJoCo {mujoco.__version__}, {method}; dvrk_twin {dvrk_twin.__version__}; "
              f"{args.duration:g} s tracking test, best of {args.repeat}")
        print(f"| scene | rapier RTF | reduced RTF | MuJoCo RTF | reduced / MuJoCo | rapier gap (m) | reduced gap (m) | MuJoCo gap (m) |")
        print("|---|---|---|---|---|---|---|---|")
        for scene in args.scenes.split(","):
            xml_path = workdir / f"{scene}.xml"
            xml_path.write_text(dvrk_twin.export_mjcf(scene))
            # Interleaved, so that a disturbance hits every engine alike.
            runs = {"rapier": [], "reduced": [], "mujoco": []}
            for _ in range(args.repeat):
                for engine in ("rapier", "reduced"):
                    runs[engine].append(dvrk_twin.run_scene(scene, args.duration, engine=engine))
                runs["mujoco"].append(mujoco_run(exe, xml_path, args.duration))
            best = {k: max(r["real_time_factor"] for r in v) for k, v in runs.items()}
            gap = {k: v[0]["max_closure_error"] for k, v in runs.items()}
            print(f"| {scene} | {best['rapier']:.1f} | {best['reduced']:.1f} | {best['mujoco']:.1f} | {best['reduced'] / best['mujoco']:.2f} "
                  f"| {gap['rapier']:.1e} | {gap['reduced']:.1e} | {gap['mujoco']:.1e} |")


if __name__ == "__main__":
    main()
