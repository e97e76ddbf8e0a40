"""Tests of the frictiond Python module: against a daemon started on
loopback (conftest.py), against a cached model offline, and vectorised calls
against the C++ scalar functions element by element."""

import json
import threading
import urllib.request

import numpy as np
import pytest

import frictiond
from conftest import TOKEN, free_port


@pytest.fixture(scope="module")
def model(felt):
    return frictiond.Client(felt.url).model("felt")


# --------------------------------------------------------------------------
# Against the daemon


def test_materials_and_model(felt, model):
    c = frictiond.Client(felt.url)
    ids = [m["id"] for m in c.materials()]
    assert "felt" in ids
    assert model.material == "felt" and model.fingertip == "default"
    assert model.version >= 1 and model.source == "daemon" and not model.stale
    coef = model.coefficients
    assert set(coef) >= {"intercept", "v_mm_s", "fn_n"}
    # The planted model (conftest.simulate_strokes) is recovered.
    assert coef["intercept"] == pytest.approx(0.9, abs=0.05)
    assert coef["v_mm_s"] == pytest.approx(0.004, abs=0.001)
    assert coef["fn_n"] == pytest.approx(-0.03, abs=0.015)
    assert model.eps_quantiles.shape == model.eps_levels.shape
    assert np.all(np.diff(model.eps_quantiles) >= 0)


def test_predict_matches_the_daemon(felt, model):
    fn = np.array([1.5, 2.5, 3.5])
    v = np.array([[20.0], [40.0]])
    p = model.predict(fn, v)
    assert p.mu.shape == (2, 3)
    for i in range(2):
        for j in range(3):
            url = (f"{felt.url}/v1/materials/felt/predict?fn_n={fn[j]!r}"
                   f"&v_mm_s={v[i, 0]!r}")
            with urllib.request.urlopen(url) as r:
                body = json.load(r)
            assert p.mu[i, j] == pytest.approx(body["mu"], rel=1e-12, abs=1e-15)
            assert p.sigma[i, j] == pytest.approx(body["sigma"], rel=1e-12)


def test_unknown_material_is_a_not_found_error_with_the_plan(felt):
    c = frictiond.Client(felt.url)
    with pytest.raises(frictiond.NotFoundError) as e:
        c.model("canvas")
    assert e.value.status == 404
    assert isinstance(e.value.body, dict)
    assert "identification" in e.value.body
    assert isinstance(e.value, LookupError)


def test_bad_upload_carries_the_daemon_field_and_message(felt, strokes):
    c = frictiond.Client(felt.url, token=TOKEN)
    bad = dict(strokes)
    bad["fn_n"] = bad["fn_n"].copy()
    bad["fn_n"][5] = -1.0
    with pytest.raises(frictiond.DaemonError) as e:
        c.upload("felt-bad", bad)
    assert e.value.status == 400
    assert e.value.field is not None and "fn_n" in e.value.field + (e.value.detail or "")
    assert e.value.detail and "line" in e.value.detail
    assert e.value.error
    # Nothing stored.
    with pytest.raises(frictiond.NotFoundError):
        c.model("felt-bad")


def test_upload_needs_a_token(felt, strokes, monkeypatch):
    monkeypatch.delenv("FRICTIOND_TOKEN", raising=False)
    c = frictiond.Client(felt.url)
    with pytest.raises(frictiond.DaemonError) as e:
        c.upload("felt-anon", strokes)
    assert e.value.status == 401


def test_upload_forms(felt, strokes, tmp_path):
    c = frictiond.Client(felt.url, token=TOKEN)
    # A CSV file path, CSV text and a structured array give the same model.
    path = tmp_path / "s.csv"
    path.write_text(frictiond._csv_text(strokes))
    r1 = c.upload("felt-file", path)
    r2 = c.upload("felt-text", path.read_text())
    arr = np.zeros(len(strokes["t_s"]), dtype=[(k, "f8") for k in strokes])
    for k in strokes:
        arr[k] = strokes[k]
    r3 = c.upload("felt-struct", arr)
    assert r1["version"] == r2["version"] == r3["version"] == 1
    m1, m3 = c.model("felt-file"), c.model("felt-struct")
    assert m1.coefficients == m3.coefficients

    class Frame:  # pandas-like
        def to_csv(self, index):
            assert index is False
            return frictiond._csv_text(strokes)

    assert c.upload("felt-frame", Frame())["version"] == 1
    # Query parameters pass through (the real trace needs slow thresholds).
    with pytest.raises(ValueError):
        c.upload("felt-x", {"t_s": [0, 1], "fn_n": [1]})


