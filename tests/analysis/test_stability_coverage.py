"""Monte Carlo coverage of the stability intervals per noise type (the fast version of
benchmarks/allan_ci_coverage.py, which runs every statistic with more records).

Per statistic and noise type: 100 phase records of 512 points (fixed seeds), 95 % intervals
with the noise identified as in use, the reference value the root of the Monte Carlo mean
variance. Pooled over the 6 octave taus with m <= n / 10. Tolerance: the binomial sigma of one
tau, sqrt(0.0475 / 100) = 0.022, is the pooled sigma's upper bound (fully correlated taus);
3 sigma gives 0.885-1.0, which catches an interval of the wrong width (a factor 1.5 too narrow
covers ~80 %) without false alarms.
"""

import numpy as np
import pytest

from benchmarks.allan_ci_coverage import coverage  # the repository root is on sys.path (tests/conftest.py)
from workbench.sim.powerlaw import NOISE_NAMES

TOL = 3 * np.sqrt(0.0475 / 100)


@pytest.mark.parametrize("stat", ["oadev", "mdev", "ohdev", "adev", "totdev", "mtotdev", "htotdev", "theo1"])
@pytest.mark.parametrize("alpha", sorted(NOISE_NAMES))
def test_coverage_per_noise_type(stat, alpha):
    cov, k = coverage(stat, alpha, 512, 100, seed=1000 + 10 * alpha)
    assert abs(cov - 0.95) <= TOL, (stat, NOISE_NAMES[alpha], cov, k)
