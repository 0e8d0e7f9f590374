#!/usr/bin/env python3
"""Forward-kinematics cost seen from Python (package `dvrk_twin`, crates/dvrk-py).

Measures, per model:
  - the per-call cost of `fk(q, frame=tip)` and `fk(q)` for one configuration (the binding's
    overhead: argument conversion, checks, result array);
  - the throughput of a Python loop over single calls against one batched call `fk(Q)`
    with Q of shape (N, nq) (one Rust loop without the GIL, one workspace reused);
  - a batch split over 2 threads (the batch releases the GIL, so threads run in parallel).

Usage (after `pip install dist/dvrk_twin-*.whl`):
    python benches/python_fk_bench.py [--models psm ecm cart] [--n 20000] [--repeat 5]
Timings are the best of --repeat runs (wall clock, time.perf_counter).
"""

import argparse
import platform
import threading
import time

import numpy as np

import dvrk_twin


def best_time(fn, repeat: int) -> float:
    """Smallest wall time (s) of `repeat` runs of fn()."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def random_q(model, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = model.joint_limits[:, 0], model.joint_limits[:, 1]
    return lo + (hi - lo) * rng.random((n, model.nq))


def in_threads(fn, parts) -> None:
    threads = [threading.Thread(target=fn, args=(p,)) for p in parts]
    for t in threads:
        t.start()
    for t in threads:
        t.join()


def bench_model(name: str, n: int, repeat: int) -> list:
    m = dvrk_twin.Model.load(name)
    tip = m.frame_indices[m.tip]
    q = random_q(m, n)
    q1 = q[0]
    n_single = max(2000, n // 10)
    rows = []

    def single_tip():
        for _ in range(n_single):
            m.fk(q1, frame=tip)

    def single_all():
        for _ in range(n_single):
            m.fk(q1)

    t = best_time(single_tip, repeat) / n_single
    rows.append((name, "fk(q, frame=tip), one call", f"{t * 1e6:8.2f} us/call", f"{1 / t:12,.0f} configs/s"))
    t = best_time(single_all, repeat) / n_single
    rows.append((name, f"fk(q), one call ({m.nframes} frames)", f"{t * 1e6:8.2f} us/call", f"{1 / t:12,.0f} configs/s"))

    loop_q = q[:n_single]
    t_loop = best_time(lambda: [m.fk(x, frame=tip) for x in loop_q], repeat) / len(loop_q)
    rows.append((name, "Python loop of fk(q, frame=tip)", f"{t_loop * 1e6:8.2f} us/conf", f"{1 / t_loop:12,.0f} configs/s"))
    t_batch = best_time(lambda: m.fk(q, frame=tip), repeat) / n
    rows.append((name, f"fk(Q, frame=tip), N={n}", f"{t_batch * 1e6:8.3f} us/conf",
                 f"{1 / t_batch:12,.0f} configs/s  (x{t_loop / t_batch:.0f} vs loop)"))
    t_full = best_time(lambda: m.fk(q), repeat) / n
    rows.append((name, f"fk(Q) all frames, N={n}", f"{t_full * 1e6:8.3f} us/conf", f"{1 / t_full:12,.0f} configs/s"))
    halves = np.array_split(q, 2)
    t_thr = best_time(lambda: in_threads(lambda p: m.fk(p, frame=tip), halves), repeat) / n
    rows.append((name, f"fk(Q, frame=tip), 2 threads", f"{t_thr * 1e6:8.3f} us/conf",
                 f"{1 / t_thr:12,.0f} configs/s  (x{t_batch / t_thr:.2f} vs 1 thread)"))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", nargs="+", default=["psm", "ecm", "cart"])
    ap.add_argument("--n", type=int, default=20000, help="configurations per batch")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"dvrk_twin {dvrk_twin.__version__}, numpy {np.__version__}, Python {platform.python_version()}, "
          f"{platform.machine()}; best of {args.repeat}")
    rows = []
    for name in args.models:
        rows += bench_model(name, args.n, args.repeat)
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    header = ("model", "what", "time")
    widths = [max(w, len(h)) for w, h in zip(widths, header)]
    print(f"{header[0]:<{widths[0]}}  {header[1]:<{widths[1]}}  {header[2]:>{widths[2]}}  throughput")
    print("-" * (sum(widths) + 6 + 36))
    for r in rows:
        print(f"{r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:>{widths[2]}}  {r[3]}")


if __name__ == "__main__":
    main()