def test_unreachable_daemon():
    c = frictiond.Client(f"http://127.0.0.1:{free_port()}", timeout_s=1)
    with pytest.raises(frictiond.UnreachableError) as e:
        c.materials()
    assert e.value.status == 0
    assert isinstance(e.value, ConnectionError)


# --------------------------------------------------------------------------
# Offline: a cached model


def test_cached_model_offline(felt, tmp_path):
    cache = tmp_path / "cache"
    online = frictiond.Client(felt.url, cache_dir=cache).model("felt")
    assert online.source == "daemon" and not online.stale
    dead = frictiond.Client(f"http://127.0.0.1:{free_port()}", cache_dir=cache,
                            timeout_s=1)
    offline = dead.model("felt")
    assert offline.stale and offline.source == "cache"
    assert offline.daemon_error
    assert offline.version == online.version
    fn, v = np.linspace(0.5, 5, 7), np.linspace(1, 80, 7)
    np.testing.assert_array_equal(offline.predict(fn, v).mu, online.predict(fn, v).mu)
    # Nothing cached for another material: the error says no daemon answered.
    with pytest.raises(frictiond.UnreachableError):
        dead.model("canvas")
    with pytest.raises(frictiond.UnreachableError):
        dead.resync()
    # Back online, resync refreshes every cached model.
    entries = frictiond.Client(felt.url, cache_dir=cache).resync()
    assert [(e["material"], e["error"]) for e in entries] == [("felt", "")]
    assert entries[0]["version"] == online.version


def test_docstrings_carry_units():
    for method, unit in ((frictiond.Model.predict, "[mm/s]"),
                         (frictiond.Model.slip_likelihood, "[N]"),
                         (frictiond.Model.grip_force, "[s]"),
                         (frictiond.Model.sample_mu, "[N]"),
                         (frictiond.Model.sample_mu_episodes, "(n_envs, n_steps)")):
        assert unit in method.__doc__, method
    assert "token" in frictiond.Client.__doc__


def test_model_json_round_trip(model):
    again = frictiond.Model.from_json(model.to_json())
    assert again.source == "json" and again.version == model.version
    fn = np.linspace(0.5, 5, 11)
    np.testing.assert_array_equal(again.predict(fn, 30.0).mu, model.predict(fn, 30.0).mu)
    again2 = frictiond.Model.from_json(json.dumps(model.to_json()))
    assert again2.coefficients == model.coefficients
    bare = frictiond.Model.from_json({"material": "x"})
    assert not bare.has_stochastic
    with pytest.raises(ValueError, match="no stochastic family"):
        bare.predict(1.0, 1.0)
    with pytest.raises(ValueError):
        frictiond.Model.from_json({"material": "x", "stochastic": {"mu": 3}})
    with pytest.raises(ValueError):
        frictiond.Model.from_json("{not json")


# --------------------------------------------------------------------------
# Vectorised == C++ scalar, element by element


def grid(rng, shape, lo, hi):
    return rng.uniform(lo, hi, size=shape)


def test_predict_equals_scalar(model):
    rng = np.random.default_rng(1)
    fn = grid(rng, (4, 1, 5), 0.2, 6.0)
    v = grid(rng, (3, 5), 0.0, 90.0)
    p = model.predict(fn, v)
    assert p.mu.shape == (4, 3, 5) and p.extrapolated.dtype == bool
    fb, vb = np.broadcast_arrays(fn, v)
    for idx in np.ndindex(p.mu.shape):
        s = model._predict_scalar(fb[idx], vb[idx])
        assert (p.mu[idx], p.sigma[idx], p.lo95[idx], p.hi95[idx],
                p.extrapolated[idx]) == s, idx


def test_scalars_give_zero_dim_arrays(model):
    p = model.predict(2.0, 30.0)
    assert isinstance(p.mu, np.ndarray) and p.mu.shape == ()
    assert float(p.mu) == model._predict_scalar(2.0, 30.0)[0]
    assert model.predict([1.0, 2.0], 30).mu.shape == (2,)
    assert model.predict(np.array([], dtype=float), 30).mu.shape == (0,)


