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


#: Names of GripForce.status codes (C++ GripForceStatus, in order).
GRIP_STATUS = ("ok", "unattainable", "unsupported_risk", "no_time_model")


class GripForce(NamedTuple):
    """Model.grip_force: the normal force fn_n [N] (NaN where not
    attainable), the mu used at it [-], whether a force holds the load at
    that risk, whether fn_n or v_mm_s lies outside the fitted range, the sd
    of fn_n [N] from the coefficient covariance, the per-instant slip
    probability at fn_n [-], the smallest risk the data support for the hold
    [-], and the status code (index into GRIP_STATUS)."""

    fn_n: np.ndarray
    mu_used: np.ndarray
    attainable: np.ndarray
    extrapolated: np.ndarray
    fn_n_sd: np.ndarray
    instant_risk: np.ndarray
    min_supported_risk: np.ndarray
    status: np.ndarray
