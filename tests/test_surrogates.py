"""Mode-model training (issue 16): fitting, the model file, training pairs, scenario design, the training run.

The simulations run on small synthetic cycle maps (as in ``test_simulate.py``)
and short traces, so the whole module stays well under a minute.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from evtms.errors import EvtmsInputError
from evtms.surrogates import design as D  # noqa: N812
from evtms.surrogates.io import FILE_NAME, load_mode_models, save_mode_models
from evtms.surrogates.train import FitSettings, compose_linear_skip, fit_network, train_surrogates
from evtms.system import loop as L  # noqa: N812
from evtms.system import mode_model as mm
from evtms.system.drive_cycles import DriveCycle
from evtms.system.params import system_params_from_dict
from evtms.system.refrigerant import Refrigerant
from evtms.system.simulate import simulate
from tests.test_simulate import _map  # the synthetic cycle maps that close their balance

pytest.importorskip("sklearn")


@pytest.fixture(scope="module")
def refrigerant() -> Refrigerant:
    return synthetic_refrigerant()


def synthetic_refrigerant() -> Refrigerant:
    """Synthetic cycle maps that close their balance (as in ``test_simulate.py``): seconds, no LUT files."""
    sp, Ta, Tair, Tc = [0.1, 0.5, 1.0], [243.15, 323.15], [243.15, 343.15], [243.15, 343.15]
    maps = {
        "ac": _map(
            "ac", ("speed", "blower", "T_amb", "T_air_in", "RH_air_in"), [sp, [0.1, 1], Ta, Tair, [0.0, 1.0]], 1, 0
        ),
        "chiller": _map("chiller", ("speed", "u_pump", "T_amb", "T_coolant_in"), [sp, [0.0, 1], Ta, Tc], 0, 1),
        "ac+chiller": _map(
            "ac+chiller",
            ("speed", "blower", "u_pump", "T_amb", "T_air_in", "T_coolant_in"),
            [sp, [0.1, 1], [0.0, 1], Ta, Tair, Tc],
            0.6,
            0.5,
        ),
    }
    T = np.linspace(220.0, 370.0, 301)
    p = 2.9e5 * np.exp(0.037 * (T - 273.15))
    return Refrigerant(maps, T, p, 4e-4 * 1070.0)


def _trip(seconds: int = 300) -> DriveCycle:
    t = np.arange(seconds + 1.0)
    v = 12.0 * np.clip(np.minimum(t, seconds - t) / 30.0, 0.0, 1.0)
    return DriveCycle("trip", t, v, np.zeros_like(t), "test")


def _random_network(rng: np.random.Generator, n_in: int, n_out: int, widths=(8, 5), activation="tanh") -> mm.Network:
    sizes = [n_in, *widths, n_out]
    return mm.Network(
        activation,
        [rng.normal(size=(a, b)) for a, b in zip(sizes[:-1], sizes[1:], strict=True)],
        [rng.normal(size=b) for b in sizes[1:]],
        x_mean=rng.normal(size=n_in),
        x_scale=rng.uniform(0.5, 2.0, n_in),
        y_mean=rng.normal(size=n_out),
        y_scale=rng.uniform(0.5, 2.0, n_out),
        x_min=-np.ones(n_in),
        x_max=np.ones(n_in),
    )


def _models(seed: int = 0, modes=("bc", "cc")) -> mm.ModeModels:
    rng = np.random.default_rng(seed)
    codes = [mm.MODE_CODES[m] for m in modes]
    return mm.ModeModels(
        power={c: _random_network(rng, len(mm.POWER_FEATURES), 1) for c in codes},
        dynamics={
            c: _random_network(rng, len(mm.DYNAMICS_FEATURES), len(mm.DYNAMICS_TARGETS), activation="relu")
            for c in codes
        },
        attrs={"scenarios": {}, "metrics": {}},
    )


# --- fitting -------------------------------------------------------------------------------------------------


def test_fit_recovers_a_linear_system():
    """Targets an exact linear map of 17 features with very different scales: the fit recovers it on new points."""
    rng = np.random.default_rng(1)
    n_in, n_out = len(mm.DYNAMICS_FEATURES), 3
    scales = 10.0 ** rng.uniform(-3, 5, n_in)
    A = rng.normal(size=(n_in, n_out)) / scales[:, None]
    c = np.array([1e-3, 5.0, -2e4])
    X = rng.uniform(-1, 1, (3000, n_in)) * scales
    X[:, 3] = 7.0  # a constant feature gets scale 1
    net, info = fit_network(X, X @ A + c, FitSettings(hidden=(16,), max_iter=150, max_samples=3000), seed=0)
    assert net.x_scale[3] == 1.0 and net.x_mean[3] == 7.0
    assert np.array_equal(net.x_min, X.min(axis=0)) and np.array_equal(net.x_max, X.max(axis=0))
    Xt = rng.uniform(-0.9, 0.9, (500, n_in)) * scales
    Xt[:, 3] = 7.0
    Yt = Xt @ A + c
    err = net.predict(Xt) - Yt
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) < 0.05 * Yt.std(axis=0)), info
    assert info.n_samples == 3000 and info.epochs >= 1


def test_linear_skip_is_exact():
    """The composed ReLU network equals the linear part plus the scaled residual MLP to round-off."""
    rng = np.random.default_rng(5)
    sizes = [6, 7, 5, 3]
    W = [rng.normal(size=(a, b)) for a, b in zip(sizes[:-1], sizes[1:], strict=True)]
    B = [rng.normal(size=b) for b in sizes[1:]]
    A, c = rng.normal(size=(6, 3)), rng.normal(size=3)
    r_mean, r_scale = rng.normal(size=3), rng.uniform(0.1, 2.0, 3)
    Wc, Bc = compose_linear_skip(W, B, A, c, r_mean, r_scale)
    assert [w.shape for w in Wc] == [(6, 19), (19, 17), (17, 3)]
    one = dict(x_mean=np.zeros(6), x_scale=np.ones(6), x_min=-np.ones(6), x_max=np.ones(6))
    net = mm.Network("relu", Wc, Bc, y_mean=np.zeros(3), y_scale=np.ones(3), **one)
    mlp = mm.Network("relu", W, B, y_mean=r_mean, y_scale=r_scale, **one)
    X = rng.normal(size=(200, 6)) * 3
    np.testing.assert_allclose(net.predict(X), X @ A + c + mlp.predict(X), rtol=1e-12, atol=1e-12)


def test_fit_is_reproducible():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(300, 4))
    Y = np.sin(X[:, :1])
    a, _ = fit_network(X, Y, FitSettings.quick(), seed=3)
    b, _ = fit_network(X, Y, FitSettings.quick(), seed=3)
    assert all(np.array_equal(u, v) for u, v in zip(a.weights, b.weights, strict=True))


# --- the file ----------------------------------------------------------------------------------------------------


def test_round_trip_is_bit_exact(tmp_path):
    models = _models()
    models.attrs["metrics"] = {"bc": {"rmse": 0.1}}
    path = save_mode_models(models, tmp_path / FILE_NAME)
    assert [p.name for p in tmp_path.iterdir()] == [FILE_NAME]  # no temporary left
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
    back = load_mode_models(path)
    assert back.codes() == models.codes()
    for heads in (("power", models.power, back.power), ("dynamics", models.dynamics, back.dynamics)):
        for code, net in heads[1].items():
            other = heads[2][code]
            assert net.activation == other.activation
            for u, v in zip(net.weights + net.biases, other.weights + other.biases, strict=True):
                assert np.array_equal(u, v) and u.dtype == v.dtype
            for name in ("x_mean", "x_scale", "x_min", "x_max", "y_mean", "y_scale"):
                assert np.array_equal(getattr(net, name), getattr(other, name))
    X = np.random.default_rng(0).normal(size=(50, len(mm.DYNAMICS_FEATURES)))
    code = mm.MODE_CODES["bc"]
    assert np.array_equal(models.dynamics[code].predict(X), back.dynamics[code].predict(X))
    assert np.array_equal(models.packed()[0], back.packed()[0])
    assert back.attrs["metrics"] == {"bc": {"rmse": 0.1}}
    assert back.attrs["evtms_version"] == __import__("evtms").__version__ and "created" in back.attrs


def _corrupt(tmp_path, change) -> str:
    path = save_mode_models(_models(), tmp_path / "good.npz")
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    change(data)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **data)
    with pytest.raises(EvtmsInputError) as exc:
        load_mode_models(bad)
    msg = str(exc.value)
    assert "bad.npz" in msg and "\n" not in msg
    return msg


def _set_attr(key, value):
    def change(d):
        a = json.loads(str(d["attrs"]))
        a[key] = value
        d["attrs"] = np.array(json.dumps(a))

    return change


@pytest.mark.parametrize(
    "change, expected",
    [
        (lambda d: d.pop("net.bc.dynamics.W1"), "missing 'net.bc.dynamics.W1'"),
        (lambda d: d.pop("net.cc.power.x_scale"), "missing 'net.cc.power.x_scale'"),
        (lambda d: d.__setitem__("net.bc.power.W0", np.ones((5, 8))), "'net.bc.power.W0' has shape (5, 8)"),
        (lambda d: d.__setitem__("net.bc.power.b1", np.ones(4)), "'net.bc.power.b1' has shape (4,)"),
        (lambda d: d["net.cc.dynamics.W2"].__setitem__((0, 0), np.nan), "'net.cc.dynamics.W2' holds non-finite"),
        (lambda d: d["net.bc.power.y_mean"].__setitem__(0, np.inf), "'net.bc.power.y_mean' holds non-finite"),
        (lambda d: d["net.bc.power.x_scale"].__setitem__(2, 0.0), "'net.bc.power.x_scale' holds values <= 0"),
        (
            lambda d: d.__setitem__("net.bc.power.features", np.array(["T_bat", *mm.POWER_FEATURES[1:]])),
            "'net.bc.power.features' does not match evtms.system.mode_model (position 0: 'T_bat'",
        ),
        (
            lambda d: d.__setitem__("net.bc.dynamics.features", np.array(mm.POWER_FEATURES)),
            "'net.bc.dynamics.features' does not match",
        ),
        (
            lambda d: d.__setitem__("net.bc.power.target_units", np.array(["kW"])),
            "'net.bc.power.target_units' does not match",
        ),
        (lambda d: d.__setitem__("net.bc.power.activation", np.array("gelu")), "'gelu'; allowed: relu, tanh"),
        (_set_attr("evtms_version", "latest"), "evtms_version 'latest' is not a version"),
        (_set_attr("evtms_version", 1), "evtms_version 1 is not a version"),
        (lambda d: d.__setitem__("attrs", np.array("{not json")), "'attrs' is not valid JSON"),
        (lambda d: d.__setitem__("modes", np.array(["bc", "xx"])), "mode 'xx' is unknown"),
        (lambda d: d.__setitem__("format_version", np.array(7)), "this evtms reads version 1"),
        (lambda d: d.__setitem__("format", np.array("something")), "'format' is 'something'"),
    ],
)
def test_corrupted_files_are_refused(tmp_path, change, expected):
    assert expected in _corrupt(tmp_path, change)


def test_not_an_npz_file(tmp_path):
    bad = tmp_path / "junk.npz"
    bad.write_bytes(b"not a zip at all")
    with pytest.raises(EvtmsInputError, match=r"model file '.*junk\.npz' is not a readable \.npz file"):
        load_mode_models(bad)
    with pytest.raises(EvtmsInputError, match="does not exist"):
        load_mode_models(tmp_path / "missing.npz")


def test_failed_write_leaves_the_old_file(tmp_path, monkeypatch):
    path = save_mode_models(_models(seed=0), tmp_path / FILE_NAME)
    before = path.read_bytes()

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", boom)
    with pytest.raises(OSError, match="disk full"):
        save_mode_models(_models(seed=1), path)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == [FILE_NAME]


# --- training pairs ----------------------------------------------------------------------------------------------


def test_training_pairs_split_by_mode(refrigerant):
    """A warm battery at 30 degC in auto, the cabin soaked at its setpoint: bc, then cc+bc once the cabin warms
    past its band; every step lands in exactly one mode's pairs."""
    p = system_params_from_dict({"controls": {"mode_hold": 0.0}, "cabin": {"T_set": 300.15}})
    r = simulate(_trip(400), 303.15, refrigerant, p, soak_cabin=300.15, T_init=309.0, keep_trace=True)
    pairs = mm.training_pairs(r.trace)
    modes = r.trace["modes"]
    assert sorted(pairs) == [mm.MODE_CODES["bc"], mm.MODE_CODES["cc+bc"]]
    assert sum(p[0].shape[0] for p in pairs.values()) == modes.size == r.trace["dts"].size
    for code, (xp, yp, xd, yd) in pairs.items():
        n = int(np.sum(modes == code))
        assert xp.shape == (n, len(mm.POWER_FEATURES)) and yp.shape == (n, 1)
        assert xd.shape == (n, len(mm.DYNAMICS_FEATURES)) and yd.shape == (n, len(mm.DYNAMICS_TARGETS))
        assert np.array_equal(xd[:, :-1], xp)
    # the dynamics target of the first step is the state's change over it
    code0 = int(modes[0])
    z = r.trace["states"][:, list(mm.STATE_COLUMNS)]
    np.testing.assert_allclose(pairs[code0][3][0], (z[1] - z[0]) / r.trace["dts"][0], rtol=1e-12)
    assert pairs[code0][0][0, mm.POWER_FEATURES.index("T_amb")] == 303.15