def test_non_contiguous_and_integer_inputs(model):
    fn = np.arange(1, 13, dtype=np.int64).reshape(3, 4).T[::2]  # strided, int
    v = np.linspace(5, 60, 6)[::-2][:, None][:2]
    p = model.predict(fn, v)
    fb, vb = np.broadcast_arrays(fn.astype(float), v)
    for idx in np.ndindex(p.mu.shape):
        assert p.mu[idx] == model._predict_scalar(fb[idx], vb[idx])[0]


def test_slip_likelihood_equals_scalar(model):
    rng = np.random.default_rng(2)
    fn = grid(rng, (6, 7), 0.5, 5.0)
    ft = fn * grid(rng, (7,), 0.2, 1.5)
    L = model.slip_likelihood(fn, ft)
    assert L.shape == (6, 7) and np.all((L >= 0) & (L <= 1))
    for idx in np.ndindex(L.shape):
        assert L[idx] == model._slip_likelihood_scalar(fn[idx], ft[idx])


def test_grip_force_equals_scalar(model):
    load = np.array([[0.5], [1.0], [3.0], [8.0]])
    risk = np.array([0.001, 0.01, 0.05, 0.3, 0.6])
    g = model.grip_force(load, risk)
    assert g.fn_n.shape == (4, 5) and g.status.shape == (4, 5)
    for i in range(4):
        for j in range(5):
            check_grip(model, g, (i, j), load[i, 0], risk[j], 0.0, 0.0)


def check_grip(model, g, idx, load, risk, hold, v):
    ok, fn, mu, extra, why, sd, inst, min_risk, status = model._grip_force_scalar(
        load, risk, hold, v)
    assert g.attainable[idx] == ok, idx
    assert g.status[idx] == status, idx
    assert (frictiond.GRIP_STATUS[status] == "ok") == ok
    if ok:
        assert (g.fn_n[idx], g.mu_used[idx], g.fn_n_sd[idx], g.instant_risk[idx]) == (
            fn, mu, sd, inst), idx
    else:
        assert np.isnan(g.fn_n[idx]) and why, idx
    assert g.extrapolated[idx] == extra and g.min_supported_risk[idx] == min_risk, idx


def test_grip_force_for_a_hold_equals_scalar(model):
    assert model.eps_time is not None, "the simulated strokes identify eps's time model"
    load = np.array([1.0, 2.0])[:, None, None]
    risk = np.array([0.01, 0.05, 0.2])[None, :, None]
    hold = np.array([0.0, 0.5, 3.0])
    g = model.grip_force(load, risk, hold_s=hold, v_mm_s=10.0)
    assert g.fn_n.shape == (2, 3, 3)
    lb, rb, hb = np.broadcast_arrays(load, risk, hold)
    for idx in np.ndindex(g.fn_n.shape):
        check_grip(model, g, idx, lb[idx], rb[idx], hb[idx], 10.0)
    # Holding longer needs at least as much force at the same risk.
    ok = g.attainable[..., 1] & g.attainable[..., 2]
    assert np.all(g.fn_n[..., 2][ok] >= g.fn_n[..., 1][ok])


def test_hold_slip_probability_inverts_grip_force(model):
    load = np.array([1.0, 2.0])[:, None, None]
    risk = np.array([0.01, 0.05, 0.2])[None, :, None]
    hold = np.array([0.0, 0.5, 3.0])
    g = model.grip_force(load, risk, hold_s=hold, v_mm_s=10.0)
    lb, rb, hb = np.broadcast_arrays(load, risk, hold)
    ok = g.attainable
    assert ok.sum() >= 9
    p = model.hold_slip_probability(g.fn_n[ok], lb[ok], hold_s=hb[ok], v_mm_s=10.0)
    np.testing.assert_allclose(p, rb[ok], rtol=1e-4)
    assert np.all(model.hold_slip_probability(1.1 * g.fn_n[ok], lb[ok],
                                              hold_s=hb[ok], v_mm_s=10.0) < rb[ok])
    assert model.hold_slip_probability(2.0, 0.0, v_mm_s=10.0) == 0.0
    with pytest.raises(ValueError, match=r"at index \(1,\): fn_n"):
        model.hold_slip_probability([2.0, -1.0], 1.0)


