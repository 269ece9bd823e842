"""The classifier and covariance shared by the capstan and Dahl fits (knitsim.friction.identification)."""
from __future__ import annotations

import numpy as np

from knitsim.friction.identification import covariance, parameter_status


def test_a_singular_jacobian_has_infinite_errors():
    """A Jacobian whose columns are dependent sets no parameter.  By hand: J = [[1, 2], [2, 4], [3, 6]] has rank 1
    (the capstan fit's pseudo-inverse of J^T J gave such a Jacobian finite errors)."""
    J = np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])
    assert np.all(np.isinf(covariance(J, 1.0)))
    assert np.all(np.isinf(covariance(np.array([[1.0, np.nan], [2.0, 1.0], [0.0, 1.0]]), 1.0)))


def test_covariance_of_a_full_rank_jacobian_by_hand():
    """s2 (J^T J)^-1 for J = [[1, 2.5], [2, 4], [3, 6]]: J^T J = [[14, 28.5], [28.5, 58.25]], its inverse by the 2 x 2
    cofactor formula, det = 14 * 58.25 - 28.5^2 = 3.25."""
    J = np.array([[1.0, 2.5], [2.0, 4.0], [3.0, 6.0]])
    np.testing.assert_allclose(covariance(J, 2.0), 2.0 * np.array([[58.25, -28.5], [-28.5, 14.0]]) / 3.25, rtol=1e-12)


def test_a_standard_error_wider_than_the_box_is_not_identified():
    """By hand: p = 0.1 +/- 2.5 in the box [-1, 1] (width 2): one standard error either side spans the whole box;
    p = 0.1 +/- 1.5 does not.  A box open at one end (Dahl's sigma, Fc) has no width: no such rule."""
    st, w = parameter_status(["p", "q", "sigma"], [0.1, 0.1, 5.0], [2.5, 1.5, 1e6], [-1, -1, 0], [1, 1, np.inf])
    assert st == {"p": "not_identified", "q": "identified", "sigma": "identified"}
    assert len(w) == 1 and w[0].startswith("p = 0.1 has a standard error of 2.5, wider than every value")
