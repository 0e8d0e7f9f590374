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


def test_recorded_formats_are_decoded_in_the_recording_home_alone():
    """ROS messages (ROS 1 and CDR), bags, MCAP and CSV are parsed in
    `crates/dvrk-sim/src/recording/` only; everything else calls its readers (issue #60: one home
    for every format)."""
    import re
    home = os.path.join(ROOT, "crates", "dvrk-sim", "src", "recording")
    pattern = re.compile(r"\bfn decode(_ros1)?\b|\brosbag::|\bmcap::|\bcsv::|\bCdrReader\b|\bfn read_cdr")
    found = []
    roots = [os.path.join(ROOT, "src")] + [os.path.join(ROOT, "crates", c, "src") for c in os.listdir(os.path.join(ROOT, "crates"))]
    for top in roots:
        for d, _, files in os.walk(top):
            if os.path.commonpath([d, home]) == home:
                continue
            for f in files:
                if f.endswith(".rs"):
                    with open(os.path.join(d, f), encoding="utf-8") as fh:
                        for n, line in enumerate(fh, 1):
                            if pattern.search(line):
                                found.append(f"{os.path.relpath(os.path.join(d, f), ROOT)}:{n}: {line.strip()}")
    assert not found, "\n".join(found)
    # The readers live there, and nowhere else.
    assert os.path.isfile(os.path.join(home, "joint_states.rs"))
    assert not os.path.exists(os.path.join(ROOT, "crates", "dvrk-calib", "src", "recordings"))