def test_grip_force_rejects_bad_elements(model):
    with pytest.raises(ValueError, match=r"at index \(2,\): load_n = -1"):
        model.grip_force([1.0, 2.0, -1.0], 0.01)
    with pytest.raises(ValueError, match="risk = 1.5"):
        model.grip_force(1.0, 1.5)
    with pytest.raises(ValueError, match="hold_s"):
        model.grip_force(1.0, 0.01, hold_s=[1.0, -2.0])
    with pytest.raises(ValueError, match="v_mm_s"):
        model.grip_force(1.0, 0.01, v_mm_s=-1.0)


def test_shapes_that_do_not_broadcast(model):
    with pytest.raises(ValueError, match="could not be broadcast"):
        model.predict(np.ones(3), np.ones(4))
    with pytest.raises(TypeError):
        model.predict("a", 1.0)


def test_sample_mu_equals_scalar_and_numpy(model):
    fn = np.array([1.0, 2.0, 4.0])
    v = np.array([[10.0], [50.0]])
    s = model.sample_mu(fn, v, rng=np.random.default_rng(5))
    u = np.random.default_rng(5).random((2, 3))  # the same stream
    for idx in np.ndindex(s.shape):
        mean = model._predict_scalar(fn[idx[1]], v[idx[0], 0])[0]
        assert s[idx] == mean + model._eps_quantile_scalar(u[idx]), idx
    # ... and eq. (1) written in plain NumPy from the model JSON agrees to
    # rounding (the bench's reference, python/bench/python_bench.py).
    j = model.to_json()["stochastic"]
    c = j["coefficients"]
    mean = c["intercept"] + c["v_mm_s"] * v + c["fn_n"] * fn
    ref = mean + np.interp(u, j["eps_quantiles"]["levels"], j["eps_quantiles"]["values"])
    np.testing.assert_allclose(s, ref, rtol=1e-13, atol=1e-15)


def test_sample_mu_is_reproducible_and_advances_the_generator(model):
    a = model.sample_mu(2.0, 30.0, rng=123, size=1000)
    b = model.sample_mu(2.0, 30.0, rng=123, size=1000)
    np.testing.assert_array_equal(a, b)
    g = np.random.default_rng(9)
    c1 = model.sample_mu(2.0, 30.0, rng=g, size=10)
    c2 = model.sample_mu(2.0, 30.0, rng=g, size=10)
    assert not np.array_equal(c1, c2)
    g2 = np.random.default_rng(9)
    np.testing.assert_array_equal(
        np.concatenate([c1, c2]), model.sample_mu(2.0, 30.0, rng=g2, size=20))
    assert model.sample_mu(2.0, 30.0, size=(3, 4)).shape == (3, 4)
    with pytest.raises(ValueError):
        model.sample_mu(np.ones(3), 30.0, size=4)
    with pytest.raises(TypeError):
        model.sample_mu(2.0, 30.0, rng="seed")


def test_sample_mu_distribution(model):
    s = model.sample_mu(2.0, 30.0, rng=4, size=200000)
    mean = model._predict_scalar(2.0, 30.0)[0]
    for p in (0.05, 0.5, 0.95):
        q = mean + model._eps_quantile_scalar(p)
        assert np.mean(s < q) == pytest.approx(p, abs=4 * np.sqrt(p * (1 - p) / 2e5))


# --------------------------------------------------------------------------
# Domain randomisation


def test_episodes_shape_seed_and_independent_case(model):
    a = model.sample_mu_episodes(64, 50, 2.0, 30.0, rng=3, ar1=None)
    assert a.shape == (64, 50) and a.dtype == np.float64
    np.testing.assert_array_equal(
        a, model.sample_mu_episodes(64, 50, 2.0, 30.0, rng=3, ar1=0.0))
    # Independent steps are sample_mu on an (N, T) grid with the same stream.
    np.testing.assert_array_equal(
        a, model.sample_mu(2.0, 30.0, rng=3, size=(64, 50)))
    # "model": the identified eps time model's phi and offset share (phi per
    # data sample, or converted to the step dt_s).
    t = model.eps_time
    assert t is not None and t["dt_s"] > 0
    assert 0 <= t["phi"] <= 1 and 0 <= t["offset_fraction"] <= 1
    assert model.eps_ar1 == t["phi"]
    np.testing.assert_array_equal(
        model.sample_mu_episodes(64, 50, 2.0, 30.0, rng=3),
        model.sample_mu_episodes(64, 50, 2.0, 30.0, rng=3, ar1=t["phi"],
                                 offset_fraction=t["offset_fraction"]))
    np.testing.assert_array_equal(
        model.sample_mu_episodes(64, 50, 2.0, 30.0, rng=3, dt_s=0.05),
        model.sample_mu_episodes(64, 50, 2.0, 30.0, rng=3,
                                 ar1=t["phi"] ** (0.05 / t["dt_s"]),
                                 offset_fraction=t["offset_fraction"]))


