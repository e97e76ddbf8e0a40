"""Result types of the vectorised model calls (arrays of one shape)."""

from typing import NamedTuple

import numpy as np


class Prediction(NamedTuple):
    """Model.predict: mu [-], its sd sigma [-], the 95 % interval
    lo95..hi95 [-] and where an input was outside the fitted range."""

    mu: np.ndarray
    sigma: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray
    extrapolated: np.ndarray


class GripForce(NamedTuple):
    """Model.grip_force: the normal force fn_n [N] (NaN where not
    attainable), the mu used at it [-], whether any force holds the load at
    that risk, and whether fn_n lies outside the fitted Fn range."""

    fn_n: np.ndarray
    mu_used: np.ndarray
    attainable: np.ndarray
    extrapolated: np.ndarray
