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
pytestmark = pytest.mark.realtime  # see conftest.py
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl.types import float32, float64, int32, sequence, uint8, uint32  # noqa: E402
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


@dataclass
class StringStamped_(IdlStruct, typename="crtk_msgs::msg::dds_::StringStamped_"):
    header: Header_
    string: str


@dataclass
class OperatingState_(IdlStruct, typename="crtk_msgs::msg::dds_::OperatingState_"):
    header: Header_
    state: str
    is_homed: bool
    is_busy: bool


@dataclass
class Vector3_(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Point_(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion_(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Pose_(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point_
    orientation: Quaternion_


@dataclass
class PoseStamped_(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header_
    pose: Pose_


@dataclass
class Twist_(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3_
    angular: Vector3_


@dataclass
class TwistStamped_(IdlStruct, typename="geometry_msgs::msg::dds_::TwistStamped_"):
    header: Header_
    twist: Twist_


@dataclass
class Joy_(IdlStruct, typename="sensor_msgs::msg::dds_::Joy_"):
    header: Header_
    axes: sequence[float32]
    buttons: sequence[int32]


@dataclass
class String_(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str


# The dVRK's QoS: reliable, volatile, keep last 10.
QOS = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile, Policy.History.KeepLast(10))
# A counting reader keeps every sample, so a count measures what the twin published, not how
# often a busy test loop (or a loaded CI machine) came round to drain a 10-deep history.
COUNT = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile, Policy.History.KeepLast(100000))
PSM_JOINTS = ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"]


def dvrk_binary():
    path = os.environ.get("DVRK_BIN") or str(ROOT / "target" / "release" / "dvrk")
    if not pathlib.Path(path).exists():
        pytest.skip(f"no dvrk binary at {path} (cargo build --release, or set DVRK_BIN)")
    return path


def unique_domain(offset):
    """A domain of this test run's own (RustDDS announces to 12 participant slots per domain),
    in 1..101: a domain's RTPS ports are 7400 + 250 domain + 0..33, so above 101 they fall in
    Linux's ephemeral range (32768 and up), where any socket the other tests open beside these
    may take one (ROS 2's advice for Linux is domains 0..101 for that reason). Not 0, ROS's own."""
    return 1 + (os.getpid() * 7 + offset) % 101


class Peer:
    """A Cyclone DDS participant on the twin's topics."""

    def __init__(self, domain):
        self.domain = domain
        self.dp = DomainParticipant(domain)
        self.readers = {}
        self.writers = {}

    def reader(self, topic, cls=JointState_, qos=QOS):
        self.readers[topic] = DataReader(self.dp, Topic(self.dp, "rt" + topic, cls), qos=qos)
        return self.readers[topic]

    def writer(self, topic, cls=JointState_):
        self.writers[topic] = DataWriter(self.dp, Topic(self.dp, "rt" + topic, cls), qos=QOS)
        return self.writers[topic]

    def take(self, topic, cls=JointState_):
        """Every message waiting on `topic`, with its arrival time."""
        now = time.time()
        return [(now, s) for s in self.readers[topic].take(N=1000) if isinstance(s, cls)]


def command(names, position=(), effort=(), velocity=()):
    return JointState_(Header_(Time_(0, 0), ""), list(names), list(position), list(velocity), list(effort))


# How long a twin may take to be discovered. RustDDS announces a new participant 100 ms after it
# starts and then every 10 s; peers created before the twin learn of it from that announcement,
# so one lost announcement (a loaded machine, the suite's other tests beside these) costs 10 s.
# Two periods and some room: a test that waits for the twin's first sample waits this long, and
# a twin it stops itself (`finish`) runs this much longer than the test needs.
DISCOVERY_S = 25


def serve(domain, seconds, *extra, stopped=True):
    """`dvrk serve` on the PSM scene for at most `seconds`, plus the discovery allowance when the
    test stops it (`stopped`: `finish(proc)`); a test that waits for its end gets `seconds`."""
    duration = seconds + DISCOVERY_S if stopped else seconds
    return subprocess.Popen(
        [dvrk_binary(), "serve", "--scene", "psm", "--domain", str(domain), "--duration", str(duration), "--json", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(proc, stop=True):
    """The twin's summary and stderr. `stop`: end it now, as Ctrl-C does (a test's --duration is
    an upper bound; a stopped twin prints the same summary), not at the end of its duration."""
    if stop and proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    return json.loads(out), err


def first_sample(peer, topic, cls=JointState_, timeout=DISCOVERY_S):
    deadline = time.time() + timeout
    while time.time() < deadline:
        got = peer.take(topic, cls)
        if got:
            return got[-1]
        time.sleep(0.002)
    raise AssertionError(f"no {topic} within {timeout} s on domain {peer.domain}")


def say(writer, text):
    """A state_command."""
    writer.write(StringStamped_(Header_(Time_(0, 0), ""), text))


def wait_for(peer, topic, cls, matches, what, timeout=2.0):
    """Wait until a message on `topic` satisfies `matches`."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        if any(matches(s) for _, s in peer.take(topic, cls)):
            return
        time.sleep(0.005)
    raise AssertionError(f"{topic} never said {what}")


@pytest.mark.parametrize("rate", [200, 1000])
def test_measured_js_arrives_at_the_configured_rate(rate):
    domain = unique_domain(rate)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    # 5 s of counting: 1,000 messages at 200 Hz resolve the rate to 0.1%, well inside the 5%
    # asked (a twin publishing at 0.9 of --rate fails it: issue #60's check of this window).
    proc = serve(domain, 8, "--rate", str(rate))
    try:
        _, first = first_sample(peer, "/PSM1/measured_js")
        assert list(first.name) == PSM_JOINTS
        # Stamped with the wall clock, as the dVRK stamps its messages.
        assert abs(first.header.stamp.sec + first.header.stamp.nanosec * 1e-9 - time.time()) < 1.0
        time.sleep(0.5)
        peer.take("/PSM1/measured_js")
        start, count = time.time(), 0
        while time.time() - start < 5.0:
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
    move = peer.writer("/PSM1/move_jp")
    effort = peer.writer("/PSM1/servo_jf")
    proc = serve(domain, 5)
    try:
        first_sample(peer, "/PSM1/measured_js")
        time.sleep(0.3)
        move.write(command(PSM_JOINTS, [3.0, 0.0, 0.1, 0.0, 0.0, 0.0]))  # the yaw's limit is 1.6 rad
        servo.write(command(PSM_JOINTS[:5], [0.0] * 5))  # wrong length
        servo.write(command(PSM_JOINTS, [0.0, float("nan"), 0.1, 0.0, 0.0, 0.0]))  # NaN
        servo.write(command(["outer_yaw", "elbow", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"], [0.0] * 6))
        # A finite but absurd feed-forward velocity (it drove every joint to its limit).
        servo.write(command(PSM_JOINTS, [0.0, 0.0, 0.1, 0.0, 0.0, 0.0], velocity=[0.0, 1e308, 0.0, 0.0, 0.0, 0.0]))
        jaw.write(command(["jaw"], [0.3]))  # a good one
        # An absurd effort (the roll's limit is 0.33 N·m): a client's bug, not a command. A
        # second later: the log shows at most five refusals a second, one by one.
        time.sleep(1.2)
        effort.write(command(PSM_JOINTS, effort=[0.0, 0.0, 0.0, 1e308, 0.0, 0.0]))
        time.sleep(0.5)
        peer.take("/PSM1/measured_js")
        time.sleep(0.3)
        assert peer.take("/PSM1/measured_js"), "the twin stopped publishing"
        logs = [s for s in rosout.take(N=100) if isinstance(s, Log_)]
    finally:
        summary, err = finish(proc)
    assert (summary["refused"], summary["commands"]) == (6, 1), summary
    lines = [l for l in err.splitlines() if "command refused" in l]
    assert len(lines) == 6, err
    assert any("goal 3 rad for joint `outer_yaw` is outside its limits" in l for l in lines), lines
    assert any("5 position values for 6 joints" in l for l in lines)
    assert any("NaN for joint `outer_pitch`" in l for l in lines)
    assert any("unknown joint `elbow`" in l for l in lines)
    assert any("velocity 1.000000e308 rad/s for joint `outer_pitch` is past 31.416 rad/s" in l for l in lines), lines
    assert any("effort 1.000000e308 N·m for joint `outer_roll` is past 3.300 N·m" in l for l in lines), lines
    warned = [l for l in logs if l.level == 30 and "command refused" in l.msg]
    assert len(warned) == 6 and all(l.name == "dvrk_twin" for l in warned), logs


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


def test_a_servo_jp_step_responds_as_the_simulator_does_for_the_same_command(tmp_path):
    """The twin's recorded step response against `dvrk_twin.Sim` (the simulator `dvrk sim`
    runs) given the same command at the same step: the twin adds transport, not physics."""
    import numpy as np
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    dvrk_twin = pytest.importorskip("dvrk_twin")
    domain = unique_domain(4)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    servo = peer.writer("/PSM1/servo_jp")
    out = tmp_path / "twin.mcap"
    proc = serve(domain, 3, "--rate", "1000", "--out", str(out), stopped=False)
    step = 0.1
    try:
        first_sample(peer, "/PSM1/measured_js")
        time.sleep(0.8)
        _, now = first_sample(peer, "/PSM1/measured_js")
        target = list(now.position)
        target[0] += step
        servo.write(command(PSM_JOINTS, target))
    finally:
        summary, _ = finish(proc, stop=False)
    assert summary["commands"] == 1
    setpoint, measured = [], []
    with open(out, "rb") as f:
        for _, channel, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=["/PSM1/setpoint_js", "/PSM1/measured_js"]):
            (setpoint if channel.topic == "/PSM1/setpoint_js" else measured).append(list(msg.position))
    setpoint, measured = np.array(setpoint), np.array(measured)
    assert len(measured) == 3000  # one sample per 1 ms step
    # Sample j follows step j + 1; the first with the new target says the command went in
    # before step j + 1, after j steps holding the start.
    j = int(np.argmax(np.abs(setpoint[:, 0] - target[0]) < 1e-12))
    assert j > 100 and abs(setpoint[j - 1, 0] - target[0]) > 0.05
    sim = dvrk_twin.Sim.from_scene("psm", engine="reduced")
    q0 = sim.q.copy()
    for i in range(len(q0)):
        sim.set_target(i, q0[i], 0.0)
    sim.step(j)
    arm = [sim.joint_names.index(f"PSM1/{n}") for n in PSM_JOINTS]
    for i, k in enumerate(arm):
        sim.set_target(k, target[i], 0.0)
    expected = []
    for _ in range(len(measured) - j):
        sim.step()
        expected.append(sim.q[arm[0]])
    twin = measured[j:, 0]
    rms = float(np.sqrt(np.mean((twin - np.array(expected)) ** 2)))
    print(f"step response: RMS difference {rms:.3e} rad over {len(twin)} ms ({rms / step:.2e} of the step); final {twin[-1]:.5f} vs {expected[-1]:.5f}")
    assert rms < 0.01 * step


def test_python_serves_the_twin_and_returns_its_summary():
    import threading

    dvrk_twin = pytest.importorskip("dvrk_twin")
    domain = unique_domain(5)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    result = {}
    worker = threading.Thread(target=lambda: result.update(dvrk_twin.serve("psm", domain=domain, duration=2.0)))
    worker.start()
    try:
        _, first = first_sample(peer, "/PSM1/measured_js")
        assert list(first.name) == PSM_JOINTS
    finally:
        worker.join(timeout=30)
    assert not worker.is_alive()
    assert result["steps"] == 2000 and result["finite"] and result["samples"] == 400, result
    with pytest.raises(dvrk_twin.InputError, match="domain"):
        dvrk_twin.serve("psm", domain=500, duration=0.1)


def stamp(msg):
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_state_commands_servo_jr_and_measured_cv():
    import numpy as np

    domain = unique_domain(6)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    peer.reader("/PSM1/setpoint_js")
    peer.reader("/PSM1/operating_state", OperatingState_)
    peer.reader("/PSM1/measured_cp", PoseStamped_)
    peer.reader("/PSM1/measured_cv", TwistStamped_)
    state = peer.writer("/PSM1/state_command", StringStamped_)
    servo = peer.writer("/PSM1/servo_jp")
    relative = peer.writer("/PSM1/servo_jr")
    proc = serve(domain, 7)

    def wait_state(want):
        wait_for(peer, "/PSM1/operating_state", OperatingState_, lambda s: (s.state, s.is_homed) == want, want)

    try:
        wait_state(("ENABLED", True))  # repeated every second for late joiners
        say(state, "disable")
        wait_state(("DISABLED", True))
        time.sleep(0.1)
        servo.write(command(PSM_JOINTS, [0.0] * 6))  # refused: disabled
        say(state, "home")  # refused: disabled
        time.sleep(0.2)
        say(state, "enable")
        wait_state(("ENABLED", True))
        say(state, "unhome")
        wait_state(("ENABLED", False))
        say(state, "home")
        wait_state(("ENABLED", True))
        say(state, "dance")  # refused: unknown
        time.sleep(0.3)
        # servo_jr: 0.05 rad more yaw than the setpoint holds now.
        _, sp = first_sample(peer, "/PSM1/setpoint_js")
        before = sp.position[0]
        relative.write(command(PSM_JOINTS, [0.05, 0, 0, 0, 0, 0]))
        deadline, after = time.time() + 1.0, None
        while time.time() < deadline and after is None:
            for _, s in peer.take("/PSM1/setpoint_js"):
                if abs(s.position[0] - before - 0.05) < 1e-9:
                    after = s.position[0]
            time.sleep(0.002)
        assert after is not None, "servo_jr did not move the setpoint by 0.05 rad"
        # measured_cv against the derivative of measured_cp while the yaw swings.
        time.sleep(0.3)
        peer.take("/PSM1/measured_cp", PoseStamped_)
        peer.take("/PSM1/measured_cv", TwistStamped_)
        servo.write(command(PSM_JOINTS, [after - 0.3, 0, 0.1, 0, 0, 0]))
        cp, cv = {}, {}
        start = time.time()
        while time.time() - start < 1.0:
            for _, m in peer.take("/PSM1/measured_cp", PoseStamped_):
                cp[round(stamp(m), 4)] = np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z])
            for _, m in peer.take("/PSM1/measured_cv", TwistStamped_):
                cv[round(stamp(m), 4)] = np.array([m.twist.linear.x, m.twist.linear.y, m.twist.linear.z])
                assert m.header.frame_id == "PSM1_base"
            time.sleep(0.002)
        times = sorted(set(cp) & set(cv))
        errors, speeds = [], []
        for a, b, c in zip(times, times[1:], times[2:]):
            if c - a > 0.011:
                continue
            fd = (cp[c] - cp[a]) / (c - a)
            errors.append(np.linalg.norm(fd - cv[b]))
            speeds.append(np.linalg.norm(cv[b]))
        assert len(errors) > 100
        print(f"measured_cv vs the derivative of measured_cp: peak speed {max(speeds):.3f} m/s, RMS difference {np.sqrt(np.mean(np.square(errors))):.4f} m/s")
        assert max(speeds) > 0.05
        assert np.sqrt(np.mean(np.square(errors))) < 0.05 * max(speeds)
    finally:
        summary, err = finish(proc)
    refused = [l for l in err.splitlines() if "command refused" in l]
    assert len(refused) == 3, err
    assert any("the arm is DISABLED" in l for l in refused) and any("home: the arm is DISABLED" in l for l in refused)
    assert any("unknown state command `dance`" in l for l in refused)


def test_servo_jf_on_a_gravity_compensated_arm_moves_it_as_the_simulator_predicts(tmp_path):
    """Efforts (servo_jf) with the dVRK's gravity compensation: the arm's joints leave PID, the
    gravity torque holds them up and 0.3 N·m turns the yaw. The twin's recorded motion against
    `dvrk_twin.Sim` given the same efforts at the same step, on the same scene."""
    import numpy as np
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    dvrk_twin = pytest.importorskip("dvrk_twin")
    scene = tmp_path / "psm-gc.toml"
    text = (ROOT / "models" / "scenes" / "psm.toml").read_text()
    scene.write_text(text.replace('name = "PSM1"\n', 'name = "PSM1"\ngravity_compensation = true\n'))
    domain = unique_domain(7)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    effort = peer.writer("/PSM1/servo_jf")
    out = tmp_path / "twin.mcap"
    proc = subprocess.Popen(
        [dvrk_binary(), "serve", "--scene", str(scene), "--domain", str(domain), "--duration", "3", "--rate", "1000", "--out", str(out), "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    push = [0.3, 0.0, 0.0, 0.0, 0.0, 0.0]
    try:
        first_sample(peer, "/PSM1/measured_js")
        time.sleep(0.8)
        effort.write(command(PSM_JOINTS, effort=push))
    finally:
        summary, _ = finish(proc, stop=False)
    assert summary["commands"] == 1
    measured, applied = [], []
    with open(out, "rb") as f:
        for _, _, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=["/PSM1/measured_js"]):
            measured.append(list(msg.position))
            applied.append(list(msg.effort))
    measured, applied = np.array(measured), np.array(applied)
    # Sample j is the first with the push in the yaw's applied effort: it went in before step j + 1.
    j = int(np.argmax(np.diff(applied[:, 0]) > 0.25)) + 1
    assert 300 < j < 2900, j
    sim = dvrk_twin.Sim.from_scene(str(scene), engine="reduced")
    q0 = sim.q.copy()
    for i in range(len(q0)):
        sim.set_target(i, q0[i], 0.0)
    sim.step(j)
    arm = [sim.joint_names.index(f"PSM1/{n}") for n in PSM_JOINTS]
    for k, e in zip(arm, push):
        sim.set_mode(k, "effort")
        sim.set_effort(k, e)
    expected = []
    for _ in range(len(measured) - j):
        sim.step()
        expected.append([sim.q[k] for k in arm])
    twin = measured[j:, :6]
    expected = np.array(expected)
    moved = twin[-1, 0] - twin[0, 0]
    others = np.abs(twin[:, 1:3] - twin[0, 1:3]).max()
    rms = float(np.sqrt(np.mean((twin - expected) ** 2)))
    print(f"servo_jf: yaw turned {moved:.4f} rad in {len(twin) / 1000:.2f} s under 0.3 N·m, pitch and insertion moved at most {others:.2e}; RMS difference from the simulator {rms:.3e}")
    assert moved > 0.05
    assert rms < 0.01 * abs(moved)


def test_one_pacing_loop_feeds_ros2_and_the_foxglove_view_together():
    import asyncio

    test_live = pytest.importorskip("test_live")
    domain = unique_domain(8)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js")
    port = test_live.free_port()
    proc = serve(domain, 4, "--live", f"127.0.0.1:{port}")
    try:
        _, ros = first_sample(peer, "/PSM1/measured_js")
        channel, data = asyncio.run(test_live.first_message(port, "/PSM1/measured_js"))
        assert channel["schemaName"] == "sensor_msgs/msg/JointState"
        from rosbags.typesys import Stores, get_typestore

        fox = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(data, "sensor_msgs/msg/JointState")
        # The same messages on both: names, and wall-clock stamps within the run.
        assert list(fox.name) == list(ros.name) == PSM_JOINTS
        assert abs((fox.header.stamp.sec + fox.header.stamp.nanosec * 1e-9) - stamp(ros)) < 4.0
    finally:
        summary, _ = finish(proc)
    assert summary["finite"]


def test_move_jp_reaches_its_goal_under_the_consoles_limits_and_the_arm_is_busy_meanwhile():
    import numpy as np

    domain = unique_domain(9)
    peer = Peer(domain)
    peer.reader("/PSM1/setpoint_js")
    peer.reader("/PSM1/measured_js")
    peer.reader("/PSM1/operating_state", OperatingState_)
    move = peer.writer("/PSM1/move_jp")
    proc = serve(domain, 5)
    try:
        _, sp = first_sample(peer, "/PSM1/setpoint_js")
        time.sleep(0.3)
        _, sp = first_sample(peer, "/PSM1/setpoint_js")
        start = np.array(sp.position)
        goal = start + np.array([0.5, 0.0, 0.1, 0.0, 0.0, 0.0])
        peer.take("/PSM1/setpoint_js")
        sent = time.time()
        move.write(command(PSM_JOINTS, list(goal)))
        trace, busy = [], []
        while time.time() - sent < 2.5:
            for arrived, s in peer.take("/PSM1/setpoint_js"):
                trace.append((stamp(s), np.array(s.position)))
            for _, s in peer.take("/PSM1/operating_state", OperatingState_):
                busy.append((time.time() - sent, s.is_busy))
            time.sleep(0.002)
        _, measured = first_sample(peer, "/PSM1/measured_js")
    finally:
        summary, _ = finish(proc)
    t = np.array([x[0] for x in trace])
    q = np.array([x[1] for x in trace])
    moving = np.where(np.abs(q[:, 0] - start[0]) > 1e-9)[0]
    t0 = t[moving[0]] - 0.005
    arrived = t[np.argmax(np.abs(q[:, 0] - goal[0]) < 1e-9)]
    # 0.5 rad of yaw and 0.1 m of insertion under (180 deg/s, 180 deg/s^2) and (0.2 m/s, 0.2
    # m/s^2): the insertion sets the pace, a triangle of 2/sqrt(2) s.
    print(f"move_jp: {arrived - t0:.3f} s to the goal (closed form 1.414 s); busy flags {busy}")
    assert abs((arrived - t0) - 2 ** 0.5) < 0.02
    # A straight line in joint space: the insertion's progress equals the yaw's.
    progress = (q[moving, 0] - start[0]) / 0.5
    assert np.allclose((q[moving, 2] - start[2]) / 0.1, progress, atol=1e-9)
    # Velocity never above the limit, along the way (finite differences of the setpoints).
    speed = np.abs(np.diff(q[:, 2])) / np.maximum(np.diff(t), 1e-9)
    assert speed.max() < 0.2 * 1.05
    # Busy from the command until the arrival (the state is also repeated every second).
    changes = [(t, b) for k, (t, b) in enumerate(busy) if k == 0 or b != busy[k - 1][1]]
    assert [b for _, b in changes] == [True, False] and changes[0][0] < 0.1 and abs(changes[1][0] - 2 ** 0.5) < 0.1, busy
    # The arm follows its setpoint within the PID's tracking (Table 8 gains, no gravity
    # compensation: the yaw settles over seconds).
    assert abs(measured.position[0] - goal[0]) < 0.03
    assert summary["commands"] == 1


def test_servo_cp_moves_the_tip_through_the_ik_and_refuses_a_pose_out_of_reach():
    import numpy as np

    domain = unique_domain(10)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_cp", PoseStamped_)
    servo = peer.writer("/PSM1/servo_cp", PoseStamped_)
    proc = serve(domain, 4)

    def tip():
        deadline = time.time() + 5
        while time.time() < deadline:
            got = peer.take("/PSM1/measured_cp", PoseStamped_)
            if got:
                return got[-1][1]
            time.sleep(0.002)
        raise AssertionError("no measured_cp")

    try:
        tip()
        time.sleep(0.5)
        now = tip()
        assert now.header.frame_id == "PSM1_base"
        p = now.pose.position
        start = np.array([p.x, p.y, p.z])
        goal = start + np.array([0.01, 0.0, -0.005])  # 1 cm sideways, 5 mm deeper
        target = PoseStamped_(Header_(Time_(0, 0), "PSM1_base"), Pose_(Point_(*goal), now.pose.orientation))
        servo.write(target)
        time.sleep(1.5)
        p = tip().pose.position
        reached = np.array([p.x, p.y, p.z])
        far = PoseStamped_(Header_(Time_(0, 0), "PSM1_base"), Pose_(Point_(2.0, 0.0, 0.0), now.pose.orientation))
        servo.write(far)
        # Issue 63: a pose in another frame was read as if in the base frame. Now a frame the
        # twin does not know is refused, and so is the ECM's view in a scene without an ECM.
        for frame in ["camera", "ECM_view"]:
            servo.write(PoseStamped_(Header_(Time_(0, 0), frame), Pose_(Point_(*reached), now.pose.orientation)))
        time.sleep(0.3)
    finally:
        summary, err = finish(proc)
    print(f"servo_cp: tip {np.linalg.norm(reached - goal) * 1e3:.2f} mm from a goal 11.2 mm away, after 1.5 s")
    # The tip goes the way asked, within the PID's tracking (Table 8 gains, no gravity
    # compensation: millimetres).
    assert np.linalg.norm(reached - goal) < 0.003
    assert np.dot(reached - start, goal - start) / np.dot(goal - start, goal - start) > 0.8
    assert (summary["commands"], summary["refused"]) == (1, 3), summary
    assert any("/PSM1/servo_cp: command refused" in l for l in err.splitlines()), err
    assert any("frame `camera`" in l and "PSM1_base" in l and "ECM_view" in l for l in err.splitlines()), err
    assert any("frame `ECM_view`, but this scene has no arm named ECM" in l for l in err.splitlines()), err


def test_a_flood_of_refused_commands_with_stderr_unread_never_stalls_the_twin():
    """Issue #63: 10,000 refused commands over 10 s while the twin's stderr is a pipe nobody
    reads (as under a launcher). The refusals are rate-limited and written off the loop, so
    `measured_js` keeps its rate every second, a valid command afterwards goes straight in, and
    the run's summary counts every refusal. (Before, after some 64 KiB of warnings the loop
    blocked on stderr: `measured_js` fell to 0 Hz.)"""
    rate, flood, seconds = 200, 10_000, 10
    domain = unique_domain(11)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js", qos=COUNT)
    peer.reader("/PSM1/setpoint_js")
    servo = peer.writer("/PSM1/servo_jp")
    proc = serve(domain, 20, "--rate", str(rate), stopped=False)  # stderr=PIPE, not read until the run ends
    bad = command(PSM_JOINTS[:5], [0.0] * 5)  # 5 values for 6 joints
    try:
        first_sample(peer, "/PSM1/measured_js")
        time.sleep(0.5)
        peer.take("/PSM1/measured_js")
        start, sent, per_second, last, worst_gap = time.time(), 0, [0] * seconds, None, 0.0
        while True:
            now = time.time()
            if now - start >= seconds:
                break
            # 1,000 refused commands a second, evenly.
            due = min(flood, int((now - start) * flood / seconds) + 1)
            while sent < due:
                servo.write(bad)
                sent += 1
            for arrived, _ in peer.take("/PSM1/measured_js"):
                per_second[min(int(arrived - start), seconds - 1)] += 1
                worst_gap = max(worst_gap, arrived - (last or arrived))
                last = arrived
            time.sleep(0.001)
        worst_gap = max(worst_gap, time.time() - (last or start))
        while sent < flood:
            servo.write(bad)
            sent += 1
        print(f"measured_js per second under the flood: {per_second} (--rate {rate}); longest gap {worst_gap * 1e3:.1f} ms")
        # The figure: within 1% over the 10 s and every second (arrivals binned by a
        # peer that polls every millisecond; measured 200-201 every second).
        assert abs(sum(per_second) / seconds - rate) < 0.01 * rate, per_second
        assert all(abs(n - rate) <= 0.01 * rate for n in per_second), per_second
        # Valid commands afterwards reach setpoint_js at once.
        time.sleep(0.3)
        _, sp = first_sample(peer, "/PSM1/setpoint_js")
        latencies = []
        for k in range(5):
            target = list(sp.position)
            target[0] += 0.02 * (k + 1)
            peer.take("/PSM1/setpoint_js")
            written = time.time()
            servo.write(command(PSM_JOINTS, target))
            seen = None
            while seen is None and time.time() - written < 2.0:
                for arrived, s in peer.take("/PSM1/setpoint_js"):
                    if seen is None and abs(s.position[0] - target[0]) < 1e-12:
                        seen = arrived - written
                time.sleep(0.0005)
            assert seen is not None, f"valid servo_jp {k} never reached setpoint_js"
            latencies.append(seen)
            time.sleep(0.2)
        print(f"valid servo_jp after the flood: in setpoint_js after {', '.join(f'{x * 1e3:.1f}' for x in latencies)} ms (setpoint_js every {1e3 / rate:.0f} ms)")
        # The issue asks 10 ms (measured 0.7-4.3 ms: a sample every 5 ms plus delivery): the
        # median within it, and none past 50 ms on a loaded 2-core machine.
        assert sorted(latencies)[len(latencies) // 2] < 0.010 and max(latencies) < 0.05, latencies
    finally:
        summary, err = finish(proc, stop=False)
    lines = err.splitlines()
    refused_lines = [l for l in lines if "command refused" in l]
    summaries = [l for l in lines if "commands refused in the last" in l]
    print(f"summary: refused {summary['refused']} of {flood} sent, commands {summary['commands']}, stderr lines {len(lines)} ({len(refused_lines)} verbatim, {len(summaries)} summaries), stderr_dropped {summary.get('stderr_dropped')}, rosout_dropped {summary.get('rosout_dropped')}; worst lag {summary['worst_lag'] * 1e3:.2f} ms")
    assert summary["commands"] == 5
    # Every refusal counted (DDS may lose a few of a burst: keep last 10).
    assert flood * 0.99 <= summary["refused"] <= flood, summary
    assert summary["refusals_summarised"] > 0.9 * summary["refused"], summary
    # Rate-limited: a few lines a second verbatim, then one summary a second by topic and reason.
    assert len(refused_lines) < 10 * (seconds + 5), len(refused_lines)
    assert summaries and all("/PSM1/servo_jp (wrong length)" in l for l in summaries), summaries[:3]
    assert summary["stderr_dropped"] == 0, summary


def test_a_live_mtm_drives_the_twins_psm_through_the_follow_mode():
    """A console's MTM played by the peer at 200 Hz (`/MTMR/measured_cp`, its gripper, the clutch
    pedal: the moves of `teleop_script.SHORT`) into `dvrk serve --teleop MTMR`: at the end of
    each hold the PSM's setpoint_cp has moved 0.2 times the followed hand in PSM1_base, with the
    hand's orientation; the clutched hand motion is not followed; the jaw closes."""
    import numpy as np
    import teleop_script as ts

    domain = unique_domain(5)
    peer = Peer(domain)
    peer.reader("/PSM1/setpoint_cp", PoseStamped_)
    peer.reader("/PSM1/jaw/setpoint_js")
    pose_w = peer.writer("/MTMR/measured_cp", PoseStamped_)
    grip_w = peer.writer("/MTMR/gripper/measured_js")
    clutch_w = peer.writer("/footpedals/clutch", Joy_)
    proc = serve(domain, 12, "--teleop", "MTMR")

    def pose_of(m):
        p, o = m.pose.position, m.pose.orientation
        return np.array([p.x, p.y, p.z]), ts.matrix([o.x, o.y, o.z, o.w])

    checked = []
    try:
        _, first = first_sample(peer, "/PSM1/setpoint_cp", PoseStamped_)
        p0, r0 = pose_of(first)
        rows = ts.samples(np.array([0.0, 0.3, -0.2]), r0, ts.SHORT)
        ends = dict(zip([w[0] for w in ts.SHORT], np.cumsum([w[1] for w in ts.SHORT])))
        followed = np.zeros(3)
        pressed = None
        start = time.time()
        for i, (t, p, r, g, clutch, name) in enumerate(rows):
            while time.time() - start < t:
                time.sleep(0.0005)
            if i > 0 and not clutch and not rows[i - 1][4]:
                followed = followed + (p - rows[i - 1][1])
            x, y, z, w = ts.quat(r)
            header = Header_(Time_(0, 0), "MTMR_base")
            if clutch != pressed:
                clutch_w.write(Joy_(header, [], [1 if clutch else 0]))
                pressed = clutch
            grip_w.write(JointState_(header, ["gripper"], [g], [], []))
            pose_w.write(PoseStamped_(header, Pose_(Point_(*p), Quaternion_(x, y, z, w))))
            last_of_window = i + 1 == len(rows) or rows[i + 1][5] != name
            if last_of_window and name.startswith("hold"):
                time.sleep(0.05)  # the twin's next steps take the last pose
                _, sp = first_sample(peer, "/PSM1/setpoint_cp", PoseStamped_)
                p_sp, r_sp = pose_of(sp)
                err_p = np.linalg.norm((p_sp - p0) - 0.2 * followed)
                err_r = np.degrees(np.arccos(np.clip((np.trace(r.T @ r_sp) - 1) / 2, -1, 1)))
                checked.append((name, err_p, err_r))
                start += 0.05
        time.sleep(0.1)
        _, jaw = first_sample(peer, "/PSM1/jaw/setpoint_js")
    finally:
        summary, err = finish(proc)
    for name, e_p, e_r in checked:
        print(f"{name}: setpoint_cp {e_p * 1e3:.4f} mm, {e_r:.4f} deg from 0.2 x the followed hand")
    assert [c[0] for c in checked] == ["hold 1", "hold 2", "hold 3", "hold 4"]
    assert all(e_p < 0.5e-3 and e_r < 1.0 for _, e_p, e_r in checked), checked
    assert abs(jaw.position[0]) < 1e-9
    t = summary["teleop"]
    assert t["psm"] == "PSM1" and t["following_from"] is not None and t["clutch_presses"] == 1 and t["ik_misses"] == 0, t
    assert summary["refused"] == 0, err


# The CRTK contract's message types, as the peer's IDL classes.
CONTRACT_TYPES = {
    "sensor_msgs/msg/JointState": JointState_,
    "geometry_msgs/msg/PoseStamped": PoseStamped_,
    "geometry_msgs/msg/TwistStamped": TwistStamped_,
    "crtk_msgs/msg/OperatingState": OperatingState_,
    "crtk_msgs/msg/StringStamped": StringStamped_,
    "std_msgs/msg/String": String_,
}


def contract_rows():
    """tests/python/crtk_contract.csv: the dVRK simulators' CRTK contract, one row per item,
    with its source (jhu-dvrk/dvrk_simulator_base's document and reference code)."""
    import csv
    with open(pathlib.Path(__file__).with_name("crtk_contract.csv")) as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("scene,arms", [("psm", ["PSM1"]), ("ecm", ["ECM"]), ("2psm-ecm", ["PSM1", "PSM2", "ECM"]), ("mtm", ["MTMR"])])
def test_serve_meets_the_crtk_contract_table(scene, arms):
    """Every row of the contract for every arm of the scene: an endpoint of the twin matches the
    peer's of the row's type, reliability and durability (DDS matches on the type's name and
    refuses a transient-local reader a volatile writer), a publisher for `publish` rows, a
    subscriber for `subscribe` rows. Then a peer that joins late gets `operating_state`,
    `state` and a PSM's `tool_type` at once (transient local). History depth is not announced
    in discovery: not checked here."""
    rows = contract_rows()
    assert len(rows) == 22  # the contract's items (docs/ros2.md)
    domain = unique_domain(20 + ["psm", "ecm", "2psm-ecm", "mtm"].index(scene))
    peer = Peer(domain)
    proc = subprocess.Popen([dvrk_binary(), "serve", "--scene", scene, "--domain", str(domain), "--duration", str(5 + DISCOVERY_S), "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    from cyclonedds.pub import DataWriter
    endpoints = []
    try:
        for arm in arms:
            kind = arm[:3]
            for row in rows:
                if kind not in row["arm_kinds"].split("|"):
                    continue
                durability = Policy.Durability.TransientLocal if row["durability"] == "transient_local" else Policy.Durability.Volatile
                qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), durability, Policy.History.KeepLast(int(row["history_depth"])))
                topic = Topic(peer.dp, f"rt/{arm}/{row['topic']}", CONTRACT_TYPES[row["message_type"]])
                if row["direction"] == "publish":
                    endpoints.append((arm, row, DataReader(peer.dp, topic, qos=qos)))
                else:
                    endpoints.append((arm, row, DataWriter(peer.dp, topic, qos=qos)))
        deadline = time.time() + 6.0
        missing = endpoints
        while missing and time.time() < deadline:
            time.sleep(0.2)
            missing = [e for e in missing if not (e[2].get_matched_publications() if e[1]["direction"] == "publish" else e[2].get_matched_subscriptions())]
        assert not missing, [f"{a}/{r['topic']} ({r['direction']} {r['message_type']}, {r['durability']})" for a, r, _ in missing]
        print(f"{scene}: {len(endpoints)} contract endpoints matched")
        # A late joiner (the twin has run over a second): the events at once.
        late = Peer(domain)
        ev = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.TransientLocal, Policy.History.KeepLast(10))
        want = [(arm, "operating_state", OperatingState_) for arm in arms] + [(arm, "state", StringStamped_) for arm in arms]
        want += [(arm, "tool_type", String_) for arm in arms if arm.startswith("PSM")]
        readers = {(a, t): late.reader(f"/{a}/{t}", cls, ev) for a, t, cls in want}
        got, deadline = {}, time.time() + 2.0
        while len(got) < len(readers) and time.time() < deadline:
            for key, r in readers.items():
                for sample in r.take(N=10):
                    got.setdefault(key, sample)
            time.sleep(0.01)
        assert set(got) == set(readers), sorted(set(readers) - set(got))
        for (arm, t), sample in got.items():
            if t == "state":
                assert sample.string == "ENABLED"
            if t == "tool_type":
                assert sample.data, "a PSM says its tool"
    finally:
        summary, _ = finish(proc)
    assert summary["finite"]


def test_move_cp_reaches_the_goal_by_an_interpolated_move_and_a_refusal_says_so_on_warning():
    """`move_cp`: the IK's goal reached by the joints' interpolated move (the arm says busy, its
    setpoint_cp goes there gradually, not in one step); a goal out of reach is refused on the
    arm's `warning` topic (crtk_msgs/StringStamped), as the contract has it."""
    import numpy as np

    domain = unique_domain(30)
    peer = Peer(domain)
    peer.reader("/PSM1/setpoint_cp", PoseStamped_)
    peer.reader("/PSM1/measured_cp", PoseStamped_)
    peer.reader("/PSM1/warning", StringStamped_)
    peer.reader("/PSM1/operating_state", OperatingState_, Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.TransientLocal, Policy.History.KeepLast(10)))
    move = peer.writer("/PSM1/move_cp", PoseStamped_)
    proc = serve(domain, 5)
    try:
        _, now = first_sample(peer, "/PSM1/setpoint_cp", PoseStamped_)
        time.sleep(0.5)
        _, now = first_sample(peer, "/PSM1/setpoint_cp", PoseStamped_)
        p = now.pose.position
        start = np.array([p.x, p.y, p.z])
        goal = start + np.array([0.01, 0.0, -0.005])
        peer.take("/PSM1/setpoint_cp", PoseStamped_)
        move.write(PoseStamped_(Header_(Time_(0, 0), "PSM1_base"), Pose_(Point_(*goal), now.pose.orientation)))
        trace, busy = [], False
        t0 = time.time()
        while time.time() - t0 < 2.0:
            for _, s in peer.take("/PSM1/setpoint_cp", PoseStamped_):
                trace.append(np.array([s.pose.position.x, s.pose.position.y, s.pose.position.z]))
            busy |= any(s.is_busy for _, s in peer.take("/PSM1/operating_state", OperatingState_))
            time.sleep(0.005)
        _, m = first_sample(peer, "/PSM1/measured_cp", PoseStamped_)
        reached = np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z])
        move.write(PoseStamped_(Header_(Time_(0, 0), "PSM1_base"), Pose_(Point_(2.0, 0.0, 0.0), now.pose.orientation)))
        _, warning = first_sample(peer, "/PSM1/warning", StringStamped_)
    finally:
        summary, err = finish(proc)
    steps = [np.linalg.norm(b - a) for a, b in zip(trace, trace[1:])]
    moving = sum(1 for s in steps if s > 1e-7)
    print(f"move_cp: setpoint moved over {moving} samples (largest step {max(steps) * 1e3:.3f} mm), measured tip {np.linalg.norm(reached - goal) * 1e3:.2f} mm from the goal")
    assert busy, "the arm said busy while moving"
    assert moving > 10 and max(steps) < 0.003, "an interpolated move, not a jump"
    assert np.linalg.norm(trace[-1] - goal) < 1e-6
    assert np.linalg.norm(reached - goal) < 0.003
    assert warning.string.startswith("rejected /PSM1/move_cp: "), warning.string
    assert (summary["commands"], summary["refused"]) == (1, 1), summary


