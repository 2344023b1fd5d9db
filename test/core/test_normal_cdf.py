"""The normal cdf and density from one exponential (workzone_ros.core.normal_cdf) against
``math.erfc`` and ``math.exp`` on a dense grid, tails included."""
import math

import numpy as np
import pytest
from numba import njit

from workzone_ros.core.normal_cdf import normal_cdf_pdf


@njit
def _on_grid(zs):
    cdf, pdf = np.empty(zs.size), np.empty(zs.size)
    for k in range(zs.size):
        cdf[k], pdf[k] = normal_cdf_pdf(zs[k])
    return cdf, pdf


def _relative_errors(zs):
    cdf, pdf = _on_grid(zs)
    ref_cdf = np.array([0.5 * math.erfc(-z / math.sqrt(2.0)) for z in zs])
    ref_pdf = np.array([math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi) for z in zs])
    return np.abs(cdf / ref_cdf - 1.0).max(), np.abs(pdf / ref_pdf - 1.0).max()


@pytest.mark.parametrize('limit, bound', [(8.5, 1e-11), (20.0, 1e-8)])
def test_cdf_and_pdf_match_erfc_and_exp(limit, bound):
    """Relative errors over 400001 points of ``[-limit, limit]`` (8.5: the chroma fit's
    range, the cdf down to 1e-17; 20: down to 3e-89), the break points at +-0.46875 sqrt(2)
    and +-4 sqrt(2) of Cody's interval and 0 included."""
    edges = np.array([0.0, 0.46875, 4.0]) * math.sqrt(2.0)
    zs = np.concatenate([np.linspace(-limit, limit, 400001), edges, -edges,
                         np.nextafter(edges, 10.0), np.nextafter(-edges, -10.0)])
    err_cdf, err_pdf = _relative_errors(zs)
    assert err_cdf < bound
    assert err_pdf < 1e-15
