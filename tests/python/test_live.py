"""The live view (`dvrk sim --live`) read by an independent client: the Python `websockets`
package speaking the Foxglove WebSocket protocol as its specification says (under its current
name, `foxglove.sdk.v1`: the `foxglove.websocket.v1` protocol renamed, identical on the wire;
the Foxglove app speaks it, Lichtblick since its pull request 819 of December 2025), and rosbags decoding the CDR messages."""

import asyncio
import json
import os
import pathlib
import signal
import socket
import struct
import subprocess
import time

import numpy as np
import pytest

websockets = pytest.importorskip("websockets")
pytestmark = pytest.mark.realtime  # see conftest.py
from rosbags.typesys import Stores, get_typestore  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]


def dvrk_binary():
    path = pathlib.Path(os.environ.get("DVRK_BIN", ROOT / "target" / "release" / "dvrk"))
    assert path.exists(), f"{path}: build the CLI first (cargo build --release) or set DVRK_BIN"
    return str(path)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(port, *extra):
    proc = subprocess.Popen(
        [dvrk_binary(), "sim", "--scene", "psm", "--duration", "120", "--realtime", "1", "--live", f"127.0.0.1:{port}", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # The server is up once the CLI says where (it binds before the run starts).
    line = proc.stderr.readline()
    assert "live: serving ws://127.0.0.1:" in line, line
    return proc


def stop(proc):
    proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    return proc.returncode, out, err


async def advertised(ws, topics):
    """The channels advertised on `ws`, once every one of `topics` is (they may come in several
    messages)."""
    channels = {}
    while not set(topics) <= set(channels):
        msg = json.loads(await asyncio.wait_for(ws.recv(), 10))
        if msg["op"] == "advertise":
            channels.update({c["topic"]: c for c in msg["channels"]})
    return channels


async def joint_states(port, topic, count):
    """Subscribe to `topic`; the first `count` messages' (timestamp ns, CDR payload). The client
    leaves with an unsubscribe and a close it waits for 1 s at most (a simulation running at
    hundreds of times real time has queued thousands of messages ahead of the server's reply)."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], close_timeout=1) as ws:
        assert ws.subprotocol == "foxglove.sdk.v1"
        channels = await advertised(ws, [topic, "/PSM1/setpoint_js", "/PSM1/measured_cp", "/PSM1/jaw/measured_js", "/tf"])
        ch = channels[topic]
        assert (ch["encoding"], ch["schemaName"], ch["schemaEncoding"]) == ("cdr", "sensor_msgs/msg/JointState", "ros2msg")
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": ch["id"]}]}))
        got = []
        while len(got) < count:
            frame = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(frame, bytes) and frame[0] == 0x01:
                sub, stamp = struct.unpack_from("<IQ", frame, 1)
                assert sub == 7
                got.append((stamp, frame[13:]))
        await ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [7]}))
        return got


def test_a_websocket_client_reads_the_live_joint_states():
    port = free_port()
    proc = start(port)
    try:
        got = asyncio.run(joint_states(port, "/PSM1/measured_js", 100))
    finally:
        code, out, err = stop(proc)
    store = get_typestore(Stores.ROS2_HUMBLE)
    msgs = [store.deserialize_cdr(data, "sensor_msgs/msg/JointState") for _, data in got]
    assert list(msgs[0].name) == ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"]
    q = np.array([m.position for m in msgs])
    stamps = np.array([s for s, _ in got])
    # The sine moves every joint; the stamps are the simulated time, 10 ms apart at --rate 100.
    assert np.all(np.ptp(q[:, :3], axis=0) > 1e-4), np.ptp(q, axis=0)
    assert np.all(np.diff(stamps) > 0) and abs(np.median(np.diff(stamps)) - 1e7) < 1e3
    # Ctrl-C: a clean stop, the summary printed, nothing left running.
    assert code == 0, err
    assert "stopped by a signal" in err and "real-time factor" in out
    assert proc.poll() is not None


async def first_message(port, topic):
    """The advertised channel `topic` and the first message on it."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], close_timeout=1) as ws:
        channels = await advertised(ws, [topic])
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channels[topic]["id"]}]}))
        while True:
            frame = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(frame, bytes) and frame[0] == 0x01:
                return channels[topic], frame[13:]


def protobuf_message(channel, data):
    """`data` decoded with the schema the channel advertised: for protobuf, a base64
    FileDescriptorSet, as the protocol's specification says (read with Google's `protobuf`)."""
    import base64

    from google.protobuf import descriptor_pb2, message_factory

    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"])).file
    return message_factory.GetMessages(files)[channel["schemaName"]].FromString(data)


def first_messages_of_a_running_sim(*topics):
    """Each topic's channel and first message, from a client that connects half a second into
    a served run (what does not change must reach a late client too)."""
    port = free_port()
    proc = start(port)
    try:
        time.sleep(0.5)
        return [asyncio.run(first_message(port, t)) for t in topics]
    finally:
        stop(proc)


def test_a_late_client_gets_the_link_geometry_as_a_scene_update():
    [(channel, data)] = first_messages_of_a_running_sim("/scene")
    assert (channel["schemaName"], channel["encoding"], channel["schemaEncoding"]) == ("foxglove.SceneUpdate", "protobuf", "protobuf")
    # Each PSM body's triangles: tens of kB; frame ids are the /tf children.
    assert len(data) > 10_000
    scene = protobuf_message(channel, data)
    frames = {e.frame_id for e in scene.entities}
    assert "PSM1/yaw_link" in frames and all(e.frame_locked and e.triangles for e in scene.entities), frames