def test_the_contracts_state_machine_pause_resume_fault_clear_fault():
    """pause / resume / fault / clear_fault as the CRTK contract's reference has them: each change
    on operating_state and on state; a command from the wrong state refused on the arm's warning
    topic; motion refused while paused."""
    domain = unique_domain(31)
    peer = Peer(domain)
    ev = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.TransientLocal, Policy.History.KeepLast(10))
    peer.reader("/PSM1/state", StringStamped_, ev)
    peer.reader("/PSM1/warning", StringStamped_)
    state = peer.writer("/PSM1/state_command", StringStamped_)
    servo = peer.writer("/PSM1/servo_jp")
    proc = serve(domain, 5)

    def wait_state(want):
        wait_for(peer, "/PSM1/state", StringStamped_, lambda s: s.string == want, want)

    warnings = []
    try:
        wait_state("ENABLED")
        time.sleep(1.0)  # every peer endpoint matched (the state is latched: it came at once)
        say(state, "pause")
        wait_state("PAUSED")
        servo.write(command(PSM_JOINTS, [0.1, 0.0, 0.1, 0.0, 0.0, 0.0]))  # refused: paused
        time.sleep(0.3)  # (state commands are taken before motion in a step: not with resume's)
        say(state, "pause")  # refused: not from PAUSED
        say(state, "resume")
        wait_state("ENABLED")
        say(state, "fault")
        wait_state("FAULT")
        say(state, "enable")  # refused: clear the fault first
        say(state, "clear_fault")
        wait_state("DISABLED")
        say(state, "enable")
        wait_state("ENABLED")
        time.sleep(0.3)
        warnings = [s.string for _, s in peer.take("/PSM1/warning", StringStamped_)]
    finally:
        summary, err = finish(proc)
    print(warnings)
    assert any(w.startswith("rejected /PSM1/servo_jp: ") and "PAUSED" in w for w in warnings), warnings
    assert any("cannot pause from PAUSED" in w for w in warnings), warnings
    assert any("cannot enable while in FAULT" in w for w in warnings), warnings
    assert (summary["commands"], summary["refused"]) == (5, 3), summary


