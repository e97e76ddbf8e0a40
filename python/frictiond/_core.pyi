"""Type hints of the native module frictiond._core (pybind11)."""

from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._types import GripForce, Prediction

ArrayLike = Union[float, int, Sequence[float], npt.NDArray[Any]]
Rng = Union[np.random.Generator, np.random.BitGenerator, int, None]

class Model:
    """A fetched (or decoded) model set of one material and fingertip."""

    @staticmethod
    def from_json(model_json: Union[str, Dict[str, Any]]) -> "Model":
        """Decodes the body of GET /v1/materials/{id}/model (a dict or
        JSON text). Raises ValueError naming a missing/malformed field."""
    material: str
    fingertip: str
    version: int
    created_at: str
    source: str  # "daemon", "cache" (stale) or "json"
    stale: bool
    fetched_at: str
    daemon_error: str
    has_stochastic: bool
    eps_ar1: Optional[float]  # identified AR(1) coefficient of eps per data sample
    eps_time: Optional[Dict[str, float]]  # dt_s [s], phi, offset_fraction; None when not identified
    sigma_eps: float  # residual sd of eq. (1) [-]
    coefficients: Dict[str, float]  # by term: intercept, v_mm_s, fn_n, ...
    eps_levels: npt.NDArray[np.float64]  # probability levels [-]
    eps_quantiles: npt.NDArray[np.float64]  # eps at those levels [-]
    def to_json(self) -> Dict[str, Any]: ...
    def predict(self, fn_n: ArrayLike, v_mm_s: ArrayLike) -> Prediction:
        """mu at normal force fn_n [N] and sliding speed v_mm_s [mm/s]."""
    def slip_likelihood(self, fn_n: ArrayLike, ft_n: ArrayLike) -> npt.NDArray[np.float64]:
        """P(slip) in [0, 1] at normal force fn_n [N], tangential ft_n [N]."""
    def grip_force(
        self, load_n: ArrayLike, risk: ArrayLike, hold_s: ArrayLike = 0.0, v_mm_s: ArrayLike = 0.0
    ) -> GripForce:
        """Smallest normal force [N] holding load_n [N] for hold_s [s] at
        v_mm_s [mm/s] with P(any slip) <= risk."""
    def sample_mu(
        self,
        fn_n: ArrayLike,
        v_mm_s: ArrayLike,
        rng: Rng = None,
        size: Union[int, Tuple[int, ...], None] = None,
    ) -> npt.NDArray[np.float64]:
        """Draws of mu [-] at fn_n [N], v_mm_s [mm/s]."""
    def sample_mu_episodes(
        self,
        n_envs: int,
        n_steps: int,
        fn_n: ArrayLike,
        v_mm_s: ArrayLike,
        rng: Rng = None,
        ar1: Union[Literal["model"], float, None] = "model",
        offset_fraction: Union[Literal["model"], float, None] = "model",
        dt_s: Optional[float] = None,
    ) -> npt.NDArray[np.float64]:
        """(n_envs, n_steps) mu [-] for domain randomisation."""
    def _predict_scalar(self, fn_n: float, v_mm_s: float) -> Tuple[float, float, float, float, bool]: ...
    def _slip_likelihood_scalar(self, fn_n: float, ft_n: float) -> float: ...
    def _grip_force_scalar(
        self, load_n: float, risk: float, hold_s: float = 0.0, v_mm_s: float = 0.0
    ) -> Tuple[bool, float, float, bool, str, float, float, float, int]: ...
    def _eps_quantile_scalar(self, p: float) -> float: ...

class _Client:
    def __init__(
        self,
        url: str,
        token: Optional[str] = None,
        cache_dir: Optional[str] = None,
        fingertip: str = "default",
        robot: str = "",
        timeout_s: float = 5.0,
    ) -> None: ...
    url: str
    def materials(self) -> List[Dict[str, Any]]: ...
    def model(self, id: str, fingertip: str = "default", version: Optional[int] = None) -> Model: ...
    def _upload_csv(self, id: str, csv: str, params: List[Tuple[str, str]]) -> Dict[str, Any]: ...
    def resync(self) -> List[Dict[str, Any]]:
        """Refreshes every cached model from the daemon."""
    def get_json(self, path: str) -> Any:
        """GET of a daemon path (e.g. "/v1/materials"), decoded."""
