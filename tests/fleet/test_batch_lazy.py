"""Batch workers load an Allan session lazily and stream it: same noise block as the eager path."""

import numpy as np
import pytest

import workbench.session as wsession
from workbench import registry
from workbench.fleet.batch import analyze_one
from workbench.session import load_session
from workbench.jobs import simulate


@pytest.fixture(scope="module")
def allan_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("allan")
    seq = registry.procedure("allan").sequence(None, duration_s=900.0, soak=False)
    simulate(seq, "industrial_mems", seed=7, out_dir=out)
    return out


def test_lazy_worker_equals_eager_analysis(allan_dir, monkeypatch):
    """The worker loads the session lazily (samples stay on disk) and streams the hold; the noise
    block equals the eager in-memory analysis. The streamed path keeps the same decimated phase
    for noise identification, so only the deviations' summation order differs (~1e-14): terms
    and interval bounds must agree to a relative 1e-9 (IRLS stops at 1e-8 steps, see
    tests/analysis/test_allan_stream.py), and observed/not-observed must be identical."""
    calls = []
    real = wsession.load_session
    monkeypatch.setattr(wsession, "load_session", lambda d, *a, **k: calls.append(k.get("lazy")) or real(d, *a, **k))
    outcome = analyze_one("allan", str(allan_dir))
    assert outcome["ok"], outcome.get("error")
    assert calls == [True]
    lazy = outcome["calibration"].to_dict()["noise"]
    eager = registry.procedure("allan").analyze(real(allan_dir)).calibration.noise
    for triad in ("gyro", "accel"):
        assert set(lazy[triad]) == set(eager[triad])
        for key, values in eager[triad].items():
            got = lazy[triad][key]
            assert [v is None for v in np.ravel(np.array(got, dtype=object))] == \
                   [v is None for v in np.ravel(np.array(values, dtype=object))], key
            ref = np.array([np.nan if v is None else v for v in np.ravel(np.array(values, dtype=object))], float)
            val = np.array([np.nan if v is None else v for v in np.ravel(np.array(got, dtype=object))], float)
            np.testing.assert_allclose(val, ref, rtol=1e-9, err_msg=f"{triad}.{key}")
    assert outcome["result"]["gyro"]["tau_s"][0] == pytest.approx(0.01)  # 100 Hz: the first tau is 1 sample


def test_lazy_session_is_streamed_by_the_procedure(allan_dir):
    session = load_session(allan_dir, lazy=True)
    assert session.samples is None
    res = registry.procedure("allan").analyze(session)
    eager = registry.procedure("allan").analyze(load_session(allan_dir))
    assert set(res.result) == set(eager.result) and set(res.result["gyro"]) == set(eager.result["gyro"])
    np.testing.assert_allclose(res.result["gyro"]["adev"], eager.result["gyro"]["adev"], rtol=1e-12)


def test_other_procedures_load_eagerly(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(wsession, "load_session", lambda d, *a, **k: calls.append(k.get("lazy")) or 1 / 0)
    outcome = analyze_one("multiposition", str(tmp_path))
    assert calls == [False] and not outcome["ok"]
