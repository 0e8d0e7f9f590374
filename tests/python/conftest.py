"""pytest settings shared by the package's tests.

``realtime``: a test whose assertions are about wall-clock behaviour (a twin's publishing rate,
the live view's real-time factor under clients). `scripts/test.sh` runs these one at a time at
normal priority, beside the other tests (the Rust tests and the other Python tests on several
pytest-xdist workers) at the lowest CPU priority (nice 19), so that the others' CPU load does not
sit in their measurements: the scheduler gives a realtime test's twin a core the moment it wakes.

``alone``: a realtime test run by itself once the streams have ended. The two flooding peers'
test (three Cyclone DDS participants created before its twin) lost the twin's discovery for its
whole 25 s allowance in 3 of 7 clean-clone runs beside the other streams (on domains 100-219 and
1-101 alike), and by itself in 1 of about 12 (session 53); the cause is not found (see
docs/testing.md). `scripts/test.sh` runs it once more when, and only when, that discovery failed.

``ray_cluster``: the two-node Ray cluster sweep (two minutes); not in `scripts/test.sh`'s default
run: `scripts/test.sh --ray` adds it (or `pytest tests/python -m ray_cluster`). One small Ray
sweep stays in the default run.
"""


def pytest_configure(config):
    config.addinivalue_line("markers", "realtime: wall-clock assertions; run one at a time, at a higher CPU priority than any other test")
    config.addinivalue_line("markers", "alone: a realtime test run by itself after the other tests (scripts/test.sh)")
    config.addinivalue_line("markers", "ray_cluster: a two-node Ray cluster sweep; run by `scripts/test.sh --ray`")
