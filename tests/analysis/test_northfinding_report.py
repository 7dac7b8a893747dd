"""North-finding result dict, summary and tables (workbench.analysis.northfinding_report)."""

import json

import numpy as np
import pytest

from tests.analysis.test_northfinding import maytag_angles, synth_session
from workbench.analysis import northfinding as nfm
from workbench.analysis import northfinding_report as nr


def test_to_result_is_json_in_labelled_units():
    nf = nfm.find_north(synth_session(maytag_angles(3), white=np.zeros(3), az0_deg=-40.0), "maytagging")
    res, summary = nr.to_result(nf)
    json.dumps(res, allow_nan=False)  # NaN (not observed) became null
    assert res["azimuth_deg"] == pytest.approx(320.0, abs=1e-6)  # -40° in [0, 360)
    assert res["azimuth_error_mrad"] == pytest.approx(0.0, abs=1e-6)
    assert summary[0].startswith("azimuth of body x at table zero: 320.0000 ± 0° (1σ = 0 mrad")  # one unit per figure


def test_sequence_table_distances_from_the_mean():
    runs = [nfm.find_north(synth_session(maytag_angles(2), white=np.zeros(3), az0_deg=a), "maytagging")
            for a in (10.0, 10.2)]
    rows = nr.sequence_table(runs, ["a", "b"])
    assert [r["sequence"] for r in rows] == ["a", "b"]
    assert [r["distance_mrad"] for r in rows] == pytest.approx(np.radians([-0.1, 0.1]) * 1e3, abs=1e-6)
