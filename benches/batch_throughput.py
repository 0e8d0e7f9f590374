"""PSM env-steps per second of many copies: ``dvrk_twin.BatchSim`` (reduced engine, PID holding
home) against MuJoCo's ``mujoco.rollout`` on our exported MJCF (open-loop: the efforts our PID
settles at holding home, constant), for n copies on 1 and all cores, same run, same machine.

A step is one 1 ms step of one PSM. Each figure is the best of ``--repeat`` timed calls after a
warm-up call; a call advances every copy ``steps`` steps, ``steps`` chosen so that a call is at
least ``--work`` env-steps. MuJoCo's rollout writes the whole state trajectory (its API); ours
keeps the latest state, which is what a policy reads. Also printed: the resident memory each
copy adds (ours: the RSS growth of a fresh process building 8192 copies).

Usage (after ``bash scripts/test.sh``, with ``mujoco``)::

    .venv/bin/python benches/batch_throughput.py [--sizes 1,64,1024,8192] [--repeat 3] [--work 200000]
        [--gym]   # also: the vector env at num_envs 1024 against SyncVectorEnv of single envs
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np

import dvrk_twin


def ours(n: int, threads: int, work: int, repeat: int) -> float:
    b = dvrk_twin.BatchSim.from_scene("psm", n, threads=threads)
    steps = max(10, work // n)
    b.step(steps)
    best = 0.0
    for _ in range(repeat):
        t = time.perf_counter()
        b.step(steps)
        best = max(best, n * steps / (time.perf_counter() - t))
    return best


def holding_efforts() -> np.ndarray:
    b = dvrk_twin.BatchSim.from_scene("psm", 1, threads=1)
    b.step(3000)
    return b.effort[0].copy()


def mujoco_rate(n: int, threads: int, work: int, repeat: int, ctrl: np.ndarray) -> float:
    import mujoco
    from mujoco import rollout

    model = mujoco.MjModel.from_xml_string(dvrk_twin.export_mjcf("psm"))
    data = [mujoco.MjData(model) for _ in range(threads)]
    mujoco.mj_forward(model, data[0])
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data[0], state, spec)
    steps = max(10, work // n)
    initial = np.tile(state, (n, 1))
    control = np.tile(ctrl, (1, 1, 1))
    with rollout.Rollout(nthread=threads) as r:
        r.rollout(model, data, initial, control, nstep=steps)
        best = 0.0
        for _ in range(repeat):
            t = time.perf_counter()
            r.rollout(model, data, initial, control, nstep=steps)
            best = max(best, n * steps / (time.perf_counter() - t))
    return best


def gym_rates(num_envs: int, seconds: float) -> tuple[float, float]:
    import gymnasium

    import dvrk_twin.envs  # noqa: F401

    out = []
    for mode in ("vector_entry_point", "sync"):
        env = gymnasium.make_vec("dvrk_twin/PSMReach-v0", num_envs=num_envs, vectorization_mode=mode)
        env.reset(seed=0)
        env.step(env.action_space.sample())
        count, t = 0, time.perf_counter()
        while time.perf_counter() - t < seconds:
            env.step(env.action_space.sample())
            count += 1
        # Control steps of 20 simulator steps each.
        out.append(num_envs * count / (time.perf_counter() - t))
        env.close()
    return out[0], out[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1,64,1024,8192")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--work", type=int, default=200_000, help="env-steps per timed call (at least)")
    ap.add_argument("--gym", action="store_true", help="also time the vector env against SyncVectorEnv")
    args = ap.parse_args()
    cores = os.cpu_count() or 1
    try:
        import mujoco
    except ImportError:
        mujoco = None
        print("note: no `mujoco` (pip install mujoco): ours only")
    ctrl = holding_efforts()
    print(f"dvrk_twin {dvrk_twin.__version__}" + (f", MuJoCo {mujoco.__version__}" if mujoco else "") + f"; {cores} cores; PSM, dt 1 ms")
    print("| n | threads | ours (env-steps/s) | MuJoCo rollout (env-steps/s) | ours / MuJoCo |")
    print("|---|---|---|---|---|")
    table = {}
    for n in (int(x) for x in args.sizes.split(",")):
        for threads in sorted({1, cores}):
            a = ours(n, threads, args.work, args.repeat)
            m = mujoco_rate(n, threads, args.work, args.repeat, ctrl) if mujoco else float("nan")
            table[(n, threads)] = a
            print(f"| {n} | {threads} | {a:,.0f} | {m:,.0f} | {a / m:.2f} |")
    if cores > 1:
        for n in (int(x) for x in args.sizes.split(",")):
            print(f"scaling at n = {n}: {table[(n, cores)] / table[(n, 1)]:.2f}x on {cores} cores ({100 * table[(n, cores)] / table[(n, 1)] / cores:.0f}% efficient)")
    # In a fresh process: here the freed memory of the runs above would absorb part of it.
    code = ("import os, dvrk_twin\n"
            "rss = lambda: int(open('/proc/self/statm').read().split()[1]) * os.sysconf('SC_PAGE_SIZE')\n"
            "dvrk_twin.BatchSim.from_scene('psm', 8, threads=1)\n"
            "a = rss(); b = dvrk_twin.BatchSim.from_scene('psm', 8192, threads=1); print((rss() - a) / 8192 / 1e3)")
    per_copy = float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    print(f"memory: {per_copy:.0f} kB per PSM copy (RSS growth building 8192, fresh process)")
    if args.gym:
        v, s = gym_rates(1024, 5.0)
        print(f"PSMReach-v0, num_envs 1024, random actions, control steps of 20 ms: native vector env {v:,.0f} env-steps/s, "
              f"SyncVectorEnv of single envs {s:,.0f} ({v / s:.1f}x)")


if __name__ == "__main__":
    main()