def test_episodes_per_environment_inputs(model):
    fn = np.linspace(1.0, 4.0, 8)[:, None]  # one Fn per environment
    a = model.sample_mu_episodes(8, 100, fn, 30.0, rng=1, ar1=1.0)
    # ar1 = 1: one draw per episode, held.
    assert np.all(a == a[:, :1])
    assert len(np.unique(a[:, 0])) == 8
    with pytest.raises(ValueError, match="broadcast"):
        model.sample_mu_episodes(8, 100, np.ones(7)[:, None], 30.0)
    with pytest.raises(ValueError, match="ar1 = 1.5"):
        model.sample_mu_episodes(8, 100, 2.0, 30.0, ar1=1.5)
    with pytest.raises(TypeError, match="ar1"):
        model.sample_mu_episodes(8, 100, 2.0, 30.0, ar1=[0.5])
    with pytest.raises(ValueError, match="ar1"):
        model.sample_mu_episodes(8, 100, 2.0, 30.0, ar1="strong")
    with pytest.raises(ValueError, match="envs = 0"):
        model.sample_mu_episodes(0, 100, 2.0, 30.0)


def test_episodes_ar1_correlation_and_marginal(model):
    a = model.sample_mu_episodes(4000, 20, 2.0, 30.0, rng=11, ar1=0.8)
    x, y = a[:, :-1].ravel(), a[:, 1:].ravel()
    r = np.corrcoef(x, y)[0, 1]
    assert 0.7 < r < 0.85, r  # ~ar1 on the mu scale (exact on normal scores)
    mean = model._predict_scalar(2.0, 30.0)[0]
    med = mean + model._eps_quantile_scalar(0.5)
    assert np.mean(a[:, -1] < med) == pytest.approx(0.5, abs=4 * np.sqrt(0.25 / 4000))


def test_episode_offset(model):
    # f = 1: one draw per episode, whatever ar1; f = 0.5, ar1 = 0: steps
    # correlate ~0.5 at any lag (on the normal scores; a little less on mu).
    a = model.sample_mu_episodes(50, 30, 2.0, 30.0, rng=2, ar1=0.3, offset_fraction=1.0)
    assert np.all(a == a[:, :1])
    b = model.sample_mu_episodes(4000, 20, 2.0, 30.0, rng=3, ar1=0.0, offset_fraction=0.5)
    r = np.corrcoef(b[:, 0], b[:, 19])[0, 1]
    assert 0.4 < r < 0.55, r
    with pytest.raises(ValueError, match="offset_fraction = 2"):
        model.sample_mu_episodes(8, 10, 2.0, 30.0, offset_fraction=2.0)
    with pytest.raises(ValueError, match="dt_s"):
        model.sample_mu_episodes(8, 10, 2.0, 30.0, dt_s=0.0)


def test_calls_release_the_gil(model):
    # While a worker thread is inside a long C++ call, this thread keeps
    # running: it records times in the middle third of the call. A call that
    # held the GIL would let it run at most one switch interval (5 ms) at
    # either end.
    import time

    window = {}

    def work():
        window["start"] = time.perf_counter()
        model.sample_mu_episodes(4000, 500, 2.0, 30.0, rng=1, ar1=0.5)
        window["end"] = time.perf_counter()

    ticks = []
    t = threading.Thread(target=work)
    t.start()
    while t.is_alive():
        ticks.append(time.perf_counter())
    t.join()
    start, end = window["start"], window["end"]
    assert end - start > 0.03, "call too short to judge"
    third = (end - start) / 3
    middle = [x for x in ticks if start + third < x < end - third]
    assert middle, (start, end, len(ticks))
