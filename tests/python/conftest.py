"""pytest settings shared by the package's tests.

``realtime``: a test whose assertions are about wall-clock behaviour (a twin's publishing rate,
the live view's real-time factor under clients). `scripts/test.sh` runs these one at a time at
normal priority, beside the other tests (the Rust tests and the other Python tests on several
pytest-xdist workers) at the lowest CPU priority (nice 19), so that the others' CPU load does not
sit in their measurements: the scheduler gives a realtime test's twin a core the moment it wakes.

``ray_cluster``: the two-node Ray cluster sweep (two minutes); not in `scripts/test.sh`'s default
run: `scripts/test.sh --ray` adds it (or `pytest tests/python -m ray_cluster`). One small Ray
sweep stays in the default run.
"""


def pytest_configure(config):
    config.addinivalue_line("markers", "realtime: wall-clock assertions; run one at a time, at a higher CPU priority than any other test")
    config.addinivalue_line("markers", "ray_cluster: a two-node Ray cluster sweep; run by `scripts/test.sh --ray`")
