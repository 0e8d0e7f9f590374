"""Progress is drawn on stderr only when it is a terminal, and never changes stdout: `--json`
output is byte-identical with and without a terminal (a pseudo-terminal from Python's `pty`)."""

import os
import pty
import select
import subprocess

from test_live import dvrk_binary


def run(args, terminal):
    """stdout of `dvrk args`, and what a terminal on stderr showed (b"" without one)."""
    if not terminal:
        r = subprocess.run([dvrk_binary(), *args], capture_output=True, timeout=300)
        assert r.returncode == 0, r.stderr
        return r.stdout, b""
    master, slave = pty.openpty()
    proc = subprocess.Popen([dvrk_binary(), *args], stdout=subprocess.PIPE, stderr=slave)
    os.close(slave)
    shown = b""
    while True:
        ready, _, _ = select.select([master], [], [], 0.1)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                break
            if not chunk:
                break
            shown += chunk
        elif proc.poll() is not None:
            break
    out = proc.stdout.read()
    assert proc.wait(timeout=300) == 0, shown
    os.close(master)
    return out, shown


def test_json_output_is_the_same_with_and_without_a_terminal(tmp_path):
    rec = tmp_path / "r.mcap"
    subprocess.run([dvrk_binary(), "synth", "hidden-effect", "--effect", "none", "--duration", "8", "--engine", "reduced", "-o", str(rec), "--answer", str(tmp_path / "a.json")], check=True, capture_output=True, timeout=300)
    args = ["identify", "--recording", str(rec), "--model", "psm", "--json"]
    piped, _ = run(args, terminal=False)
    on_terminal, shown = run(args, terminal=True)
    assert piped == on_terminal and piped.startswith(b"{")
    # --json draws nothing even on a terminal.
    assert b"identifying" not in shown, shown
    # Without --json the terminal shows the stages; stdout is the text report either way.
    text_piped, _ = run(["identify", "--recording", str(rec), "--model", "psm"], terminal=False)
    text_terminal, shown = run(["identify", "--recording", str(rec), "--model", "psm"], terminal=True)
    assert b"identifying" in shown, shown
    assert text_piped == text_terminal
