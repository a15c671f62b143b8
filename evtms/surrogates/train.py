"""Training the mode models: LUT simulations -> per-mode step pairs -> two small networks per mode -> held-out check.

:func:`train_surrogates` is what ``evtms surrogate train`` runs:

1. data: every scenario of :func:`evtms.surrogates.design.design` is simulated
   on the cycle maps (``model="lut"``, dt 1 s) keeping the loop's trace, and
   :func:`evtms.system.mode_model.training_pairs` splits its steps by mode code;
2. fit: per mode code, a ``power`` and a ``dynamics`` network
   (:func:`fit_network`: inputs and outputs standardised, scikit-learn's
   :class:`~sklearn.neural_network.MLPRegressor` with early stopping and a
   fixed ``random_state``); the weights are copied into
   :class:`~evtms.system.mode_model.Network`, so inference needs NumPy only;
3. held-out check: on the held-out scenarios (other drive cycles and
   ambients than training), the one-step error of each network, and, when
   :func:`~evtms.system.simulate.simulate` offers ``model="surrogate"``, the
   closed-loop error of the run on the networks against the LUT run (RMSE
   and largest deviation of T_battery, T_cabin, T_coolant, SOC and P_hvac);
4. the file: ``<out_dir>/mode_models.npz`` (:mod:`evtms.surrogates.io`),
   written atomically; modes already in an existing file and not retrained
   are kept.

scikit-learn is needed here only (an optional extra); nothing in
:mod:`evtms.system` imports it.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import evtms
from evtms.errors import EvtmsInputError
from evtms.surrogates import design as D  # noqa: N812 - the design module, read as D.*
from evtms.surrogates.io import FILE_NAME, load_mode_models, save_mode_models
from evtms.system import loop as L  # noqa: N812 - the loop's index constants
from evtms.system import mode_model as mm
from evtms.system.params import SystemParams
from evtms.system.refrigerant import Refrigerant, load_refrigerant
from evtms.system.simulate import SimulationResult, simulate

Progress = Callable[[int, int, str], None]
#: Variables compared between the surrogate and the LUT run on held-out scenarios.
ROLLOUT_VARIABLES = ("T_battery", "T_cabin", "T_coolant", "SOC", "P_hvac")
#: One-step targets reported (name -> column in the dynamics targets, or the power target).
ONE_STEP = {
    "P_compressor": ("power", 0),
    "dT_battery_dt": ("dynamics", mm.DYNAMICS_TARGETS.index("dT_battery_dt")),
    "dT_cabin_dt": ("dynamics", mm.DYNAMICS_TARGETS.index("dT_cabin_dt")),
    "dT_coolant_dt": ("dynamics", mm.DYNAMICS_TARGETS.index("dT_coolant_dt")),
}
SKLEARN_MISSING = "surrogate training needs scikit-learn; install it with: python3 -m pip install scikit-learn"
#: Fewest training steps a mode needs to get networks.
MIN_SAMPLES = 200


@dataclass(frozen=True)
class FitSettings:
    """How each network is fitted.

    Attributes
    ----------
    hidden : tuple of int
        Hidden-layer widths (1-2 layers of 16-64 units).
    activation : str
        ``tanh`` or ``relu``.
    max_iter : int
        Most epochs (early stopping usually ends sooner).
    max_samples : int
        Most steps per mode fitted (a seeded random subset beyond).
    alpha : float
        L2 penalty [1].
    linear : bool
        Fit a linear least-squares model first and the MLP (ReLU) on its residual, composed into one
        network (:func:`compose_linear_skip`).
    """

    hidden: tuple[int, ...] = (32, 32)
    activation: str = "tanh"
    max_iter: int = 200
    max_samples: int = 12_000
    alpha: float = 1e-6
    linear: bool = True

    @classmethod
    def quick(cls) -> FitSettings:
        """Tiny networks and few epochs (tests)."""
        return cls(hidden=(16,), max_iter=40, max_samples=3000)


@dataclass
class FitInfo:
    """What one fit did: samples, epochs, time [s] and the training loss (standardised)."""

    n_samples: int
    epochs: int
    time_s: float
    loss: float


@dataclass
class ModeReport:
    """Per mode: data, fit and held-out errors.

    Attributes
    ----------
    mode : str
        Mode name; ``code`` its loop code.
    n_train, n_fitted : int
        Training steps of the mode, and how many were fitted (subset above ``max_samples``).
    n_heldout : int
        Held-out steps of the mode (one-step check).
    fit_power, fit_dynamics : FitInfo
    one_step : dict of str to float
        RMSE on the held-out steps: ``P_compressor`` [W], ``dT_battery_dt``, ``dT_cabin_dt``, ``dT_coolant_dt`` [K/s].
    fit_attempts : int
        Fits made: a fit whose closed-loop run on the mode's own training
        scenarios strays more than :data:`STABLE_ROLLOUT_K` from the LUT runs
        is redone with another seed (at most :data:`FIT_ATTEMPTS`), the best kept.
    train_rollout_rmse_K : float
        That check's worst RMSE of T_battery, T_cabin, T_coolant [K] (inf: a run left finite numbers).
    rollout : dict of str to dict, or None
        Closed-loop errors on the mode's held-out runs (forced mode), per
        variable of :data:`ROLLOUT_VARIABLES`: ``rmse`` and ``max`` (largest
        absolute deviation) [K, 1 for SOC, W for P_hvac]; ``out_of_range``
        the share of steps flagged out of the training range. None when the
        simulator cannot run the surrogate or the mode has no held-out run.
    """

    mode: str
    code: int
    n_train: int
    n_fitted: int
    n_heldout: int
    fit_power: FitInfo
    fit_dynamics: FitInfo
    one_step: dict[str, float]
    rollout: dict | None = None
    fit_attempts: int = 1
    train_rollout_rmse_K: float = math.nan


@dataclass
class TrainReport:
    """A training run.

    Attributes
    ----------
    path : Path
        Model file written.
    modes : dict of str to ModeReport
        Modes trained in this run.
    skipped : dict of str to str
        Modes without networks and why (too few steps).
    auto : dict or None
        Closed-loop errors of the held-out ``auto`` runs (every mode trained), as :attr:`ModeReport.rollout`.
    kept : list of str
        Modes kept from an existing file.
    n_train_runs, n_heldout_runs : int
    data_time_s, fit_time_s, eval_time_s, total_time_s : float
        Wall times [s].
    """

    path: Path
    modes: dict[str, ModeReport]
    skipped: dict[str, str] = field(default_factory=dict)
    auto: dict | None = None
    kept: list[str] = field(default_factory=list)
    n_train_runs: int = 0
    n_heldout_runs: int = 0
    data_time_s: float = 0.0
    fit_time_s: float = 0.0
    eval_time_s: float = 0.0
    total_time_s: float = 0.0

    def to_dict(self) -> dict:
        """Plain values for ``--json`` (NaN as None)."""
        d = dataclasses.asdict(self)
        d["path"] = str(self.path)
        return _json_safe(d)


# ---------------------------------------------------------------------------------------------------------------
# Simulator capabilities


def run_scenario(
    sc: D.Scenario,
    refrigerant: Refrigerant,
    params: SystemParams | None = None,
    *,
    keep_trace: bool = True,
    mode_models: mm.ModeModels | None = None,
) -> SimulationResult:
    """Simulate one scenario at dt 1 s (on the LUT maps, or on ``mode_models`` when given).

    With ``keep_trace`` the result carries ``trace`` (the loop's states,
    outputs, modes, step lengths and parameters).
    """
    kwargs = dict(
        dt=1.0,
        mode=sc.mode,
        RH_amb=sc.RH_amb,
        sun=sc.sun,
        soak_cabin=sc.T_cabin0,
        scenario=sc.name,
    )
    if mode_models is not None:
        kwargs.update(model="surrogate", mode_models=mode_models)
    return simulate(sc.drive_cycle(), sc.T_amb, refrigerant, sc.params(params), keep_trace=keep_trace, **kwargs)


# ---------------------------------------------------------------------------------------------------------------
# Fitting


def _scaling(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation per column; a (near) constant column gets scale 1."""
    mean = a.mean(axis=0)
    std = a.std(axis=0)
    flat = ~(std > 1e-12 * np.maximum(np.abs(mean), 1.0))
    return mean, np.where(flat, 1.0, std)