def _constant_rate_models(rates: dict[str, float]) -> mm.ModeModels:
    """Mode models for every mode whose dynamics head predicts the constant rates ``rates`` [unit s-1] (zero
    weights: the output is ``y_mean``) and whose power head predicts 0 W; every feature range is wide."""

    def net(n_in: int, y: np.ndarray) -> mm.Network:
        return mm.Network(
            "relu",
            [np.zeros((n_in, 4)), np.zeros((4, y.size))],
            [np.zeros(4), np.zeros(y.size)],
            x_mean=np.zeros(n_in),
            x_scale=np.ones(n_in),
            y_mean=y,
            y_scale=np.ones(y.size),
            x_min=np.full(n_in, -1e9),
            x_max=np.full(n_in, 1e9),
        )

    y_dyn = np.array([rates.get(name, 0.0) for name in mm.STATE_NAMES])
    codes = list(mm.MODE_CODES.values())
    return mm.ModeModels(
        power={c: net(len(mm.POWER_FEATURES), np.zeros(1)) for c in codes},
        dynamics={c: net(len(mm.DYNAMICS_FEATURES), y_dyn) for c in codes},
        attrs={"scenarios": {}, "metrics": {}},
    )


def test_a_mode_model_that_runs_away_ends_the_run_with_its_reason(refrigerant):
    """A cabin model cooling at 3 K/s leaves -100 degC after about 43 s: the run ends there with termination
    surrogate_out_of_bounds, every recorded state finite and physical (it used to go on to about -243 degC,
    where the cabin humidity's saturation pressure is 0 and the compiled loop raised ZeroDivisionError)."""
    models = _constant_rate_models({"T_cabin": -3.0})
    p = system_params_from_dict({})
    r = simulate(_trip(300), 303.15, refrigerant, p, model="surrogate", mode_models=models, keep_trace=True)
    assert r.summary["termination"] == r.attrs["termination"] == "surrogate_out_of_bounds"
    states = r.trace["states"]
    assert 40 <= r.summary["steps"] == states.shape[0] - 1 <= 45
    ta = states[:, L.S_TA]
    assert np.all(np.isfinite(ta)) and ta.min() >= L.T_STATE_MIN and ta[-1] < L.T_STATE_MIN + 3.5
    assert math.isfinite(r.summary["T_cabin_end_degC"]) and math.isfinite(r.summary["soc_end"])
    # the same models held to a physical rate finish the trip
    calm = _constant_rate_models({"T_cabin": -0.01})
    r = simulate(_trip(300), 303.15, refrigerant, p, model="surrogate", mode_models=calm)
    assert r.summary["termination"] == "end of cycle" and r.summary["steps"] == 300


