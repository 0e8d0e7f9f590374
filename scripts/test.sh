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

# Rust: every crate's tests (release: the simulation tests are heavy). `--workspace` puts the
# Python binding, which has no Rust tests, into the feature resolution, so that the wheel's build
# below reuses every dependency compiled here (see crates/dvrk-py/Cargo.toml). The venv comes
# first on PATH so tests that write fixtures with Python's mcap packages find them.
PATH="$venv/bin:$PATH" cargo test --release --workspace

# Python: build the wheel as a user would, install it, test it.
rm -rf target/wheels
"$venv/bin/maturin" build --release --quiet -m crates/dvrk-py/Cargo.toml -o target/wheels
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps target/wheels/*.whl
# Two passes: the tests on as many workers as there are cores (pytest-xdist), then those with
# wall-clock assertions (marked `realtime`, tests/python/conftest.py) alone, one at a time.
DVRK_BIN="$PWD/target/release/dvrk" "$py" -m pytest tests/python -q -m "not realtime and not ray_cluster" -n auto
DVRK_BIN="$PWD/target/release/dvrk" "$py" -m pytest tests/python -q -m realtime
# `--ray`: also the two-node Ray cluster sweep (tests/python/test_sweep.py, two minutes).
if [ "${1:-}" = "--ray" ]; then
    "$py" -m pytest tests/python -q -m ray_cluster
fi
