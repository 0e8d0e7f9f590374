"""Every `dvrk` command that reads a file the user names, given a file that never ends, a huge one
or one that never arrives: `/dev/zero`, a 1 GB file of zeros and a FIFO nobody writes to.

Issue #63 found `identify --recording /dev/zero` growing to 3.1 GB in 3 s, a 1 GB file of zeros
peaking at 6.3 GB and quoting itself whole on stderr (268 MB), and a FIFO waiting forever. What
must hold instead, for each (command, input): exit 1 with one short line on stderr that names the
file, peak memory under 100 MB and a clean exit within 5 s. The child is killed at 20 s (or at
2 GB) so that a hang or a runaway read fails its case instead of stalling the run or the machine.
"""

import ctypes
import os
import pathlib
import signal
import subprocess
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]

PEAK_MB = 100  # the must-show's bound (decimal MB of peak RSS)
WALL_S = 5.0  # ... and its clean exit
HARD_TIMEOUT_S = 20.0  # a hang is killed here and fails its case
GUARD_KIB = 2 << 20  # a runaway read is killed at 2 GiB RSS, before it hurts the machine
GIB = 1 << 30
PR_SET_CHILD_SUBREAPER = 36  # prctl(2), Linux
# sh -c GATED_FORK sh CMD...: fork CMD held until stdin (kept as fd 3) closes, print its pid, exit
GATED_FORK = 'exec 3<&0; { read _ <&3; exec "$@" 3<&- </dev/null >/dev/null; } & echo $!'

# (input suffix, arguments): {input} is the hostile file, {tmp} a directory for outputs. The
# suffix is the extension the command's files usually have, so that a reader told the format by
# the name (CSV, MCAP, TOML, JSON) is the one that meets the zeros.
COMMANDS = {
    "identify": (".csv", "identify --recording {input} --model psm"),
    "discrepancy": (".csv", "discrepancy --model psm --recording {input} --report {tmp}/r.json"),
    "sim-scene": (".toml", "sim --scene {input} --duration 0.01"),
    "sim-replay": (".csv", "sim --scene psm --trajectory replay:{input} --duration 0.01"),
    "sim-model": (".toml", "sim --scene psm --model PSM1={input} --duration 0.01"),
    "serve-scene": (".toml", "serve --scene {input} --duration 1"),
    "model-show": (".toml", "model show {input}"),
    "model-check": (".toml", "model check {input}"),
    "fk-model": (".toml", "fk {input} --q 0"),
    "fk-input": (".csv", "fk psm --input {input} --output {tmp}/poses.csv"),
    "fk-tool": (".json", "fk psm --tool {input}"),
    "ik-model": (".toml", "ik {input} --pose 0,0,-0.1,0,0,0,1"),
    "export-urdf": (".toml", "export urdf {input} --output {tmp}/out.urdf"),
    "calib-pivot": (".csv", "calib pivot --recording {input}"),
    "calib-axes": (".csv", "calib axes --recording {input} --config {input}"),  # both required
    "calib-apply": (".json", "calib apply --axes {input} --output {tmp}/model.toml"),
    "gc-recording": (".csv", "gc --recording {input}"),
    "gc-model": (".toml", "gc --model {input}"),
    "teleop-mtm": (".mcap", "teleop --mtm {input} --scene psm --out {tmp}/teleop.mcap"),
    "synth-mocap-model": (".toml", "synth mocap --model {input} --output {tmp}/mocap.csv"),
    "synth-hidden-model": (".toml", "synth hidden-effect --model {input} --output {tmp}/h.csv --answer {tmp}/a.json"),
}
INPUTS = ["dev-zero", "zeros-1GB", "fifo"]


def dvrk_binary():
    path = os.environ.get("DVRK_BIN") or str(ROOT / "target" / "release" / "dvrk")
    if not pathlib.Path(path).exists():
        pytest.skip(f"no dvrk binary at {path} (cargo build --release, or set DVRK_BIN)")
    return path


