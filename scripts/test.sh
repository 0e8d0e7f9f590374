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

# Build first: every crate's tests (release: the simulation tests are heavy). `--workspace` puts
# the Python binding, which has no Rust tests, into the feature resolution, so that the wheel's
# build below reuses every dependency compiled here (see crates/dvrk-py/Cargo.toml).
cargo test --release --workspace --no-run

# The Python package: the wheel built as a user would, installed.
rm -rf target/wheels
"$venv/bin/maturin" build --release --quiet -m crates/dvrk-py/Cargo.toml -o target/wheels
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps target/wheels/*.whl

# Then two streams side by side. The tests with wall-clock assertions (marked `realtime`,
# tests/python/conftest.py) one at a time at normal priority; they mostly wait on the wall
# clock. The rest at the lowest CPU priority (nice 19: the scheduler gives it a weight of 15
# against their 1024, so a realtime test's twin gets a core the moment it wakes): the Rust tests,
# with the venv first on PATH so tests that write fixtures with Python's mcap packages find them,
# then the other Python tests on as many workers as there are cores (pytest-xdist). The rest's
# output is printed when both are done.
export DVRK_BIN="$PWD/target/release/dvrk"
rest_log="$(mktemp)"
trap 'rm -f "$rest_log"' EXIT
(
    PATH="$venv/bin:$PATH" nice -n 19 cargo test --release --workspace \
        && nice -n 19 "$py" -m pytest tests/python -q -m "not realtime and not ray_cluster" -n auto
) > "$rest_log" 2>&1 &
rest=$!
status=0
"$py" -m pytest tests/python -q -m realtime || status=$?
wait "$rest" || status=$?
cat "$rest_log"
# `--ray`: also the two-node Ray cluster sweep (tests/python/test_sweep.py, two minutes).
if [ "$status" -eq 0 ] && [ "${1:-}" = "--ray" ]; then
    "$py" -m pytest tests/python -q -m ray_cluster || status=$?
fi
exit "$status"