# --- design ------------------------------------------------------------------------------------------------------


def test_design_holds_out_cycles_and_ambients():
    des = D.design(D.modes_for(["all"]), seed=4)
    assert des.cycles("train").isdisjoint(des.cycles("heldout"))
    assert des.cycles("heldout") == set(D.HELDOUT_CYCLES)
    assert des.ambients("train").isdisjoint(des.ambients("heldout"))
    held = {round(t - D.C0, 6) for t in des.ambients("heldout")}
    assert held <= set(D.HELDOUT_AMBIENTS_C) and {-10.0, 30.0, 40.0} <= held
    for sc in des.train:
        lo, hi = D.RANGES[sc.target].T_amb
        assert lo <= sc.T_amb - D.C0 <= hi
        assert min(abs(sc.T_amb - D.C0 - h) for h in D.HELDOUT_AMBIENTS_C) >= D.AMBIENT_GAP
    for sc in des.heldout:  # held-out ambients lie inside the training range: generalisation, not extrapolation
        lo, hi = D.RANGES[sc.target].T_amb if sc.target != "auto" else D.RANGES["off"].T_amb
        assert lo + D.AMBIENT_GAP <= sc.T_amb - D.C0 <= hi - D.AMBIENT_GAP
    for m in mm.MODE_CODES:  # training ambients reach past every held-out one on both sides
        T = [s.T_amb for s in des.train if s.target == m]
        assert all(min(T) < s.T_amb < max(T) for s in des.heldout if s.target == m)
    assert {s.target for s in des.train} == set(mm.MODE_CODES)
    assert {s.mode for s in des.heldout if s.target != "auto"} == set(mm.MODE_CODES)
    assert len({s.name for s in des.train + des.heldout}) == len(des.train) + len(des.heldout)
    assert D.design(["bc"], seed=4) == D.design(["bc"], seed=4) != D.design(["bc"], seed=5)