def test_a_flood_of_valid_servo_jp_keeps_the_rate_and_the_memory_flat():
    """The contract's flood: servo_jp as fast as the peer can send for 10 s (each a valid
    setpoint, the newest wins): `measured_js` keeps its rate within 1% and the twin's resident
    memory does not grow (read from /proc: flat within 5 MB from the second second on)."""
    import numpy as np

    rate, seconds = 200, 10
    domain = unique_domain(32)
    peer = Peer(domain)
    peer.reader("/PSM1/measured_js", qos=COUNT)
    servo = peer.writer("/PSM1/servo_jp")
    proc = serve(domain, seconds + 6, "--rate", str(rate))

    def rss_mb():
        with open(f"/proc/{proc.pid}/status") as f:
            return next(int(l.split()[1]) for l in f if l.startswith("VmRSS:")) / 1024.0

    try:
        _, first = first_sample(peer, "/PSM1/measured_js")
        time.sleep(1.0)
        base = list(first.position)
        peer.take("/PSM1/measured_js")
        start, sent, per_second, memory = time.time(), 0, [0] * seconds, []
        while time.time() - start < seconds:
            k = sent % 1000
            target = list(base)
            target[0] += 0.05 * np.sin(2 * np.pi * k / 1000)
            servo.write(command(PSM_JOINTS, target))
            sent += 1
            if sent % 200 == 0:
                for arrived, _ in peer.take("/PSM1/measured_js"):
                    per_second[min(int(arrived - start), seconds - 1)] += 1
                second = int(time.time() - start)
                if len(memory) <= second < seconds:
                    memory.append(rss_mb())
        for arrived, _ in peer.take("/PSM1/measured_js"):
            per_second[min(int(arrived - start), seconds - 1)] += 1
    finally:
        summary, _ = finish(proc)
    print(f"servo_jp flood: {sent} sent in {seconds} s ({sent / seconds:.0f}/s), {summary['commands']} applied; measured_js per second {per_second}; RSS per second (MB) {[round(m, 1) for m in memory]}")
    assert sent > 20 * seconds * rate, "the peer flooded"
    assert abs(sum(per_second) / seconds - rate) < 0.01 * rate, per_second
    assert max(memory[1:]) - min(memory[1:]) < 5.0, memory
    assert summary["refused"] == 0 and summary["commands"] > 0.5 * sent, summary


