"""A node starts without the libraries only some of its work needs, and gives the same numbers.

Structural, not timed: scipy.signal (which imports scipy.stats, scipy.optimize and
scipy.interpolate) was 0.9 s of each node's 1.75 s of imports, paid at every `ros2 run` and
every graph a test starts. It is imported on first use now (`fmm_ros._lazy.LazyModule`), and
the p-values and quantiles that came from scipy.stats come from the special functions
scipy.stats itself calls (`fmm_ros.core.distributions`), to the bit.
"""

import numpy as np
import pytest
import scipy.stats
from import_probe import modules_after

from fmm_ros.core import distributions
from fmm_ros.ros.nodes import NODES

DEFERRED = ('scipy.signal', 'scipy.stats', 'matplotlib')


@pytest.mark.parametrize('node', sorted(NODES))
def test_a_node_module_imports_no_library_it_uses_only_on_demand(node):
    imported = modules_after(f'import fmm_ros.ros.nodes.{node}')
    assert f'fmm_ros.ros.nodes.{node}' in imported
    assert [name for name in DEFERRED if name in imported] == []


def test_the_distributions_are_scipy_stats_to_the_bit():
    rng = np.random.default_rng(2019)
    for dof in (1, 2, 3, 7.5, 30, 1000):
        for x in np.concatenate(([0.0, 1e-12, 0.5, 1.0, 50.0], rng.exponential(5.0, 20))):
            assert distributions.chi2_sf(x, dof) == scipy.stats.chi2.sf(x, dof)
            assert distributions.t_sf(x, dof) == scipy.stats.t.sf(x, dof)
            assert distributions.t_sf(-x, dof) == scipy.stats.t.sf(-x, dof)
        for p in np.concatenate(([1e-9, 0.001, 0.025, 0.5, 0.975], rng.uniform(0, 1, 20))):
            assert distributions.chi2_isf(p, dof) == scipy.stats.chi2.isf(p, dof)
            assert distributions.t_ppf(p, dof) == scipy.stats.t.ppf(p, dof)
            assert distributions.t_isf(p, dof) == scipy.stats.t.isf(p, dof)