def test_cooling_modes_train_warm_heating_modes_cold():
    des = D.design(["cc", "ch"], seed=0)
    assert all(s.T_amb >= D.C0 + 20 for s in des.train + des.heldout if s.target == "cc")
    assert all(s.T_amb <= D.C0 + 10 for s in des.train + des.heldout if s.target == "ch")


def test_synthetic_cycle():
    c = D.synthetic_cycle(3)
    assert c.duration == 1800.0 and c.speed[0] == 0.0 == c.speed[-1]
    assert np.all(c.speed >= 0) and c.speed.max() <= 130 / 3.6 + 1e-9 and c.distance > 1000
    assert np.array_equal(c.speed, D.synthetic_cycle(3).speed)


# --- a training run ----------------------------------------------------------------------------------------------


def test_train_writes_a_checked_file_and_keeps_other_modes(refrigerant, tmp_path, monkeypatch):
    monkeypatch.setattr(D, "synthetic_cycle", lambda seed, duration=300.0: _trip(300))
    seen = []
    rep = train_surrogates(refrigerant, ["bc"], tmp_path, quick=True, progress=lambda *a: seen.append(a))
    assert rep.path == tmp_path / FILE_NAME and rep.path.is_file()
    assert list(rep.modes) == ["bc"] and rep.modes["bc"].n_train >= 200
    assert seen[-1][0] == seen[-1][1] and all(isinstance(m, str) for _, _, m in seen)
    bc = rep.modes["bc"]
    assert set(bc.one_step) == {"P_compressor", "dT_battery_dt", "dT_cabin_dt", "dT_coolant_dt"}
    assert all(np.isfinite(v) for v in bc.one_step.values())
    assert bc.rollout["runs"] >= 1 and np.isfinite(bc.rollout["T_battery"]["rmse"])
    m = load_mode_models(rep.path)
    assert m.codes() == [mm.MODE_CODES["bc"]]
    assert m.attrs["metrics"]["bc"]["n_train"] == bc.n_train
    assert all(s["cycle"] not in D.HELDOUT_CYCLES for s in m.attrs["scenarios"]["bc"] if s["role"] == "train")
    rep2 = train_surrogates(refrigerant, ["cc"], tmp_path, quick=True)
    assert rep2.kept == ["bc"]
    m2 = load_mode_models(rep2.path)
    assert m2.codes() == sorted([mm.MODE_CODES["bc"], mm.MODE_CODES["cc"]])
    assert np.array_equal(m2.packed()[0][: m.power[2].packed().size], m.power[2].packed())
    assert set(m2.attrs["metrics"]) == {"bc", "cc"}