@pytest.mark.alone  # see conftest.py
def test_two_flooding_peers_and_peers_coming_and_going_keep_the_rate_and_the_memory():
    """Issue #63's re-measure: one peer floods valid servo_jp, a second floods refused ones (5
    values for 6 joints), and a third joins, reads measured_js for a second and leaves, five
    times, over 10 s: `measured_js` at its rate within 1%, the twin's resident memory flat."""
    rate, seconds = 200, 10
    domain = unique_domain(33)
    reader = Peer(domain)
    reader.reader("/PSM1/measured_js", qos=COUNT)
    good = Peer(domain).writer("/PSM1/servo_jp")
    bad = Peer(domain).writer("/PSM1/servo_jp")
    proc = serve(domain, seconds + 6, "--rate", str(rate))

    def rss_mb():
        with open(f"/proc/{proc.pid}/status") as f:
            return next(int(l.split()[1]) for l in f if l.startswith("VmRSS:")) / 1024.0

    visitors = []
    try:
        _, first = first_sample(reader, "/PSM1/measured_js")
        time.sleep(1.0)
        base = list(first.position)
        reader.take("/PSM1/measured_js")
        start, sent, per_second, memory, visitor = time.time(), [0, 0], [0] * seconds, [], None
        while time.time() - start < seconds:
            target = list(base)
            target[0] += 0.02 * ((sent[0] % 200) / 200.0)
            good.write(command(PSM_JOINTS, target))
            bad.write(command(PSM_JOINTS[:5], [0.0] * 5))
            sent[0] += 1
            sent[1] += 1
            if sent[0] % 100 == 0:
                for arrived, _ in reader.take("/PSM1/measured_js"):
                    per_second[min(int(arrived - start), seconds - 1)] += 1
                second = int(time.time() - start)
                if len(memory) <= second < seconds:
                    memory.append(rss_mb())
                    # Every other second a peer joins, the next it counts what it got and leaves.
                    if visitor is None and second % 2 == 0:
                        visitor = Peer(domain)
                        visitor.reader("/PSM1/measured_js")
                    elif visitor is not None:
                        visitors.append(len(visitor.take("/PSM1/measured_js")))
                        visitor = None
            time.sleep(0.0002)
        for arrived, _ in reader.take("/PSM1/measured_js"):
            per_second[min(int(arrived - start), seconds - 1)] += 1
    finally:
        summary, _ = finish(proc)
    print(f"two floods: {sent[0]} valid and {sent[1]} refused sent in {seconds} s; applied {summary['commands']}, refused {summary['refused']}; measured_js per second {per_second}; visitors got {visitors}; RSS (MB) {[round(m, 1) for m in memory]}")
    assert abs(sum(per_second) / seconds - rate) < 0.01 * rate, per_second
    assert max(memory[1:]) - min(memory[1:]) < 5.0, memory
    # Each visitor's reader was full after its second (keep last 10: it holds the newest 10).
    assert len(visitors) >= 4 and all(v == 10 for v in visitors), visitors
    assert summary["refused"] > 0.5 * sent[1] and summary["commands"] > 0.5 * sent[0], summary


