"""Site data of the rig configurations (workbench/rigsites.py): the declination of a session's rig."""

from dataclasses import replace

import numpy as np
import pytest

from workbench.errors import AnalysisError
from workbench.jobs import simulate
from workbench.rigsites import declination
from workbench.sequence import Hold, Sequence


@pytest.fixture(scope="module")
def session():
    return simulate(Sequence("s", [Hold("z-down", 0.0, 1.0)]), "industrial_mems", seed=1)[0]


def test_declination_from_the_rig_named_in_the_session(session):
    # fixtures/rigs/acutrol_espec.yaml: magnetic_field.declination_deg 3.5 (through the field vector)
    assert declination(replace(session, rig="lab-acutrol-espec")) == pytest.approx(np.radians(3.5), abs=1e-12)
    assert declination(replace(session, rig="lab-aerosmith-watlow")) == pytest.approx(np.radians(3.0), abs=1e-12)


def test_option_first_and_unknown_rig_refused(session):
    assert declination(replace(session, rig="lab-acutrol-espec"), -2.0) == pytest.approx(np.radians(-2.0))
    with pytest.raises(AnalysisError, match=r"magnetic declination unknown \(rig 'nowhere' has no configuration\)"):
        declination(replace(session, rig="nowhere"))