def test_a_fit_that_runs_away_in_closed_loop_is_refit_and_the_best_kept(refrigerant, tmp_path, monkeypatch):
    from evtms.surrogates import train as train_module

    monkeypatch.setattr(D, "synthetic_cycle", lambda seed, duration=300.0: _trip(300))
    errors = iter([math.inf, 0.4 * train_module.STABLE_ROLLOUT_K + 1.0, 0.5 * train_module.STABLE_ROLLOUT_K])
    seeds = []
    real_fit = train_module.fit_network
    monkeypatch.setattr(train_module, "_training_rollout_error", lambda *a: next(errors))

    def fit(*args, seed, **kwargs):
        seeds.append(seed)
        return real_fit(*args, seed=seed, **kwargs)

    monkeypatch.setattr(train_module, "fit_network", fit)
    rep = train_surrogates(refrigerant, ["bc"], tmp_path, quick=True, seed=7)
    bc = rep.modes["bc"]
    # inf (diverged), then above the limit, then within it: three fits with three seeds, the last kept.
    assert bc.fit_attempts == 3 and bc.train_rollout_rmse_K == 0.5 * train_module.STABLE_ROLLOUT_K
    assert seeds == [7, 7, 1007, 1007, 2007, 2007]


def test_a_rollout_the_model_cut_short_counts_as_diverged(refrigerant, monkeypatch):
    """The training's closed-loop check: a rollout ended by a state leaving the physical range is inf, not the
    RMSE of the steps before it (which would let a model that ran away pass as merely inaccurate)."""
    from evtms.surrogates import train as train_module

    p = system_params_from_dict({})
    lut = simulate(_trip(120), 303.15, refrigerant, p, mode="off")
    runs = {}

    def run(sc, refrigerant, params, keep_trace, mode_models):
        runs[sc.name] = simulate(
            _trip(120), 303.15, refrigerant, p, mode="off", model="surrogate", mode_models=mode_models
        )
        return runs[sc.name]

    monkeypatch.setattr(train_module, "run_scenario", run)
    code = mm.MODE_CODES["off"]
    for rate, expected in ((-3.0, math.inf), (0.0, None)):
        models = _constant_rate_models({"T_cabin": rate})
        err = train_module._training_rollout_error(
            code, models.power[code], models.dynamics[code], [SimpleNamespace(name="s")], {"s": lut}, refrigerant, p
        )
        if expected is None:
            assert runs["s"].summary["termination"] == "end of cycle" and math.isfinite(err)
        else:
            assert runs["s"].summary["termination"] == "surrogate_out_of_bounds" and err == expected


