"""frictiond: stochastic friction models of robot fingertips, from Python.

Fetch a material's model from a frictiond daemon once, then evaluate it
locally on NumPy arrays (paper 000: mu = b0 + b1*v + b2*Fn + eps with eps
from its empirical distribution). Every formula is the C++ client
library's; this package only binds it (pybind11) and broadcasts arrays.

    >>> import numpy as np, frictiond
    >>> client = frictiond.Client("http://127.0.0.1:8080")
    >>> model = client.model("microtribo-recip")
    >>> model.predict(fn_n=np.linspace(1, 5, 5), v_mm_s=0.2).mu
    >>> model.sample_mu_episodes(4096, 200, fn_n=5.0, v_mm_s=0.2, rng=7)

Units are in the names: fn_n, ft_n, load_n [N]; v_mm_s [mm/s]; hold_s [s];
mu, risk and probabilities are dimensionless.
"""

import io
import os
from typing import Any, Dict, List, Mapping, Optional, Union

from ._core import Model, _Client
from ._errors import DaemonError, NotFoundError, UnreachableError
from ._types import GRIP_STATUS, GripForce, Prediction

__all__ = [
    "Client",
    "Model",
    "Prediction",
    "GripForce",
    "GRIP_STATUS",
    "DaemonError",
    "NotFoundError",
    "UnreachableError",
]


def _csv_text(data: Any) -> str:
    """CSV text of a stroke file path, CSV text, a pandas-like data frame
    (has to_csv), a mapping of column name -> 1-D array, or a NumPy
    structured array. Columns per CONTRACT.md: t_s, fn_n, ft_n, v_mm_s,
    optional slip, stroke and covariates."""
    if isinstance(data, (str, os.PathLike)):
        text = os.fspath(data)
        if "\n" in text or "," in text and not os.path.exists(text):
            return text  # already CSV text
        with open(text, "r", encoding="utf-8") as f:
            return f.read()
    if isinstance(data, (bytes, bytearray)):
        return bytes(data).decode("utf-8")
    if hasattr(data, "to_csv"):
        return data.to_csv(index=False)
    import numpy as np

    if isinstance(data, np.ndarray) and data.dtype.names:
        columns = {name: data[name] for name in data.dtype.names}
    elif isinstance(data, Mapping):
        columns = dict(data)
    else:
        raise TypeError(
            "upload: expected a CSV path or text, a data frame (to_csv), a "
            "mapping of column -> array or a structured array, got "
            + type(data).__name__)
    names = list(columns)
    arrays = [np.asarray(columns[n]).reshape(-1) for n in names]
    if arrays and any(len(a) != len(arrays[0]) for a in arrays):
        raise ValueError("upload: columns differ in length: " + ", ".join(
            f"{n}={len(a)}" for n, a in zip(names, arrays)))
    out = io.StringIO()
    out.write(",".join(names) + "\n")
    if arrays:
        table = np.column_stack([a.astype(np.float64) for a in arrays])
        np.savetxt(out, table, delimiter=",", fmt="%.17g")
    return out.getvalue()


class Client(_Client):
    """A frictiond daemon, reached over HTTP by the C++ client library.

    Args:
        url: the daemon, e.g. "http://127.0.0.1:8080".
        token: API token (docs/auth.md); None reads $FRICTIOND_TOKEN (lookups
            on loopback need none).
        cache_dir: offline model cache directory (docs/offline.md); models
            fetched are kept there and served, marked stale, when no daemon
            answers. None reads $FRICTIOND_CACHE_DIR, else no cache.
        fingertip: default fingertip of uploads.
        robot: sent as X-Robot-Id (may be empty).
        timeout_s: connect/read timeout [s].

    Calls release the GIL; one Client may be shared by threads (calls are
    serialised).
    """

    def __init__(self, url: str = "http://127.0.0.1:8080",
                 token: Optional[str] = None,
                 cache_dir: Optional[Union[str, os.PathLike]] = None,
                 fingertip: str = "default", robot: str = "",
                 timeout_s: float = 5.0) -> None:
        if token is None:
            token = os.environ.get("FRICTIOND_TOKEN") or None
        if cache_dir is None:
            cache_dir = os.environ.get("FRICTIOND_CACHE_DIR") or None
        super().__init__(url, token,
                         None if cache_dir is None else os.fspath(cache_dir),
                         fingertip, robot, timeout_s)

    def materials(self) -> List[Dict[str, Any]]:
        """The daemon's materials: dicts with id, name, description, tags
        and latest_version (None when no model yet).

        Raises:
            DaemonError: HTTP error; UnreachableError when no daemon answers.
        """
        return super().materials()

    def model(self, id: str, fingertip: str = "default",
              version: Optional[int] = None) -> Model:
        """The newest (or a given version's) model of material `id` with
        `fingertip`. With a cache_dir it is cached, and served from the
        cache (model.stale True) when no daemon answers.

        Raises:
            NotFoundError: unknown material (err.body["identification"] holds
                the stroke plan the daemon recorded), fingertip or version.
            UnreachableError: no daemon and nothing cached.
            ValueError: version <= 0.
        """
        return super().model(id, fingertip, version)

    def upload(self, id: str, strokes: Any, **params: Any) -> Dict[str, Any]:
        """Uploads test strokes of material `id`; the daemon identifies (or
        refits) its model and answers with the new version.

        Args:
            id: material id.
            strokes: a CSV file path, CSV text, a pandas-like data frame, a
                mapping of column name -> array, or a structured array, with
                columns t_s [s], fn_n [N], ft_n [N], v_mm_s [mm/s] (plus
                optional slip, stroke and covariates; CONTRACT.md).
            **params: query parameters of the upload, e.g.
                slip_peak_mm_s=0.1, slip_floor_mm_s=0.02, robot="arm-1".

        Returns:
            The daemon's reply (version, stroke_id, model summary, ...).

        Raises:
            DaemonError: 400 naming the line/field and reason (nothing
                stored), 401/403 token, 422 no slipping samples.
        """
        text = _csv_text(strokes)
        pairs = [(str(k), _param_text(v)) for k, v in params.items()]
        return self._upload_csv(id, text, pairs)


def _param_text(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(v)
