"""How soon after it starts `dvrk` catches SIGTERM (issue #63: a SIGTERM in its first ~2 ms
killed it before the handler was installed). Polls bit 15 of SigCgt in /proc/PID/status (Linux)
after spawning `dvrk sim`, 30 times. Usage: python3 scripts/signal_handler_delay.py target/release/dvrk"""
import subprocess, sys, time, statistics
B = sys.argv[1]
ts = []
for _ in range(30):
    t0 = time.perf_counter()
    p = subprocess.Popen([B, "sim", "--scene", "psm", "--duration", "0.2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t1 = time.perf_counter()
    while True:
        try:
            s = open(f"/proc/{p.pid}/status").read()
        except OSError:
            break
        cgt = int(next(l.split()[1] for l in s.splitlines() if l.startswith("SigCgt")), 16)
        if cgt & (1 << 14):
            ts.append((time.perf_counter() - t1) * 1e3)
            break
    p.wait()
print(f"handler after spawn returned: median {statistics.median(ts):.2f} ms, max {max(ts):.2f} ms over {len(ts)}")
