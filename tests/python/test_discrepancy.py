"""``dvrk_twin.synth_hidden_effect`` and ``dvrk_twin.discrepancy``: a recording simulated with
viscous friction hidden on one joint is diagnosed, from Python, as that effect."""

import pytest

import dvrk_twin


def test_a_hidden_viscous_friction_is_named(tmp_path):
    rec = tmp_path / "hidden.mcap"
    answer = dvrk_twin.synth_hidden_effect(rec, effect="viscous_friction", seed=3)
    assert answer["effects"][0]["name"] == "viscous_friction"
    report = dvrk_twin.discrepancy(rec, model="psm", arm="PSM1", tracking=False)
    assert report["verdict"] == "named", report["verdict"]
    named = report["effects"][0]
    assert named["name"] == "viscous_friction"
    assert named["joint"] == answer["effects"][0]["joint"]
    assert report["rms_heldout_after"] < report["rms_heldout_before"]


def test_discrepancy_names_a_missing_topic(tmp_path):
    rec = tmp_path / "hidden.mcap"
    dvrk_twin.synth_hidden_effect(rec, effect="none", seed=1, duration=5.0)
    with pytest.raises(dvrk_twin.DvrkError, match="/PSM2/measured_js"):
        dvrk_twin.discrepancy(rec, arm="PSM2")