def _quaternion(r):
    """(x, y, z, w) of rotation matrix `r`."""
    import numpy as np

    w = np.sqrt(max(0.0, 1.0 + np.trace(r))) / 2.0
    if w > 1e-3:
        return ((r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w), w)
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = np.sqrt(max(0.0, 1.0 + r[i, i] - r[j, j] - r[k, k])) * 2.0
    q = [0.0, 0.0, 0.0]
    q[i], q[j], q[k] = s / 4.0, (r[j, i] + r[i, j]) / s, (r[k, i] + r[i, k]) / s
    return (q[0], q[1], q[2], (r[k, j] - r[j, k]) / s)


def test_servo_cp_in_the_ecm_view_moves_the_tip_along_the_cameras_axes():
    """Issue #61: `servo_cp` with frame_id `ECM_view` (the ECM's camera: its tool tip, as the dVRK
    defines the camera frame) while the ECM is posed away from home: 1 cm along the camera's x
    axis moves PSM1's tip 1 cm along that axis in the world, within 0.5 mm. The expectation is
    computed here from the scene file's mounts and the models' forward kinematics (not from the
    twin's frames), at the ECM's measured joints; the tip is read from PSM1's setpoints (the
    IK's answer, not the PID's tracking of it)."""
    import tomllib

    import numpy as np

    dvrk_twin = pytest.importorskip("dvrk_twin")
    scene = tomllib.loads((ROOT / "models" / "scenes" / "2psm-ecm.toml").read_text())
    mount = {a["name"]: np.array(a["mount"]) for a in scene["arms"]}
    ecm, psm = dvrk_twin.Model.load("ecm"), dvrk_twin.Model.load("psm")

    def world_tip(model, arm, q):
        # The scene's mount places the model's base (its frame 0 at the full scene's SUJ home).
        return mount[arm] @ model.fk(np.asarray(q, dtype=float))[model.tip]

    domain = unique_domain(40)
    peer = Peer(domain)
    for topic in ["/ECM/measured_js", "/ECM/setpoint_js", "/PSM1/setpoint_js"]:
        peer.reader(topic)
    peer.reader("/PSM1/setpoint_cp", PoseStamped_)
    peer.reader("/PSM1/local/setpoint_cp", PoseStamped_)
    move = peer.writer("/ECM/move_jp")
    servo = peer.writer("/PSM1/servo_cp", PoseStamped_)
    proc = subprocess.Popen(
        [dvrk_binary(), "serve", "--scene", "2psm-ecm", "--domain", str(domain), "--duration", "30", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )

    def psm_tip():
        time.sleep(0.3)
        _, sp = first_sample(peer, "/PSM1/setpoint_js")
        return world_tip(psm, "PSM1", list(sp.position)[:6] + [0.0])

    try:
        _, first = first_sample(peer, "/ECM/measured_js")
        ecm_names = list(first.name)
        goal = [0.25, -0.2, 0.12, 0.3]  # yaw, pitch (rad), insertion (m), roll (rad): away from home
        time.sleep(0.5)
        move.write(command(ecm_names, goal))
        wait_for(peer, "/ECM/setpoint_js", JointState_, lambda s: np.allclose(s.position, goal, atol=1e-9), "the ECM's goal", timeout=10.0)
        time.sleep(1.0)  # the ECM settles on its goal (its PID, gravity-compensated)
        peer.take("/ECM/measured_js")
        _, measured = first_sample(peer, "/ECM/measured_js")
        view = world_tip(ecm, "ECM", list(measured.position))
        assert np.linalg.norm(view[:3, 3] - world_tip(ecm, "ECM", [0.0, 0.0, 0.1, 0.0])[:3, 3]) > 0.02, "posed away from home"
        start = psm_tip()
        tips = []
        for dx in (0.0, 0.01):
            in_view = np.linalg.inv(view) @ start
            in_view[0, 3] += dx
            p, q = in_view[:3, 3], _quaternion(in_view[:3, :3])
            servo.write(PoseStamped_(Header_(Time_(0, 0), "ECM_view"), Pose_(Point_(*p), Quaternion_(*q))))
            tips.append(psm_tip())
        # The contract: a PSM's Cartesian reports in the ECM's view when the scene has an ECM
        # (local/* in its own base).
        peer.take("/PSM1/setpoint_cp", PoseStamped_)
        peer.take("/PSM1/local/setpoint_cp", PoseStamped_)
        time.sleep(0.1)
        _, reported = first_sample(peer, "/PSM1/setpoint_cp", PoseStamped_)
        _, local = first_sample(peer, "/PSM1/local/setpoint_cp", PoseStamped_)
    finally:
        summary, err = finish(proc)
    moved = tips[1][:3, 3] - tips[0][:3, 3]
    along = view[:3, 0] * 0.01
    turned = np.degrees(np.arccos(np.clip((np.trace(tips[0][:3, :3].T @ tips[1][:3, :3]) - 1) / 2, -1, 1)))
    print(f"ECM_view: the tip moved {np.round(moved * 1e3, 3)} mm for 10 mm along the camera's x {np.round(view[:3, 0], 4)}; off by {np.linalg.norm(moved - along) * 1e3:.3f} mm, turned {turned:.4f} deg; the first command moved it {np.linalg.norm(tips[0][:3, 3] - start[:3, 3]) * 1e3:.3f} mm")
    # Measured 0.12 mm off and 0.07 deg turned: the twin takes the ECM's simulated pose (its
    # joints' loops and PID, still settling), this test the FK of its measured joints.
    assert np.linalg.norm(moved - along) < 0.5e-3, (moved, along, summary, err[-800:])
    assert turned < 0.2
    # Where the tip was, said in the view frame, is where it stays (the frame is the ECM's now).
    assert np.linalg.norm(tips[0][:3, 3] - start[:3, 3]) < 0.5e-3
    assert summary["commands"] == 3 and summary["refused"] == 0, (summary, err)
    expected = (np.linalg.inv(view) @ tips[1])[:3, 3]
    got = np.array([reported.pose.position.x, reported.pose.position.y, reported.pose.position.z])
    print(f"setpoint_cp in {reported.header.frame_id}: {np.linalg.norm(got - expected) * 1e3:.3f} mm from the expectation; local/setpoint_cp in {local.header.frame_id}")
    assert reported.header.frame_id == "ECM_view" and local.header.frame_id == "PSM1_base"
    # Measured 0.46 mm: the view here is the FK of the ECM's measured joints, the twin's its
    # simulated links (the loops' constraint error); another frame would be centimetres off.
    assert np.linalg.norm(got - expected) < 1.5e-3, (got, expected)
