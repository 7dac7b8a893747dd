"""``workbench allan --stat`` / ``--method gmwm`` helpers (workbench.cli.allan_variants): argument checks."""

import pytest

from workbench.cli.allan_variants import parse_taus, run_family, run_gmwm
from workbench.errors import AnalysisError


def test_parse_taus_keeps_names_and_reads_lists():
    assert parse_taus("octave") == "octave" and parse_taus("3-per-decade") == "3-per-decade"
    assert parse_taus("0.1,1,10") == [0.1, 1.0, 10.0] and parse_taus("2") == [2.0]
    with pytest.raises(AnalysisError, match="--taus '1,x'"):
        parse_taus("1,x")


@pytest.mark.parametrize("kw,match", [
    ({"stat": "xdev"}, "--stat 'xdev' is not one of"),
    ({"data_type": "angle"}, "--data-type 'angle' is not freq or phase"),
    ({"level": 1.0}, "--confidence 1.0 must lie between 0 and 1"),
])
def test_family_arguments_are_refused_before_reading(tmp_path, kw, match):
    args = {"stat": "mdev", "data_type": "freq", "level": 0.95, **kw}
    with pytest.raises(AnalysisError, match=match):  # the record does not exist: it is never read
        run_family(tmp_path / "none.csv", None, None, args["stat"], args["data_type"], "octave", args["level"], None)


def test_gmwm_bootstrap_is_refused_before_reading(tmp_path):
    with pytest.raises(AnalysisError, match="--bootstrap 5: must be 50 or more"):
        run_gmwm(tmp_path / "none.csv", None, None, "wn+rw", 5, "error", None)
