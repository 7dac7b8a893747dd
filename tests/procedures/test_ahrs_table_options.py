"""ahrs-table refuses a malformed rate or mount list with one line naming the option (not a traceback)."""

import pytest

from workbench.errors import ProcedureError
from workbench.grades import load_spec
from workbench.registry import procedure


@pytest.mark.parametrize("options, name", [({"rates_dps": [20.0]}, "rates_dps"), ({"rates_dps": [20.0, 0.0]}, "rates_dps"),
                                           ({"mounts": [[10.0]]}, "mounts"), ({"mounts": []}, "mounts")])
def test_malformed_lists_are_one_line_errors(options, name):
    with pytest.raises(ProcedureError, match=rf"ahrs-table: {name}="):
        procedure("ahrs-table").sequence(load_spec("consumer_9axis"), **options)


def test_the_default_lists_make_a_sequence():
    seq = procedure("ahrs-table").sequence(load_spec("consumer_9axis"))
    assert len(seq.steps) > 0
