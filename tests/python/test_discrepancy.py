"""``dvrk_twin.synth_hidden_effect`` and ``dvrk_twin.discrepancy``: a recording simulated with
viscous friction hidden on one joint is diagnosed, from Python, as that effect. The truths run on
the reduced engine (16x faster than rapier): these test the binding; the detection tables and
``test_independent_generator.py`` grade the workflow on truths that share no code with it."""

import pytest

import dvrk_twin


def test_a_hidden_viscous_friction_is_named(tmp_path):
    rec = tmp_path / "hidden.mcap"
    # 12 s, two rounds, as the CSV test below: the binding's MCAP path, not the workflow's power.
    answer = dvrk_twin.synth_hidden_effect(rec, effect="viscous_friction", seed=3, duration=12.0, engine="reduced")
    assert answer["effects"][0]["name"] == "viscous_friction"
    report = dvrk_twin.discrepancy(rec, model="psm", arm="PSM1", tracking=False, max_rounds=2)
    assert report["verdict"] == "named", report["verdict"]
    named = report["effects"][0]
    assert named["name"] == "viscous_friction"
    assert named["joint"] == answer["effects"][0]["joint"]
    assert report["rms_heldout_after"] < report["rms_heldout_before"]


def test_discrepancy_names_a_missing_topic(tmp_path):
    rec = tmp_path / "hidden.mcap"
    dvrk_twin.synth_hidden_effect(rec, effect="none", seed=1, duration=5.0, engine="reduced")
    with pytest.raises(dvrk_twin.DvrkError, match='engine: "mujoco": rapier or reduced'):
        dvrk_twin.synth_hidden_effect(tmp_path / "other.mcap", effect="none", duration=5.0, engine="mujoco")
    with pytest.raises(dvrk_twin.DvrkError, match="/PSM2/measured_js"):
        dvrk_twin.discrepancy(rec, arm="PSM2")


def test_a_csv_log_is_analysed_and_the_residual_plotted(tmp_path):
    rec = tmp_path / "hidden.csv"
    dvrk_twin.synth_hidden_effect(rec, effect="viscous_friction", seed=3, duration=12.0, engine="reduced")
    assert rec.read_text().splitlines()[2].startswith("time,q1,")
    png = tmp_path / "residual.png"
    report = dvrk_twin.discrepancy(rec, format="csv", tracking=False, max_rounds=2, plot=png)
    assert report["verdict"] == "named", report["verdict"]
    assert report["effects"][0]["name"] == "viscous_friction"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(dvrk_twin.DvrkError, match="--plot"):
        dvrk_twin.discrepancy(rec, format="csv", plot=tmp_path / "residual.txt")
    assert not (tmp_path / "residual.txt").exists()


def test_a_tracked_marker_adds_the_kinematic_channel(tmp_path):
    """A hidden encoder offset with a tracker on the tool shaft: named with both channels'
    evidence, and the tracker's held-out residual falls to its noise."""
    rec = tmp_path / "tracked.mcap"
    answer = dvrk_twin.synth_hidden_effect(rec, effect="joint_offset", seed=3, duration=12.0, marker_link="tool_roll", engine="reduced")
    report = dvrk_twin.discrepancy(rec, tracking=False, max_rounds=1, marker_topic=answer["marker_topic"], marker_link="tool_roll")
    assert report["channel"] == "torque+kinematic"
    assert report["verdict"] == "named"
    assert report["effects"][0]["name"] == "joint_offset"
    truth = answer["effects"][0]["parameters"]["offset"]
    assert abs(report["effects"][0]["parameters"]["offset"] - truth) < 0.02 * abs(truth)
    kin = report["kinematic"]
    assert kin["rms_heldout_before"] > 3.0 and kin["rms_heldout_after"] < 1.3, kin
    with pytest.raises(dvrk_twin.DvrkError, match="marker_link"):
        dvrk_twin.discrepancy(rec, marker_topic=answer["marker_topic"])
