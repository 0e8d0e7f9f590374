"""pytest settings shared by the package's tests.

``realtime``: a test whose assertions are about wall-clock behaviour (a twin's publishing rate,
the live view's real-time factor under clients). `scripts/test.sh` runs these one at a time at
normal priority, beside the other tests (the Rust tests, then the other Python tests on several
pytest-xdist workers) at the lowest CPU priority (nice 19), so that no other test's CPU load sits
in their measurements.

``ray_cluster``: the two-node Ray cluster sweep (two minutes); not in `scripts/test.sh`'s default
run: `scripts/test.sh --ray` adds it (or `pytest tests/python -m ray_cluster`). One small Ray
sweep stays in the default run.
"""


def pytest_configure(config):
    config.addinivalue_line("markers", "realtime: wall-clock assertions; run one at a time, others only at nice 19 beside them")
    config.addinivalue_line("markers", "ray_cluster: a two-node Ray cluster sweep; run by `scripts/test.sh --ray`")
