"""Rate-table fit helpers (workbench.analysis.turntable_rate): bias and G from per-mount offsets."""

import numpy as np
import pytest

from workbench.analysis.turntable_rate import _bias_from_offsets


def test_bias_and_g_sensitivity_from_mount_offsets_exactly():
    """c_m = b + G f_m at four or more mounts with independent f: b and G recovered exactly, sigmas from the
    offsets' covariance propagated linearly."""
    b, g = np.array([1e-4, -2e-4, 3e-4]), np.array([[1e-5, 0, 2e-6], [0, -3e-6, 0], [4e-6, 0, 1e-6]])
    f = 9.8 * np.array([[0, 0, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0]], float)
    off = b + f @ g.T
    covs = [np.eye(5) * 1e-12] * 3
    bias, bias_s, gs, gs_s = _bias_from_offsets(off, covs, f)
    assert bias == pytest.approx(b, abs=1e-15) and np.allclose(gs, g, atol=1e-15)
    assert np.all(bias_s > 0) and np.all(np.isfinite(gs_s))
    # three mounts cannot separate b from G: not observed
    _, s3, _, _ = _bias_from_offsets(off[:3], [np.eye(3) * 1e-12] * 3, f[:3])
    assert np.isnan(s3).all()