def test_train_refuses_bad_input(refrigerant, tmp_path):
    with pytest.raises(EvtmsInputError, match="`mode` 'heat' is unknown; allowed: off, bh"):
        train_surrogates(refrigerant, ["heat"], tmp_path)
    (tmp_path / "file").write_text("x")
    with pytest.raises(EvtmsInputError, match="exists and is not a folder"):
        train_surrogates(refrigerant, ["bc"], tmp_path / "file")
    (tmp_path / FILE_NAME).write_bytes(b"junk")
    with pytest.raises(EvtmsInputError, match="is not a readable .npz file"):
        train_surrogates(refrigerant, ["bc"], tmp_path, quick=True)
    assert (tmp_path / FILE_NAME).read_bytes() == b"junk"


def test_simulation_never_imports_sklearn():
    code = "import sys, evtms.system.simulate, evtms.system.mode_model; assert 'sklearn' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_missing_sklearn_is_one_line_before_any_work(refrigerant, tmp_path, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "sklearn" else real(name, *a))
    with pytest.raises(EvtmsInputError, match=r"needs scikit-learn; install it with: python3 -m pip install"):
        train_surrogates(refrigerant, ["bc"], tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_report_is_json(refrigerant, tmp_path, monkeypatch):
    monkeypatch.setattr(D, "synthetic_cycle", lambda seed, duration=300.0: _trip(300))
    rep = train_surrogates(refrigerant, ["ch"], tmp_path, quick=True)
    d = json.loads(json.dumps(rep.to_dict(), allow_nan=False))
    assert d["path"] == str(tmp_path / FILE_NAME) and d["modes"]["ch"]["n_train"] == rep.modes["ch"].n_train