def hostile_input(kind, directory, suffix):
    """The input's path: /dev/zero, a sparse 1 GB file of zeros (no disk used), or a FIFO."""
    if kind == "dev-zero":
        return "/dev/zero"
    path = directory / (("zeros" if kind == "zeros-1GB" else "fifo") + suffix)
    if kind == "zeros-1GB":
        path.touch()
        os.truncate(path, GIB)
    else:
        os.mkfifo(path)
    return str(path)


def rss_kib(pid):
    """The child's resident set now (KiB), 0 once it is gone."""
    try:
        for line in pathlib.Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


def start_own_child(args, stderr):
    """Start `args`, held at a gate, as a child of this process whose ru_maxrss is its own.

    Popen starts a child by vfork, and Linux carries the parent's peak RSS into the child's
    ru_maxrss at exec: `/bin/true` started by this pytest "peaks" at pytest's own peak (35 MB
    alone, hundreds of MB in a worker that imported MuJoCo). So a shell, which is small, forks
    the command and exits; this process, a child subreaper for that moment, inherits the orphan
    and can reap it with os.wait4. The command waits on fd 3 until the returned pipe is closed,
    or the shell might reap it first. Returns (pid, gate)."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_CHILD_SUBREAPER, 1)
    try:
        shell = subprocess.Popen(
            ["/bin/sh", "-c", GATED_FORK, "sh", *args],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=stderr,
        )
        pid = int(shell.stdout.readline())
        shell.stdout.close()
        assert shell.wait() == 0
    finally:
        libc.prctl(PR_SET_CHILD_SUBREAPER, 0)
    return pid, shell.stdin


def run_measured(args, stderr_path):
    """Run `args` to its end (or kill it at the hard timeout or the memory guard): its exit code,
    peak RSS in MB (wait4's ru_maxrss, KiB on Linux), wall time and why it was killed, if it was."""
    with open(stderr_path, "wb") as err:  # a file, not a pipe: a 268 MB message must not block it
        pid, gate = start_own_child(args, err)
    start = time.monotonic()
    gate.close()
    killed = None
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() - start > HARD_TIMEOUT_S:
            killed = f"still running after {HARD_TIMEOUT_S:.0f} s: killed"
        elif rss_kib(pid) > GUARD_KIB:
            killed = f"RSS past {GUARD_KIB >> 20} GiB after {time.monotonic() - start:.1f} s: killed"
        if killed:
            os.kill(pid, signal.SIGKILL)  # not yet reaped: the pid is still ours
            _, status, usage = os.wait4(pid, 0)
            break
        time.sleep(0.01)
    wall = time.monotonic() - start
    return os.waitstatus_to_exitcode(status), usage.ru_maxrss * 1024 / 1e6, wall, killed


@pytest.mark.parametrize("kind", INPUTS)
@pytest.mark.parametrize("command", list(COMMANDS))
def test_hostile_input_is_refused_quickly_in_little_memory(command, kind, tmp_path):
    """Refused at once: a device or FIFO by its type, a huge file by its size or by a bound on
    what is read (a recording's first line), in one line of a few hundred bytes at most."""
    binary = dvrk_binary()
    suffix, template = COMMANDS[command]
    path = hostile_input(kind, tmp_path, suffix)
    args = [binary] + [a.format(input=path, tmp=tmp_path) for a in template.split()]
    stderr_path = tmp_path / "stderr.txt"
    code, peak_mb, wall, killed = run_measured(args, stderr_path)
    print(f"\n{command}[{kind}]: exit {code}, peak {peak_mb:.1f} MB, {wall:.2f} s")
    with open(stderr_path, "rb") as f:
        err = f.read(4096).decode(errors="replace")
    size = stderr_path.stat().st_size
    said = f"stderr ({size} bytes): {err[:400]}"
    assert killed is None, f"{killed}; {said}"
    assert code == 1, f"exit {code}; {said}"
    assert size < 400 and len(err.strip().splitlines()) == 1, f"one short line; {said}"
    assert err.startswith("error: ") and path in err and "panicked" not in err, said
    assert peak_mb < PEAK_MB, f"peak {peak_mb:.1f} MB; {said}"
    assert wall < WALL_S, f"{wall:.2f} s; {said}"
