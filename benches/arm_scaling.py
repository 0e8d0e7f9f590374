"""How the cost of a step grows with the number of arms, on both engines: 1, 2, 4 and 8 PSMs on
fixed bases (the psm scene's arm repeated, 0.5 m apart), the section 4.3 tracking test.

Prints, per arm count and engine, the real-time factor and the wall time per simulated second per
arm (ms). Each arm is its own rapier world / reduced tree, so both should grow linearly.

Usage (after ``bash scripts/test.sh`` or installing the wheel)::

    .venv/bin/python benches/arm_scaling.py [--duration 10] [--repeat 3]
"""

from __future__ import annotations

import argparse
import re
import tempfile
from pathlib import Path

import dvrk_twin

HERE = Path(__file__).resolve().parent
PSM_SCENE = HERE.parent / "models" / "scenes" / "psm.toml"


def scene_with(n: int, directory: Path) -> Path:
    """The psm scene with its arm repeated `n` times, each 0.5 m further along x."""
    text = PSM_SCENE.read_text()
    head, arm = text.split("[[arms]]", 1)
    arms = []
    for i in range(n):
        a = arm.replace('name = "PSM1"', f'name = "PSM{i + 1}"')
        a = re.sub(r"mount = \[\[-1\.0, 0\.0, 0\.0, 0\.0\]", f"mount = [[-1.0, 0.0, 0.0, {0.5 * i}]", a)
        arms.append("[[arms]]" + a)
    path = directory / f"psm{n}.toml"
    path.write_text(head.replace('name = "psm"', f'name = "psm{n}"') + "".join(arms))
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=10.0, help="simulated time per run (s)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure; the best is kept")
    args = ap.parse_args()
    print(f"dvrk_twin {dvrk_twin.__version__}; {args.duration:g} s tracking test, best of {args.repeat}, one thread")
    print("| PSMs | rapier RTF | rapier ms per s per arm | reduced RTF | reduced ms per s per arm |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in (1, 2, 4, 8):
            path = scene_with(n, Path(tmp))
            best = {}
            for _ in range(args.repeat):
                for engine in ("rapier", "reduced"):
                    r = dvrk_twin.run_scene(str(path), args.duration, engine=engine)
                    assert len(r["joints"]) == 7 * n
                    best[engine] = max(best.get(engine, 0.0), r["real_time_factor"])
            per_arm = {e: 1000.0 / rtf / n for e, rtf in best.items()}
            print(f"| {n} | {best['rapier']:.1f} | {per_arm['rapier']:.2f} | {best['reduced']:.1f} | {per_arm['reduced']:.3f} |")


if __name__ == "__main__":
    main()