def fit_network(
    X: np.ndarray,
    Y: np.ndarray,
    settings: FitSettings | None = None,
    *,
    seed: int = 0,
) -> tuple[mm.Network, FitInfo]:
    """Fit one network ``Y ~ f(X)`` on standardised inputs and outputs.

    With ``settings.linear`` (default) the fit has two parts: a linear least-squares model of the
    standardised data (the thermal network's derivatives are nearly linear in the states at given
    commands), and an :class:`~sklearn.neural_network.MLPRegressor` with ReLU units on its
    residual. Both go into one ReLU network exactly (:func:`compose_linear_skip`: ``x = relu(x) -
    relu(-x)`` carries the inputs through the hidden layers), so inference stays a plain MLP.
    Without it the MLP fits the standardised targets directly with ``settings.activation``.

    Parameters
    ----------
    X : numpy.ndarray
        Features ``(n, n_in)`` [feature units].
    Y : numpy.ndarray
        Targets ``(n, n_out)`` [target units].
    settings : FitSettings, optional
    seed : int
        ``random_state`` of the initial weights, the validation split and the batches.

    Returns
    -------
    Network, FitInfo
        The network (training range: the columns' min and max) and what the fit did.
    """
    try:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPRegressor
    except ImportError:
        raise EvtmsInputError(SKLEARN_MISSING) from None
    import warnings

    s = settings or FitSettings()
    X = np.asarray(X, np.float64)
    Y = np.asarray(Y, np.float64)
    if Y.ndim == 1:
        Y = Y[:, None]
    if X.shape[0] != Y.shape[0] or X.shape[0] < 10:
        raise ValueError(f"fit_network: {X.shape[0]} inputs and {Y.shape[0]} targets; need the same number >= 10")
    x_mean, x_scale = _scaling(X)
    y_mean, y_scale = _scaling(Y)
    Xn = (X - x_mean) / x_scale
    Yn = (Y - y_mean) / y_scale
    n = X.shape[0]
    activation = "relu" if s.linear else s.activation
    if s.linear:
        coef = np.linalg.lstsq(np.column_stack([Xn, np.ones(n)]), Yn, rcond=None)[0]
        A, c = coef[:-1], coef[-1]
        R = Yn - Xn @ A - c
        r_mean, r_scale = _scaling(R)
        target = (R - r_mean) / r_scale
    else:
        target = Yn
    reg = MLPRegressor(
        hidden_layer_sizes=s.hidden,
        activation=activation,
        solver="adam",
        alpha=s.alpha,
        batch_size=min(200, n),
        learning_rate_init=2e-3,
        max_iter=s.max_iter,
        early_stopping=n >= 100,
        validation_fraction=0.1,
        n_iter_no_change=10,
        tol=1e-6,
        random_state=seed,
    )
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        reg.fit(Xn, target[:, 0] if target.shape[1] == 1 else target)
    elapsed = time.perf_counter() - t0
    weights = [np.asarray(w, np.float64) for w in reg.coefs_]
    biases = [np.asarray(b, np.float64) for b in reg.intercepts_]
    if s.linear:
        weights, biases = compose_linear_skip(weights, biases, A, c, r_mean, r_scale)
    net = mm.Network(
        activation=activation,
        weights=[np.ascontiguousarray(w) for w in weights],
        biases=[np.ascontiguousarray(b) for b in biases],
        x_mean=x_mean,
        x_scale=x_scale,
        y_mean=y_mean,
        y_scale=y_scale,
        x_min=X.min(axis=0),
        x_max=X.max(axis=0),
    )
    return net, FitInfo(n_samples=n, epochs=int(reg.n_iter_), time_s=elapsed, loss=float(reg.loss_))


