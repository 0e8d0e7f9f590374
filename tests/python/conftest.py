"""pytest settings shared by the package's tests.

``realtime``: a test whose assertions are about wall-clock behaviour (a twin's publishing rate,
the live view's real-time factor under clients). `scripts/test.sh` runs the other tests on
several workers (pytest-xdist) and these alone, one at a time, so that no other test's CPU load
sits in their measurements.

``ray_cluster``: the two-node Ray cluster sweep (two minutes); not in `scripts/test.sh`'s default
run: `scripts/test.sh --ray` adds it (or `pytest tests/python -m ray_cluster`). One small Ray
sweep stays in the default run.
"""


def pytest_configure(config):
    config.addinivalue_line("markers", "realtime: wall-clock assertions; run alone, not beside other tests")
    config.addinivalue_line("markers", "ray_cluster: a two-node Ray cluster sweep; run by `scripts/test.sh --ray`")
