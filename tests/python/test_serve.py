"""`dvrk serve` read and driven by an independent DDS peer: Eclipse Cyclone DDS (the PyPI
package `cyclonedds`), the middleware of most ROS 2 installations, speaking to our RustDDS node
with the ROS 2 type names and the dVRK's QoS. Loopback only, on a domain of the test's own."""

import json
import os
import pathlib
import signal
import subprocess
import time
from dataclasses import dataclass

import pytest

# Loopback only, no multicast: nothing leaves the machine (set before cyclonedds loads).
os.environ["CYCLONEDDS_URI"] = (
    '<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any"><General><Interfaces>'
    '<NetworkInterface address="127.0.0.1" multicast="false"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General></Domain></CycloneDDS>"
)
cyclonedds = pytest.importorskip("cyclonedds")
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl.types import float64, int32, sequence, uint8, uint32  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.qos import Policy, Qos  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]


@dataclass
class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time_
    frame_id: str


@dataclass
class JointState_(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header_
    name: sequence[str]
    position: sequence[float64]
    velocity: sequence[float64]
    effort: sequence[float64]


@dataclass
class Log_(IdlStruct, typename="rcl_interfaces::msg::dds_::Log_"):
    stamp: Time_
    level: uint8
    name: str
    msg: str
    file: str
    function: str
    line: uint32


# The dVRK's QoS: reliable, volatile, keep last 10.
QOS = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile, Policy.History.KeepLast(10))
PSM_JOINTS = ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"]


def dvrk_binary():
    path = os.environ.get("DVRK_BIN") or str(ROOT / "target" / "release" / "dvrk")
    if not pathlib.Path(path).exists():
        pytest.skip(f"no dvrk binary at {path} (cargo build --release, or set DVRK_BIN)")
    return path


def unique_domain(offset):
    """A domain of this test run's own (RustDDS announces to 12 participant slots per domain)."""
    return 100 + (os.getpid() * 7 + offset) % 120


class Peer:
    """A Cyclone DDS participant on the twin's topics."""

    def __init__(self, domain):
        self.dp = DomainParticipant(domain)
        self.readers = {}
        self.writers = {}

    def reader(self, topic, cls=JointState_, qos=QOS):
        self.readers[topic] = DataReader(self.dp, Topic(self.dp, "rt" + topic, cls), qos=qos)
        return self.readers[topic]

    def writer(self, topic):
        self.writers[topic] = DataWriter(self.dp, Topic(self.dp, "rt" + topic, JointState_), qos=QOS)
        return self.writers[topic]

    def take(self, topic):
        """Every JointState waiting on `topic`, with its arrival time."""
        now = time.time()
        return [(now, s) for s in self.readers[topic].take(N=1000) if isinstance(s, JointState_)]


def command(names, position=(), effort=()):
    return JointState_(Header_(Time_(0, 0), ""), list(names), list(position), [], list(effort))