def compose_linear_skip(
    weights: list[np.ndarray],
    biases: list[np.ndarray],
    A: np.ndarray,
    c: np.ndarray,
    r_mean: np.ndarray,
    r_scale: np.ndarray,
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """One ReLU network computing ``x A + c + r_mean + r_scale mlp(x)`` exactly.

    ``weights``, ``biases``: a ReLU MLP with at least one hidden layer; ``A``
    ``(n_in, n_out)`` and ``c`` the linear part. Every hidden layer gets
    ``2 n_in`` more units holding ``relu(x)`` and ``relu(-x)`` (identity
    weights; a ReLU of a non-negative value is itself), and the output layer
    adds ``(relu(x) - relu(-x)) A = x A``.
    """
    if len(weights) < 2:
        raise ValueError("compose_linear_skip needs at least one hidden layer")
    n_in = weights[0].shape[0]
    eye = np.eye(n_in)
    pair = np.hstack([eye, -eye])
    W: list[np.ndarray] = [np.hstack([weights[0], pair])]
    B: list[np.ndarray] = [np.concatenate([biases[0], np.zeros(2 * n_in)])]
    for w, b in zip(weights[1:-1], biases[1:-1], strict=True):
        blk = np.zeros((w.shape[0] + 2 * n_in, w.shape[1] + 2 * n_in))
        blk[: w.shape[0], : w.shape[1]] = w
        blk[w.shape[0] :, w.shape[1] :] = np.eye(2 * n_in)
        W.append(blk)
        B.append(np.concatenate([b, np.zeros(2 * n_in)]))
    W.append(np.vstack([weights[-1] * r_scale, A, -A]))
    B.append(biases[-1] * r_scale + r_mean + c)
    return W, B


# ---------------------------------------------------------------------------------------------------------------
# Data


def training_setup(sc: D.Scenario, params: SystemParams | None):
    """A design scenario as the simulation engine's setup (:class:`evtms.system.scenarios.ScenarioSetup`).

    The same run as :func:`run_scenario` (the scenario's cycle, parameters, mode, humidity and sun; its
    initial cabin temperature goes with the run, :class:`evtms.system.sweep.Run`).
    """
    from evtms.system.scenarios import Scenario, ScenarioSetup

    p = sc.params(params)
    return ScenarioSetup(
        scenario=Scenario(name=sc.name, cycle=sc.cycle, mode=sc.mode, heating=p.hvac.heating),
        cycle=sc.drive_cycle(),
        T_amb=sc.T_amb,
        params=p,
        mode=sc.mode,
        RH_amb=sc.RH_amb,
        sun=sc.sun,
        inputs={},
        heating=p.hvac.heating,
    )


class TrainingData:
    """The engine's ``reduce`` for training runs: a run's step pairs of ``codes`` and its LUT records.

    Runs on the worker, so only the pairs and the records the held-out
    comparisons read (:data:`ROLLOUT_VARIABLES`) travel back, not the loop's trace.
    """

    def __init__(self, codes: set[int]) -> None:
        self.codes = frozenset(codes)

    def __call__(self, index: int, run, res: SimulationResult):
        pairs = {code: p for code, p in mm.training_pairs(res.trace).items() if code in self.codes}
        res.trace = None  # type: ignore[attr-defined]
        res.records = {v: res.records[v] for v in ROLLOUT_VARIABLES}
        return pairs, res


def _collect(
    scenarios: list[D.Scenario],
    refrigerant: Refrigerant,
    params: SystemParams | None,
    codes: set[int],
    tick: Callable[[str], None],
    runner=None,
) -> list[tuple[dict[int, tuple[np.ndarray, ...]], SimulationResult]]:
    """Each scenario's step pairs by mode code (only ``codes``) and its LUT result, in scenario order.

    The runs go through the simulation engine (:func:`evtms.system.sweep.run_batches`), in this
    process or on ``runner``'s workers; they come back in scenario order either way, so the fits
    (and the models) do not depend on where the runs ran.
    """
    from evtms.system.sweep import Run, SweepContext, run_batches

    setups = [training_setup(sc, params) for sc in scenarios]
    runs = [Run(i, sc.T_amb, soak_cabin=sc.T_cabin0) for i, sc in enumerate(scenarios)]
    context = SweepContext(setups, [refrigerant], runs, TrainingData(codes), {"dt": 1.0, "keep_trace": True})
    seen = [0]

    def done(n: int, total: int) -> None:
        for sc in scenarios[seen[0] : n]:
            tick(f"simulated {sc.name}")
        seen[0] = n

    return run_batches(context, runner, progress=done)


def _by_mode(
    scenarios: list[D.Scenario], out: list, codes: set[int]
) -> tuple[dict[int, list[tuple[np.ndarray, ...]]], dict[str, SimulationResult]]:
    """The step pairs of ``scenarios`` by mode code (in scenario order) and their results by name."""
    pairs: dict[int, list[tuple[np.ndarray, ...]]] = {c: [] for c in codes}
    results = {}
    for sc, (run_pairs, res) in zip(scenarios, out, strict=True):
        for code, p in run_pairs.items():
            pairs[code].append(p)
        results[sc.name] = res
    return pairs, results


def _stack(chunks: list[tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
    if not chunks:
        return (np.zeros((0, len(mm.POWER_FEATURES))), np.zeros((0, 1)), np.zeros((0, len(mm.DYNAMICS_FEATURES))),
                np.zeros((0, len(mm.DYNAMICS_TARGETS))))  # fmt: skip
    return tuple(np.concatenate([c[i] for c in chunks]) for i in range(4))


def _finite_rows(*arrays: np.ndarray) -> np.ndarray:
    ok = np.ones(arrays[0].shape[0], bool)
    for a in arrays:
        ok &= np.all(np.isfinite(a.reshape(a.shape[0], -1)), axis=1)
    return ok


# ---------------------------------------------------------------------------------------------------------------
# Held-out evaluation


def rollout_errors(lut: SimulationResult, sur: SimulationResult) -> dict[str, np.ndarray]:
    """Per variable of :data:`ROLLOUT_VARIABLES`, surrogate minus LUT on the common records (NaN-free)."""
    out = {}
    for v in ROLLOUT_VARIABLES:
        a, b = np.asarray(lut.records[v], float), np.asarray(sur.records[v], float)
        n = min(a.size, b.size)
        d = b[:n] - a[:n]
        out[v] = d[np.isfinite(d)]
    return out


def _summarise(diffs: list[dict[str, np.ndarray]], oor: list[float]) -> dict:
    s: dict = {}
    for v in ROLLOUT_VARIABLES:
        d = np.concatenate([x[v] for x in diffs]) if diffs else np.zeros(0)
        s[v] = {
            "rmse": float(np.sqrt(np.mean(d**2))) if d.size else math.nan,
            "max": float(np.max(np.abs(d))) if d.size else math.nan,
        }
    s["out_of_range"] = float(np.mean(oor)) if oor else math.nan
    s["runs"] = len(diffs)
    return s


#: Closed-loop check of a fit on the mode's own training runs: worst RMSE [K] accepted, refits, runs used.
STABLE_ROLLOUT_K = 1.0
FIT_ATTEMPTS = 3
ROLLOUT_CHECK_RUNS = 6


def _training_rollout_error(
    code: int,
    power: mm.Network,
    dyn: mm.Network,
    scenarios: list[D.Scenario],
    lut: dict[str, SimulationResult],
    refrigerant: Refrigerant,
    params: SystemParams | None,
) -> float:
    """Worst RMSE [K] of T_battery, T_cabin, T_coolant of the fitted mode against its LUT runs (inf: non-finite, or
    a run the model ended by leaving the physical range)."""
    if not scenarios:
        return math.nan
    models = mm.ModeModels({code: power}, {code: dyn})
    worst = 0.0
    for sc in scenarios:
        sur = run_scenario(sc, refrigerant, params, keep_trace=False, mode_models=models)
        # Compared over its shorter length, a run cut short would hide how far the model ran away.
        if sur.summary["termination"] == L.STOP_NAMES[L.STOP_SURROGATE_RANGE]:
            return math.inf
        for v in ("T_battery", "T_cabin", "T_coolant"):
            a, b = np.asarray(lut[sc.name].records[v], float), np.asarray(sur.records[v], float)
            n = min(a.size, b.size)
            d = b[:n] - a[:n]
            if not np.all(np.isfinite(d)):
                return math.inf
            worst = max(worst, float(np.sqrt(np.mean(d**2))))
    return worst


def _one_step(power: mm.Network, dyn: mm.Network, data: tuple[np.ndarray, ...]) -> dict[str, float]:
    xp, yp, xd, yd = data
    if yp.shape[0] == 0:
        return {k: math.nan for k in ONE_STEP}
    ep = power.predict(xp) - yp
    ed = dyn.predict(xd) - yd
    out = {}
    for name, (head, col) in ONE_STEP.items():
        e = (ep if head == "power" else ed)[:, col]
        out[name] = float(np.sqrt(np.mean(e**2)))
    return out


# ---------------------------------------------------------------------------------------------------------------
# The command


def check_modes(modes: list[str]) -> list[str]:
    """The mode names ``modes`` stand for (``all``: every one); an unknown or no mode is an input error."""
    for m in modes:
        if m != "all" and m not in D.MODE_NAMES:
            raise EvtmsInputError(f"`mode` {m!r} is unknown; allowed: {', '.join(D.MODE_NAMES)}, all")
    names = D.modes_for(list(modes))
    if not names:
        raise EvtmsInputError("`mode`: no mode given; allowed: " + ", ".join(D.MODE_NAMES) + ", all")
    return names


def train_surrogates(
    luts: str | Path | Refrigerant,
    modes: list[str],
    out_dir: str | Path,
    *,
    params: SystemParams | None = None,
    progress: Progress | None = None,
    seed: int = 0,
    quick: bool = False,
    settings: FitSettings | None = None,
    runs_per_mode: int = 24,
    runner=None,
) -> TrainReport:
    """Generate LUT simulations, fit the mode models of ``modes``, check them on held-out runs, write the file.

    Parameters
    ----------
    luts : str, Path or Refrigerant
        Folder of cycle LUTs (maps built and cached there when missing), or loaded maps.
    modes : list of str
        Mode names (:data:`evtms.surrogates.design.MODE_NAMES`) or ``all``.
    out_dir : str or Path
        Output folder; the file is ``<out_dir>/mode_models.npz``. Modes of an
        existing file there that are not retrained are kept.
    params : SystemParams, optional
        Base parameters (each scenario sets its own setpoint, initial temperatures and SOC on top).
    progress : callable, optional
        ``progress(done, total, message)`` after each simulation and fit.
    seed : int
        Seed of the scenario design and of every fit.
    quick : bool
        Small design and tiny networks (tests; errors are not representative).
    settings : FitSettings, optional
        Network sizes and epochs (default :class:`FitSettings`, or :meth:`FitSettings.quick` with ``quick``).
    runs_per_mode : int
        Training simulations per mode.
    runner : InProcessRunner or DaskRunner, optional
        Where the LUT simulations run (:func:`evtms.system.sweep.make_runner`; default: this process).
        The models are the same wherever they run.

    Returns
    -------
    TrainReport

    Raises
    ------
    EvtmsInputError
        An unknown mode name, an output that is a file, an existing model
        file that does not load, no mode with enough training steps, or
        scikit-learn missing (all but too few steps before any simulation).
    """
    t_start = time.perf_counter()
    names = check_modes(modes)
    settings = settings or (FitSettings.quick() if quick else FitSettings())
    if importlib.util.find_spec("sklearn") is None:
        raise EvtmsInputError(SKLEARN_MISSING)
    if Path(out_dir).exists() and not Path(out_dir).is_dir():
        raise EvtmsInputError(f"`output` {out_dir}: exists and is not a folder")
    path = Path(out_dir) / FILE_NAME
    existing = load_mode_models(path) if path.exists() else None
    refrigerant = luts if isinstance(luts, Refrigerant) else load_refrigerant(luts, params)
    des = D.design(names, seed=seed, runs_per_mode=runs_per_mode, quick=quick)
    total = len(des.train) + 2 * len(des.heldout) + 2 * len(names)
    done = 0

    def tick(message: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total, message)

    codes = {mm.MODE_CODES[m] for m in names}
    t0 = time.perf_counter()
    out = _collect(des.train + des.heldout, refrigerant, params, codes, tick, runner)  # one install of the maps
    train_pairs, train_lut = _by_mode(des.train, out[: len(des.train)], codes)
    held_pairs, held_lut = _by_mode(des.heldout, out[len(des.train) :], codes)
    data_time = time.perf_counter() - t0

    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    reports: dict[str, ModeReport] = {}
    skipped: dict[str, str] = {}
    power: dict[int, mm.Network] = {}
    dynamics: dict[int, mm.Network] = {}
    for m in names:
        code = mm.MODE_CODES[m]
        xp, yp, xd, yd = _stack(train_pairs[code])
        ok = _finite_rows(xp, yp, xd, yd)
        xp, yp, xd, yd = xp[ok], yp[ok], xd[ok], yd[ok]
        n_train = xp.shape[0]
        if n_train < MIN_SAMPLES:
            skipped[m] = f"{n_train} training steps in mode {m}; at least {MIN_SAMPLES} needed"
            tick(f"skipped {m}")
            tick(f"skipped {m}")
            continue
        if n_train > settings.max_samples:
            sel = np.sort(rng.choice(n_train, settings.max_samples, replace=False))
            xp, yp, xd, yd = xp[sel], yp[sel], xd[sel], yd[sel]
        # A fit that is good step by step can still run away in closed loop: check it on the mode's own training
        # scenarios (forced runs; no held-out data) and refit with another seed when it does, keeping the best.
        forced_runs = [sc for sc in des.train if sc.target == m and sc.mode == m][:ROLLOUT_CHECK_RUNS]
        best = None
        for attempt in range(FIT_ATTEMPTS):
            fit_seed = seed + 1000 * attempt
            p_net, fit_p = fit_network(xp, yp, settings, seed=fit_seed)
            d_net, fit_d = fit_network(xd, yd, settings, seed=fit_seed)
            err = _training_rollout_error(code, p_net, d_net, forced_runs, train_lut, refrigerant, params)
            if best is None or err < best[0]:
                best = (err, p_net, fit_p, d_net, fit_d, attempt + 1)
            if not err > STABLE_ROLLOUT_K:  # NaN: no forced training run to check against, keep the fit
                break
        err, power[code], fit_p, dynamics[code], fit_d, attempts = best
        tick(f"fitted {m} power ({fit_p.epochs} epochs, {fit_p.time_s:.1f} s)")
        tick(f"fitted {m} dynamics ({fit_d.epochs} epochs, {fit_d.time_s:.1f} s; {attempts} fit(s))")
        held = _stack(held_pairs[code])
        ok = _finite_rows(*held)
        held = tuple(a[ok] for a in held)
        reports[m] = ModeReport(
            mode=m,
            code=code,
            n_train=n_train,
            n_fitted=xp.shape[0],
            n_heldout=held[0].shape[0],
            fit_power=fit_p,
            fit_dynamics=fit_d,
            one_step=_one_step(power[code], dynamics[code], held),
            fit_attempts=attempts,
            train_rollout_rmse_K=err,
        )
    fit_time = time.perf_counter() - t0
    if not reports:
        raise EvtmsInputError("no mode model trained: " + "; ".join(skipped.values()))

    kept: list[str] = []
    attrs_scen: dict = {}
    attrs_metrics: dict = {}
    if existing is not None:
        for name, code in mm.MODE_CODES.items():
            if name not in reports and code in existing.codes():
                power[code], dynamics[code] = existing.power[code], existing.dynamics[code]
                kept.append(name)
                attrs_scen[name] = existing.attrs.get("scenarios", {}).get(name, [])
                attrs_metrics[name] = existing.attrs.get("metrics", {}).get(name, {})
    models = mm.ModeModels(power=power, dynamics=dynamics)

    t0 = time.perf_counter()
    auto = None
    diffs: dict[str, list] = {}
    oor: dict[str, list] = {}
    for sc in des.heldout:
        target = sc.target
        if target != "auto" and target not in reports:
            tick(f"no model for {sc.name}")
            continue
        sur = run_scenario(sc, refrigerant, params, keep_trace=False, mode_models=models)
        diffs.setdefault(target, []).append(rollout_errors(held_lut[sc.name], sur))
        oor.setdefault(target, []).append(float(np.mean((sur.flags & L.F_SURROGATE_OOR) > 0)))
        tick(f"surrogate {sc.name}")
    for m, rep in reports.items():
        if m in diffs:
            rep.rollout = _summarise(diffs[m], oor[m])
    if "auto" in diffs:
        auto = _summarise(diffs["auto"], oor["auto"])
    eval_time = time.perf_counter() - t0

    for m, rep in reports.items():
        attrs_scen[m] = [s.to_dict() for s in des.train if s.target == m] + [
            s.to_dict() for s in des.heldout if s.target == m
        ]
        attrs_metrics[m] = {
            "n_train": rep.n_train,
            "n_fitted": rep.n_fitted,
            "n_heldout": rep.n_heldout,
            "fit_power": dataclasses.asdict(rep.fit_power),
            "fit_dynamics": dataclasses.asdict(rep.fit_dynamics),
            "one_step_rmse": rep.one_step,
            "rollout": rep.rollout,
        }
    if auto is not None:
        attrs_metrics["auto"] = auto
        attrs_scen["auto"] = [s.to_dict() for s in des.heldout if s.target == "auto"]
    models.attrs = {
        "evtms_version": evtms.__version__,
        "seed": seed,
        "quick": quick,
        "fit_settings": dataclasses.asdict(settings),
        "dt": 1.0,
        "held_out_cycles": list(D.HELDOUT_CYCLES),
        "held_out_ambients_degC": list(D.HELDOUT_AMBIENTS_C),
        "scenarios": attrs_scen,
        "metrics": _json_safe(attrs_metrics),
        "kept_from_previous_file": kept,
    }
    save_mode_models(models, path)
    return TrainReport(
        path=path,
        modes=reports,
        skipped=skipped,
        auto=auto,
        kept=kept,
        n_train_runs=len(des.train),
        n_heldout_runs=len(des.heldout),
        data_time_s=data_time,
        fit_time_s=fit_time,
        eval_time_s=eval_time,
        total_time_s=time.perf_counter() - t_start,
    )


def _json_safe(obj):  # noqa: ANN001, ANN202
    """NaN -> None, recursively (JSON has no NaN)."""
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
