#!/usr/bin/env bash
# Every test of the project: the Rust workspace (`cargo test`) and the Python package (a wheel
# built by maturin, installed into a private virtual environment, then `pytest`).
# Needs only Rust and Python 3.9+; everything else comes from crates.io and PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."

venv="${DVRK_VENV:-.venv}"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
venv="$(cd "$venv" && pwd)"
py="$venv/bin/python"
logs="$(mktemp -d)"
trap 'rm -rf "$logs"' EXIT
cpu_of() {  # cpu_of FILE: user + system seconds of the finished children, as bash's `times` wrote FILE
    tail -1 "$1" | tr 'ms' '  ' | awk '{ printf "%.0f", 60 * $1 + $2 + 60 * $3 + $4 }'
}

# The Python packages install while the CLI builds below (pip waits on the network and the disk,
# cargo on the cores); a failure of the required ones fails the run once the build is done.
(
    "$py" -m pip install --quiet --disable-pip-version-check "maturin>=1.5,<2" "pytest>=7" pytest-xdist "numpy>=1.21" mcap mcap-ros2-support mcap-protobuf-support foxglove-schemas-protobuf rosbags websockets "gymnasium>=1.0"
    # Ray for the trial tables (dvrk_twin.sweep); optional: where it cannot be installed the sweep runs
    # serially and its Ray tests skip, saying so.
    "$py" -m pip install --quiet --disable-pip-version-check ray pyarrow \
        || echo "note: could not install ray from PyPI: the Ray sweep tests will skip"
    # Pinocchio, the independent dynamics the Python dynamics are checked against (test_pinocchio.py).
    "$py" -m pip install --quiet --disable-pip-version-check pin \
        || echo "note: could not install pin (Pinocchio) from PyPI: its cross-check will skip"
    # Eclipse Cyclone DDS, the independent ROS 2 peer of `dvrk serve`'s tests (tests/python/test_serve.py);
    # optional like MuJoCo: where no wheel installs, those tests say so and skip.
    "$py" -m pip install --quiet --disable-pip-version-check cyclonedds \
        || echo "note: could not install cyclonedds from PyPI: the ROS 2 twin's tests will skip"
    # MuJoCo for the second-engine cross-check (tests/python/test_mujoco.py); optional: where it cannot
    # be installed the test says so and skips.
    "$py" -m pip install --quiet --disable-pip-version-check mujoco \
        || echo "note: could not install mujoco from PyPI: the MuJoCo cross-check will skip"
) > "$logs/pip" 2>&1 &
pips=$!

# Build the CLI first: every dependency, the three libraries and `dvrk`, which the Python tests
# need. `--workspace` puts the Python binding into the feature resolution, so that this build,
# the wheel's below and the tests' (`cargo test --workspace`) share every compiled dependency
# (the binding pins the features the tests' dev-dependencies add: crates/dvrk-py/Cargo.toml).
# Release: the simulation tests are heavy.
cargo build --release --workspace --bin dvrk
pip_status=0
wait "$pips" || pip_status=$?
cat "$logs/pip"
[ "$pip_status" -eq 0 ] || { echo "the Python packages did not install (pip exit status $pip_status)"; exit "$pip_status"; }

# The Python package: the wheel built as a user would, installed.
rm -rf target/wheels
"$venv/bin/maturin" build --release --quiet -m crates/dvrk-py/Cargo.toml -o target/wheels
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps target/wheels/*.whl
times > "$logs/times"
echo "(set-up, CLI and wheel: $SECONDS s, CPU $(cpu_of "$logs/times") s)"

# Then three streams side by side; each one's output is printed when all have ended.
# - The tests with wall-clock assertions (marked `realtime`, tests/python/conftest.py), one at a
#   time at normal priority: they mostly wait on the wall clock.
# - The other Python tests on as many workers as there are cores (pytest-xdist), and
# - the Rust tests (scripts/rust_tests.sh: the longest binary beside the rest of the build and
#   the other binaries), with the venv first on PATH so tests that write fixtures with Python's
#   mcap packages find them,
#   both at the lowest CPU priority (nice 19: the scheduler weighs them 15 against a realtime
#   test's 1024, so its twin gets a core the moment it wakes). Each fills the cores the others'
#   last long tests leave idle.
# Then the one realtime test marked `alone`, by itself (its twin's discovery failed beside the
# streams: tests/python/conftest.py).
export DVRK_BIN="$PWD/target/release/dvrk"
stream() {  # stream NAME COMMAND...: the command's output, wall time and CPU time in $logs/NAME
    local name="$1" t0="$SECONDS" rc=0
    shift
    # In a subshell of its own, whose `times` (not in a pipe or $(...): those fork) counts the
    # stream's CPU alone.
    ( code=0; "$@" > "$logs/$name" 2>&1 || code=$?; times > "$logs/$name.times"; exit "$code" ) || rc=$?
    echo "($name: $((SECONDS - t0)) s, exit status $rc, CPU $(cpu_of "$logs/$name.times") s)" >> "$logs/$name"
    return "$rc"
}
stream rust nice -n 19 env PATH="$venv/bin:$PATH" bash scripts/rust_tests.sh "$py" &
rust=$!
stream python nice -n 19 "$py" -m pytest tests/python -q -m "not realtime and not ray_cluster" -n auto &
python=$!
status=0
stream realtime "$py" -m pytest tests/python -q -m "realtime and not alone" || status=$?
wait "$rust" || status=$?
wait "$python" || status=$?
for stream in rust python realtime; do
    echo "=== $stream"
    cat "$logs/$stream"
done
# The realtime test that must run by itself (tests/python/conftest.py, `alone`).
echo "=== alone"
alone=0
stream alone "$py" -m pytest tests/python -q -m alone || alone=$?
cat "$logs/alone"
# Once more when, and only when, its twin was never discovered: that failure (no sample in the
# whole 25 s allowance) came back once in ten runs by itself (session 53's ci29), its cause not
# found (docs/testing.md); the test is about the rate and memory under flooding peers, and a
# failure of those, or a second discovery failure, fails the run.
if [ "$alone" -ne 0 ] && grep -q "no /PSM1/measured_js within" "$logs/alone"; then
    echo "=== alone, once more: its twin was not discovered (the known discovery failure above)"
    alone=0
    stream alone_again "$py" -m pytest tests/python -q -m alone || alone=$?
    cat "$logs/alone_again"
fi
[ "$alone" -eq 0 ] || status=$alone
# On two cores the run is as fast as its CPU time allows when the CPU is near twice the wall time.
times > "$logs/times"
echo "(everything: $SECONDS s, CPU $(cpu_of "$logs/times") s)"
# `--ray`: also the two-node Ray cluster sweep (tests/python/test_sweep.py, two minutes).
if [ "$status" -eq 0 ] && [ "${1:-}" = "--ray" ]; then
    "$py" -m pytest tests/python -q -m ray_cluster || status=$?
fi
exit "$status"