def serve(domain, seconds, *extra):
    return subprocess.Popen(
        [dvrk_binary(), "serve", "--scene", "psm", "--domain", str(domain), "--duration", str(seconds), "--json", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(proc):
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    return json.loads(out), err


def first_sample(peer, topic, timeout=10):
    deadline = time.time() + timeout
    while time.time() < deadline:
        got = peer.take(topic)
        if got:
            return got[-1]
        time.sleep(0.002)
    raise AssertionError(f"no {topic} within {timeout} s")


@pytest.mark.parametrize("rate", [200, 1000])
def test_measured_js_arrives_at_the_configured_rate(rate):
    domain = unique_domain(rate)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    proc = serve(domain, 13, "--rate", str(rate))
    try:
        _, first = first_sample(peer, "/PSM1/measured_js")
        assert list(first.name) == PSM_JOINTS
        # Stamped with the wall clock, as the dVRK stamps its messages.
        assert abs(first.header.stamp.sec + first.header.stamp.nanosec * 1e-9 - time.time()) < 1.0
        time.sleep(0.5)
        peer.take("/PSM1/measured_js")
        start, count = time.time(), 0
        while time.time() - start < 10.0:
            count += len(peer.take("/PSM1/measured_js"))
            time.sleep(0.002)
        measured = count / (time.time() - start)
        print(f"measured_js at {measured:.1f} Hz for --rate {rate}")
        assert abs(measured - rate) < 0.05 * rate, (measured, rate)
    finally:
        summary, _ = finish(proc)
    assert summary["finite"] and summary["refused"] == 0
    print(f"worst lag {summary['worst_lag'] * 1e3:.2f} ms over {summary['simulated']:.1f} s")


def test_servo_jp_moves_the_arm_and_the_latency_is_measured():
    domain = unique_domain(1)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    peer.reader("/PSM1/setpoint_js")
    servo = peer.writer("/PSM1/servo_jp")
    proc = serve(domain, 6)
    try:
        _, now = first_sample(peer, "/PSM1/measured_js")
        time.sleep(1.0)
        _, now = first_sample(peer, "/PSM1/measured_js")
        start = list(now.position)
        target = list(start)
        target[0] += 0.1  # a 0.1 rad yaw step
        peer.take("/PSM1/setpoint_js")
        sent = time.time()
        servo.write(command(PSM_JOINTS, target))
        seen_setpoint, moved, trace = None, None, []
        while time.time() - sent < 2.5:
            for arrived, s in peer.take("/PSM1/setpoint_js"):
                if seen_setpoint is None and abs(s.position[0] - target[0]) < 1e-12:
                    seen_setpoint = arrived - sent
            for arrived, s in peer.take("/PSM1/measured_js"):
                trace.append((arrived - sent, s.position[0]))
                if moved is None and s.position[0] - start[0] > 0.001:
                    moved = arrived - sent
            time.sleep(0.001)
        print(f"command to setpoint_js {seen_setpoint * 1e3:.1f} ms, to 1% of the step in measured_js {moved * 1e3:.1f} ms")
        assert seen_setpoint is not None and seen_setpoint < 0.1
        assert moved is not None and moved < 0.2
        # The arm follows: within 10% of the step after 2 s (the PID of Table 8).
        final = trace[-1][1]
        assert abs(final - target[0]) < 0.01, (start[0], target[0], final)
    finally:
        summary, _ = finish(proc)
    assert summary["commands"] == 1 and summary["refused"] == 0


def test_bad_commands_are_refused_with_a_log_line_and_the_twin_keeps_running():
    domain = unique_domain(2)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    rosout = peer.reader("/rosout", Log_, Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.TransientLocal, Policy.History.KeepLast(100)))
    servo = peer.writer("/PSM1/servo_jp")
    jaw = peer.writer("/PSM1/jaw/servo_jp")
    proc = serve(domain, 4)
    try:
        first_sample(peer, "/PSM1/measured_js")
        time.sleep(0.3)
        servo.write(command(PSM_JOINTS[:5], [0.0] * 5))  # wrong length
        servo.write(command(PSM_JOINTS, [0.0, float("nan"), 0.1, 0.0, 0.0, 0.0]))  # NaN
        servo.write(command(["outer_yaw", "elbow", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"], [0.0] * 6))
        jaw.write(command(["jaw"], [0.3]))  # a good one
        time.sleep(0.5)
        peer.take("/PSM1/measured_js")
        time.sleep(0.3)
        assert peer.take("/PSM1/measured_js"), "the twin stopped publishing"
        logs = [s for s in rosout.take(N=100) if isinstance(s, Log_)]
    finally:
        summary, err = finish(proc)
    assert (summary["refused"], summary["commands"]) == (3, 1), summary
    lines = [l for l in err.splitlines() if "command refused" in l]
    assert len(lines) == 3, err
    assert any("5 position values for 6 joints" in l for l in lines)
    assert any("NaN for joint `outer_pitch`" in l for l in lines)
    assert any("unknown joint `elbow`" in l for l in lines)
    warned = [l for l in logs if l.level == 30 and "command refused" in l.msg]
    assert len(warned) == 3 and all(l.name == "dvrk_twin" for l in warned), logs


def test_ctrl_c_stops_the_twin_and_leaves_no_process():
    domain = unique_domain(3)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    proc = subprocess.Popen([dvrk_binary(), "serve", "--scene", "psm", "--domain", str(domain)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first_sample(peer, "/PSM1/measured_js")
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "served" in out and proc.poll() is not None