def test_the_robot_description_names_the_tf_frames():
    import xml.etree.ElementTree as ET

    (channel, data), (tf_channel, tf) = first_messages_of_a_running_sim("/PSM1/robot_description", "/tf")
    assert (channel["schemaName"], channel["encoding"]) == ("std_msgs/msg/String", "cdr")
    urdf = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(data, "std_msgs/msg/String").data
    robot = ET.fromstring(urdf)
    links = {l.get("name") for l in robot.findall("link")}
    # Every body's link, named as its /tf frame, with visuals; floating joints from world.
    assert "world" in links and all(l.startswith("PSM1/") for l in links - {"world"}) and len(links) > 10, links
    assert all(j.get("type") == "floating" and j.find("parent").get("link") == "world" for j in robot.findall("joint"))
    assert sum(len(l.findall("visual")) for l in robot.findall("link")) > 10
    assert tf_channel["schemaName"] == "foxglove.FrameTransforms"
    children = {t.child_frame_id for t in protobuf_message(tf_channel, tf).transforms}
    assert children == links - {"world"}, (sorted(children), sorted(links))


def test_a_stopped_live_run_leaves_its_recording_valid(tmp_path):
    from mcap.reader import make_reader

    port, out_file = free_port(), tmp_path / "live.mcap"
    proc = start(port, "--out", str(out_file))
    try:
        asyncio.run(joint_states(port, "/PSM1/measured_js", 20))
    finally:
        code, _, err = stop(proc)
    assert code == 0, err
    with open(out_file, "rb") as f:
        topics = {ch.topic for _, ch, _ in make_reader(f).iter_messages()}
    assert "/PSM1/measured_js" in topics


def test_a_busy_port_is_a_one_line_error():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        r = subprocess.run([dvrk_binary(), "sim", "--scene", "psm", "--duration", "1", "--live", f"127.0.0.1:{port}"], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert f"--live 127.0.0.1:{port}: cannot serve" in r.stderr and r.stderr.count("\n") <= 2, r.stderr


def rss_kb(pid):
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))


def fast_run(port, seconds, clients):
    """`dvrk sim` as fast as it can with the live view on, stopped after `seconds` of wall time
    while `clients` clients connect, subscribe, read a few messages and disconnect over and over:
    its real-time factor and its resident memory (kB) at a quarter and at the end."""
    proc = subprocess.Popen(
        [dvrk_binary(), "sim", "--scene", "psm", "--duration", "1e6", "--live", f"127.0.0.1:{port}", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert "live: serving" in proc.stderr.readline()

    async def churn(deadline):
        connections = 0
        while time.monotonic() < deadline:
            try:
                got = await joint_states(port, "/PSM1/measured_js", 5)
                assert len(got) == 5
                connections += 1
            except (OSError, websockets.exceptions.WebSocketException):
                await asyncio.sleep(0.05)
        return connections

    async def soak():
        deadline = time.monotonic() + seconds
        early = None
        tasks = [asyncio.create_task(churn(deadline)) for _ in range(clients)]
        await asyncio.sleep(seconds / 4)
        early = rss_kb(proc.pid)
        while time.monotonic() < deadline:
            await asyncio.sleep(0.2)
        counts = await asyncio.gather(*tasks) if tasks else []
        return early, rss_kb(proc.pid), sum(counts)

    try:
        early, late, connections = asyncio.run(soak())
    finally:
        code, out, err = stop(proc)
    assert code == 0, err
    return json.loads(out)["real_time_factor"], early, late, connections


def test_ten_clients_coming_and_going_neither_slow_the_simulation_nor_grow_its_memory():
    port = free_port()
    rtf_alone, _, _, _ = fast_run(port, 10, 0)
    rtf_soaked, early, late, connections = fast_run(free_port(), 30, 10)
    print(f"real-time factor alone {rtf_alone:.1f}, with 10 clients {rtf_soaked:.1f}; {connections} connections; RSS {early} -> {late} kB")
    assert connections >= 100, connections
    # A 10 s run's real-time factor varies by +-20% on a 2-core machine (session 40: alone 266,
    # 326 and 358 in three runs; 0.86 of alone once in CI-like conditions), and the ten clients
    # run in this process on the same two cores (session 43, a clean-clone CI: 415 alone, 286
    # with them, 0.69): a client that blocked the loop would stall it for seconds and take it
    # far lower than half.
    assert rtf_soaked > 0.5 * rtf_alone, (rtf_alone, rtf_soaked)
    # Flat: the last three quarters of the soak grow the memory by less than 10% (no per-client
    # or per-message leak: 30 s is thousands of connections and millions of messages).
    assert late < 1.1 * early, (early, late)


def test_sim_serve_publishes_as_python_steps_it():
    import threading

    import dvrk_twin

    sim = dvrk_twin.Sim.from_scene("psm", engine="reduced")
    url = sim.serve(port=0)
    assert url.startswith("ws://127.0.0.1:") and sim.live_url == url
    port = int(url.rsplit(":", 1)[1])
    got = {}
    client = threading.Thread(target=lambda: got.update(msgs=asyncio.run(joint_states(port, "/PSM1/measured_js", 50))))
    client.start()
    sim.set_target("PSM1/outer_yaw", 0.3)
    deadline = time.monotonic() + 30
    while client.is_alive() and time.monotonic() < deadline:
        sim.step(10)
        time.sleep(0.002)
    client.join(5)
    sim.stop_serving()
    assert sim.live_url is None
    store = get_typestore(Stores.ROS2_HUMBLE)
    yaw = [store.deserialize_cdr(d, "sensor_msgs/msg/JointState").position[0] for _, d in got["msgs"]]
    stamps = [s for s, _ in got["msgs"]]
    # Sampled every 10 ms of simulated time while the yaw moves toward its new target.
    assert len(yaw) == 50 and yaw[-1] > yaw[0] + 1e-3, yaw
    assert abs(np.median(np.diff(stamps)) - 1e7) < 1e3
