"""The house's rules that a script checks (issue #60): the import loops between source files are
the one ARCHITECTURE.md documents (`scripts/import_loops.py`), nothing new."""

import os
import subprocess
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))


def test_the_only_import_loop_is_the_documented_one():
    out = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "import_loops.py")],
                         capture_output=True, text=True, check=True).stdout
    loops = [line for line in out.splitlines() if "loop of" in line]
    assert out.strip().endswith("1 import loop(s)") and len(loops) == 1, out
    assert "crates/dvrk-kin/src/compose.rs -> crates/dvrk-kin/src/load.rs" in out, out
    with open(os.path.join(ROOT, "ARCHITECTURE.md"), encoding="utf-8") as f:
        assert "`load.rs` with `compose.rs`" in f.read()
